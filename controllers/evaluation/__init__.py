"""Evaluation harness shared by the controllers and the RL agents.

* :mod:`.scenarios` - start from rest / from a stick-slip cycle, friction +-20 %, sensor noise
* :mod:`.runner` - batched closed-loop simulation with the rig's measurement chain
* :mod:`.metrics` - SSI, stuck fraction, tracking RMS, voltage, energy, lowest stick-slip-free speed
* :mod:`.harness` - all jobs in parallel with a progress bar (:func:`evaluate`)
* :mod:`.population`, :mod:`.plants_file`, :mod:`.population_jobs` - a population of plants: drawn from an
  uncertainty set or listed in a plants file (:func:`load_plants`), and its jobs
* :mod:`.report` - CSV and markdown tables, SSI-versus-target figure
"""

from .harness import evaluate, run_job
from .metrics import SSI_THRESHOLD, lowest_free_speed, run_metrics, stick_slip_severity
from .plants_file import load_plants
from .runner import ClosedLoopRun, run_closed_loop
from .scenarios import DEFAULT_TARGETS, SCENARIOS, Scenario, parse_scenarios

__all__ = [
    "evaluate",
    "run_job",
    "load_plants",
    "SSI_THRESHOLD",
    "lowest_free_speed",
    "run_metrics",
    "stick_slip_severity",
    "ClosedLoopRun",
    "run_closed_loop",
    "DEFAULT_TARGETS",
    "SCENARIOS",
    "Scenario",
    "parse_scenarios",
]
