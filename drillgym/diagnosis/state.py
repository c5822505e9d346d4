"""What the diagnosis' steps hand each other: the settings, the screened recording, the search's outcome.

The steps of :func:`.pipeline.diagnose` (:mod:`.screening`, :mod:`.orders`, :mod:`.checks`, :mod:`.ranking`,
:mod:`.input_order`, :mod:`.discovery`, :mod:`.candidate_fit`, :mod:`.reselection`) import from here and from
the modules below them, never from each other (an import-linter contract in ``pyproject.toml``): each takes
what it needs and returns its result, and the pipeline puts the results together.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..configurations import Configuration
from ..effects import Composition
from ..identification.experiment import Experiment
from ..params import N_PARAMS, RigParams
from .option_checks import as_sequence, check_diagnosis_options
from .results import Selection
from .search_model import SearchModel
from .selection_options import SelectionOptions
from .timing import FineDecision

__all__ = ["DiagnosisOptions", "Screening", "SearchOutcome", "REFIT_BUDGET", "transfer"]

#: joint refits' budget, times the selection's, when the model's own effects are refitted with the base: a
#: discovered candidate fitted without the library effect beside it starts far from where the two end together
#: (a dead zone's width and a 39 ms motor lag: 21 ms after the usual 15 evaluations, 37 ms converged, and the
#: residual on the motor angle 30 -> 1.6 noise units)
REFIT_BUDGET = 3


@dataclass
class DiagnosisOptions:
    """The settings of a diagnosis.

    Attributes
    ----------
    effects : sequence, optional
        The candidates: names, ``path/to/file.py:NAME`` specs or Effect classes (default: the library's
        effects that act in the configuration).  A candidate must vanish at its neutral values
        (:func:`.context.neutral_values`).
    base_effects : any, optional
        Effects already in the model (as :func:`drillgym.effects.compose`), held at ``effect_params``.
    effect_params : mapping of str to float, optional
        Their values.
    segment_s : float or None
        Multiple-shooting segment length (s); -1: :func:`default_segment`; None: one free run.  Default -1.
    compare_rate_hz : float
        Comparison grid rate (Hz) when a recording is given.  Default 50.
    lvdt_lowpass_hz : float or None
        LVDT low-pass cut-off (Hz) when a recording is given.  Default 5.
    refine_speeds : bool
        Fit the segments' initial speeds with every model.  Default True.
    fixed_base : bool
        Hold the base parameters at the nominal ones (no re-identification).  Default False.
    refit_model_effects : bool
        Free the parameters of the model's own effects (``base_effects``) wherever the base parameters are
        freed (with ``fixed_base``: in their place): an estimate held fixed (a discovered candidate's first fit)
        leaves a residual no library effect beside it can remove, where refitting both together does.
        Default False.
    held_effect_params : sequence of str
        Parameters of the model's own effects held at their values where ``refit_model_effects`` frees the
        others (the terms of its group a candidate does not use, :mod:`.group_terms`, at 0).  Default none.
    n_joint : int
        Candidates refitted jointly with the base parameters per round.  Default 2.
    max_effects : int
        At most this many effects are selected.  Default 4.
    discover : bool
        Also look for an effect outside the library in the residual torques (:mod:`.discovery`), on the
        recording's own samples (up to 250 Hz).  Default False.
    candidate_out : str or path, optional
        With ``discover``: where to write the candidate's effect file (a second candidate's goes beside it,
        ``NAME_2.py``).
    max_candidates : int
        With ``discover``: candidates outside the library found in turn.  Once one is kept and the library
        selected again beside it, discovery runs on that model's residual for the next (two unknown effects, one
        in the drive and one on a disc, leave a residual no single group of terms explains).  Default 1: on a
        recording of a rig that differs from the model beyond the noise, the next search also finds a share of
        that floor to take (docs/identify.md).
    """

    effects: Sequence[Any] | None = None
    base_effects: Any = None
    effect_params: Mapping[str, float] | None = None
    segment_s: float | None = -1.0
    compare_rate_hz: float = 50.0
    lvdt_lowpass_hz: float | None = 5.0
    refine_speeds: bool = True
    fixed_base: bool = False
    refit_model_effects: bool = False
    held_effect_params: Sequence[str] = ()
    n_joint: int = 2
    max_effects: int = 4
    discover: bool = False
    candidate_out: Any = None
    max_candidates: int = 1

    def __post_init__(self) -> None:
        self.effects = as_sequence("effects", self.effects)
        check_diagnosis_options(self)

    def selection(self) -> SelectionOptions:
        """The options of the forward selection."""
        joint = SelectionOptions.max_nfev_joint * (REFIT_BUDGET if self.refit_model_effects else 1)
        return SelectionOptions(
            n_joint=self.n_joint,
            max_effects=self.max_effects,
            refine=self.refine_speeds,
            max_nfev_joint=joint,
            guard_base=not self.refit_model_effects,
        )


@dataclass
class Screening:
    """A recording screened for the selection.

    Attributes
    ----------
    exps : list of Experiment
        The conditioned experiments.
    config : Configuration
        Their configuration.
    model_label : str
        The label of the model diagnosed (its effects).
    segment_s : float or None
        Multiple-shooting segment length (s).
    model : SearchModel
        The search model.
    skipped : dict of str to str
        Candidates not tried, and why.
    channel_rms_before : dict of str to float
        The nominal model's residual RMS per channel (noise units).
    """

    exps: list[Experiment]
    config: Configuration
    model_label: str
    segment_s: float | None
    model: SearchModel
    skipped: dict[str, str] = field(default_factory=dict)
    channel_rms_before: dict[str, float] = field(default_factory=dict)


@dataclass
class SearchOutcome:
    """What the search found: the model kept, what each order selected, the sensors' weights.

    Attributes
    ----------
    kept : Selection
        The model kept (the checks may replace it).
    paths : dict of str to list of str
        Each order's selection (``bound:NAME``: a base parameter at a bound of its range).
    sensor_misfit : dict of str to float
        Sensor -> the misfit (noise units) its channels were rescaled by.
    scales : dict of str to float
        The channels' scales as weighted.
    lag_delay : FineDecision or None
        The lag/delay decision at the recording's rate (set by the checks).
    """

    kept: Selection
    paths: dict[str, list[str]] = field(default_factory=dict)
    sensor_misfit: dict[str, float] = field(default_factory=dict)
    scales: dict[str, float] = field(default_factory=dict)
    lag_delay: FineDecision | None = None


def transfer(vec: np.ndarray, src: Composition, dst: Composition) -> np.ndarray:
    """A parameter vector of ``dst`` taking every parameter ``src`` has from ``vec`` (the others at their defaults).

    Parameters
    ----------
    vec : numpy.ndarray
        A vector of ``src``.
    src, dst : Composition
        The compositions.

    Returns
    -------
    numpy.ndarray
        The vector of ``dst``.
    """
    out = dst.vector(RigParams.from_vector(np.asarray(vec)[:N_PARAMS]))
    for i, n in enumerate(src.param_names[N_PARAMS:], start=N_PARAMS):
        if n in dst.param_names:
            out[dst.param_index(n)] = vec[i]
    return out
