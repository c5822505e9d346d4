"""Compile once what ``drillgym diagnose`` runs, so that the first diagnosis of a recording is as fast
as the next.

A diagnosis fits one search model per configuration (the base model with every candidate effect of
the configuration held at its neutral values, :func:`drillgym.diagnosis.diagnose`); numba
compiles its kernels on first use (about a minute on 2 cores) and caches them on disk
(:mod:`drillgym.effects.codegen`).  :func:`prepare_diagnosis` runs the whole command's path on a
few seconds of simulated data per configuration, so the cache holds them; ``make venv`` calls it
(``drillgym prepare``).
"""

from __future__ import annotations

import os
import tempfile
import time
from collections.abc import Sequence
from contextlib import nullcontext
from pathlib import Path

__all__ = ["prepare_diagnosis", "PREPARED_CONFIGS"]

#: the rig's configurations with the motor driving (their search models are compiled by ``make venv``: a
#: lateral model compiled in the user's first diagnosis took 45-80 s of it on 2 cores, beyond the 60 s that a
#: diagnosis of 60 s of 1 kHz data should take)
PREPARED_CONFIGS = ("torsional", "coupled", "lateral", "upper")


def prepare_diagnosis(
    configs: Sequence[str] = PREPARED_CONFIGS, duration: float = 6.0, workers: int | None = None
) -> dict[str, float]:
    """Compile the diagnosis' kernels: diagnose a short simulated recording of each configuration.

    Runs ``diagnose`` and the discovery of a candidate (as ``drillgym diagnose`` does) with the library's
    default candidates, the configurations side by side (their models share no kernels; numba compiles on one
    core: 127 s one after the other on 2 cores, about half of it side by side).

    Parameters
    ----------
    configs : sequence of str, optional
        The configurations.
    duration : float, optional
        Length of each recording (s).  Default 6.
    workers : int, optional
        Processes compiling side by side (default: the machine's cores, at most one per configuration; 1: in
        this process).

    Returns
    -------
    dict of str to float
        The seconds each configuration took (compilation included when the kernels were not cached yet).
    """
    from ..configurations import parse_configuration
    from ..parallel import map_ordered, open_executor

    names = list(configs)
    n = max(1, min(len(names), workers or os.cpu_count() or 1))
    with open_executor(None, n) or nullcontext() as executor:
        seconds = map_ordered(executor, _prepare_one, [(name, duration) for name in names])
    return {parse_configuration(name).label: t for name, t in zip(names, seconds)}


def _prepare_one(name: str, duration: float) -> float:
    """Diagnose (and discover on) a short simulated recording of one configuration; its seconds."""
    from ..configurations import Configuration, parse_configuration
    from ..identification.experiment import prepare_experiment
    from ..identification.synthetic import synthetic_measurement
    from .discovery import discover
    from .pipeline import diagnose

    cfg = parse_configuration(name)
    t0 = time.perf_counter()
    ts = synthetic_measurement(cfg.label, duration=duration, rate_hz=250.0, seed=0)
    d = diagnose(prepare_experiment(ts, compare_rate_hz=50.0))
    if cfg is not Configuration.UPPER:
        with tempfile.TemporaryDirectory() as tmp:
            discover(prepare_experiment(ts, compare_rate_hz=250.0), d, Path(tmp) / "candidate.py")
    return time.perf_counter() - t0
