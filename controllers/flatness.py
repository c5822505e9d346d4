"""Feedback-linearising tracking law for the lower-disc speed of the torsional model (flatness-based).

The torsional model is a chain from the voltage to the lower speed
(docs/model.md, absolute coordinates, alpha = theta_l - theta_u)::

    Jl d omega_l/dt = -k_theta alpha - Tfl(omega_l)              -> a = d omega_l/dt
    d alpha/dt      = omega_l - omega_u                           -> j = d^2 omega_l/dt^2
    Ju d omega_u/dt = km u - Tfu(omega_u) + k_theta alpha         -> d^3 omega_l/dt^3, linear in u

so omega_l has relative degree 3 and, with the friction law known (plus an estimated offset d),
the voltage that gives ``d^3 omega_l/dt^3 = v`` is exact (no zero dynamics): the negative slope of
the brake law, the cause of stick-slip, is cancelled instead of out-damped.  ``v`` is an LQR
state feedback (python-control ``lqr`` on the triple integrator) on the errors (omega_l - r,
a - r', j - r'') to a smooth reference r(t): the target passed through three first-order lags of
time constant ``tau_ref`` (a gentle start from rest: the disc breaks away and is caught at a
small speed instead of being hit with the full target's voltage).  While the lower disc is
(estimated) at rest with a string torque inside the stick set, a = j = 0 and the law only winds
the string (the rest of the chain is not moving).

Low targets (below ``low_speed``) are approached from above: the lags' input is first
``approach`` (a speed where the motor-angle estimate of omega_l is accurate and the disc breaks
away cleanly), held until ``hold`` seconds, then ramped linearly down to the target over
``ramp`` seconds, and the error chain uses the slower ``low_bandwidth`` plus integral action on
the speed error once the ramp is over (weight ``integral``).  Breakaway at low speed and the
estimator's poor view of it are avoided.  The integral is needed: with estimates from the
quantized motor angle the law's nonlinear terms rectify the estimation noise, and without it the
lower disc settles 0.1-0.9 rad/s ABOVE a low target (smoothly, so SSI alone does not show it);
the estimate of omega_l itself is unbiased.
"""

from __future__ import annotations

from functools import lru_cache

import control
import numpy as np

from drillgym import RigParams
from drillgym.errors import InputError
from drillgym.friction import lower_friction, upper_friction

__all__ = ["FlatnessLaw", "chain_gain"]


def chain_gain(bandwidth: float, r: float = 1.0, integral: float = 0.0) -> np.ndarray:
    """LQR gain of the triple integrator e''' = v for the errors (e, e', e''), weights chosen so that
    the closed loop has its poles near ``bandwidth`` (rad/s): Q = diag(b^6, b^4, b^2), R = r.

    ``integral`` > 0 adds the integral of e as a fourth state (weight integral * b^8): gain (4,) on
    (int e, e, e', e''); otherwise (3,)."""
    if not (np.isfinite(bandwidth) and bandwidth > 0):
        raise InputError(f"bandwidth must be a positive rate (rad/s), got {bandwidth!r}")
    if not (np.isfinite(integral) and integral >= 0):
        raise InputError(f"integral weight must be a non-negative number, got {integral!r}")
    return _chain_gain(float(bandwidth), float(r), float(integral)).copy()


@lru_cache(maxsize=64)
def _chain_gain(b: float, r: float, integral: float) -> np.ndarray:
    """:func:`chain_gain` solved once per (bandwidth b in rad/s, input weight r, integral weight) and process."""
    q = [integral * b**8] if integral > 0 else []
    n = len(q) + 3
    A = np.diag(np.ones(n - 1), 1)
    B = np.zeros((n, 1))
    B[-1, 0] = 1.0
    K, _, _ = control.lqr(A, B, np.diag(q + [b**6, b**4, b**2]), np.array([[r]]))
    return np.asarray(K)[0]


ANGLE_STEP = 1e-3  # step (rad) of the brake law's derivatives in the lower angle
TRIM_BAND = 0.05  # a motor-angle integral starts with the estimated lower speed within this fraction of the target
TRIM_CLIP = 0.15  # and moves the law's target by at most this fraction of it


