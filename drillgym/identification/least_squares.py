"""The pieces of a least-squares fit: its options, the variables' scaled box, the residual and its
finite-difference Jacobian, a Gaussian prior's rows, and the identifiability of the result
(:func:`drillgym.identification.fitting.fit_parameters` puts them together)."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..errors import InputError
from .variables import FitVariable, SpeedVariables

if TYPE_CHECKING:
    from .fitting import Objective

__all__ = ["FitOptions", "ScaledBox", "ResidualFunction", "GaussianPrior", "identifiability", "ApplyFn"]

ApplyFn = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class FitOptions:
    """How :func:`fit_parameters` fits.

    Attributes
    ----------
    max_nfev : int
        Least-squares evaluations.  Default 30.
    fd_step : float
        Finite-difference step of the Jacobian, in the variables' scales.  Default 1e-3.
    rel_std_limit : float
        Relative standard error above which a parameter is reported as poorly identifiable.  Default 0.1.
    collinearity_limit : float
        Collinearity index above which the fit reports parameters that are not separately identifiable.
        Default 1000.
    ftol, xtol : float
        Least-squares tolerances.  Default 1e-6.
    prior : mapping of str to (float, float), optional
        {variable: (mean, standard deviation)} of a Gaussian prior (maximum a posteriori: the rows
        √prior_weight · (value − mean) / std are appended to the residual).
    prior_weight : float
        The data residual's variance per independent sample, so that one unit of Σ ((value − mean) / std)²
        weighs as much as one of the data's log-likelihood.  Default 1.
    fit_speeds : bool
        Correct the speeds at the segment starts in the same fit.  Default False.
    speed_step : float
        The speeds' finite-difference step (rad/s).  Default 0.005.
    """

    max_nfev: int = 30
    fd_step: float = 1e-3
    rel_std_limit: float = 0.1
    collinearity_limit: float = 1000.0
    ftol: float = 1e-6
    xtol: float = 1e-6
    prior: Mapping[str, tuple[float, float]] | None = None
    prior_weight: float = 1.0
    fit_speeds: bool = False
    speed_step: float = 0.005


class ScaledBox:
    """The variables' start, scale and bounds; the fit runs on z = (x − x0) / scale."""

    def __init__(self, variables: Sequence[FitVariable]) -> None:
        names = [v.name for v in variables]
        x0 = np.array([v.x0 for v in variables])
        self.scale = np.array([v.scale for v in variables])
        self.lo = lo = np.array([v.lo for v in variables])
        self.hi = hi = np.array([v.hi for v in variables])
        if np.any(lo >= hi):
            bad = names[int(np.argmax(lo >= hi))]
            raise InputError(f"fit variable {bad!r}: empty bounds")
        self.x0 = np.clip(x0, lo + 1e-9 * (hi - lo), hi - 1e-9 * (hi - lo))
        self.zlo, self.zhi = (lo - self.x0) / self.scale, (hi - self.x0) / self.scale


class ResidualFunction:
    """The data's residual of z and its finite-difference Jacobian (the speeds' columns from two batched rows)."""

    def __init__(
        self,
        objective: Objective,
        apply: ApplyFn,
        base_vec: np.ndarray,
        box: ScaledBox,
        speeds: SpeedVariables | None,
        opts: FitOptions,
    ) -> None:
        self.objective, self.apply, self.base_vec, self.box, self.speeds, self.opts = (
            objective,
            apply,
            base_vec,
            box,
            speeds,
            opts,
        )
        self.n = len(box.x0)
        self.ks = speeds.count if speeds is not None else 0
        self.cache: dict[bytes, np.ndarray] = {}

    def rows(self, Z: np.ndarray) -> np.ndarray:
        n, box = self.n, self.box
        return np.stack([self.apply(self.base_vec, box.x0 + box.scale * z[:n]) for z in Z])

    def fun(self, z: np.ndarray) -> np.ndarray:
        key = z.tobytes()
        if key not in self.cache:
            self.cache.clear()
            if self.ks:
                self.speeds.set(z[self.n :])
            self.cache[key] = self.objective.residual_matrix(self.rows(z[None, :]))[0]
        return self.cache[key]

    def jac(self, z: np.ndarray, zhi: np.ndarray) -> np.ndarray:
        n, fd_step, objective = self.n, self.opts.fd_step, self.objective
        f0 = self.fun(z)
        h = np.where(z[:n] + fd_step <= zhi[:n], fd_step, -fd_step)
        Z = np.repeat(z[None, :], n, axis=0)
        Z[:, :n] += np.diag(h)
        if not self.ks:
            R = objective.residual_matrix(self.rows(Z))
            return ((R - f0[None, :]) / h[:, None]).T
        speed_step = self.opts.speed_step
        self.speeds.set(z[n:])
        Z = np.vstack([Z, z[None, :], z[None, :]])
        dspeed = np.zeros((n + 2, 2))
        dspeed[n, 0] = dspeed[n + 1, 1] = speed_step
        R = objective.residual_matrix(self.rows(Z), dspeed=dspeed)
        Jp = ((R[:n] - f0[None, :]) / h[:, None]).T
        return np.hstack([Jp, self.speeds.columns((R[n:] - f0[None, :]) / speed_step)])


