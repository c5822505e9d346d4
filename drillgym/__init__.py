"""drillgym: a testbed for friction-induced vibrations in a drill-string rotor rig.

The physics core (parameters, equations of motion, set-valued friction,
integrators, equilibria) lives in this package and depends on nothing else in
the repository.  Importing ``drillgym`` also registers the Gymnasium
environments ``drillgym/Torsional-v0``, ``drillgym/Lateral-v0``,
``drillgym/Coupled-v0`` (and ``drillgym/Hardware-v0``) when they are available.
"""

from ._kernel_cache import invalidate_stale_kernels
from ._simd import prefer_full_vector_width

prefer_full_vector_width()  # 512-bit vectors on AVX-512 hosts (opt out: DRILLGYM_SIMD=256)
invalidate_stale_kernels()  # before any compiled kernel is loaded from numba's cache

from .configurations import N_STATE, STATE_NAMES, Configuration, parse_configuration
from .errors import (
    DataFormatError,
    DrillgymError,
    EffectError,
    FitError,
    InputError,
    InputTypeError,
    MissingFileError,
    OutputPathError,
    ParameterError,
    SafetyError,
    SimulationError,
    UnavailableError,
)
from .integrators import DEFAULT_DT, OUTPUT_NAMES
from .params import RigParams
from .simulator import BatchSimulator, BatchTrajectory, Trajectory, initial_state, simulate, simulate_batch

__version__ = "0.1.0"

__all__ = [
    "Configuration",
    "N_STATE",
    "STATE_NAMES",
    "parse_configuration",
    "DEFAULT_DT",
    "OUTPUT_NAMES",
    "ParameterError",
    "RigParams",
    "BatchSimulator",
    "BatchTrajectory",
    "Trajectory",
    "initial_state",
    "simulate",
    "simulate_batch",
    "DrillgymError",
    "InputError",
    "InputTypeError",
    "DataFormatError",
    "EffectError",
    "OutputPathError",
    "MissingFileError",
    "SimulationError",
    "FitError",
    "UnavailableError",
    "SafetyError",
]

import importlib.util as _ilu

if _ilu.find_spec("drillgym.envs") is not None:  # registers the Gymnasium ids
    from . import envs as _envs  # noqa: F401
