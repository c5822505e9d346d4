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
from dataclasses import dataclass, field
from typing import Callable, Mapping, Sequence

import numpy as np
from scipy.optimize import least_squares

from ..effects import Composition
from ..params import N_PARAMS, PARAM_INFO, RigParams
from .blas import on_one_blas_thread
from .experiment import Experiment
from .segmented import SegmentedModel

__all__ = ["FitVariable", "Objective", "FitResult", "fit_parameters", "default_scales", "IdentifiabilityWarning",
           "base_vector"]


class IdentifiabilityWarning(UserWarning):
    """A parameter cannot be determined well from the data given."""


@dataclass(frozen=True)
class FitVariable:
    """One fitted variable: the name of a parameter of the model's composition (a RigParams name or
    an effect's parameter; or a variable an ``apply`` function maps), initial value, bounds and
    typical magnitude (for scaling and the finite-difference step), in the parameter's SI unit."""

    name: str
    x0: float
    lo: float
    hi: float
    scale: float

    @classmethod
    def of_effect(cls, composition: Composition, name: str, x0: float | None = None) -> "FitVariable":
        """An effect parameter of ``composition`` with the effect's own bounds, guess and scale
        (``x0`` overrides the guess, clipped into the bounds)."""
        prm = composition.parameter(name)
        if composition.owner(name) is None:
            raise ValueError(f"{name!r} is a base parameter, not an effect's: use FitVariable.relative")
        v = prm.guess if x0 is None else min(max(float(x0), prm.lo), prm.hi)
        return cls(name, float(v), float(prm.lo), float(prm.hi), float(prm.scale))

    @classmethod
    def named(cls, composition: Composition, name: str, vector: np.ndarray | None = None) -> "FitVariable":
        """Any parameter of ``composition``: an effect's (its Parameter's bounds and scale, starting
        from ``vector``'s value when given, else the guess), or a base one (:meth:`relative`
        around ``vector``'s value, within ×0.5–×2)."""
        i = composition.param_index(name)
        if composition.owner(name) is not None:
            return cls.of_effect(composition, name, None if vector is None else float(vector[i]))
        base = RigParams() if vector is None else RigParams.from_vector(np.asarray(vector)[:N_PARAMS])
        if getattr(base, name) == 0:
            info = PARAM_INFO[name]
            return cls(name, 0.0, max(info["lo"], -0.5), min(info["hi"], 0.5), 0.01)
        return cls.relative(base, name, 0.5, 2.0)

    @classmethod
    def relative(cls, params: RigParams, name: str, lo: float = 0.3, hi: float = 3.0) -> "FitVariable":
        """A base parameter fitted around its current value, bounds [lo, hi] x value (and PARAM_INFO's)."""
        v = getattr(params, name)
        info = PARAM_INFO[name]
        a, b = sorted((v * lo, v * hi))
        a, b = max(a, info["lo"]), min(b, info["hi"])
        return cls(name, v, a, b, max(abs(v), 1e-9))


def default_scales(experiments: Sequence[Experiment]) -> dict[str, float]:
    """Residual scale per channel (≈ measurement noise): angles one encoder count / √12
    (at least 1e-4 rad), LVDT channels 10 µm."""
    q = []
    for ex in experiments:
        for c in ("theta_u", "theta_l"):
            if c in ex.meas:
                d = np.abs(np.diff(ex.meas[c]))
                d = d[d > 1e-12]
                if d.size:
                    q.append(float(np.min(d)))
    sa = max(min(q) / math.sqrt(12) if q else 0.0, 1e-4)
    sl = 1e-5
    return {"theta_u": sa, "theta_l": sa, "alpha": sa, "x": sl, "y": sl, "r": sl}


