"""LQG on both encoders (``lqg-2enc``): robust active damping that the motor angle alone cannot give.

With the motor angle as the only measurement, the lower disc's unstable modes below omega_2 nearly
cancel against right-half-plane zeros and no linear controller is robust to a few percent of model
error (:mod:`controllers.limits`).  The lower encoder removes those zeros: from the voltage to the
lower angle the torsional model has none.  This controller is a gain-scheduled discrete LQG
(python-control ``dlqr`` and ``dare``) on the linearised torsional model at the reference speed,
measuring theta_u and theta_l:

* design model: states (theta_u, omega_u, alpha, omega_l) about the equilibrium at the reference r,
  plus a first-order motor lag ``tau`` (a robust middle of 0-50 ms) and a random-walk torque on the
  lower disc (what the brake law misses; estimated, not cancelled); the brake's slope made steeper
  by ``slope_margin``; white torque noise on both discs (``sigma_upper``, ``sigma_lower``: how far the
  filter trusts the model), a coarser encoder than nominal plus an angle-noise floor;
* LQR weights on the motor angle's deviation from the integral of r (so the mean speed is exact
  whatever the model's km or friction), on the upper and lower speeds, and on the voltage;
* the reference: a target below ``approach`` is reached from above (``approach`` rad/s held for
  ``hold`` s, then a linear ramp over ``ramp`` s), through a first-order lag ``tau_ref``; designs on a
  0.25 rad/s grid of speeds, the nearest one used.

Built on a model with effects (``model=``, :mod:`controllers.model`): the model's motor lag replaces the
design lag ``tau``, its delay adds the line of past commands to the design model (exact zero-order hold, LQR
and Kalman gains on the augmented state), and its lower-disc friction effects set the equilibrium's
winding and voltage at the estimated lower angle (the design slope stays the base law's).

Its robustness was checked on the linearisation first: the default design is stable on all 40
plants of a tuning population (seed 11 of the default uncertainty set, lags and delays included) at
every speed from 0.3 to 8 rad/s; the evaluation population is another seed.
"""

from __future__ import annotations

from dataclasses import astuple, dataclass, replace
from functools import lru_cache

import control
import numpy as np

from drillgym import RigParams
from drillgym.equilibria import equilibrium_voltage
from drillgym.errors import InputError
from drillgym.friction import lower_friction

from .base import Controller
from .limits import brake_slope
from .model import delayed_discretisation

__all__ = ["TwoEncoderLQG", "TwoEncoderDesign"]

GRID = 0.25  # rad/s, spacing of the designs' speeds


@dataclass(frozen=True)
class TwoEncoderDesign:
    """Design options (units in :mod:`controllers.two_encoder`'s doc)."""

    tau: float = 0.025  # s, motor lag of the design model
    slope_margin: float = 0.3  # the brake's negative slope times 1 + margin
    sigma_upper: float = 0.03  # N m/sqrt(Hz)
    sigma_lower: float = 0.03  # N m/sqrt(Hz)
    sigma_d: float = 0.3  # N m/sqrt(s), random walk of the lower-disc torque (fast: angle-dependent friction)
    counts: int = 4096  # counts/rev the filter assumes
    noise_floor: float = 3e-4  # rad
    q_theta: float = 10.0  # rad^-2
    q_omega_u: float = 1.0  # (rad/s)^-2
    q_omega_l: float = 100.0  # (rad/s)^-2
    r: float = 3.0  # V^-2


@lru_cache(maxsize=512)
def _design(params: RigParams, omega: float, dt: float, o: TwoEncoderDesign, delay: float = 0.0):
    """(A, B, C, K, L) of the discrete design at ``omega`` (rad/s); states (theta_u, omega_u, alpha,
    omega_l, u_a, d) in deviations from the equilibrium, then the line of past commands of a ``delay`` (s)."""
    p = params
    s = brake_slope(omega, p)
    if s < 0:
        s *= 1.0 + o.slope_margin
    bu = p.bu + p.dbu
    A = np.zeros((6, 6))
    A[0, 1] = 1.0
    A[1, 1], A[1, 2], A[1, 4] = -bu / p.Ju, p.ktheta / p.Ju, p.km / p.Ju
    A[2, 1], A[2, 3] = -1.0, 1.0
    A[3, 2], A[3, 3], A[3, 5] = -p.ktheta / p.Jl, -s / p.Jl, -1.0 / p.Jl
    A[4, 4] = -1.0 / o.tau
    B = np.zeros((6, 1))
    B[4, 0] = 1.0 / o.tau
    sysd = delayed_discretisation(A, B, dt, delay)
    Ad, Bd, nx = sysd.Ad, sysd.Bd, 6 + sysd.n_line
    C = np.zeros((2, nx))
    C[0, 0] = 1.0
    C[1, 0], C[1, 2] = 1.0, 1.0  # theta_l = theta_u + alpha
    G = np.zeros((nx, 3))
    G[1, 0], G[3, 1], G[5, 2] = 1.0 / p.Ju, 1.0 / p.Jl, 1.0
    Qd = G @ np.diag([o.sigma_upper**2, o.sigma_lower**2, o.sigma_d**2]) @ G.T * dt + 1e-12 * np.eye(nx)
    rv = (2 * np.pi / o.counts) ** 2 / 12 + o.noise_floor**2
    P, _, _ = control.dare(Ad.T, C.T, Qd, rv * np.eye(2))
    P = np.asarray(P)
    L = P @ C.T @ np.linalg.inv(C @ P @ C.T + rv * np.eye(2))
    keep = [0, 1, 2, 3, 4] + list(range(6, nx))  # d is estimated, not controlled
    Q = np.diag([o.q_theta, o.q_omega_u, 0.0, o.q_omega_l, 0.0] + [0.0] * sysd.n_line)
    Ks, _, _ = control.dlqr(Ad[np.ix_(keep, keep)], Bd[keep], Q, np.array([[o.r]]))
    K = np.zeros((1, nx))
    K[0, keep] = np.asarray(Ks)[0]
    return Ad, Bd, C, K, L


