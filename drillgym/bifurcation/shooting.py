"""Shooting for periodic solutions of the non-smooth rig, with Floquet multipliers.

A periodic solution is a fixed point z* = P(z*, u) of the Poincare map of
:class:`~.poincare.SectionMap`.  The Jacobian of H(z, u) = P(z, u) - z is taken
by central finite differences of the flow map (all 2 (n + 1) flows in one
parallel batch).  Between stick/slip events the return map is smooth and the
flow is integrated with located events, so the differences include the
saltation of the stick/slip transitions implicitly; the test suite checks the
multipliers against a 10x smaller perturbation and a halved time step, and
:mod:`.verification` against direct simulation (docs/bifurcation_verification.md).

Floquet multipliers: the n eigenvalues of dP/dz (the monodromy matrix
restricted to the section) plus the trivial multiplier 1 along the flow.  A
stick phase inside the orbit collapses the lower disc's speed, which shows as
multipliers at (numerically near) zero.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import FitError
from .poincare import F_OK, F_R_MAX, F_R_MIN, F_STICK, F_T, F_WL_MAX, F_WL_MIN, SectionMap

FD_STEP = 1e-6  # perturbation of the (scaled) section coordinates and of u (V)


@dataclass
class PeriodicSolution:
    """A periodic solution of the rig at a constant voltage.

    Parameters
    ----------
    u : float
        Voltage (V).
    z : ndarray
        Section point (scaled reduced coordinates of the section map).
    period : float
        Period (s).
    omega_l_min, omega_l_max : float
        Extremes of the lower-disc speed along the orbit (rad/s).
    r_min, r_max : float
        Extremes of the whirl amplitude (m).
    stick_time : float
        Time the lower disc sticks per period (s).
    multipliers : ndarray
        The non-trivial Floquet multipliers.
    section_offset : float, optional
        ``z`` lies on omega_l = omega_s(u) + section_offset (rad/s).
    """

    u: float
    z: np.ndarray
    period: float
    omega_l_min: float
    omega_l_max: float
    r_min: float
    r_max: float
    stick_time: float
    multipliers: np.ndarray
    section_offset: float = 0.0  # rad/s: z lies on omega_l = omega_s(u) + section_offset

    @property
    def stable(self) -> bool:
        """All non-trivial Floquet multipliers inside the unit circle."""
        return bool(np.max(np.abs(self.multipliers)) < 1.0)

    @property
    def stick_slip(self) -> bool:
        """The orbit contains a stick phase of the lower disc."""
        return self.stick_time > 0.0

    def to_dict(self) -> dict:
        return {
            "u": self.u,
            "period": self.period,
            "omega_l_min": self.omega_l_min,
            "omega_l_max": self.omega_l_max,
            "r_min": self.r_min,
            "r_max": self.r_max,
            "stick_time": self.stick_time,
            "stick_slip": self.stick_slip,
            "stable": self.stable,
            "section_offset": self.section_offset,
            "max_abs_multiplier": float(np.max(np.abs(self.multipliers))),
            "multipliers": [[float(m.real), float(m.imag)] for m in self.multipliers],
        }


class ShootingFailure(FitError):
    """The flow did not return to the section (no orbit near this point)."""


def residual_and_jacobian(
    smap: SectionMap, z: np.ndarray, u: float, h: float = FD_STEP
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """H(z, u) = P(z, u) - z, its Jacobian (n, n + 1) w.r.t. (z, u) by central differences, and the
    flow summary of the centre point.  Raises ShootingFailure when a flow does not return."""
    n = smap.dim
    X0 = np.append(np.asarray(z, dtype=float), u)
    pts = [X0]
    for j in range(n + 1):
        for sgn in (1.0, -1.0):
            X = X0.copy()
            X[j] += sgn * h
            pts.append(X)
    Xs = np.array(pts)
    images, summ = smap.evaluate(Xs[:, :n], Xs[:, n])
    if not np.all(summ[:, F_OK] > 0):
        raise ShootingFailure(f"flow from the section did not return at u = {u:.5g} V")
    H = images - Xs[:, :n]
    J = np.empty((n, n + 1))
    for j in range(n + 1):
        J[:, j] = (H[1 + 2 * j] - H[2 + 2 * j]) / (2 * h)
    return H[0], J, summ[0]


def make_solution(u: float, z: np.ndarray, J: np.ndarray, summary: np.ndarray, offset: float = 0.0) -> PeriodicSolution:
    """Package a converged fixed point with its Floquet multipliers eig(dP/dz) = eig(J_z + I);
    ``offset`` (rad/s) is the section's (:attr:`SectionMap.offset`)."""
    n = J.shape[0]
    mult = np.linalg.eigvals(J[:, :n] + np.eye(n))
    mult = mult[np.argsort(-np.abs(mult))]
    return PeriodicSolution(
        float(u),
        np.asarray(z, dtype=float).copy(),
        float(summary[F_T]),
        float(summary[F_WL_MIN]),
        float(summary[F_WL_MAX]),
        float(summary[F_R_MIN]),
        float(summary[F_R_MAX]),
        float(summary[F_STICK]),
        mult,
        float(offset),
    )


def shoot(smap: SectionMap, z0: np.ndarray, u: float, tol: float = 1e-9, max_iter: int = 20) -> PeriodicSolution:
    """Newton's method for the fixed point of the section map at a fixed voltage.

    Parameters
    ----------
    smap : SectionMap
        The Poincare map of the configuration.
    z0 : ndarray
        Initial guess of the section point (scaled coordinates of ``smap``).
    u : float
        Voltage (V).
    tol : float, optional
        Tolerance on the Newton step and the residual (scaled).
    max_iter : int, optional
        Most Newton iterations.

    Returns
    -------
    PeriodicSolution
        The periodic orbit: section point, period (s), Floquet multipliers, speed range.

    Raises
    ------
    ShootingFailure
        Newton did not converge or the orbit did not return to the section.
    """
    z = np.asarray(z0, dtype=float).copy()
    n = smap.dim
    for _ in range(max_iter):
        H, J, s = residual_and_jacobian(smap, z, u)
        dz = np.linalg.solve(J[:, :n], -H)
        z += dz
        if np.linalg.norm(dz) < tol and np.linalg.norm(H) < 1e3 * tol:
            H, J, s = residual_and_jacobian(smap, z, u)
            return make_solution(u, z, J, s, smap.offset)
    raise ShootingFailure(f"shooting did not converge at u = {u:.5g} V (|H| = {np.linalg.norm(H):.3g})")