class Objective:
    """Normalised residuals of parameter rows on experiments.

    Args:
        model: the multiple-shooting predictor.
        weights: channel -> weight (e.g. ``{"theta_l": 1, "alpha": 13}``); channels an
            experiment lacks are skipped.
        scales: channel -> residual scale (default :func:`default_scales`).
    """

    def __init__(self, model: SegmentedModel, weights: dict[str, float],
                 scales: dict[str, float] | None = None) -> None:
        self.model = model
        self.weights = dict(weights)
        self.scales = dict(scales or default_scales(model.experiments))
        self._meas = []
        for k, ex in enumerate(model.experiments):
            chans = [c for c in weights if c in ex.meas or (c == "alpha" and "theta_l" in ex.meas)
                     or (c == "r" and "x" in ex.meas)]
            self._meas.append({c: model.measured_segments(k, c) for c in chans})
        self.channels = sorted({c for m in self._meas for c in m})
        if not self.channels:
            raise ValueError(f"none of the channels {list(weights)} is in the data")
        #: index into :attr:`channels` of every entry of a residual row (the layout of :meth:`residual_matrix`)
        self.channel_ids = np.concatenate([np.full(int(np.count_nonzero(~np.isnan(m[:, 1:]))), self.channels.index(c))
                                           for meas in self._meas for c, m in meas.items()])
        #: index of the independent block (experiment, channel, multiple-shooting segment) of every entry of a
        #: residual row: a segment re-started from the data does not carry its misfit over to the next one
        rows = [np.count_nonzero(~np.isnan(m[:, 1:]), axis=1) for meas in self._meas for m in meas.values()]
        counts = np.concatenate(rows) if rows else np.zeros(0, dtype=int)
        self.block_ids = np.repeat(np.arange(len(counts)), counts)
        #: index of the multiple-shooting segment (numbered over all experiments) of every entry of a residual row
        first = np.cumsum([0] + [len(model.segments(k)[0]) for k in range(len(model.experiments))])
        seg = np.concatenate([first[k] + np.arange(m.shape[0]) for k, meas in enumerate(self._meas)
                              for m in meas.values()]) if rows else np.zeros(0, dtype=int)
        self.segment_ids = np.repeat(seg, counts)
        self.segment_offsets = first[:-1]
        #: per (experiment, channel) of a residual row: the flat indices of its measured samples in a segment
        #: array's (n_seg, seg_len - 1) tail, and the measured values there
        self._layout = [{c: (idx, m[:, 1:].ravel()[idx]) for c, m in meas.items()
                         for idx in [np.flatnonzero(~np.isnan(m[:, 1:]).ravel())]} for meas in self._meas]

    def with_own_speeds(self) -> "Objective":
        """The same objective on a copy of its model whose speed corrections at the segment starts are its own
        (started from the model's): a fit that moves them, or refines them per point, can run beside others on
        this one.  The measured segments and residual layout are shared, not derived again."""
        other = copy.copy(self)
        other.model = self.model.with_composition(self.model.composition)
        other.weights, other.scales = dict(self.weights), dict(self.scales)
        return other

    def residual_matrix(self, P: np.ndarray, dspeed: np.ndarray | None = None) -> np.ndarray:
        """(B, M) weighted, normalised residuals (model − data); a segment's first sample is skipped.
        ``dspeed`` (B, 2): (ω_u, ω_l) added to every segment's initial speeds of that row (rad/s)."""
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
        """Unweighted RMS (physical units) per channel for one parameter row."""
        pred = self.model.predict(np.atleast_2d(P), tuple(self.channels))[0]
        out = {}
        for c in self.channels:
            es = [(pred.outputs[k][c] - m[c])[:, 1:] for k, m in enumerate(self._meas) if c in m]
            e = np.concatenate([x[np.isfinite(x)] for x in es])
            out[c] = float(np.sqrt(np.mean(e ** 2)))
        return out


@dataclass
class FitResult:
    """Outcome of :func:`fit_parameters` (values in the variables' physical units)."""

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


ApplyFn = Callable[[np.ndarray, np.ndarray], np.ndarray]


