"""Pseudo-arclength continuation of periodic solutions in the voltage u.

The unknowns are X = (z, u): the section point of the orbit and the voltage.
Predictor: a step ``ds`` along the unit tangent (null vector of dH/dX);
corrector: Newton on ``H(X) = 0, t . (X - X_prev) = ds`` (Keller).  The step
halves when Newton fails and grows after easy steps, so the branch follows
through smooth folds and through the corners of *discontinuous* folds, where
a stick-slip cycle meets an unstable slip cycle (report 4.1.2).

Folds are the turning points of u along the branch (sign change of du/ds),
located by the extreme u of a parabola through the three points around the
turn.  A branch ends at a Hopf point when the orbit's amplitude shrinks below
``amplitude_min``, at the ends of the voltage window, or after ``max_points``.

Section control: the section omega_l = omega_s(u) + offset must be crossed
transversally once per period.  A whirl orbit of the lateral configuration
has several local extrema of omega_l per period; when one of them comes close
to the section level the return map becomes discontinuous (an extra crossing
appears) and the corrector fails.  After each accepted point
:func:`section_margin` measures the distance of the level from every local
extremum of omega_l along the orbit (one simulated period); below
``SECTION_MARGIN`` of the orbit's omega_l range the section is moved to the
middle of the widest gap between extremum values that is crossed upwards once
per period, and the point is re-shot on the new section.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .poincare import F_OK, SectionMap
from .shooting import PeriodicSolution, ShootingFailure, make_solution, residual_and_jacobian, shoot


@dataclass
class Fold:
    """A fold (saddle-node) of periodic solutions.

    Parameters
    ----------
    u : float
        Voltage of the fold (V).
    omega_l_max : float
        Largest lower-disc speed of the orbit there (rad/s).
    discontinuous : bool
        The orbits there contain stick: the stick-slip cycle is born or dies at the fold.
    """

    u: float
    omega_l_max: float
    discontinuous: bool

    def to_dict(self) -> dict:
        return {"u": self.u, "omega_l_max": self.omega_l_max, "discontinuous": self.discontinuous}


@dataclass
class PeriodicBranch:
    """Solutions along one continuation run and the folds found on it.

    Parameters
    ----------
    solutions : list of PeriodicSolution, optional
        The periodic solutions, in order of arclength.
    folds : list of Fold, optional
        The folds found on the branch.
    end_reason : str, optional
        Why the continuation stopped.
    """

    solutions: list[PeriodicSolution] = field(default_factory=list)
    folds: list[Fold] = field(default_factory=list)
    end_reason: str = ""

    def array(self, name: str) -> np.ndarray:
        """One attribute of every solution (e.g. ``"u"``, ``"period"``) as an array."""
        return np.array([getattr(s, name) for s in self.solutions])


SECTION_MARGIN = 0.1  # fraction of the orbit's omega_l range kept between the section and any extremum


def _upward_crossings(w: np.ndarray, level: float) -> int:
    """Upward crossings of ``level`` by the periodic sample sequence w (one period, wrapped)."""
    g = np.append(w, w[0]) - level
    return int(np.sum((g[:-1] < 0) & (g[1:] >= 0)))


def section_margin(smap: SectionMap, sol: PeriodicSolution) -> tuple[float, float | None]:
    """(margin, better offset): the distance (as a fraction of the omega_l range) between the section
    level and the nearest local extremum of omega_l along the orbit of ``sol`` (one period simulated
    from its section point), and, if that is below SECTION_MARGIN, the offset (rad/s) of a section
    level in the middle of the widest gap between extremum values that the orbit crosses upwards
    exactly once per period (None when no such level is better)."""
    from ..simulator import simulate_batch

    if not np.isfinite(sol.period) or sol.period <= 0:
        return 1.0, None
    sm = smap.with_offset(sol.section_offset)
    tr = simulate_batch(  # one period: not a whole number of steps, which simulate() refuses
        sm.config,
        sol.u,
        sol.period,
        dt=sm.dt,
        params=sm.p,  # the section map's model: its parameter vector and effects
        effects=sm.composition,
        x0=sm.to_state(sol.z, sol.u),
        method=sm.method,
        n_batch=1,
    )[0]
    w = tr.omega_l
    span = float(w.max() - w.min())
    if span <= 0 or len(w) < 5:
        return 1.0, None
    d = np.diff(w)
    d = d[d != 0]
    wd = w[1:][np.diff(w) != 0]
    ext = wd[:-1][np.sign(d[:-1]) != np.sign(d[1:])] if len(d) > 1 else np.empty(0)
    values = np.unique(np.concatenate([ext, [w.min(), w.max()]]))
    level = sm.level(sol.u)
    margin = float(np.min(np.abs(values - level))) / span
    if margin >= SECTION_MARGIN:
        return margin, None
    best, best_gap = None, margin * span
    for lo, hi in zip(values[:-1], values[1:]):
        mid = 0.5 * (lo + hi)
        if 0.5 * (hi - lo) > best_gap and _upward_crossings(w, mid) == 1:
            best, best_gap = mid, 0.5 * (hi - lo)
    return margin, (None if best is None else float(best - sm.omega_s(sol.u)))


def _resection(smap: SectionMap, sol: PeriodicSolution) -> tuple[SectionMap, PeriodicSolution] | None:
    """Move the section if the orbit comes close to touching it; the point re-shot on the new one."""
    margin, offset = section_margin(smap, sol)
    if offset is None:
        return None
    new = smap.with_offset(offset)
    Z, S = new.flow_states(smap.with_offset(sol.section_offset).to_state(sol.z, sol.u)[None, :], np.array([sol.u]))
    if S[0, F_OK] == 0:
        return None
    try:
        return new, shoot(new, Z[0], sol.u)
    except (ShootingFailure, np.linalg.LinAlgError):
        return None


def _tangent(J: np.ndarray, previous: np.ndarray | None) -> np.ndarray:
    t = np.linalg.svd(J)[2][-1]
    if previous is not None and np.dot(t, previous) < 0:
        t = -t
    return t / np.linalg.norm(t)


def continue_branch(
    smap: SectionMap,
    start: PeriodicSolution,
    direction: float,
    *,
    umin: float,
    umax: float,
    ds: float = 0.05,
    ds_min: float = 1e-4,
    ds_max: float = 0.3,
    max_points: int = 400,
    amplitude_min: float = 2e-3,
    tol: float = 1e-8,
    max_newton: int = 8,
    resection: bool = True,
    progress: Callable[[PeriodicSolution], None] | None = None,
) -> PeriodicBranch:
    """Follow the periodic branch through ``start`` with u initially moving in ``direction`` (+1/-1).

    Pseudo-arclength continuation in the scaled (z, u) space.  The branch ends when its amplitude falls
    below ``amplitude_min``, at the ends of the voltage window, at a fold, or after ``max_points``.

    Parameters
    ----------
    smap : SectionMap
        The Poincare map of the configuration.
    start : PeriodicSolution
        A periodic solution on the branch (:func:`start_at_hopf`, :func:`shoot`).
    direction : float
        Initial direction of the voltage, +1 or -1.
    umin, umax : float
        Voltage window (V).
    ds : float, optional
        First arclength step (scaled (z, u) space).
    ds_min, ds_max : float, optional
        Smallest and largest arclength step.
    max_points : int, optional
        Most points on the branch.
    amplitude_min : float, optional
        Smallest omega_l range of an orbit (rad/s); below it the branch has shrunk to its Hopf point.
    tol : float, optional
        Newton tolerance of the corrector (scaled).
    max_newton : int, optional
        Most Newton iterations per point.
    resection : bool, optional
        Move the section away from extrema of omega_l along the orbit (module docstring); each solution
        records its section's offset (:attr:`PeriodicSolution.section_offset`).
    progress : callable, optional
        Called with each new periodic solution.

    Returns
    -------
    PeriodicBranch
        The periodic solutions along the branch and how it ended.
    """
    n = smap.dim
    smap = smap.with_offset(start.section_offset)
    X = np.append(start.z, start.u)
    H, J, s = residual_and_jacobian(smap, start.z, start.u)
    t = _tangent(J, None)
    if np.sign(t[n]) != np.sign(direction):
        t = -t
    branch = PeriodicBranch([start])
    while len(branch.solutions) < max_points:
        Xp = X + ds * t
        ok = False
        try:
            for _ in range(max_newton):
                H, J, s = residual_and_jacobian(smap, Xp[:n], Xp[n])
                F = np.append(H, np.dot(t, Xp - X) - ds)
                dX = np.linalg.solve(np.vstack([J, t]), -F)
                Xp += dX
                if np.linalg.norm(dX) < tol * 10 and np.linalg.norm(H) < tol * 100:
                    H, J, s = residual_and_jacobian(smap, Xp[:n], Xp[n])
                    ok = True
                    break
                if np.linalg.norm(dX) > 4 * ds + 0.5:
                    break
        except (ShootingFailure, np.linalg.LinAlgError):
            ok = False
        if not ok:
            ds *= 0.5
            if ds < ds_min:
                branch.end_reason = "corrector failed (step below ds_min)"
                break
            continue
        sol = make_solution(Xp[n], Xp[:n], J, s, smap.offset)
        t_new = _tangent(J, t)
        X, t = Xp, t_new
        branch.solutions.append(sol)
        moved = _resection(smap, sol) if resection else None
        if moved is not None:
            smap, sol = moved  # the same orbit, on the new section
            branch.solutions[-1] = sol
            X = np.append(sol.z, sol.u)
            _, J2, _ = residual_and_jacobian(smap, sol.z, sol.u)
            t2 = _tangent(J2, None)
            t = t2 if t2[n] * t[n] >= 0 else -t2  # keep the direction of travel in u
        if progress is not None:
            progress(sol)
        ds = min(ds * 1.5, ds_max)
        if not umin <= sol.u <= umax:
            branch.end_reason = "left the voltage window"
            break
        if sol.omega_l_max - sol.omega_l_min < amplitude_min:
            branch.end_reason = "amplitude vanished (Hopf point)"
            break
    else:
        branch.end_reason = "max_points reached"
    branch.folds = find_folds(branch.solutions)
    return branch


def find_folds(solutions: list[PeriodicSolution]) -> list[Fold]:
    """Turning points of u along a branch: parabola through the three points around each turn."""
    u = np.array([s.u for s in solutions])
    folds = []
    for i in range(1, len(u) - 1):
        if (u[i] - u[i - 1]) * (u[i + 1] - u[i]) < 0:
            # parabola in the arclength index through (i-1, i, i+1)
            a = 0.5 * (u[i + 1] - 2 * u[i] + u[i - 1])
            bq = 0.5 * (u[i + 1] - u[i - 1])
            u_f = u[i] - bq * bq / (4 * a) if a != 0 else u[i]
            lo, hi = min(u[i - 1 : i + 2]), max(u[i - 1 : i + 2])
            u_f = float(np.clip(u_f, lo, hi + (hi - lo)) if a < 0 else np.clip(u_f, lo - (hi - lo), hi))
            stick = solutions[i].stick_slip or solutions[i - 1].stick_slip or solutions[i + 1].stick_slip
            folds.append(Fold(u_f, solutions[i].omega_l_max, bool(stick)))
    return folds


def refine_fold(smap: SectionMap, branch: PeriodicBranch, fold: Fold, ds_min: float = 2e-3) -> Fold:
    """Re-run the continuation across a fold with small steps to locate it to about ds_min in u."""
    sols = branch.solutions
    u = np.array([s.u for s in sols])
    i = int(np.argmin(np.abs(u - fold.u)))
    k = max(i - 2, 0)
    direction = np.sign(u[k + 1] - u[k]) or 1.0
    local = continue_branch(
        smap,
        sols[k],
        direction,
        umin=-np.inf,
        umax=np.inf,
        ds=ds_min,
        ds_min=ds_min / 8,
        ds_max=ds_min * 2,
        max_points=int(8 * (abs(u[i] - u[k]) + 0.05) / ds_min) + 10,
    )
    near = [f for f in local.folds if abs(f.u - fold.u) < 0.2]
    return min(near, key=lambda f: abs(f.u - fold.u)) if near else fold


__all__ = ["Fold", "PeriodicBranch", "continue_branch", "find_folds", "refine_fold", "shoot"]


def start_at_hopf(
    smap: SectionMap,
    u_hopf: float,
    z_eq: np.ndarray,
    eigvec: np.ndarray,
    omega_l_row: int,
    amplitude: float = 0.02,
    tol: float = 1e-9,
    max_iter: int = 40,
    max_step: float = 0.02,
) -> PeriodicSolution:
    """The small periodic solution born at a Hopf point, by shooting with the section point's first
    coordinate (alpha) held at ``z_eq[0] + amplitude`` and the voltage free.

    The guess is the linear orbit's point where omega_l crosses its equilibrium value upwards.

    Parameters
    ----------
    smap : SectionMap
        The Poincare map of the configuration.
    u_hopf : float
        Voltage of the Hopf point (V).
    z_eq : ndarray
        The equilibrium's section coordinates (scaled).
    eigvec : ndarray
        Critical eigenvector of the reduced linearisation (states: the section coordinates with
        omega_l inserted at ``omega_l_row``).
    omega_l_row : int
        Row of omega_l in ``eigvec``.
    amplitude : float, optional
        Offset of the first coordinate (alpha, rad) from the equilibrium.
    tol : float, optional
        Newton tolerance (scaled).
    max_iter : int, optional
        Most Newton iterations.
    max_step : float, optional
        Largest Newton step (scaled).

    Returns
    -------
    PeriodicSolution
        The small periodic orbit near the Hopf point.
    """
    v = np.asarray(eigvec, dtype=complex)
    # phase where Re(v_wl e^{i phi}) = 0 with d/dt > 0 (i.e. Re(i v_wl e^{i phi}) > 0)
    phi = np.angle(1j / v[omega_l_row]) if abs(v[omega_l_row]) > 0 else 0.0
    if np.real(1j * v[omega_l_row] * np.exp(1j * phi)) < 0:
        phi += np.pi
    d = np.real(v * np.exp(1j * phi))
    d = np.delete(d, omega_l_row) / smap.scale
    d = d / abs(d[0]) * abs(amplitude)
    z = z_eq + d
    u = u_hopf
    for _ in range(max_iter):
        H, J, s = residual_and_jacobian(smap, z, u)
        step = np.linalg.solve(J[:, 1:], -H)
        big = np.max(np.abs(step)) / max_step
        if big > 1.0:  # damped Newton: the branch is flat in u near the Hopf point
            step /= big
        z[1:] += step[:-1]
        u += step[-1]
        if np.linalg.norm(step) < tol and np.linalg.norm(H) < 1e3 * tol:
            H, J, s = residual_and_jacobian(smap, z, u)
            return make_solution(u, z, J, s, smap.offset)
    raise ShootingFailure(f"no periodic solution near the Hopf point u = {u_hopf:.5g} V")
