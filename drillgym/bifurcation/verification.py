"""Independent checks of periodic solutions by direct simulation (no code shared with the section map).

The shooting code (:mod:`.poincare`, :mod:`.shooting`) integrates to the section
with its own event location and differentiates the return map by finite
differences.  The checks here use only the public simulator
(:func:`drillgym.simulate_batch`, exact stick/slip, usually a 10x smaller
step) and locate the section crossings in the recorded samples by cubic
interpolation:

* :func:`section_returns` - successive upward crossings of omega_l = omega_s
  (reduced, scaled coordinates, the same as :class:`~.poincare.SectionMap`'s);
* :func:`periodicity_error` - how far the orbit started at a branch point lands
  from it after one period, and the simulated period;
* :func:`simulated_monodromy` - the section map's Jacobian from central
  differences of simulated returns (other step, other perturbation, other
  crossing location); its eigenvalues are the Floquet multipliers;
* :func:`leading_growth` - growth per period of a perturbation along the
  leading eigenvector of the shooting Jacobian, over several periods
  (the divergence rate of an unstable cycle, the convergence rate of a stable one);
* :func:`long_run_fate` - where a long simulation from a slightly perturbed
  point goes (stays on the cycle, or leaves it towards the equilibrium / another
  attractor).
"""

from __future__ import annotations

import numpy as np

from ..errors import FitError
from ..simulator import simulate_batch
from .poincare import SectionMap
from .shooting import PeriodicSolution

_COLUMNS = {"alpha": "alpha", "omega_u": "omega_u", "x": "x_rot", "y": "y_rot", "vx": "vx_rot", "vy": "vy_rot"}


def _cubic_root(t4: np.ndarray, g4: np.ndarray) -> float:
    """Root of the cubic through four samples (t, g) inside [t4[1], t4[2]] (sign change there)."""
    c = np.polyfit(t4 - t4[1], g4, 3)
    lo, hi = 0.0, t4[2] - t4[1]
    glo = np.polyval(c, lo)
    for _ in range(60):  # bisection: robust, ~1e-18 s after 60 halvings of a 1e-4 s step
        mid = 0.5 * (lo + hi)
        gm = np.polyval(c, mid)
        if (gm < 0) == (glo < 0):
            lo, glo = mid, gm
        else:
            hi = mid
    return t4[1] + 0.5 * (lo + hi)


def section_returns(
    smap: SectionMap, u: float, Y0: np.ndarray, duration: float, dt: float = 1e-4, params=None, with_batch: bool = False
):
    """Simulate each full state of Y0 (B, 9) for ``duration`` s at constant voltage u (V) with the
    exact stick/slip simulator and step ``dt`` (s); return, per trajectory, the crossing times (s)
    and the reduced scaled coordinates (k, smap.dim) of the upward crossings of omega_l = omega_s(u)
    (a crossing counts after omega_l has been below omega_s, as in the section map).  With
    ``with_batch`` the simulated BatchTrajectory is returned as a third item."""
    Y0 = np.atleast_2d(np.asarray(Y0, dtype=float))
    ws = smap.level(u)
    # default: the section map's model (its parameter vector and effects); given params run the base model
    effects = smap.composition if params is None else None
    params = params if params is not None else smap.p
    batch = simulate_batch(
        smap.config,
        np.full(len(Y0), float(u)),
        duration,
        dt=dt,
        params=params,
        effects=effects,
        x0=Y0,
        n_batch=len(Y0),
    )
    times, points = [], []
    for k in range(len(Y0)):
        tr = batch[k]
        t = tr.t
        g = tr.omega_l - ws
        cols = [getattr(tr, _COLUMNS.get(c, c)) for c in smap.coords]  # an effect's state: its own column
        below = np.flatnonzero(g < 0)
        tk, zk = [], []
        if below.size:
            start = below[0]
            idx = np.flatnonzero((g[start:-2] < 0) & (g[start + 1 : -1] >= 0)) + start
            for i in idx:
                if i < 1:
                    continue
                sl = slice(i - 1, i + 3)
                tc = _cubic_root(t[sl], g[sl])
                z = np.array([np.polyval(np.polyfit(t[sl] - t[i], col[sl], 3), tc - t[i]) for col in cols])
                tk.append(tc)
                zk.append(z / smap.scale)
        times.append(np.array(tk))
        points.append(np.array(zk).reshape(-1, smap.dim))
    return (times, points, batch) if with_batch else (times, points)