class GaussianPrior:
    """The prior's rows, linear in z, and their Jacobian."""

    def __init__(self, names: Sequence[str], box: ScaledBox, ks: int, opts: FitOptions) -> None:
        prior = opts.prior
        n = len(names)
        self.idx = [i for i, nm in enumerate(names) if prior and nm in prior]
        self.mean = np.array([prior[names[i]][0] for i in self.idx], dtype=float)
        self.std = np.array([prior[names[i]][1] for i in self.idx], dtype=float)
        self.w = math.sqrt(max(opts.prior_weight, 0.0))
        self.box = box
        self.jac = np.zeros((len(self.idx), n + ks))
        for k, i in enumerate(self.idx):
            self.jac[k, i] = self.w * box.scale[i] / self.std[k]

    def rows(self, z: np.ndarray) -> np.ndarray:
        idx, box = self.idx, self.box
        return self.w * (box.x0[idx] + box.scale[idx] * z[idx] - self.mean) / self.std


#: singular values of the scaled Jacobian below this share of the largest are directions the data do not see
#: (finite differences resolve the residual's change to about 1e-8 of its largest; the normal equations' inverse
#: would cut at 1e-15 of the *squared* values and call such a direction's variance 0)
BLIND_RCOND = 1e-8
#: a variable is not identified when this share of it (the norm of its unit vector's projection) lies in the
#: directions the data do not see (b and c entering only as b + c: 0.71 each)
BLIND_SHARE = 0.3


def identifiability(
    names: Sequence[str],
    values: np.ndarray,
    J: np.ndarray,
    s2: float,
    z: np.ndarray,
    zlo: np.ndarray,
    zhi: np.ndarray,
    box: ScaledBox,
    opts: FitOptions,
) -> tuple[np.ndarray, list[str]]:
    """The standard errors of the fitted values, and the identifiability messages.

    The covariance is s2 V S⁻² Vᵀ over the directions of the scaled Jacobian J = U S Vᵀ the data see (singular
    values above :data:`BLIND_RCOND` of the largest).  A variable with :data:`BLIND_SHARE` of it in the directions
    they do not see has an infinite standard error and is said not identifiable: the data do not depend on it (its
    own column is below that share of the largest singular value), or only a combination of it with the others
    said so changes the data.
    """
    n = len(names)
    msgs: list[str] = []
    _, sv, vt = np.linalg.svd(J, full_matrices=False)
    top = float(sv[0]) if sv.size else 0.0
    seen = sv > BLIND_RCOND * top if top > 0 else np.zeros(sv.size, dtype=bool)
    cov = (vt[seen].T / sv[seen] ** 2) @ vt[seen] * s2
    std = box.scale * np.sqrt(np.clip(np.diag(cov)[:n], 0, None))
    hidden = np.sqrt(np.sum(vt[~seen][:, :n] ** 2, axis=0)) if top > 0 else np.ones(n)
    col = np.linalg.norm(J[:, :n], axis=0)
    blind = (hidden >= BLIND_SHARE) | (col == 0)
    alone = blind & (col <= BLIND_RCOND * top)
    for i in np.flatnonzero(alone):
        msgs.append(f"{names[i]}: the data do not depend on it (not excited): not identifiable")
    together = np.flatnonzero(blind & ~alone)
    if len(together) == 1:
        msgs.append(
            f"{names[together[0]]}: only its combination with other parameters changes the data: not identifiable "
            "on its own"
        )
    elif len(together):
        msgs.append(
            f"{', '.join(names[i] for i in together)}: only a combination of them changes the data: not separately "
            "identifiable"
        )
    std[blind] = np.inf  # any value fits (the normal equations' inverse would say 0)
    if n > 1 and not blind.any():  # every column nonzero here
        _, sk, vk = np.linalg.svd(J[:, :n] / col, full_matrices=False)
        gamma = 1.0 / max(sk[-1], 1e-300)  # collinearity index (unit-norm columns)
        if gamma > opts.collinearity_limit:
            v = np.abs(vk[-1])
            involved = [names[i] for i in np.flatnonzero(v > 0.1 * v.max())]
            msgs.append(
                f"near-singular JᵀJ (collinearity index {gamma:.0f} > {opts.collinearity_limit:.0f}): "
                f"{', '.join(involved)} are not separately identifiable from these data"
            )
    lim = opts.rel_std_limit
    for i, nm in enumerate(names):
        ref = max(abs(values[i]), 1e-12)
        if abs(values[i]) > 0 and std[i] / ref > lim and not any(nm in mm for mm in msgs):
            msgs.append(f"{nm}: relative standard error {std[i] / ref:.0%} > {lim:.0%}: poorly identifiable")
        if (z[i] <= zlo[i] + 1e-6 or z[i] >= zhi[i] - 1e-6) and np.isfinite(zlo[i] + zhi[i]):
            msgs.append(f"{nm}: estimate {values[i]:.4g} is at a bound of [{box.lo[i]:.4g}, {box.hi[i]:.4g}]")
    return std, msgs
