"""Weighted nonlinear least squares of model parameters on recorded experiments.

The cost is the report's: Σ over channels of weight² · Σ (ŷ − y)² / scale²,
minimised by scipy's ``least_squares`` (trust-region reflective, bounds).  The
finite-difference Jacobian comes from ONE batched simulation of the n
perturbed parameter rows (:class:`SegmentedModel` runs them in parallel).

Results: fitted values, standard errors from the Jacobian
(cov = s² (JᵀJ)⁻¹, s² = RSS / (N − n); residual samples are correlated, so
these are lower bounds), and warnings when a parameter is not identifiable
from the data given (relative standard error > 10 %, near-singular JᵀJ:
collinearity index 1/σmin of the column-normalised Jacobian > 1000, or the
estimate at a bound).
"""

from __future__ import annotations

import copy
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import least_squares

from ..effects import Composition
from ..errors import FitFailedError, InputError, ParameterError
from ..params import N_PARAMS, RigParams
from .blas import on_one_blas_thread
from .experiment import Experiment
from .least_squares import ApplyFn, FitOptions, GaussianPrior, ResidualFunction, ScaledBox, identifiability
from .reading_noise import ANGLE_FLOOR_RAD, finest_angle_noise
from .segmented import SegmentedModel
from .variables import FitVariable, SpeedVariables

__all__ = [
    "FitVariable",
    "Objective",
    "FitResult",
    "FitOptions",
    "SpeedVariables",
    "fit_parameters",
    "default_scales",
    "IdentifiabilityWarning",
    "base_vector",
]


class IdentifiabilityWarning(UserWarning):
    """A parameter cannot be determined well from the data given."""


def default_scales(experiments: Sequence[Experiment]) -> dict[str, float]:
    """Residual scale per channel (≈ measurement noise).

    Parameters
    ----------
    experiments : sequence of Experiment
        The recordings.

    Returns
    -------
    dict of str to float
        Angles the finest reading's noise (:func:`.reading_noise.angle_noise`: one encoder count / √12, or
        the scatter of a reading off any lattice of counts; at least 1e-4 rad), LVDT channels 10 µm.
    """
    finest = finest_angle_noise(ex.meas[c] for ex in experiments for c in ("theta_u", "theta_l") if c in ex.meas)
    sa = max(finest or 0.0, ANGLE_FLOOR_RAD)
    sl = 1e-5
    return {"theta_u": sa, "theta_l": sa, "alpha": sa, "x": sl, "y": sl, "r": sl}