class TwoEncoderLQG(Controller):
    """Gain-scheduled LQG on the motor and lower encoders (see the module doc).

    Parameters
    ----------
    omega_ref : float or ndarray, optional
        Target lower-disc speed(s) (rad/s), as :class:`controllers.Controller`.
    design : TwoEncoderDesign, optional
        Design options (model, noise, weights).
    approach : float, optional
        Targets below this speed are reached from above, from this speed (rad/s).  Default 3.
    hold : float, optional
        Time at ``approach`` (s).  Default 5.
    ramp : float, optional
        Duration of the linear ramp down to the target (s).  Default 15.
    tau_ref : float, optional
        Time constant of the reference's first-order lag (s).  Default 1.
    feedforward : float, optional
        Weight of the estimated lower-disc torque in the equilibrium shift (the string winds by
        -d/ktheta more, the motor leads by d/ktheta; 0: none).  Default 1.
    **kw
        ``config``, ``params``, ``dt``, ``u_max`` of :class:`controllers.Controller`.
    """

    name = "lqg-2enc"
    uses = ("theta_u", "theta_l")
    default_dt = 0.002
    uses_effects = True

    def __init__(
        self,
        omega_ref=None,
        *,
        design: TwoEncoderDesign | None = None,
        approach: float = 3.0,
        hold: float = 5.0,
        ramp: float = 15.0,
        tau_ref: float = 1.0,
        feedforward: float = 1.0,
        **kw,
    ) -> None:
        super().__init__(omega_ref, **kw)
        for name, v in (("approach", approach), ("hold", hold), ("ramp", ramp)):
            if not (np.isfinite(v) and v >= 0):
                raise InputError(f"{name} must be a non-negative number, got {v!r}")
        if not (np.isfinite(tau_ref) and tau_ref > 0):
            raise InputError(f"tau_ref must be a positive time (s), got {tau_ref!r}")
        self.design = design or TwoEncoderDesign()
        if self.effects.lag > 0:  # the model's motor lag instead of the design's robust middle
            self.design = replace(self.design, tau=self.effects.lag)
        self.delay = self.effects.delay
        if not all(np.isfinite(v) and v > 0 for v in astuple(self.design)[:3]):
            raise InputError(f"design: tau, slope_margin and the noise levels must be positive, got {self.design}")
        self.approach, self.hold, self.ramp, self.tau_ref = float(approach), float(hold), float(ramp), float(tau_ref)
        self.feedforward = float(feedforward)

    def approach_time(self, omega_ref: float | np.ndarray) -> np.ndarray:
        """Time (s) the reference needs: the hold and ramp for targets below ``approach``, plus 6 lags."""
        w = np.asarray(omega_ref, dtype=float)
        return np.where(w < self.approach, self.hold + self.ramp, 0.0) + 6.0 * self.tau_ref

    def _equilibrium(self, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(alpha*, u*) of the model's equilibrium at speeds r (rad/s, > 0)."""
        grid = self._grid
        a = np.interp(r, grid, self._alpha_grid)
        u = np.interp(r, grid, self._u_grid)
        return a, u

    def _reset(self, m: dict[str, np.ndarray]) -> None:
        n = self.n
        top = max(float(np.max(self.omega_ref)), self.approach) + 1.0
        self._grid = np.arange(GRID, top + GRID, GRID)
        p = self.params
        self._alpha_grid = -lower_friction(self._grid, p) / p.ktheta
        self._u_grid = np.asarray(equilibrium_voltage(self.config, self._grid, p), dtype=float)
        mats = [_design(p, float(w), float(self.dt), self.design, self.delay) for w in self._grid]
        self._A, self._B, self._C, self._K, self._L = (np.stack([mm[i] for mm in mats]) for i in range(5))
        self.t = np.zeros(n)  # time since each rig's reset (s)
        self.r = np.zeros(n)  # reference speed (rad/s), from rest
        self.theta_ref = np.zeros(n)
        self.x = np.zeros((n, self._A.shape[1]))
        self._b = np.zeros((n, self._A.shape[1]))  # the input column of the design used last (per rig)
        self._start(np.arange(n), m)

    def _start(self, index: np.ndarray, m: dict[str, np.ndarray]) -> None:
        """Rigs ``index`` at rest at the encoder angles of ``m`` ((n,) arrays), reference and time from 0."""
        n = self.n
        tu = np.broadcast_to(m.get("theta_u", 0.0), (n,)).astype(float)[index]
        tl = np.broadcast_to(m.get("theta_l", 0.0), (n,)).astype(float)[index]
        self.t[index], self.r[index] = 0.0, 0.0
        self.theta_ref[index] = tu
        # absolute estimate (theta_u, omega_u, alpha, omega_l, u_a, d): the rig at rest
        self.x[index] = 0.0  # and the line of past commands: none sent
        self.x[index, 0], self.x[index, 2] = tu, tl - tu

    def _check_new_targets(self, ref: np.ndarray) -> None:
        if np.max(ref, initial=0.0) + 1.0 > self._grid[-1] + 1e-9:
            raise InputError(
                f"reset_rigs: target {float(np.max(ref)):g} rad/s is above the designs' grid (up to "
                f"{self._grid[-1]:g}); reset() the batch with the highest target first"
            )

    def _restart_rigs(self, index: np.ndarray, m: dict[str, np.ndarray]) -> None:
        self._start(index, m)

    def applied(self, voltage) -> None:
        """The voltage (V) actually held over the period just begun, when it differs from this controller's
        own output (the controller run in shadow, e.g. as a teacher): the estimate's prediction uses it.

        Parameters
        ----------
        voltage : float or ndarray
            Applied voltage of each rig (V), clipped to [-u_max, u_max]; call after :meth:`act`.
        """
        u = np.clip(np.broadcast_to(np.asarray(voltage, dtype=float), (self.n,)), -self.u_max, self.u_max)
        # the prediction is linear in the input: x_next += B (u_applied - u_own)
        self.x = self.x + self._b * (u - self.u_prev)[:, None]
        self.u_prev = u.copy()

    def _target(self) -> np.ndarray:
        s = np.clip((self.t - self.hold) / self.ramp, 0.0, 1.0) if self.ramp > 0 else (self.t >= self.hold) * 1.0
        return np.where(
            self.omega_ref < self.approach, self.approach + s * (self.omega_ref - self.approach), self.omega_ref
        )

    def _act(self, m: dict[str, np.ndarray]) -> np.ndarray:
        r = np.maximum(self.r, GRID)  # designs exist from GRID up; the reference starts there
        k = np.clip(np.rint(r / GRID).astype(int) - 1, 0, self._grid.size - 1)
        A, B, C, K, L = self._A[k], self._B[k], self._C[k], self._K[k], self._L[k]
        a_eq, u_eq = self._equilibrium(r)
        if self.effects.friction_effects:  # the model's brake at the estimated lower angle shifts the equilibrium
            extra = self.effects.lower_friction(r, self.x[:, 0] + self.x[:, 2]) - lower_friction(r, self.params)
            a_eq, u_eq = a_eq - extra / self.params.ktheta, u_eq + extra / self.params.km
        # the estimated extra torque on the lower disc shifts the equilibrium: the string winds by -d/k_theta
        # more, the motor leads by d/k_theta (the lower disc stays on its track); with angle-dependent
        # friction this is a feedforward of the torque ripple
        shift = self.feedforward * self.x[:, 5] / self.params.ktheta
        a_eq = a_eq - shift
        eq = np.zeros_like(self.x)
        eq[:, 0], eq[:, 1], eq[:, 2], eq[:, 3], eq[:, 4] = self.theta_ref + shift, r, a_eq, r, u_eq
        eq[:, 6:] = u_eq[:, None]  # the line's commands, about the equilibrium voltage
        xd = self.x - eq
        tu = np.asarray(m["theta_u"], dtype=float)
        tl = np.asarray(m["theta_l"], dtype=float)
        y = np.stack([tu - eq[:, 0], tl - eq[:, 0] - a_eq], axis=1)
        xd = xd + np.einsum("nij,nj->ni", L, y - np.einsum("nij,nj->ni", C, xd))
        u = np.clip(u_eq - np.einsum("nij,nj->ni", K, xd)[:, 0], -self.u_max, self.u_max)
        xd = np.einsum("nij,nj->ni", A, xd) + B[:, :, 0] * (u - u_eq)[:, None]
        self._b = B[:, :, 0]
        # advance the reference and keep the estimate in absolute coordinates
        self.theta_ref = self.theta_ref + r * self.dt
        self.x = xd + eq
        self.x[:, 0] = xd[:, 0] + self.theta_ref + shift  # the deviation is about the advanced reference angle
        self.r = self.r + self.dt / self.tau_ref * (self._target() - self.r)
        self.t += self.dt
        return u
