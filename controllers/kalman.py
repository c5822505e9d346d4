"""Kalman filter that sees only the motor angle: the model's composition + an unknown brake-level deviation.

Model (torsional, absolute coordinates; the estimator's state, :data:`STATES`)::

    z = (theta_u, omega_u, alpha, omega_l, d, [du], effect states ..., [line of past commands])

    dz/dt = f(z, v)       the composition's compiled right-hand side (:class:`controllers.dynamics.ModelDynamics`)
    d d / dt = w_d        (random walk)

with the brake torque T(omega_l) the model's law with its Friction effects, times 1 + d (``disturbance='scale'``,
d dimensionless: a brake whose level is off, as with the oil's temperature) or plus d (``'offset'``, N m),
the exact stick logic of the kernels while a disc rests (speed below 1 mrad/s), every Force, Friction on
either disc and the Input chain (a lag state, a dead zone, an offset ...) of the model it is built on, and
``du`` (``sigma_du > 0``) a torque on the upper disc the model misses.  ``v`` is the command after the
model's Delay effects: a line of past commands (exact zero-order hold of the fractional delay,
:func:`controllers.model.delayed_discretisation`).

Discretisation (period ``dt``): ``A`` is the Jacobian of f at the slip equilibrium at 3 rad/s with the lower
disc's speed and level columns left out (the brake's slope changes sign with the speed: it is evaluated at the
estimate each period instead); the mean is propagated by the exponential Euler step

    z+ = z + Gamma f(z, v),      Gamma = int_0^dt e^{A s} ds

(exact for a linear f, stable for a stiff lag), split at the fractional delay between the older and the newer
command; the covariance with ``e^{A dt} + Gamma (J(z) - A)``, J the Jacobian of f at the estimate (numerical,
friction modes held).  For the base model this is the linearisation of :func:`drillgym.equilibria.linearise`
with the friction torques as known inputs.

Measurement: what the motor encoder reads, the model's Measurement effects on theta_u applied (an encoder
scale error, a backlash); its Jacobian is the filter's output map.  Its noise variance is q^2/12 (q = 2 pi /
counts per rev) plus any extra white noise.

Three estimators share the model: :class:`KalmanObserver` (filterpy ``KalmanFilter``, time-varying covariance,
batched: the covariance does not depend on the data, so one filter carries the states of n trajectories as
the columns of ``x``), :class:`ExtendedKalmanObserver` (filterpy's equations with one covariance per
trajectory, propagated with the Jacobian at the estimate: the filter knows where the lower disc is locally
unstable and trusts the measurement more there) and :func:`steady_state_gain` (python-control ``dlqe``) for
the LQG design.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import control
import numpy as np
from filterpy.kalman import KalmanFilter
from scipy.linalg import expm

from drillgym import RigParams
from drillgym.errors import InputError
from drillgym.measurement import DEFAULT_COUNTS_PER_REV

from .dynamics import ModelDynamics
from .model import delayed_discretisation, model_of, torsional_part

__all__ = [
    "STATES",
    "I_DU",
    "DisturbanceModel",
    "disturbance_model",
    "KalmanObserver",
    "ExtendedKalmanObserver",
    "steady_state_gain",
    "compensate",
]

STATES = ("theta_u", "omega_u", "alpha", "omega_l", "d")
"""State order of the estimator: rad, rad/s, rad, rad/s, relative level (or N m); a model built with
``sigma_du > 0`` has a sixth state ``du`` (N m): a torque on the upper disc the model misses; then the model's
effect states, then the line of past commands."""
I_TU, I_WU, I_AL, I_WL, I_D = range(5)
I_DU = 5
_W0 = 3.0  # rad/s, the slip equilibrium of the fixed linear part


@dataclass(frozen=True)
class DisturbanceModel:
    """Discrete model of the estimator (period ``dt``; module doc).

    ``Ac``, ``Bc``: the fixed linear part (nc continuous states, the command); ``Ad``, ``Bd``: its exact
    discretisation with the delay line (dim = nc + n_line states); ``H`` the output map at the reference;
    ``Qd`` (process, dim x dim) and ``R`` (measurement) covariances.
    """

    params: RigParams
    dt: float
    Ac: np.ndarray
    Bc: np.ndarray
    Ad: np.ndarray
    Bd: np.ndarray
    H: np.ndarray
    Qd: np.ndarray
    R: np.ndarray
    dynamics: ModelDynamics
    gamma_new: np.ndarray
    """Gamma of the newer command (nc x nc): int_0^{dt-f} e^{A s} ds, f the fractional delay."""
    gamma_old: np.ndarray
    """Gamma of the older command (nc x nc): e^{A (dt-f)} int_0^f e^{A s} ds (zero without a fraction)."""
    friction_known: bool = True
    disturbance: str = "offset"
    """What the state ``d`` is: 'offset' (N m added to the brake law) or 'scale'
    (relative level: the brake law times 1 + d while the disc slips)."""
    effects: Any = None
    """The model with its effects (a :class:`drillgym.Model`; None: the base model of ``params``)."""
    has_du: bool = False
    """Whether the state ``du`` (row :data:`I_DU`) is there."""
    lag_index: int = -1
    """Row of the first declared lag state (V); -1 without one."""
    line_index: int = -1
    """First row of the line of past commands u[k-1], u[k-2], ... (V); -1 without a delay."""
    delay_steps: int = 0
    """Whole control periods of the delay (the command the motor sees now is u[k - delay_steps])."""
    reads_effects: bool = False
    """Whether a Measurement effect changes what the motor encoder reads."""
    compensates: bool = False
    """Whether the model's static input map is inverted in the command (:func:`compensate`)."""

    @property
    def nc(self) -> int:
        """Number of continuous states."""
        return self.dynamics.nz

    def commands(self, x: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(newer, older) commands (V, (n,)) the Input chain sees over the period starting now with command u."""
        if self.line_index < 0:
            return u, u
        line = x[self.line_index :]
        new = u if self.delay_steps == 0 else line[self.delay_steps - 1]
        old = line[self.delay_steps] if self.delay_steps < line.shape[0] else new
        return new, old

    def predict_mean(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """The estimates one period on (dim, n) from x (dim, n) with the command u (V, (n,)) held."""
        u = np.broadcast_to(np.asarray(u, dtype=float), (x.shape[1],))
        nc = self.nc
        new, old = self.commands(x, u)
        out = x.copy()
        out[:nc] = x[:nc] + self.gamma_new @ self.dynamics.f(x, new)
        if np.any(self.gamma_old):
            out[:nc] += self.gamma_old @ self.dynamics.f(x, old)
        if self.line_index >= 0:
            out[nc + 1 :] = x[nc:-1]
            out[nc] = u
        return out

    def transition(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Jacobians of :meth:`predict_mean` (n, dim, dim) at x with the command u (the covariance's)."""
        u = np.broadcast_to(np.asarray(u, dtype=float), (x.shape[1],))
        nc = self.nc
        new, _ = self.commands(x, u)
        J, _ = self.dynamics.jacobian(x, new)
        F = np.broadcast_to(self.Ad, (x.shape[1],) + self.Ad.shape).copy()
        F[:, :nc, :nc] += (self.gamma_new + self.gamma_old) @ (J - self.Ac)
        return F

    def reading(self, x: np.ndarray) -> np.ndarray:
        """What the motor encoder reads (rad, (n,)) at the estimates x."""
        if not self.reads_effects:
            return x[I_TU]
        return self.dynamics.readings(x)[0]

    def output_map(self, x: np.ndarray) -> np.ndarray:
        """d(reading)/dx (n, dim) at the estimates x."""
        H = np.zeros((x.shape[1], self.Ad.shape[0]))
        if not self.reads_effects:
            H[:, I_TU] = 1.0
        else:
            H[:, : self.nc] = self.dynamics.reading_jacobian(x)[:, 0]
        return H

    def brake_law(self, w: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Torque (N m, (n,)) against the lower disc besides kθ α at lower speeds w (rad/s, != 0) and the estimates x:
        the model's brake law with its effects (level 1), the lower-disc forces and the string's extra torque."""
        return self.dynamics.lower_torque(x, np.broadcast_to(np.asarray(w, dtype=float), (x.shape[1],)))

    def upper_law(self, w: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Torque (N m, (n,)) against the upper disc besides the motor and kθ α at upper speeds w (rad/s)."""
        return self.dynamics.upper_torque(x, np.broadcast_to(np.asarray(w, dtype=float), (x.shape[1],)))

    def lower_friction(self, x: np.ndarray, eps: float = 1e-3) -> np.ndarray:
        """Estimated torque (N m, (n,)) against the lower disc besides kθ α at the estimates x: the model's law
        times 1 + d ('scale') or plus d ('offset') while it slips; while it rests, the torque that holds it."""
        wl = x[I_WL]
        slip = np.abs(wl) > eps
        T = self.brake_law(np.where(slip, wl, eps), x)
        T = T * (1.0 + x[I_D]) if self.disturbance == "scale" else T + x[I_D]
        hold = -self.params.ktheta * x[I_AL]
        return np.where(slip, T, hold)

    @property
    def upper_coulomb(self) -> float:
        """Upper friction offset for positive rotation, Tcu + dTcu (N m)."""
        return self.params.Tcu + self.params.dTcu

    @property
    def upper_damping(self) -> float:
        """Upper viscous friction for positive rotation, bu + dbu (N m s/rad)."""
        return self.params.bu + self.params.dbu


def _gammas(A: np.ndarray, dt: float, frac: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(e^{A dt}, Gamma of the newer command, Gamma of the older one) for a fractional delay ``frac`` (s)."""
    n = A.shape[0]

    def phi_gamma(tau: float) -> tuple[np.ndarray, np.ndarray]:
        M = expm(np.block([[A, np.eye(n)], [np.zeros((n, 2 * n))]]) * tau)
        return M[:n, :n], M[:n, n:]

    Ad, _ = phi_gamma(dt)
    Pn, Gn = phi_gamma(dt - frac)
    Go = Pn @ phi_gamma(frac)[1] if frac > 0 else np.zeros((n, n))
    return Ad, Gn, Go


def _reference(dyn: ModelDynamics, p: RigParams) -> tuple[np.ndarray, float]:
    """(z, command) of the model's slip equilibrium at :data:`_W0` (rad/s): the lags settled."""
    z = np.zeros((dyn.nz, 1))
    z[I_WU] = z[I_WL] = _W0
    for _ in range(3):  # the winding that carries the lower torque, the effect states settled
        z[I_AL] = -dyn.lower_torque(z, np.array([_W0]), np.array([_W0])) / p.ktheta
    vm = (dyn.upper_torque(z, np.array([_W0])) - p.ktheta * z[I_AL]) / p.km
    u = dyn.command(z, vm, 5.0) if dyn.invertible() else vm
    for _ in range(len(dyn.lag_rows) + 2):
        dz = dyn.f(z, u)
        for row, tau in dyn.lag_rows.items():
            z[row] += tau * dz[row]
    return z, float(u[0])


def disturbance_model(
    params: RigParams | None = None,
    dt: float = 0.01,
    *,
    counts_per_rev: int = DEFAULT_COUNTS_PER_REV,
    angle_noise: float = 0.0,
    sigma_d: float = 0.02,
    sigma_upper: float = 0.03,
    sigma_lower: float = 0.005,
    friction_known: bool = True,
    disturbance: str = "offset",
    sigma_du: float = 0.0,
    model: Any = None,
) -> DisturbanceModel:
    """Build the estimator's model.

    Parameters
    ----------
    params : RigParams, optional
        Model parameters (the identified set by default).
    dt : float, optional
        Sample period (s).
    counts_per_rev : int, optional
        Encoder resolution (0: no quantization).
    angle_noise : float, optional
        Extra white noise on theta_u (rad, std).
    sigma_d : float, optional
        Random-walk intensity of the disturbance state (N m / sqrt(s) for 'offset', 1 / sqrt(s) for 'scale').
    sigma_upper, sigma_lower : float, optional
        White torque noise on the discs (N m / sqrt(Hz)), model error.
    friction_known : bool, optional
        The model's brake law (with stick) is known and ``d`` its unknown deviation (default); False: ``d`` is
        the whole lower friction torque (the brake's law and its effects left out).
    disturbance : str, optional
        'offset' (``d`` in N m added to the brake law) or 'scale' (``d`` the relative error of the brake law's
        level: Ts, Tc, bb all off by the same factor, as with the oil's temperature); 'scale' needs
        ``friction_known``.
    sigma_du : float, optional
        > 0 adds a sixth state ``du`` (N m), a torque on the upper disc that the model misses (motor constant,
        upper friction, lag errors), as a random walk of this intensity (N m/sqrt(s)).
    model : drillgym.Model, optional
        The model with its effects (its base parameters replace ``params``): every effect enters f (module doc).

    Returns
    -------
    DisturbanceModel
        The estimator's model.

    Raises
    ------
    InputError
        Bad options, or an effect the estimator's torsional model cannot represent (one line naming it).
    """
    if model is not None:
        if params is not None and params != model.params:
            raise InputError("give the estimator's base parameters either as params or in its model, not both")
        model = torsional_part(model, "the motor-angle Kalman filter", ("theta_u",))
    else:
        model = model_of(None, params)
    p = model.params
    if not (np.isfinite(dt) and dt > 0):
        raise InputError(f"dt must be a positive period (s), got {dt!r}")
    if disturbance not in ("offset", "scale"):
        raise InputError(f"disturbance must be 'offset' or 'scale', got {disturbance!r}")
    if disturbance == "scale" and not friction_known:
        raise InputError("a 'scale' disturbance needs the nominal brake law (friction_known=True)")
    for name, v in (
        ("sigma_d", sigma_d),
        ("sigma_upper", sigma_upper),
        ("sigma_lower", sigma_lower),
        ("angle_noise", angle_noise),
        ("sigma_du", sigma_du),
    ):
        if not (np.isfinite(v) and v >= 0):
            raise InputError(f"{name} must be a non-negative number, got {v!r}")
    vec = np.array(model.vector, dtype=float)
    if not friction_known:  # d is the whole brake torque: no law, no stick set
        from drillgym.params import IDX

        vec[[IDX.Ts, IDX.Tc, IDX.bb]] = 0.0
    dyn = ModelDynamics(model.composition, vec, scale=disturbance == "scale", has_du=sigma_du > 0)
    nc = dyn.nz
    z0, u0 = _reference(dyn, p)
    J, b = dyn.jacobian(z0, np.array([u0]))
    A, B = J[0].copy(), b[0][:, None].copy()
    if friction_known:  # the lower disc's own-speed terms (the brake's slope): at the estimate, each period
        A[:, I_WL] = 0.0
        A[I_AL, I_WL] = 1.0  # alpha' = omega_l - omega_u stays
    if disturbance == "scale":
        A[:, I_D] = 0.0
    G = np.zeros((nc, 4))
    G[I_WU, 0] = 1.0 / p.Ju
    G[I_WL, 1] = 1.0 / p.Jl
    G[I_D, 2] = 1.0
    if sigma_du > 0:
        G[I_DU, 3] = 1.0
    Qc = np.diag([sigma_upper**2, sigma_lower**2, sigma_d**2, sigma_du**2])
    Qd = _discrete_noise(A, G @ Qc @ G.T, dt)
    delay = dyn.delay
    sysd = delayed_discretisation(A, B, dt, delay)
    n_line = sysd.n_line
    steps = int(np.floor(delay / dt + 1e-9)) if n_line else 0
    frac = max(delay - steps * dt, 0.0) if n_line else 0.0
    if frac < 1e-9 * dt:
        frac = 0.0
    Ad_c, g_new, g_old = _gammas(A, dt, frac)
    Qd = np.pad(Qd, ((0, n_line), (0, n_line)))
    reads = bool(dyn.composition.has_measurement) and "theta_u" in {
        c for e in dyn.composition.effects for c in getattr(e, "channels", ())
    }
    H = np.zeros((1, nc + n_line))
    if reads:
        H[0, :nc] = dyn.reading_jacobian(z0)[0, 0]
    else:
        H[0, I_TU] = 1.0
    q = 2.0 * np.pi / counts_per_rev if counts_per_rev > 0 else 0.0
    R = np.array([[q * q / 12.0 + angle_noise**2 + 1e-12]])
    lags = sorted(dyn.lag_rows)
    return DisturbanceModel(
        p,
        float(dt),
        A,
        B,
        sysd.Ad,
        sysd.Bd,
        H,
        Qd,
        R,
        dyn,
        g_new,
        g_old,
        friction_known,
        disturbance,
        effects=model,
        has_du=sigma_du > 0,
        lag_index=lags[0] if lags else -1,
        line_index=nc if n_line else -1,
        delay_steps=steps,
        reads_effects=reads,
        compensates=dyn.invertible(),
    )


def compensate(model: DisturbanceModel, x: np.ndarray, v: np.ndarray, u_max: float) -> np.ndarray:
    """The commands (V, (n,)) that give the motor the voltages v (V) at the estimates x: the model's static input map
    inverted where it is monotone (a dead zone: v +- u0; an offset: v - offset), else v itself.

    Parameters
    ----------
    model : DisturbanceModel
        The estimator's model.
    x : ndarray
        Estimates (dim, n).
    v : ndarray
        Wanted voltages at the motor (V, (n,)).
    u_max : float
        The amplifier's range (V); the inverse is searched within twice it.

    Returns
    -------
    ndarray
        Commands (V, (n,)), not clipped.
    """
    if not model.compensates:
        return np.asarray(v, dtype=float)
    return model.dynamics.command(x, v, u_max)


def _discrete_noise(A: np.ndarray, Qc: np.ndarray, dt: float) -> np.ndarray:
    """Covariance of the discretised white process noise (Van Loan's method)."""
    n = A.shape[0]
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = -A
    M[:n, n:] = Qc
    M[n:, n:] = A.T
    E = expm(M * dt)
    Phi = E[n:, n:].T
    Q = Phi @ E[:n, n:]
    return 0.5 * (Q + Q.T)


class KalmanObserver:
    """Batched Kalman filter (filterpy) estimating (theta_u, omega_u, alpha, omega_l, d) from theta_u.

    One ``filterpy.kalman.KalmanFilter`` holds the covariance (the same for
    every trajectory: it does not depend on the data) and the n state
    estimates as the columns of its ``x`` (5, n).  Per control period:
    :meth:`update` with the measured angle, read :attr:`x`, then
    :meth:`predict` with the voltage applied over the period.

    Parameters
    ----------
    model : DisturbanceModel
        The estimator's model (:func:`disturbance_model`).
    p0_alpha : float, optional
        Initial standard deviation of the winding (rad).
    p0_speed : float, optional
        Initial standard deviation of the speeds (rad/s).
    p0_d : float, optional
        Initial standard deviation of the disturbance state (its unit, see :class:`DisturbanceModel`).
    """

    def __init__(
        self, model: DisturbanceModel, *, p0_alpha: float = 5.0, p0_speed: float = 2.0, p0_d: float = 0.3
    ) -> None:
        if model.Ad.shape[0] != 5:
            raise InputError("the linear KalmanObserver takes the 5-state model; use ExtendedKalmanObserver")
        self.model = model
        self.kf = KalmanFilter(dim_x=5, dim_z=1)
        self.kf.F = model.Ad.copy()
        self.kf.H = model.H.copy()
        self.kf.Q = model.Qd.copy()
        self.kf.R = model.R.copy()
        self._P0 = np.diag([model.R[0, 0], p0_speed**2, p0_alpha**2, p0_speed**2, p0_d**2])

    def reset(self, theta_u: np.ndarray, alpha0: float | np.ndarray = 0.0) -> None:
        """Start at rest at the measured angles theta_u (n,), winding guess alpha0 (rad)."""
        th = np.atleast_1d(np.asarray(theta_u, dtype=float))
        x = np.zeros((5, th.size))
        x[I_TU] = th
        x[I_AL] = alpha0
        x[I_D] = 0.0 if self.model.friction_known else -self.model.params.ktheta * x[I_AL]
        self.kf.x = x
        self.kf.P = self._P0.copy()

    @property
    def x(self) -> np.ndarray:
        """Current estimates (5, n), rows in :data:`STATES` order."""
        return self.kf.x

    def update(self, theta_u: np.ndarray) -> np.ndarray:
        """Correct with the measured motor angle (n,) (rad); returns the estimates (5, n)."""
        self.kf.update(np.atleast_2d(np.asarray(theta_u, dtype=float)), H=self.kf.H)
        return self.kf.x

    def predict(self, u: np.ndarray) -> None:
        """Propagate over one period with the voltage u (n,) held (V)."""
        u = np.atleast_1d(np.asarray(u, dtype=float))
        x = self.kf.x.copy()
        self.kf.predict()
        self.kf.x = self.model.predict_mean(x, u)  # the model's mean, the linear part's covariance

    def friction(self) -> np.ndarray:
        """Estimated lower friction torque (N m, (n,)): nominal law at the estimate + disturbance state."""
        return self.model.lower_friction(self.kf.x)


class ExtendedKalmanObserver:
    """Extended Kalman filter on the same model, batched over n trajectories (covariances (n, 5, 5)).

    The mean is propagated like :class:`KalmanObserver`'s (nonlinear known inputs: upper Coulomb
    friction, nominal brake law with stick); the covariance with the Jacobian, i.e. ``Ad`` plus
    the brake's slope dTfl/domega at the estimated lower speed (first order in ``dt``).  The
    equations are filterpy's ``KalmanFilter.predict`` / ``update`` (Joseph form), written once for
    the whole batch: a control loop at 500 Hz runs the filter of every trajectory of the harness
    in one numpy call (``tests/test_controllers_kalman.py`` checks the numbers against one filterpy
    ``KalmanFilter`` per trajectory).  Default initial uncertainty: a rig at rest, winding known to
    0.1 rad.  Rows may be reset and updated on their own (``index``), for vector environments.

    Parameters
    ----------
    model : DisturbanceModel
        The estimator's model (:func:`disturbance_model`).
    p0_alpha : float, optional
        Initial standard deviation of the winding (rad).
    p0_speed : float, optional
        Initial standard deviation of the speeds (rad/s).
    p0_d : float, optional
        Initial standard deviation of the disturbance state (its unit, see :class:`DisturbanceModel`).
    slope_step : float, optional
        Finite-difference step of the brake slope (rad/s).
    p0_du : float, optional
        Initial standard deviation of the upper-disc torque state (N m), when the model has one.

    Raises
    ------
    InputError
        A model without the nominal brake law (``friction_known=False``).
    """

    def __init__(
        self,
        model: DisturbanceModel,
        *,
        p0_alpha: float = 0.1,
        p0_speed: float = 0.05,
        p0_d: float = 0.01,
        slope_step: float = 1e-3,
        p0_du: float = 0.1,
    ) -> None:
        if model.friction_known is False:
            raise InputError("the extended filter needs the nominal brake law (friction_known=True)")
        self.model = model
        self.h = float(slope_step)
        self.dim = int(model.Ad.shape[0])  # 5, 6 with the upper-disc torque du, then a lag state, a delay line
        p0 = [model.R[0, 0], p0_speed**2, p0_alpha**2, p0_speed**2, p0_d**2] + ([p0_du**2] if model.has_du else [])
        self.P0 = np.diag(p0 + [0.0] * (self.dim - len(p0)))  # the rig at rest: no voltage at the motor, none sent
        self.x = np.zeros((self.dim, 0))
        """Current estimates (dim, n), rows in :data:`STATES` order (then du)."""
        self.P = np.zeros((0, self.dim, self.dim))
        """Current covariances (n, dim, dim)."""

    def allocate(self, n: int) -> None:
        """Room for n trajectories (at rest at angle 0; :meth:`reset` them before use)."""
        self.x = np.zeros((self.dim, int(n)))
        self.P = np.broadcast_to(self.P0, (int(n), self.dim, self.dim)).copy()

    def reset(self, theta_u: np.ndarray, alpha0: float | np.ndarray = 0.0, index: np.ndarray | None = None) -> None:
        """Start at rest at the measured angles theta_u (rad), winding guess alpha0 (rad).

        ``index`` None: all trajectories, their number is theta_u's size; otherwise only the rows
        ``index`` (theta_u and alpha0 broadcast to its shape)."""
        if index is None:
            th = np.atleast_1d(np.asarray(theta_u, dtype=float))
            self.allocate(th.size)
            index = np.arange(th.size)
        idx = np.atleast_1d(np.asarray(index))
        self.x[:, idx] = 0.0
        self.x[I_TU, idx] = np.broadcast_to(np.asarray(theta_u, dtype=float), idx.shape)
        self.x[I_AL, idx] = np.broadcast_to(np.asarray(alpha0, dtype=float), idx.shape)
        self.P[idx] = self.P0

    def update(self, theta_u: np.ndarray, index: np.ndarray | slice = slice(None)) -> np.ndarray:
        """Correct rows ``index`` with their measured motor angles (rad); returns all estimates (dim, n)."""
        P, x, r = self.P[index], self.x[:, index], self.model.R[0, 0]
        z = np.broadcast_to(np.asarray(theta_u, dtype=float), (x.shape[1],))
        if not self.model.reads_effects:  # H = e_theta_u
            K = P[:, :, I_TU] / (P[:, I_TU, I_TU] + r)[:, None]  # (m, dim): P H' S^-1
            self.x[:, index] = x + K.T * (z - x[I_TU])
            IKH = np.broadcast_to(np.eye(self.dim), P.shape).copy()
            IKH[:, :, I_TU] -= K
        else:  # the reading through the model's Measurement effects, linearised at the estimate
            H = self.model.output_map(x)  # (m, dim)
            PH = np.einsum("mij,mj->mi", P, H)
            K = PH / (np.einsum("mi,mi->m", H, PH) + r)[:, None]
            self.x[:, index] = x + K.T * (z - self.model.reading(x))
            IKH = np.broadcast_to(np.eye(self.dim), P.shape) - K[:, :, None] * H[:, None, :]
        self.P[index] = IKH @ P @ IKH.transpose(0, 2, 1) + r * K[:, :, None] * K[:, None, :]
        return self.x

    def jacobians(self, x: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
        """Discrete Jacobians (n, dim, dim) of the prediction at the estimates x with the commands u (V; default
        the voltage that keeps the motor's voltage, 0 without a lag)."""
        u = np.zeros(x.shape[1]) if u is None else u
        return self.model.transition(x, u)

    def predict(self, u: np.ndarray) -> None:
        """Propagate every trajectory over one period with the voltages u (V, (n,)) held."""
        m, x = self.model, self.x
        u = np.broadcast_to(np.asarray(u, dtype=float), (x.shape[1],))
        F = m.transition(x, u)
        self.P = F @ self.P @ F.transpose(0, 2, 1) + m.Qd
        self.x = m.predict_mean(x, u)

    def friction(self) -> np.ndarray:
        """Estimated lower friction torque (N m, (n,)): nominal law at the estimate + disturbance state."""
        return self.model.lower_friction(self.x)


def steady_state_gain(model: DisturbanceModel) -> tuple[np.ndarray, np.ndarray]:
    """Stationary Kalman gains from python-control ``dlqe``: (filter gain K (5, 1), predictor gain L (5, 1)).

    ``L`` is dlqe's gain (x+ = A x + B u + L (z - C x)); ``K = P C' (C P C' + R)^-1`` the
    measurement-update gain of the same filter (P: dlqe's Riccati solution, the prior covariance).
    """
    L, P, _ = control.dlqe(model.Ad, np.eye(model.Ad.shape[0]), model.H, model.Qd, model.R)
    P = np.asarray(P)
    K = P @ model.H.T @ np.linalg.inv(model.H @ P @ model.H.T + model.R)
    return K, np.asarray(L)