class Objective:
    """Normalised residuals of parameter rows on experiments.

    Parameters
    ----------
    model : SegmentedModel
        The multiple-shooting predictor.
    weights : dict of str to float
        Channel -> weight (e.g. ``{"theta_l": 1, "alpha": 13}``); channels an experiment lacks are skipped.
    scales : dict of str to float, optional
        Channel -> residual scale (default :func:`default_scales`).

    Raises
    ------
    InputError
        None of the channels is in the data.
    """

    def __init__(
        self, model: SegmentedModel, weights: dict[str, float], scales: dict[str, float] | None = None
    ) -> None:
        self.model = model
        self.weights = dict(weights)
        self.scales = dict(scales or default_scales(model.experiments))
        self._meas = []
        for k, ex in enumerate(model.experiments):
            chans = [
                c
                for c in weights
                if c in ex.meas or (c == "alpha" and "theta_l" in ex.meas) or (c == "r" and "x" in ex.meas)
            ]
            self._meas.append({c: model.measured_segments(k, c) for c in chans})
        self.channels = sorted({c for m in self._meas for c in m})
        if not self.channels:
            raise InputError(f"none of the channels {list(weights)} is in the data")
        #: index into :attr:`channels` of every entry of a residual row (the layout of :meth:`residual_matrix`)
        self.channel_ids = np.concatenate(
            [
                np.full(int(np.count_nonzero(~np.isnan(m[:, 1:]))), self.channels.index(c))
                for meas in self._meas
                for c, m in meas.items()
            ]
        )
        #: index of the independent block (experiment, channel, multiple-shooting segment) of every entry of a
        #: residual row: a segment re-started from the data does not carry its misfit over to the next one
        rows = [np.count_nonzero(~np.isnan(m[:, 1:]), axis=1) for meas in self._meas for m in meas.values()]
        counts = np.concatenate(rows) if rows else np.zeros(0, dtype=int)
        self.block_ids = np.repeat(np.arange(len(counts)), counts)
        #: index of the multiple-shooting segment (numbered over all experiments) of every entry of a residual row
        first = np.cumsum([0] + [len(model.segments(k)[0]) for k in range(len(model.experiments))])
        seg = (
            np.concatenate(
                [first[k] + np.arange(m.shape[0]) for k, meas in enumerate(self._meas) for m in meas.values()]
            )
            if rows
            else np.zeros(0, dtype=int)
        )
        self.segment_ids = np.repeat(seg, counts)
        self.segment_offsets = first[:-1]
        #: per (experiment, channel) of a residual row: the flat indices of its measured samples in a segment
        #: array's (n_seg, seg_len - 1) tail, and the measured values there
        self._layout = [
            {
                c: (idx, m[:, 1:].ravel()[idx])
                for c, m in meas.items()
                for idx in [np.flatnonzero(~np.isnan(m[:, 1:]).ravel())]
            }
            for meas in self._meas
        ]

    def with_own_speeds(self) -> Objective:
        """The same objective on a copy of its model whose speed corrections at the segment starts are its own
        (started from the model's): a fit that moves them, or refines them per point, can run beside others on
        this one.  The measured segments and residual layout are shared, not derived again."""
        other = copy.copy(self)
        other.model = self.model.with_composition(self.model.composition)
        other.weights, other.scales = dict(self.weights), dict(self.scales)
        return other

    def residual_matrix(self, P: np.ndarray, dspeed: np.ndarray | None = None) -> np.ndarray:
        """Weighted, normalised residuals (model − data); a segment's first sample is skipped.

        Parameters
        ----------
        P : numpy.ndarray
            Parameter rows (B, n_params).
        dspeed : numpy.ndarray, optional
            (B, 2): (ω_u, ω_l) added to every segment's initial speeds of that row (rad/s).

        Returns
        -------
        numpy.ndarray
            (B, M) residuals.
        """
        per_exp = self.model.predict_arrays(P, tuple(self.channels), dspeed=dspeed)
        parts = []
        for outputs, layout in zip(per_exp, self._layout):
            for c, (idx, measured) in layout.items():
                pred = outputs[c][:, :, 1:]
                e = (pred.reshape(pred.shape[0], -1)[:, idx] - measured) * (self.weights[c] / self.scales[c])
                parts.append(np.nan_to_num(e, nan=1e6, posinf=1e6, neginf=-1e6))
        # rows in C order, as a stack of per-row vectors: a fit's Jacobian is built from these rows, and the
        # layout it reaches LAPACK in changes the SVD's rounding
        return np.ascontiguousarray(np.concatenate(parts, axis=1))

    def channel_rms(self, P: np.ndarray) -> dict[str, float]:
        """Unweighted RMS per channel for one parameter row.

        Parameters
        ----------
        P : numpy.ndarray
            The parameter row.

        Returns
        -------
        dict of str to float
            RMS per channel (physical units).
        """
        pred = self.model.predict(np.atleast_2d(P), tuple(self.channels))[0]
        out = {}
        for c in self.channels:
            es = [(pred.outputs[k][c] - m[c])[:, 1:] for k, m in enumerate(self._meas) if c in m]
            e = np.concatenate([x[np.isfinite(x)] for x in es])
            out[c] = float(np.sqrt(np.mean(e**2)))
        return out