def periodicity_error(smap: SectionMap, sol: PeriodicSolution, dt: float = 1e-4) -> tuple[float, float]:
    """(max-norm distance in scaled section coordinates between the branch point and its first return
    by direct simulation, simulated period in s)."""
    y0 = smap.to_state(sol.z, sol.u)
    times, pts = section_returns(smap, sol.u, y0[None, :], 1.3 * sol.period + 0.5, dt)
    if len(times[0]) == 0:
        return float("inf"), float("nan")
    return float(np.max(np.abs(pts[0][0] - sol.z))), float(times[0][0])


def simulated_monodromy(smap: SectionMap, sol: PeriodicSolution, eps: float = 1e-5, dt: float = 1e-4) -> np.ndarray:
    """Jacobian (n, n) of the section map at the branch point from central differences of directly
    simulated first returns (perturbation ``eps`` of each scaled coordinate)."""
    n = smap.dim
    Y0 = []
    for j in range(n):
        for sgn in (1.0, -1.0):
            z = sol.z.copy()
            z[j] += sgn * eps
            Y0.append(smap.to_state(z, sol.u))
    times, pts = section_returns(smap, sol.u, np.array(Y0), 1.3 * sol.period + 0.5, dt)
    if any(len(tk) == 0 for tk in times):
        raise FitError(f"a perturbed orbit did not return to the section at u = {sol.u:.5g} V")
    M = np.empty((n, n))
    for j in range(n):
        M[:, j] = (pts[2 * j][0] - pts[2 * j + 1][0]) / (2 * eps)
    return M


def leading_growth(
    smap: SectionMap,
    sol: PeriodicSolution,
    jacobian: np.ndarray,
    eps: float = 1e-7,
    n_returns: int = 3,
    dt: float = 1e-4,
) -> np.ndarray:
    """Growth factors per period of a perturbation ``eps`` along the (real part of the) leading
    eigenvector of ``jacobian`` (the section map's, (n, n)), measured against the simulation of the
    unperturbed point: |d_1| / |d_0| and then |d_{k+1}| / |d_k| for k = 1 .. n_returns - 1."""
    lam, V = np.linalg.eig(jacobian)
    v = np.real(V[:, int(np.argmax(np.abs(lam)))])
    v /= np.linalg.norm(v)
    y_ref = smap.to_state(sol.z, sol.u)
    y_pert = smap.to_state(sol.z + eps * v, sol.u)
    times, pts = section_returns(smap, sol.u, np.array([y_ref, y_pert]), (n_returns + 0.3) * sol.period + 0.5, dt)
    k = min(len(pts[0]), len(pts[1]), n_returns)
    d = [eps] + [float(np.linalg.norm(pts[1][i] - pts[0][i])) for i in range(k)]
    return np.array([d[i + 1] / d[i] if d[i] > 0 else 0.0 for i in range(k)])


def long_run_fate(
    smap: SectionMap,
    sol: PeriodicSolution,
    jacobian: np.ndarray,
    eps: float = 1e-4,
    duration: float = 200.0,
    dt: float = 1e-3,
) -> dict:
    """Simulate ``duration`` s from the branch point pushed by +-eps along the leading eigenvector of
    ``jacobian``.  Per side ('plus', 'minus'): distance (max-norm, scaled section coordinates) from the
    branch point at the first and at the last return, the number of returns, and over the last two
    periods the range of omega_l (rad/s) and the lower disc's stuck fraction.  A stable cycle keeps
    both sides on it (last distance <~ first); an unstable one loses them to another attractor."""
    lam, V = np.linalg.eig(jacobian)
    v = np.real(V[:, int(np.argmax(np.abs(lam)))])
    v /= np.linalg.norm(v)
    Y0 = np.array([smap.to_state(sol.z + s * eps * v, sol.u) for s in (1.0, -1.0)])
    times, pts, tail = section_returns(smap, sol.u, Y0, duration, dt, with_batch=True)
    n_tail = max(2, int(round(2 * sol.period / dt)))
    out = {}
    for k, (name, p) in enumerate(zip(("plus", "minus"), pts)):
        dist = np.max(np.abs(p - sol.z), axis=1) if len(p) else np.array([np.inf])
        wl = tail[k].omega_l[-n_tail:]
        out[name] = {
            "first": float(dist[0]),
            "last": float(dist[-1]),
            "returns": int(len(p)),
            "omega_l_range": float(wl.max() - wl.min()),
            "stuck_fraction": float(np.mean(tail[k].stick_l[-n_tail:] > 0)),
        }
    return out


__all__ = ["section_returns", "periodicity_error", "simulated_monodromy", "leading_growth", "long_run_fate"]
