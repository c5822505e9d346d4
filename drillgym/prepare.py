"""Compile once what ``drillgym diagnose`` and :func:`drillgym.identify` run, so that the first
identification of a recording is as fast as the next.

A diagnosis fits one search model per configuration (the base model with every candidate effect of
the configuration held at its neutral values, :func:`drillgym.diagnosis.diagnose`), and the joint fit of a
model without a motor lag runs that search model without it (its runs are the model's to the bit); numba
compiles their kernels on first use (about a minute on 2 cores) and caches them on disk
(:mod:`drillgym.effects.codegen`).  :func:`prepare_identification` runs the whole command's path on a
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

__all__ = ["prepare_identification", "PREPARED_CONFIGS"]

#: the rig's configurations with the motor driving (their search models are compiled by ``make venv``: a
#: lateral model compiled in the user's first diagnosis took 45-80 s of it on 2 cores, beyond the 60 s that a
#: diagnosis of 60 s of 1 kHz data should take)
PREPARED_CONFIGS = ("torsional", "coupled", "lateral", "upper")


def prepare_identification(
    configs: Sequence[str] = PREPARED_CONFIGS, duration: float = 6.0, workers: int | None = None
) -> dict[str, float]:
    """Compile the identification's kernels: identify a short simulated recording of each configuration.

    Runs :func:`drillgym.identify` (as ``drillgym diagnose --model-out`` and ``drillgym identify`` do: the
    diagnosis, the discovery of a candidate, the joint fit) with the library's default candidates, the
    configurations side by side (their models share no kernels; numba compiles on one core).

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
    from .configurations import parse_configuration
    from .parallel import map_ordered, open_executor

    names = list(configs)
    n = max(1, min(len(names), workers or os.cpu_count() or 1))
    with open_executor(None, n) or nullcontext() as executor:
        seconds = map_ordered(executor, _prepare_one, [(name, duration) for name in names])
    return {parse_configuration(name).label: t for name, t in zip(names, seconds)}


def _prepare_one(name: str, duration: float) -> float:
    """Identify a short simulated recording of one configuration (:func:`drillgym.identify`: the diagnosis, the
    discovery, the joint fit of a model without a motor lag on the search model without it); its seconds."""
    from .configurations import parse_configuration
    from .identification.synthetic import synthetic_measurement
    from .identified import identify

    cfg = parse_configuration(name)
    t0 = time.perf_counter()
    ts = synthetic_measurement(cfg.label, duration=duration, rate_hz=250.0, seed=0)
    with tempfile.TemporaryDirectory() as tmp:
        identify(ts, candidate_out=Path(tmp) / "candidate.py")
    return time.perf_counter() - t0
