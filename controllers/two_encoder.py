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

Built on a model with effects (``model=``, :mod:`controllers.model`): the design's discs are the Jacobian of
the model's composition at each design speed (:class:`controllers.dynamics.ModelDynamics`: string damping,
upper-disc friction, forces, the brake's slope with its effects), the model's motor lag replaces the design
lag ``tau``, its delay adds the line of past commands to the design model (exact zero-order hold, LQR and
Kalman gains on the augmented state), the equilibrium's winding and voltage are the composition's torques
at the reference speed and the estimated lower angle, the encoders' readings pass through its Measurement
effects (the output map their Jacobian), and a monotone static input map (a dead zone, an offset) is
inverted in the command.  An Input effect with a state other than one first-order lag is refused.

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
from drillgym.effects.base import Input
from drillgym.equilibria import equilibrium_voltage
from drillgym.errors import InputError
from drillgym.friction import lower_friction
from drillgym.run_setup import real_number, whole_number

from .base import Controller
from .dynamics import ModelDynamics
from .limits import brake_slope
from .model import delayed_discretisation, input_delay, motor_lag

__all__ = ["TwoEncoderLQG", "TwoEncoderDesign"]

GRID = 0.25  # rad/s, spacing of the designs' speeds
#: a told encoder's quantisation counts as this many counts of white noise (std) besides q^2/12: read once per
#: period, a disc turning about a whole number of counts per period makes the error a slow sawtooth, not white
ALIASING = 1.25
#: innovations within this fraction of half a count are not corrected (the angle is within the reading's count)
DEAD_BAND = 0.7


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
    dead_band: float = 0.0  # innovations within this fraction of half a count (of ``counts``) are not corrected


@lru_cache(maxsize=512)
def _design(
    params: RigParams,
    omega: float,
    dt: float,
    o: TwoEncoderDesign,
    delay: float = 0.0,
    discs: tuple | None = None,
    readings: tuple | None = None,
):
    """(A, B, C, K, L) of the discrete design at ``omega`` (rad/s); states (theta_u, omega_u, alpha,
    omega_l, u_a, d) in deviations from the equilibrium, then the line of past commands of a ``delay`` (s).
    ``discs``: the model's Jacobian rows of omega_u and omega_l in (theta_u, omega_u, alpha, omega_l) (1/s^2,
    1/s; the brake's slope without the margin), default the base model's; ``readings``: the encoders' output
    map (2 x 4), default theta_u and theta_u + alpha."""
    p = params
    A = np.zeros((6, 6))
    A[0, 1] = 1.0
    A[2, 1], A[2, 3] = -1.0, 1.0
    A[1, 4], A[3, 5] = p.km / p.Ju, -1.0 / p.Jl
    if discs is None:
        s = brake_slope(omega, p)
        A[1, 1], A[1, 2] = -(p.bu + p.dbu) / p.Ju, p.ktheta / p.Ju
        A[3, 2], A[3, 3] = -p.ktheta / p.Jl, -s / p.Jl
    else:
        A[1, :4], A[3, :4] = np.reshape(discs, (2, 4))
        s = -p.Jl * A[3, 3]
    if s < 0:  # the brake's negative slope made steeper
        A[3, 3] = -s * (1.0 + o.slope_margin) / p.Jl
    A[4, 4] = -1.0 / o.tau
    B = np.zeros((6, 1))
    B[4, 0] = 1.0 / o.tau
    sysd = delayed_discretisation(A, B, dt, delay)
    Ad, Bd, nx = sysd.Ad, sysd.Bd, 6 + sysd.n_line
    C = np.zeros((2, nx))
    if readings is None:
        C[0, 0] = 1.0
        C[1, 0], C[1, 2] = 1.0, 1.0  # theta_l = theta_u + alpha
    else:
        C[:, :4] = np.reshape(readings, (2, 4))
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