class FlatnessLaw:
    """Batched feedback-linearising law: estimates (omega_u, alpha, omega_l, d) -> voltage (V).

    The integral state is the law's own (the integral of the estimated speed error) unless the
    caller passes one (``z``, rad: e.g. the measured motor angle minus the reference's integral).

    Parameters
    ----------
    params : RigParams
        The design model.
    dt : float
        Control period (s).
    bandwidth : float, optional
        Closed-loop bandwidth of the speed error (rad/s), see :func:`chain_gain`.
    tau_ref : float, optional
        Time constant of each of the reference's three lags (s).
    w_rest : float, optional
        Lower speed (rad/s) below which the disc counts as at rest when the string torque is inside the stick
        set.
    step : float, optional
        Finite-difference step (rad/s) of the friction law's first and second derivatives.
    low_speed : float, optional
        Targets below this speed (rad/s) are approached from above (0: never).
    approach : float, optional
        Speed (rad/s) the reference goes to first for a low target.
    hold, ramp : float, optional
        Time (s) the reference input stays at ``approach``, then duration (s) of its linear ramp down to the low
        target.
    low_bandwidth : float, optional
        Bandwidth (rad/s) of the error chain for low targets.
    integral : float, optional
        Weight of the speed error's integral for low targets (0: none), see :func:`chain_gain`.
    disturbance : str, optional
        How the estimate ``d`` corrects the brake law: 'offset' (N m added) or 'scale' (the law, its slope and
        curvature times 1 + d), as the estimator's :class:`controllers.kalman.DisturbanceModel`.
    integral_high : float, optional
        Weight of the integral for the other targets (0: none).
    brake : callable, optional
        ``brake(w)`` -> brake torque (N m) at lower speeds w (rad/s, (n,)) of the model with its effects (e.g. at
        the estimated lower angle: :class:`controllers.observer.ObserverController`); default the base law of
        ``params``.  Its slope and curvature are taken in w alone.
    upper : callable, optional
        ``upper(w)`` -> torque (N m) against the upper disc besides the motor and kθ α at upper speeds w (rad/s,
        (n,)) of the model with its effects; default the base law's upper friction.
    """

    def __init__(
        self,
        params: RigParams,
        dt: float,
        *,
        bandwidth: float = 2.5,
        tau_ref: float = 1.0,
        w_rest: float = 0.1,
        step: float = 2e-3,
        low_speed: float = 0.0,
        approach: float = 2.5,
        hold: float = 8.0,
        ramp: float = 15.0,
        low_bandwidth: float = 1.0,
        integral: float = 0.0,
        disturbance: str = "offset",
        integral_high: float = 0.0,
        brake=None,
        upper=None,
    ) -> None:
        if not (np.isfinite(tau_ref) and tau_ref > 0):
            raise InputError(f"tau_ref must be a positive time (s), got {tau_ref!r}")
        for name, v in (
            ("low_speed", low_speed),
            ("approach", approach),
            ("hold", hold),
            ("ramp", ramp),
            ("integral", integral),
        ):
            if not (np.isfinite(v) and v >= 0):
                raise InputError(f"{name} must be a non-negative number, got {v!r}")
        if disturbance not in ("offset", "scale"):
            raise InputError(f"disturbance must be 'offset' or 'scale', got {disturbance!r}")
        self.scale = disturbance == "scale"
        self.brake = brake
        self.upper = upper
        if low_speed > approach:
            raise InputError(f"approach ({approach} rad/s) must not be below low_speed ({low_speed} rad/s)")
        self.p, self.dt, self.tau = params, float(dt), float(tau_ref)
        self.w_rest, self.h = float(w_rest), float(step)
        self.low_speed, self.approach, self.hold, self.ramp = (
            float(low_speed),
            float(approach),
            float(hold),
            float(ramp),
        )
        self.K_high = (
            chain_gain(bandwidth, integral=integral_high)
            if integral_high > 0
            else np.concatenate([[0.0], chain_gain(bandwidth)])
        )
        self.K_low = (
            chain_gain(low_bandwidth, integral=integral)
            if integral > 0
            else np.concatenate([[0.0], chain_gain(low_bandwidth)])
        )
        self.K = np.broadcast_to(self.K_high, (1, 4))
        self.z = np.zeros(1)
        self.y = np.zeros((3, 1))
        self.target = np.zeros(1)
        self.low = np.zeros(1, dtype=bool)
        self.t = np.zeros(1)

    def reset(self, target: np.ndarray) -> None:
        """Start from rest towards the targets (rad/s), (n,)."""
        self.target = np.asarray(target, dtype=float)
        self.y = np.zeros((3, self.target.size))
        self.low = self.target < self.low_speed
        self.K = np.where(self.low[:, None], self.K_low, self.K_high)  # (n, 4): on (int e, e, e', e'')
        self.z = np.zeros(self.target.size)
        self.t = np.zeros(self.target.size)  # time since each rig's start (s)

    def restart(self, index: np.ndarray, target: np.ndarray) -> None:
        """Rigs ``index`` start again from rest towards ``target`` (rad/s, one per index), the others untouched."""
        index = np.asarray(index, dtype=np.int64)
        self.target, self.low, self.K = self.target.copy(), self.low.copy(), np.array(self.K)
        self.target[index] = np.asarray(target, dtype=float)
        self.low[index] = self.target[index] < self.low_speed
        self.K[index] = np.where(self.low[index, None], self.K_low, self.K_high)
        self.y[:, index], self.z[index], self.t[index] = 0.0, 0.0, 0.0

    def setpoint(self, t: float | np.ndarray) -> np.ndarray:
        """Input of the reference lags (rad/s, (n,)) at time t (s, scalar or per rig): the target, or for a low
        target ``approach`` until ``hold``, then a linear ramp down to the target over ``ramp``."""
        t = np.asarray(t, dtype=float)
        s = np.clip((t - self.hold) / self.ramp, 0.0, 1.0) if self.ramp > 0 else (t >= self.hold) * 1.0
        return np.where(self.low, self.approach + s * (self.target - self.approach), self.target)

    def reference(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(r, r', r'', r''') now (rad/s and derivatives), then advance the three lags one period."""
        t, (y1, y2, r), w = self.tau, self.y, self.setpoint(self.t)
        self.t += self.dt
        d1, d2, d3 = (w - y1) / t, (y1 - y2) / t, (y2 - r) / t
        dd2, dd3 = (d1 - d2) / t, (d2 - d3) / t
        ddd3 = (dd2 - dd3) / t
        self.y = self.y + self.dt * np.stack([d1, d2, d3])
        return r.copy(), d3, dd3, ddd3

    def lower_friction(self, w: np.ndarray, shift: float = 0.0) -> np.ndarray:
        """Brake torque Tfl(w) (N m) of the design model at speeds w != 0 (rad/s, (n,)), with ``brake`` at the
        estimated lower angle moved by ``shift`` (rad)."""
        return lower_friction(w, self.p) if self.brake is None else self.brake(w, shift)

    def upper_friction(self, w: np.ndarray) -> np.ndarray:
        """Upper friction torque Tfu(w) (N m) of the design model at speeds w != 0 (rad/s, (n,))."""
        return upper_friction(w, self.p) if self.upper is None else self.upper(w)

    def friction(self, w: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, ...]:
        """Brake torque (N m) corrected by d, its slope and curvature at speed w (forward rotation), and its
        derivatives in the lower angle: first, second and mixed with the speed (zero for the base law)."""
        h = self.h
        w = np.maximum(w, self.w_rest + h)
        t0, tp, tm = self.lower_friction(w), self.lower_friction(w + h), self.lower_friction(w - h)
        T, T1, T2 = t0, (tp - tm) / (2 * h), (tp - 2 * t0 + tm) / h**2
        if self.brake is None:
            Ta = Taa = Twa = np.zeros_like(T)
        else:
            g = ANGLE_STEP
            ap, am = self.lower_friction(w, g), self.lower_friction(w, -g)
            Ta, Taa = (ap - am) / (2 * g), (ap - 2 * t0 + am) / g**2
            Twa = (self.brake(w + h, g) - self.brake(w - h, g) - self.brake(w + h, -g) + self.brake(w - h, -g)) / (
                4 * h * g
            )
        if self.scale:
            return tuple((1.0 + d) * x for x in (T, T1, T2, Ta, Taa, Twa))
        return T + d, T1, T2, Ta, Taa, Twa

    def __call__(
        self, omega_u: np.ndarray, alpha: np.ndarray, omega_l: np.ndarray, d: np.ndarray, z: np.ndarray | None = None
    ) -> np.ndarray:
        """Voltage (V, (n,), not clipped) for the estimated state; ``z`` (rad, (n,)): the integral of the
        speed error to use instead of the law's own."""
        p, kt = self.p, self.p.ktheta
        r, r1, r2, r3 = self.reference()
        T, T1, T2, Ta, Taa, Twa = self.friction(omega_l, d)
        rest = (omega_l <= self.w_rest) & (-kt * alpha < T)
        T1, T2, Ta, Taa, Twa = (np.where(rest, 0.0, x) for x in (T1, T2, Ta, Taa, Twa))
        a = np.where(rest, 0.0, (-kt * alpha - T) / p.Jl)
        j = np.where(rest, 0.0, (-kt * (omega_l - omega_u) - T1 * a - Ta * omega_l) / p.Jl)
        if z is not None:
            self.z = np.asarray(z, dtype=float)
        else:  # integral of the speed error once the reference has settled (per rig)
            self.z = np.where(self.t > self.hold + self.ramp, self.z + self.dt * (omega_l - r), self.z)
        v = r3 - np.einsum("nk,kn->n", self.K, np.stack([self.z, omega_l - r, a - r1, j - r2]))
        # the upper acceleration that gives v: d/dt of the lower disc's jerk with T(w, theta_l)
        wu_dot = (p.Jl * v + kt * a + T2 * a * a + T1 * j + 2 * Twa * omega_l * a + Taa * omega_l**2 + Ta * a) / kt
        tfu = self.upper_friction(np.where(omega_u == 0, 1e-9, omega_u))
        return (p.Ju * wu_dot + tfu - kt * alpha) / p.km