def base_vector(composition: Composition, base: "RigParams | np.ndarray | None",
                values: dict[str, float] | None = None) -> np.ndarray:
    """The composition's parameter vector from RigParams (+ effect ``values``) or a vector
    (a base-only vector gets the effects' defaults, or ``values``)."""
    if base is None or isinstance(base, RigParams):
        return composition.vector(base, values)
    vec = np.asarray(base, dtype=float).ravel()
    if vec.shape[0] == N_PARAMS and composition.n_params != N_PARAMS:
        return composition.vector(RigParams.from_vector(vec), values)
    if vec.shape[0] != composition.n_params:
        raise ValueError(f"parameter vector has {vec.shape[0]} entries, the model {composition.label!r} needs "
                         f"{composition.n_params}")
    return vec.copy()


def _set_by_name(composition: Composition, names: Sequence[str]) -> ApplyFn:
    idx = [composition.param_index(n) for n in names]

    def apply(base: np.ndarray, z: np.ndarray) -> np.ndarray:
        v = base.copy()
        v[idx] = z
        return v

    return apply


@on_one_blas_thread  # the simulations hold the cores; and a result that does not depend on thread timing
def fit_parameters(objective: Objective, base: "RigParams | np.ndarray", variables: Sequence[FitVariable], *,
                   apply: ApplyFn | None = None, max_nfev: int = 30, fd_step: float = 1e-3,
                   rel_std_limit: float = 0.1, collinearity_limit: float = 1000.0, ftol: float = 1e-6,
                   xtol: float = 1e-6, effect_values: dict[str, float] | None = None,
                   prior: "Mapping[str, tuple[float, float]] | None" = None, prior_weight: float = 1.0,
                   fit_speeds: bool = False, speed_step: float = 0.005) -> FitResult:
    """Fit ``variables`` (everything else held at ``base``) by trf least squares.

    ``prior``: {variable: (mean, standard deviation)} of a Gaussian prior (maximum a posteriori: the rows
    √prior_weight · (value − mean) / std are appended to the residual; ``prior_weight`` is the data
    residual's variance per independent sample, so that one unit of Σ ((value − mean) / std)² weighs as
    much as one of the data's log-likelihood).  The returned residual, RSS and standard errors' scale are
    the data's alone; the Jacobian behind the standard errors includes the prior.

    ``fit_speeds``: the speeds at the segment starts (the data's derivative estimates, nuisance states of
    the multiple shooting) are corrected in the same fit, each within its bound
    (:meth:`SegmentedModel.speed_variables`), from the model's current corrections; the model keeps the
    fitted ones.  Segments are independent, so two more rows in the Jacobian's batched run (every
    segment's ω_u, then ω_l, raised by ``speed_step`` rad/s) give every segment's columns.  The standard
    errors are then the parameters' marginal ones, the speeds' uncertainty accounted for.  (Alternating
    between a fit of the parameters and :meth:`SegmentedModel.refine_initial_speeds` reaches the same
    minimum in several fits.)

    The model is the objective's composition (``objective.model.composition``); ``base`` is
    RigParams (the effects' parameters from ``effect_values``, else their defaults) or a
    parameter vector in the composition's layout.  Variables name parameters of the
    composition (base or effect).  ``apply(base_vector, z) -> parameter vector`` may map
    other variables to that layout.  Returns a :class:`FitResult` whose ``params`` validates
    the fitted base set (a ParameterError names a bad value).
    """
    comp = objective.model.composition
    variables = list(variables)
    names = [v.name for v in variables]
    apply = apply or _set_by_name(comp, names)
    base_vec = base_vector(comp, base, effect_values)
    x0 = np.array([v.x0 for v in variables])
    scale = np.array([v.scale for v in variables])
    lo = np.array([v.lo for v in variables])
    hi = np.array([v.hi for v in variables])
    if np.any(lo >= hi):
        bad = names[int(np.argmax(lo >= hi))]
        raise ValueError(f"fit variable {bad!r}: empty bounds")
    x0 = np.clip(x0, lo + 1e-9 * (hi - lo), hi - 1e-9 * (hi - lo))
    zlo, zhi = (lo - x0) / scale, (hi - x0) / scale
    n = len(variables)
    speeds = _SpeedVariables(objective) if fit_speeds else None
    ks = speeds.count if speeds is not None else 0
    if ks:
        zlo, zhi = np.concatenate([zlo, speeds.zlo]), np.concatenate([zhi, speeds.zhi])
    cache: dict[bytes, np.ndarray] = {}

    def rows(Z: np.ndarray) -> np.ndarray:
        return np.stack([apply(base_vec, x0 + scale * z[:n]) for z in Z])

    def fun(z: np.ndarray) -> np.ndarray:
        key = z.tobytes()
        if key not in cache:
            cache.clear()
            if ks:
                speeds.set(z[n:])
            cache[key] = objective.residual_matrix(rows(z[None, :]))[0]
        return cache[key]

    def jac(z: np.ndarray) -> np.ndarray:
        f0 = fun(z)
        h = np.where(z[:n] + fd_step <= zhi[:n], fd_step, -fd_step)
        Z = np.repeat(z[None, :], n, axis=0)
        Z[:, :n] += np.diag(h)
        if not ks:
            R = objective.residual_matrix(rows(Z))
            return ((R - f0[None, :]) / h[:, None]).T
        speeds.set(z[n:])
        Z = np.vstack([Z, z[None, :], z[None, :]])
        dspeed = np.zeros((n + 2, 2))
        dspeed[n, 0] = dspeed[n + 1, 1] = speed_step
        R = objective.residual_matrix(rows(Z), dspeed=dspeed)
        Jp = ((R[:n] - f0[None, :]) / h[:, None]).T
        return np.hstack([Jp, speeds.columns((R[n:] - f0[None, :]) / speed_step)])

    # the prior's rows: linear in z
    pidx = [i for i, nm in enumerate(names) if prior and nm in prior]
    pmean = np.array([prior[names[i]][0] for i in pidx], dtype=float)
    pstd = np.array([prior[names[i]][1] for i in pidx], dtype=float)
    pw = math.sqrt(max(prior_weight, 0.0))
    Jp = np.zeros((len(pidx), n + ks))
    for k, i in enumerate(pidx):
        Jp[k, i] = pw * scale[i] / pstd[k]

    def prior_rows(z: np.ndarray) -> np.ndarray:
        return pw * (x0[pidx] + scale[pidx] * z[pidx] - pmean) / pstd

    def fun_map(z: np.ndarray) -> np.ndarray:
        return np.concatenate([fun(z), prior_rows(z)]) if pidx else fun(z)

    def jac_map(z: np.ndarray) -> np.ndarray:
        return np.vstack([jac(z), Jp]) if pidx else jac(z)

    z0 = np.zeros(n + ks)
    q0 = fun_map(z0)
    r0 = fun(z0)
    sol = least_squares(fun_map, z0, jac=jac_map, bounds=(zlo, zhi), method="trf", x_scale=1.0,
                        max_nfev=max_nfev, ftol=ftol, xtol=xtol)
    z = sol.x
    q1 = fun_map(z)
    r1 = fun(z)
    J = np.asarray(sol.jac)  # trf's Jacobian is evaluated at its last accepted point, sol.x
    if float(q1 @ q1) > float(q0 @ q0):  # never return something worse than the start
        z, r1 = z0, r0
        J = jac_map(z)
    if ks:
        speeds.set(z[n:])  # the model keeps the fitted speeds
    values = x0 + scale * z[:n]
    m = len(r1)
    s2 = float(r1 @ r1) / max(m - n - ks, 1)
    msgs: list[str] = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cov = np.linalg.pinv(J.T @ J) * s2
    std = scale * np.sqrt(np.clip(np.diag(cov)[:n], 0, None))
    J = J[:, :n]
    col = np.linalg.norm(J, axis=0)
    std[col == 0] = np.inf  # the data do not depend on it: any value fits (pinv would say 0)
    if np.any(col == 0):
        for i in np.flatnonzero(col == 0):
            msgs.append(f"{names[i]}: the data do not depend on it (not excited): not identifiable")
    elif n > 1:
        _, sv, vt = np.linalg.svd(J / col, full_matrices=False)
        gamma = 1.0 / max(sv[-1], 1e-300)  # collinearity index (unit-norm columns)
        if gamma > collinearity_limit:
            v = np.abs(vt[-1])
            involved = [names[i] for i in np.flatnonzero(v > 0.1 * v.max())]
            msgs.append(f"near-singular JᵀJ (collinearity index {gamma:.0f} > {collinearity_limit:.0f}): "
                        f"{', '.join(involved)} are not separately identifiable from these data")
    for i, nm in enumerate(names):
        ref = max(abs(values[i]), 1e-12)
        if abs(values[i]) > 0 and std[i] / ref > rel_std_limit and not any(nm in mm for mm in msgs):
            msgs.append(f"{nm}: relative standard error {std[i] / ref:.0%} > {rel_std_limit:.0%}: poorly identifiable")
        if (z[i] <= zlo[i] + 1e-6 or z[i] >= zhi[i] - 1e-6) and np.isfinite(zlo[i] + zhi[i]):
            msgs.append(f"{nm}: estimate {values[i]:.4g} is at a bound of [{lo[i]:.4g}, {hi[i]:.4g}]")
    for mm in msgs:
        warnings.warn(mm, IdentifiabilityWarning, stacklevel=2)
    vec = apply(base_vec, values)
    return FitResult(names, dict(zip(names, values.tolist())), dict(zip(names, std.tolist())),
                     RigParams.from_vector(vec[:N_PARAMS]), vec, float(r0 @ r0), float(r1 @ r1), m, int(sol.nfev),
                     msgs, r1, composition=comp)


