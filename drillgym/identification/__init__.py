"""Parameter identification from recordings (report chapter 3).

* :mod:`.experiment` — recordings on a comparison grid, speeds and initial states from data;
* :mod:`.segmented` — batched multiple-shooting model predictions;
* :mod:`.fitting` — weighted trf least squares, standard errors, identifiability warnings;
* :mod:`.metrics` — the report's R² and RMS per channel;
* :mod:`.staged` — the report's staged procedure (upper, lower without brake, lateral, brake).
"""

from .experiment import Experiment, prepare_experiment
from .fitting import FitResult, FitVariable, IdentifiabilityWarning, Objective, default_scales, fit_parameters
from .metrics import channel_metrics, r2, rms
from .segmented import SegmentedModel

__all__ = [
    "Experiment",
    "prepare_experiment",
    "FitResult",
    "FitVariable",
    "IdentifiabilityWarning",
    "Objective",
    "default_scales",
    "fit_parameters",
    "channel_metrics",
    "r2",
    "rms",
    "SegmentedModel",
]