@dataclass
class FitResult:
    """Outcome of :func:`fit_parameters` (values in the variables' physical units).

    Attributes
    ----------
    names : list of str
        The variables fitted.
    values, std : dict of str to float
        Their fitted values and standard errors.
    params : RigParams
        The fitted base parameters (validated).
    vector : numpy.ndarray
        The fitted parameter vector.
    rss_before, rss_after : float
        The residual sums of squares at the start and at the end.
    n_residuals : int
        Residual samples.
    nfev : int
        Function evaluations.
    warnings : list of str
        Identifiability warnings.
    residual : numpy.ndarray or None
        The final residual.
    channel_rms : dict of str to float or None
        Its RMS per channel, when computed.
    composition : Composition or None
        The model fitted.
    """

    names: list[str]
    values: dict[str, float]
    std: dict[str, float]
    params: RigParams
    vector: np.ndarray
    rss_before: float
    rss_after: float
    n_residuals: int
    nfev: int
    warnings: list[str] = field(default_factory=list)
    residual: np.ndarray | None = None
    channel_rms: dict[str, float] | None = None
    composition: Composition | None = None

    @property
    def effect_values(self) -> dict[str, float]:
        """The effects' parameters of the fitted vector by name (empty for the base model)."""
        if self.composition is None:
            return {}
        return self.composition.split(self.vector)[1]

    @property
    def rmse_before(self) -> float:
        return math.sqrt(self.rss_before / max(self.n_residuals, 1))

    @property
    def rmse_after(self) -> float:
        return math.sqrt(self.rss_after / max(self.n_residuals, 1))


def base_vector(
    composition: Composition, base: RigParams | np.ndarray | None, values: dict[str, float] | None = None
) -> np.ndarray:
    """A composition's parameter vector.

    Parameters
    ----------
    composition : Composition
        The composition.
    base : RigParams, numpy.ndarray or None
        Base parameters (default: the identified set), a base-only vector (the effects get their defaults, or
        ``values``) or a full vector.
    values : dict of str to float, optional
        The effects' parameter values.

    Returns
    -------
    numpy.ndarray
        The vector.

    Raises
    ------
    InputError
        A vector of the wrong length.
    """
    if base is None or isinstance(base, RigParams):
        return composition.vector(base, values)
    vec = np.asarray(base, dtype=float).ravel()
    if vec.shape[0] == N_PARAMS and composition.n_params != N_PARAMS:
        return composition.vector(RigParams.from_vector(vec), values)
    if vec.shape[0] != composition.n_params:
        raise InputError(
            f"parameter vector has {vec.shape[0]} entries, the model {composition.label!r} needs {composition.n_params}"
        )
    return vec.copy()


def _set_by_name(composition: Composition, names: Sequence[str]) -> ApplyFn:
    idx = [composition.param_index(n) for n in names]

    def apply(base: np.ndarray, z: np.ndarray) -> np.ndarray:
        v = base.copy()
        v[idx] = z
        return v

    return apply