class _SpeedVariables:
    """The segment-start speed corrections of ``objective``'s model as fit variables (``fit_speeds`` of
    :func:`fit_parameters`): z = (correction − start) / limit, within ±limit."""

    def __init__(self, objective: Objective) -> None:
        model = self.model = objective.model
        found = model.speed_variables()
        self.count = len(found)
        self.exp = np.array([v[0] for v in found], dtype=int)
        self.seg = np.array([v[1] for v in found], dtype=int)
        self.comp = np.array([v[2] for v in found], dtype=int)
        self.scale = np.array([v[3] for v in found], dtype=float)
        start = np.array([model.speed_offsets[k][j, c] for k, j, c, _ in found], dtype=float)
        self.start = np.clip(start, -self.scale * (1 - 1e-9), self.scale * (1 - 1e-9))
        self.zlo, self.zhi = (-self.scale - self.start) / self.scale, (self.scale - self.start) / self.scale
        # residual entries of each variable's segment
        gid = objective.segment_offsets[self.exp] + self.seg if self.count else np.zeros(0, dtype=int)
        order = np.argsort(objective.segment_ids, kind="stable")
        bounds = np.searchsorted(objective.segment_ids[order], np.arange(objective.segment_ids.max(initial=-1) + 2))
        self.entries = [order[bounds[g]:bounds[g + 1]] for g in gid]

    def set(self, z: np.ndarray) -> None:
        values = self.start + self.scale * z
        for i in range(self.count):
            self.model.speed_offsets[self.exp[i]][self.seg[i], self.comp[i]] = values[i]

    def columns(self, D: np.ndarray) -> np.ndarray:
        """The variables' Jacobian columns from the two sensitivity rows ``D`` (2, M): every segment's ω_u,
        then ω_l, raised together (per unit of speed)."""
        J = np.zeros((D.shape[1], self.count))
        for i in range(self.count):
            idx = self.entries[i]
            J[idx, i] = D[self.comp[i], idx] * self.scale[i]
        return J
