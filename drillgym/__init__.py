"""drillgym: a testbed for friction-induced vibrations in a drill-string rotor rig.

The physics core (parameters, equations of motion, set-valued friction,
integrators, equilibria) lives in this package and depends on nothing else in
the repository.  Importing ``drillgym`` also registers the Gymnasium
environments ``drillgym/Torsional-v0``, ``drillgym/Lateral-v0``,
``drillgym/Coupled-v0`` (and ``drillgym/Hardware-v0``) when they are available:
at once if Gymnasium is imported already, else as soon as it is
(:mod:`drillgym._import_hooks`).

``import drillgym`` is light: the simulator, the parameters and the other names
of ``__all__`` load on first use (``from drillgym import simulate`` as before).
"""

from typing import TYPE_CHECKING

from . import _import_hooks
from ._lazy import lazy_names

# When numba loads (or now, if it is loaded): 512-bit vectors on AVX-512 hosts (opt out: DRILLGYM_SIMD=256;
# before numba, as it reads them, not here: it would load LLVM, 110 MB) and the stale kernels dropped from
# numba's cache; the Gymnasium ids registered when gymnasium loads (or now)
_import_hooks.install()

from .configurations import N_STATE, STATE_NAMES, Configuration, parse_configuration
from .errors import (
    DataFormatError,
    DrillgymError,
    EffectError,
    FitError,
    FitFailedError,
    InputError,
    InputTypeError,
    MissingFileError,
    OutputPathError,
    ParameterError,
    SafetyError,
    SimulationError,
    UnavailableError,
)

if TYPE_CHECKING:  # pragma: no cover - the names below load on first use (_LAZY)
    from .identified import Identified, IdentifyOptions, identify
    from .integrators import DEFAULT_DT, OUTPUT_NAMES
    from .model import Encoders, Model, Provenance
    from .params import RigParams
    from .simulator import BatchSimulator, BatchTrajectory, Trajectory, initial_state, simulate, simulate_batch

#: name -> the module that defines it, imported on first use (PEP 562): ``import drillgym`` and the
#: command line's ``--help`` do not load the simulator, numba, scipy or the environments
_LAZY = {
    "DEFAULT_DT": "integrators",
    "OUTPUT_NAMES": "integrators",
    "Identified": "identified",
    "IdentifyOptions": "identified",
    "identify": "identified",
    "Encoders": "model",
    "Model": "model",
    "Provenance": "model",
    "RigParams": "params",
    "BatchSimulator": "simulator",
    "BatchTrajectory": "simulator",
    "Trajectory": "simulator",
    "initial_state": "simulator",
    "simulate": "simulator",
    "simulate_batch": "simulator",
}

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
    "Model",
    "Encoders",
    "Provenance",
    "identify",
    "Identified",
    "IdentifyOptions",
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
    "FitFailedError",
    "UnavailableError",
    "SafetyError",
]


__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
