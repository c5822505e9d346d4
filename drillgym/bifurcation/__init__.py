"""Open-loop bifurcation analysis of the rig (report chapter 4).

* :mod:`.equilibrium_branch` - equilibria versus voltage, stability, Hopf points
* :mod:`.poincare`, :mod:`.shooting`, :mod:`.continuation` - periodic solutions of the
  non-smooth system: event-aware shooting on a Poincare section, Floquet multipliers,
  pseudo-arclength continuation, (discontinuous) folds
* :mod:`.verification` - independent checks of periodic solutions by direct simulation
* :mod:`.sweeps` - brute-force sweeps through a ``concurrent.futures.Executor``
* :mod:`.measured` - diagrams from measurement files; the report's measured points
* :mod:`.diagram` - everything for one configuration (``compute_diagram``), JSON output
* :mod:`.plots` - the report-style figures
"""

from .continuation import Fold, PeriodicBranch, continue_branch, start_at_hopf
from .diagram import BifurcationDiagram, compute_diagram, periodic_branches
from .equilibrium_branch import EquilibriumBranch, HopfPoint, equilibrium_branch
from .measured import REPORT_POINTS, measured_diagram, measured_point
from .shooting import PeriodicSolution, ShootingFailure, shoot
from .sweeps import SweepResult, sweep_constant, sweep_staircase

__all__ = [
    "Fold",
    "PeriodicBranch",
    "continue_branch",
    "start_at_hopf",
    "BifurcationDiagram",
    "compute_diagram",
    "periodic_branches",
    "EquilibriumBranch",
    "HopfPoint",
    "equilibrium_branch",
    "REPORT_POINTS",
    "measured_diagram",
    "measured_point",
    "PeriodicSolution",
    "ShootingFailure",
    "shoot",
    "SweepResult",
    "sweep_constant",
    "sweep_staircase",
]