def _model_dynamics(model, who: str) -> ModelDynamics | None:
    """The composition's dynamics of a model with effects (None without), refusing in one line an effect state
    the design has no place for (it has one first-order lag on the command)."""
    comp = model.composition
    if not comp.effects:
        return None
    stateful = [e for e in comp.effects if e.states]
    for i, e in enumerate(stateful):
        lag = issubclass(e, Input) and len(e.states) == 1 and set(e.lag) == {e.states[0].name}
        why = "" if lag else "a state other than a first-order lag on the command"
        if lag and i > 0:
            why = "a second lag on the command"
        if why:
            raise InputError(f"{who} cannot use the model's effect {e.name!r} ({why}: its design has one lag)")
    return ModelDynamics(comp, np.asarray(model.vector, dtype=float), scale=False)


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
    counts_per_rev : int, optional
        The encoders' resolution (counts/rev), when known: the filter's angle noise is then q^2/12 plus
        :data:`ALIASING` counts (std) plus ``angle_noise``, and innovations within :data:`DEAD_BAND` of half a count
        are not corrected (on 2048-count encoders the default design, which assumes 4096 counts, limit-cycles
        at 1.4-1.6 rad/s, where the lower disc turns about one count per 2 ms period).  Default: the design's.
    angle_noise : float, optional
        White angle noise of the encoders (rad, std), with ``counts_per_rev``.
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
        counts_per_rev: int | None = None,
        angle_noise: float = 0.0,
        **kw,
    ) -> None:
        super().__init__(omega_ref, **kw)
        for name, v in (("approach", approach), ("hold", hold), ("ramp", ramp)):
            if not (np.isfinite(v) and v >= 0):
                raise InputError(f"{name} must be a non-negative number, got {v!r}")
        if not (np.isfinite(tau_ref) and tau_ref > 0):
            raise InputError(f"tau_ref must be a positive time (s), got {tau_ref!r}")
        self.design = design or TwoEncoderDesign()
        if counts_per_rev is not None:  # the encoders' resolution is known: it sets the measurement noise
            counts_per_rev = whole_number("counts_per_rev", counts_per_rev, 1)
            angle_noise = real_number("angle_noise", angle_noise, "rad")
            if not (
                np.isfinite(counts_per_rev) and counts_per_rev >= 1 and np.isfinite(angle_noise) and angle_noise >= 0
            ):
                raise InputError(
                    f"counts_per_rev must be >= 1 and angle_noise >= 0, got {counts_per_rev!r}, {angle_noise!r}"
                )
            q = 2.0 * np.pi / counts_per_rev
            floor = float(np.hypot(ALIASING * q, angle_noise))
            self.design = replace(self.design, counts=int(counts_per_rev), noise_floor=floor, dead_band=DEAD_BAND)
        self.dyn = _model_dynamics(self.effects, f"controller {self.name!r}")
        lag = motor_lag(self.effects)
        if lag > 0:  # the model's motor lag instead of the design's robust middle
            self.design = replace(self.design, tau=lag)
        self.delay = input_delay(self.effects)
        self.compensates = self.dyn is not None and self.dyn.invertible(self.u_max)
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

    def _model_equilibrium(self, r: np.ndarray, theta_u: np.ndarray, alpha: np.ndarray):
        """(z, alpha*, voltage at the motor*) of the model's slip equilibrium at speeds r (rad/s, (n,)) near the
        estimated angles (rad): the composition's torques on both discs."""
        p, dyn = self.params, self.dyn
        z = np.zeros((dyn.nz, r.size))
        z[0], z[1], z[2], z[3] = theta_u, r, alpha, r
        a = -dyn.lower_torque(z, r, r) / p.ktheta
        z[2] = a
        v = (dyn.upper_torque(z, r, r) - p.ktheta * a) / p.km
        return z, a, v

    def _reset(self, m: dict[str, np.ndarray]) -> None:
        n = self.n
        top = max(float(np.max(self.omega_ref)), self.approach) + 1.0
        self._grid = np.arange(GRID, top + GRID, GRID)
        p = self.params
        discs = readings = [None] * self._grid.size
        if self.dyn is None:
            self._alpha_grid = -lower_friction(self._grid, p) / p.ktheta
            self._u_grid = np.asarray(equilibrium_voltage(self.config, self._grid, p), dtype=float)
        else:  # the composition's equilibrium and Jacobian at each design speed (the lower angle at 0)
            zero = np.zeros(self._grid.size)
            z, self._alpha_grid, self._u_grid = self._model_equilibrium(self._grid, zero, zero)
            J, _ = self.dyn.jacobian(z, zero)
            discs = [tuple(np.round(J[i][[1, 3], :4].ravel(), 12)) for i in range(self._grid.size)]
            if self.dyn.composition.has_measurement:
                H = self.dyn.reading_jacobian(z)[:, :, :4]
                readings = [tuple(np.round(H[i].ravel(), 12)) for i in range(self._grid.size)]
        mats = [
            _design(p, float(w), float(self.dt), self.design, self.delay, discs[i], readings[i])
            for i, w in enumerate(self._grid)
        ]
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

    def _command(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The commands (V) that give the motor the voltages v (V): the model's static input map inverted."""
        if not self.compensates:
            return v
        return self.dyn.command(self._z(x), v, self.u_max)

    def _motor(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """The voltage at the motor (V) the commands u (V) give once the lags settled (the static input map)."""
        return self.dyn.motor_voltage(self._z(x), u)

    def _z(self, x: np.ndarray) -> np.ndarray:
        z = np.zeros((self.dyn.nz, x.shape[0]))
        z[:4] = x[:, :4].T
        return z

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
        # the prediction is linear in the motor's voltage: x_next += B (v_applied - v_own)
        dv = self._motor(self.x, u) - self._motor(self.x, self.u_prev) if self.compensates else u - self.u_prev
        self.x = self.x + self._b * dv[:, None]
        self.u_prev = u.copy()

    def _compiled_law(self):
        """The filter and the law compiled from the current state (:mod:`controllers.compiled.two_encoder_law`, on a
        model with effects :mod:`controllers.compiled.model_law`); None with a Measurement effect in the model or
        for a subclass with its own ``act`` (the step-by-step loop runs them)."""
        from .compiled.model_law import compiled_law

        return compiled_law(self, "lqg-2enc")

    def _target(self) -> np.ndarray:
        s = np.clip((self.t - self.hold) / self.ramp, 0.0, 1.0) if self.ramp > 0 else (self.t >= self.hold) * 1.0
        return np.where(
            self.omega_ref < self.approach, self.approach + s * (self.omega_ref - self.approach), self.omega_ref
        )

    def _act(self, m: dict[str, np.ndarray]) -> np.ndarray:
        r = np.maximum(self.r, GRID)  # designs exist from GRID up; the reference starts there
        k = np.clip(np.rint(r / GRID).astype(int) - 1, 0, self._grid.size - 1)
        A, B, C, K, L = self._A[k], self._B[k], self._C[k], self._K[k], self._L[k]
        if self.dyn is None:
            a_eq, u_eq = self._equilibrium(r)
        else:  # the composition's torques at the reference speed and the estimated lower angle
            _, a_eq, u_eq = self._model_equilibrium(r, self.x[:, 0], self.x[:, 2])
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
        if self.dyn is not None and self.dyn.composition.has_measurement:  # the readings through the model's
            zx = np.zeros((self.dyn.nz, self.n))  # Measurement effects, at the estimate
            zx[:4] = (xd + eq)[:, :4].T
            innov = np.stack([tu, tl], axis=1) - np.stack(self.dyn.readings(zx), axis=1)
        else:
            y = np.stack([tu - eq[:, 0], tl - eq[:, 0] - a_eq], axis=1)
            innov = y - np.einsum("nij,nj->ni", C, xd)
        if self.design.dead_band > 0:  # within the encoder's quantisation cell the reading says nothing more
            q = 2.0 * np.pi / self.design.counts  # a count of the encoder: the angle is in [reading, reading + q)
            w = self.design.dead_band * q / 2
            innov = innov + q / 2
            innov = innov - np.clip(innov, -w, w)
        xd = xd + np.einsum("nij,nj->ni", L, innov)
        v = u_eq - np.einsum("nij,nj->ni", K, xd)[:, 0]  # the voltage the motor should see
        u = np.clip(self._command(xd + eq, v), -self.u_max, self.u_max)
        v = self._motor(xd + eq, u) if self.compensates else u
        xd = np.einsum("nij,nj->ni", A, xd) + B[:, :, 0] * (v - u_eq)[:, None]
        self._b = B[:, :, 0]
        # advance the reference and keep the estimate in absolute coordinates
        self.theta_ref = self.theta_ref + r * self.dt
        self.x = xd + eq
        self.x[:, 0] = xd[:, 0] + self.theta_ref + shift  # the deviation is about the advanced reference angle
        self.r = self.r + self.dt / self.tau_ref * (self._target() - self.r)
        self.t += self.dt
        return u