@on_one_blas_thread  # the simulations hold the cores; and a result that does not depend on thread timing
def fit_parameters(
    objective: Objective,
    base: RigParams | np.ndarray,
    variables: Sequence[FitVariable],
    *,
    apply: ApplyFn | None = None,
    effect_values: dict[str, float] | None = None,
    options: FitOptions | None = None,
    **settings,
) -> FitResult:
    """Fit some variables (everything else held) by trf least squares.

    With a ``prior``, the returned residual, RSS and standard errors' scale are the data's alone; the
    Jacobian behind the standard errors includes the prior.

    With ``fit_speeds``, the speeds at the segment starts (the data's derivative estimates, nuisance states of
    the multiple shooting) are corrected in the same fit, each within its bound
    (:meth:`SegmentedModel.speed_variables`), from the model's current corrections; the model keeps the
    fitted ones.  Segments are independent, so two more rows in the Jacobian's batched run (every
    segment's ω_u, then ω_l, raised by ``speed_step`` rad/s) give every segment's columns.  The standard
    errors are then the parameters' marginal ones, the speeds' uncertainty accounted for.  (Alternating
    between a fit of the parameters and :meth:`SegmentedModel.refine_initial_speeds` reaches the same
    minimum in several fits.)

    Parameters
    ----------
    objective : Objective
        The residual; the model is its composition (``objective.model.composition``).
    base : RigParams or numpy.ndarray
        The values held: RigParams (the effects' parameters from ``effect_values``, else their defaults) or a
        parameter vector in the composition's layout.
    variables : sequence of FitVariable
        The variables fitted: parameters of the composition (base or effect), or variables ``apply`` maps.
    apply : callable, optional
        ``apply(base_vector, z) -> parameter vector``: maps other variables to the composition's layout.
    effect_values : dict of str to float, optional
        The effects' parameter values when ``base`` is RigParams.
    options : FitOptions, optional
        How to fit (default: :class:`FitOptions` ()).
    **settings
        Fields of :class:`FitOptions` (``max_nfev``, ``prior``, ``fit_speeds``, ...), overriding ``options``.

    Returns
    -------
    FitResult
        The fit; its ``params`` validates the fitted base set.

    Raises
    ------
    InputError
        A variable with empty bounds.
    FitFailedError
        A fit that could not start (the residual is not finite at its start) or whose fitted base values
        leave their physical range.

    Warns
    -----
    IdentifiabilityWarning
        A parameter the data do not determine well.
    """
    opts = replace(options or FitOptions(), **settings)
    comp = objective.model.composition
    variables = list(variables)
    names = [v.name for v in variables]
    apply = apply or _set_by_name(comp, names)
    base_vec = base_vector(comp, base, effect_values)
    box = ScaledBox(variables)
    n = len(variables)
    speeds = SpeedVariables(objective) if opts.fit_speeds else None
    ks = speeds.count if speeds is not None else 0
    zlo, zhi = box.zlo, box.zhi
    if ks:
        zlo, zhi = np.concatenate([zlo, speeds.zlo]), np.concatenate([zhi, speeds.zhi])
    res = ResidualFunction(objective, apply, base_vec, box, speeds, opts)
    prior = GaussianPrior(names, box, ks, opts)

    def fun_map(z: np.ndarray) -> np.ndarray:
        return np.concatenate([res.fun(z), prior.rows(z)]) if prior.idx else res.fun(z)

    def jac_map(z: np.ndarray) -> np.ndarray:
        return np.vstack([res.jac(z, zhi), prior.jac]) if prior.idx else res.jac(z, zhi)

    z0 = np.zeros(n + ks)
    q0 = fun_map(z0)
    r0 = res.fun(z0)
    if not np.all(np.isfinite(q0)):
        raise FitFailedError(f"the fit of {', '.join(names)} did not start: the model's residual is not finite there")
    sol = least_squares(
        fun_map,
        z0,
        jac=jac_map,
        bounds=(zlo, zhi),
        method="trf",
        x_scale=1.0,
        max_nfev=opts.max_nfev,
        ftol=opts.ftol,
        xtol=opts.xtol,
    )
    z = sol.x
    q1 = fun_map(z)
    r1 = res.fun(z)
    J = np.asarray(sol.jac)  # trf's Jacobian is evaluated at its last accepted point, sol.x
    if float(q1 @ q1) > float(q0 @ q0):  # never return something worse than the start
        z, r1 = z0, r0
        J = jac_map(z)
    if ks:
        speeds.set(z[n:])  # the model keeps the fitted speeds
    values = box.x0 + box.scale * z[:n]
    m = len(r1)
    std, msgs = identifiability(names, values, J, float(r1 @ r1) / max(m - n - ks, 1), z, zlo, zhi, box, opts)
    for mm in msgs:
        warnings.warn(mm, IdentifiabilityWarning, stacklevel=2)
    vec = apply(base_vec, values)
    try:
        fitted = RigParams.from_vector(vec[:N_PARAMS])
    except ParameterError as exc:
        raise FitFailedError(f"the fit of {', '.join(names)} left the physical range: {exc}") from None
    return FitResult(
        names,
        dict(zip(names, values.tolist())),
        dict(zip(names, std.tolist())),
        fitted,
        vec,
        float(r0 @ r0),
        float(r1 @ r1),
        m,
        int(sol.nfev),
        msgs,
        r1,
        composition=comp,
    )
