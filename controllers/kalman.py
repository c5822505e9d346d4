"""Kalman filter that sees only the motor angle: torsional model + unknown lower-friction deviation.

Model (torsional equations of docs/model.md, absolute coordinates, slipping upper disc)::

    d theta_u / dt = omega_u
    Ju d omega_u / dt = km u - Tcu+ - du omega_u + k_theta alpha     (du = bu + dbu, Tcu+ = Tcu + dTcu)
    d alpha / dt   = omega_l - omega_u
    Jl d omega_l / dt = -k_theta alpha - Tfl
    d d / dt       = w_d                                            (random walk)

with the brake torque ``Tfl`` = T(omega_l) + d (``disturbance='offset'``, d in N m) or
(1 + d) T(omega_l) (``'scale'``, d dimensionless: a brake whose level is off, as with the oil's
temperature) while the disc slips, T the identified Stribeck law (a known input), and the torque
that holds the disc while it sticks (within the stick set).  ``d`` collects what the law misses
(level errors, lateral losses in the coupled configuration); it is estimated, not modelled.  With
``friction_known=False`` the law is not used and ``d`` is the whole brake torque.  The linear
part (``A``, ``B``) is taken from the core's linearisation (:func:`drillgym.equilibria.linearise`,
'angles' variant) with the brake's slope removed (the brake torque is an input), and discretised
with zero-order hold (python-control ``c2d``).  The upper disc's Coulomb level enters as a known
input; while the model says the upper disc rests, the known input is the torque that keeps it at
rest (stick).

Measurement: the quantized motor-side angle theta_u only; its noise variance
is q^2/12 (q = 2 pi / counts per rev) plus any extra white noise.

A model with effects (``model=``, :class:`controllers.model.ControllerModel`) extends it: a motor lag
adds the state ``u_m`` (V; the motor torque is km u_m), a delay the line of past commands (V; exact
zero-order hold of the fractional delay, :func:`controllers.model.delayed_discretisation`), after
``d`` (and ``du``); Friction effects on the lower disc replace the brake law, its stick set and the
slope of the covariance propagation by the composition's compiled law at the estimated lower angle
theta_u + alpha.

Three estimators share the model: :class:`KalmanObserver` (filterpy
``KalmanFilter``, time-varying covariance, batched: the covariance does not
depend on the data, so one filter carries the states of n trajectories as the
columns of ``x``), :class:`ExtendedKalmanObserver` (filterpy's equations with
one covariance per trajectory, propagated with the brake's local slope at the
estimate: the filter knows where the lower disc is locally unstable and trusts
the measurement more there) and :func:`steady_state_gain` (python-control
``dlqe``) for the LQG design.
"""

from __future__ import annotations

from dataclasses import dataclass

import control
import numpy as np
from filterpy.kalman import KalmanFilter

from drillgym import Configuration, RigParams
from drillgym.equilibria import linearise, lower_damping, slip_equilibrium
from drillgym.errors import InputError
from drillgym.friction import lower_friction
from drillgym.measurement import DEFAULT_COUNTS_PER_REV

from .model import ControllerModel, delayed_discretisation

__all__ = [
    "STATES",
    "I_DU",
    "DisturbanceModel",
    "disturbance_model",
    "KalmanObserver",
    "ExtendedKalmanObserver",
    "steady_state_gain",
]

STATES = ("theta_u", "omega_u", "alpha", "omega_l", "d")
"""State order of the estimator: rad, rad/s, rad, rad/s, N m (or relative level); a model built with
``sigma_du > 0`` has a sixth state ``du`` (N m): a torque on the upper disc the model misses."""
I_TU, I_WU, I_AL, I_WL, I_D = range(5)
I_DU = 5


@dataclass(frozen=True)
class DisturbanceModel:
    """Discrete model of the estimator (period ``dt``): x+ = Ad x + Bd [u, Tfu_c], z = H x + v.

    ``Bd`` has two columns: the voltage u (V) and the upper friction offset
    (N m, the part of Tfu not in ``Ad``).  ``Qd`` (process) and ``R``
    (measurement) are covariances; ``Ac``, ``Bc`` the continuous model.
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
    friction_known: bool = True
    disturbance: str = "offset"
    """What the state ``d`` is: 'offset' (N m added to the nominal brake law) or 'scale'
    (relative level: the brake law times 1 + d while the disc slips)."""
    effects: ControllerModel | None = None
    """The model with its effects (None: the base model of ``params``)."""
    has_du: bool = False
    """Whether the state ``du`` (row :data:`I_DU`) is there."""
    lag_index: int = -1
    """Row of the motor-lag state u_m (V); -1 without a lag."""
    line_index: int = -1
    """First row of the line of past commands u[k-1], u[k-2], ... (V); -1 without a delay."""
    delay_steps: int = 0
    """Whole control periods of the delay (the command the motor sees now is u[k - delay_steps])."""

    def motor_voltage(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """The voltage acting on the motor now (V, (n,)): the lag state, else the delayed command, else u."""
        if self.lag_index >= 0:
            return x[self.lag_index]
        if self.line_index >= 0 and self.delay_steps > 0:
            return x[self.line_index + self.delay_steps - 1]
        return u

    def brake_law(self, w: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Brake torque (N m, (n,)) of the model at lower speeds w (rad/s, != 0) and the estimated lower angles."""
        if self.effects is None or not self.effects.friction_effects:
            return lower_friction(w, self.params)
        return self.effects.lower_friction(w, x[I_TU] + x[I_AL])

    def stick_limit(self, x: np.ndarray) -> np.ndarray | float:
        """Largest torque (N m) the brake holds the resting disc with, at the estimated lower angles."""
        if self.effects is None or not self.effects.friction_effects:
            return self.params.Ts
        return self.effects.stick_limit(x[I_TU] + x[I_AL])

    @property
    def upper_coulomb(self) -> float:
        """Upper friction offset for positive rotation, Tcu + dTcu (N m)."""
        return self.params.Tcu + self.params.dTcu

    @property
    def upper_damping(self) -> float:
        """Upper viscous friction for positive rotation, bu + dbu (N m s/rad)."""
        return self.params.bu + self.params.dbu

    def known_inputs(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Input matrix (3, n) of the model: voltage, upper friction offset, nominal lower friction."""
        return np.vstack([u, self.known_friction(x, u), self.nominal_lower_friction(x)])

    def nominal_lower_friction(self, x: np.ndarray, eps: float = 1e-3) -> np.ndarray:
        """Lower friction input of the model at the estimates x (5, n) (N m, (n,)); 0 when not modelled.

        Slipping (|omega_l| > eps): the Stribeck law of the core (:func:`drillgym.friction.lower_friction`),
        times 1 + d for the 'scale' disturbance; resting: the torque that holds the disc against the
        string, limited to the stick set (+-Ts, scaled likewise).
        """
        if not self.friction_known:
            return np.zeros(x.shape[1])
        wl = x[I_WL]
        level = 1.0 + x[I_D] if self.disturbance == "scale" else 1.0
        ts = self.stick_limit(x) * level
        hold = np.clip(-self.params.ktheta * x[I_AL], -ts, ts)
        slip = level * self.brake_law(np.where(np.abs(wl) > eps, wl, eps), x)
        return np.where(np.abs(wl) > eps, slip, hold)

    def lower_friction(self, x: np.ndarray) -> np.ndarray:
        """Estimated lower friction torque (N m, (n,)) at the estimates x (5, n): the model's input
        plus the offset state (the 'scale' state is already in the input)."""
        f = self.nominal_lower_friction(x)
        return f if self.disturbance == "scale" else f + x[I_D]

    def known_friction(self, x: np.ndarray, u: np.ndarray, eps: float = 1e-3) -> np.ndarray:
        """Upper friction offset (N m, (n,)) for states x (5, n) and voltages u (n,).

        Slipping (|omega_u| > eps): the Coulomb level with the sign of omega_u.  Resting: the
        torque that keeps the disc at rest, limited to the stick set.
        """
        p = self.params
        drive = p.km * self.motor_voltage(x, u) + p.ktheta * x[I_AL] - self.upper_damping * x[I_WU]
        if self.has_du:
            drive = drive + x[I_DU]
        rest = np.clip(drive, -p.Tcu + p.dTcu, p.Tcu + p.dTcu)
        slip = np.where(x[I_WU] > 0, p.Tcu + p.dTcu, -(p.Tcu - p.dTcu))
        return np.where(np.abs(x[I_WU]) > eps, slip, rest)


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
    model: ControllerModel | None = None,
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
        The nominal brake law (with stick) is a known input and ``d`` its unknown deviation (default); False:
        ``d`` is the whole lower friction torque.
    disturbance : str, optional
        'offset' (``d`` in N m added to the brake law) or 'scale' (``d`` the relative error of the brake law's
        level: Ts, Tc, bb all off by the same factor, as with the oil's temperature); 'scale' needs
        ``friction_known``.
    sigma_du : float, optional
        > 0 adds a sixth state ``du`` (N m), a torque on the upper disc that the model misses (motor constant,
        upper friction, lag errors), as a random walk of this intensity (N m/sqrt(s)).
    model : ControllerModel, optional
        The model with its effects (its base parameters replace ``params``): a motor lag becomes a state, a
        delay a line of past commands, lower-disc friction effects change the brake law (module doc).
    """
    if model is not None:
        if params is not None and params != model.params:
            raise InputError("give the estimator's base parameters either as params or in its model, not both")
        model.check_usable("the motor-angle Kalman filter", ("theta_u",))
        params = model.params
    p = params or RigParams()
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
    # exact Jacobian of the core at a slip equilibrium (angles variant: theta_u, theta_l, omega_u, omega_l)
    eq = slip_equilibrium(Configuration.TORSIONAL, 3.0, p, with_eigenvalues=False)
    lin = linearise(eq, "angles")
    names = list(lin.state_labels)
    iu, il, iwu, iwl = (names.index(s) for s in ("theta_u", "theta_l", "omega_u", "omega_l"))
    A4, B4 = np.asarray(lin.A), np.asarray(lin.B)[:, 0]
    brake_slope = lower_damping(eq.omega, p)
    if abs(A4[iwl, iwl] + brake_slope / p.Jl) > 1e-4 * max(1.0, abs(brake_slope / p.Jl)):
        raise RuntimeError("linearisation does not have the expected brake damping term")
    # to (theta_u, omega_u, alpha, omega_l, d): alpha = theta_l - theta_u
    T = np.zeros((4, 4))  # z4 = T @ (theta_u, theta_l, omega_u, omega_l)
    T[I_TU, iu] = 1.0
    T[I_WU, iwu] = 1.0
    T[I_AL, il], T[I_AL, iu] = 1.0, -1.0
    T[I_WL, iwl] = 1.0
    Ti = np.linalg.inv(T)
    A = np.zeros((5, 5))
    A[:4, :4] = T @ A4 @ Ti
    A[I_WL, I_WL] += brake_slope / p.Jl  # remove the brake's slope: the whole brake torque is the state d
    A[I_WL, I_D] = -1.0 / p.Jl if disturbance == "offset" else 0.0  # a scale acts through the friction input
    Bu = np.zeros(5)
    Bu[:4] = T @ B4
    Bl = np.zeros(5)
    Bl[I_WL] = -1.0 / p.Jl
    B = np.column_stack([Bu, -Bu / p.km, Bl])  # [u (V), upper friction offset (N m), nominal lower friction (N m)]
    nx = 6 if sigma_du > 0 else 5
    if nx == 6:  # du: a torque on the upper disc (N m), random walk
        A = np.pad(A, ((0, 1), (0, 1)))
        A[I_WU, I_DU] = 1.0 / p.Ju
        B = np.pad(B, ((0, 1), (0, 0)))
    G = np.zeros((nx, nx - 2))
    G[I_WU, 0] = 1.0 / p.Ju
    G[I_WL, 1] = 1.0 / p.Jl
    G[I_D, 2] = 1.0
    if nx == 6:
        G[I_DU, 3] = 1.0
    Qc = np.diag([sigma_upper**2, sigma_lower**2, sigma_d**2, sigma_du**2][: nx - 2])
    lag = model.lag if model is not None else 0.0
    lag_index = -1
    if lag > 0:  # u_m: tau_m du_m/dt = u - u_m, the motor torque km u_m
        lag_index, nx = nx, nx + 1
        A, B, G = np.pad(A, ((0, 1), (0, 1))), np.pad(B, ((0, 1), (0, 0))), np.pad(G, ((0, 1), (0, 0)))
        A[:, lag_index] = B[:, 0]
        B[:, 0] = 0.0
        A[lag_index, lag_index] = -1.0 / lag
        B[lag_index, 0] = 1.0 / lag
    Qd = _discrete_noise(A, G @ Qc @ G.T, dt)
    delay = model.delay if model is not None else 0.0
    if delay > 0:
        sysd = delayed_discretisation(A, B, dt, delay)
        Ad, Bd, n_line = sysd.Ad, sysd.Bd, sysd.n_line
        Qd = np.pad(Qd, ((0, n_line), (0, n_line)))
    else:
        sysd = control.c2d(control.ss(A, B, np.eye(nx)[:1], np.zeros((1, 3))), dt, method="zoh")
        Ad, Bd, n_line = np.asarray(sysd.A), np.asarray(sysd.B), 0
    C = np.zeros((1, nx + n_line))
    C[0, I_TU] = 1.0
    q = 2.0 * np.pi / counts_per_rev if counts_per_rev > 0 else 0.0
    R = np.array([[q * q / 12.0 + angle_noise**2 + 1e-12]])
    return DisturbanceModel(
        p,
        float(dt),
        A,
        B,
        Ad,
        Bd,
        C,
        Qd,
        R,
        friction_known,
        disturbance,
        effects=model,
        has_du=sigma_du > 0,
        lag_index=lag_index,
        line_index=nx if n_line else -1,
        delay_steps=int(np.floor(delay / dt + 1e-9)) if n_line else 0,
    )


def _discrete_noise(A: np.ndarray, Qc: np.ndarray, dt: float) -> np.ndarray:
    """Covariance of the discretised white process noise (Van Loan's method)."""
    from scipy.linalg import expm

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
        self.kf = KalmanFilter(dim_x=5, dim_z=1, dim_u=3)
        self.kf.F = model.Ad.copy()
        self.kf.B = model.Bd.copy()
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
        self.kf.predict(u=self.model.known_inputs(self.kf.x, u))

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
        """Correct rows ``index`` with their measured motor angles (rad); returns all estimates (5, n)."""
        P, x, r = self.P[index], self.x[:, index], self.model.R[0, 0]
        K = P[:, :, I_TU] / (P[:, I_TU, I_TU] + r)[:, None]  # (m, 5): P H' S^-1 with H = e_theta_u
        self.x[:, index] = x + K.T * (np.asarray(theta_u, dtype=float) - x[I_TU])
        IKH = np.broadcast_to(np.eye(self.dim), P.shape).copy()
        IKH[:, :, I_TU] -= K
        self.P[index] = IKH @ P @ IKH.transpose(0, 2, 1) + r * K[:, :, None] * K[:, None, :]
        return self.x

    def jacobians(self, x: np.ndarray) -> np.ndarray:
        """Discrete Jacobians (n, 5, 5): ``Ad`` with the brake slope at the estimated omega_l."""
        m, p, h = self.model, self.model.params, self.h
        wl = x[I_WL]
        w = np.maximum(np.abs(wl), 2 * h)
        slope = (m.brake_law(w + h, x) - m.brake_law(w - h, x)) / (2 * h)
        slipping = np.abs(wl) > 1e-3
        slope = np.where(slipping, slope, 0.0)  # a disc at rest has no slope
        F = np.broadcast_to(m.Ad, (x.shape[1], self.dim, self.dim)).copy()
        if m.disturbance == "scale":  # Tfl = (1 + d) T(omega_l): slope scaled, d acts through T
            slope = slope * (1.0 + x[I_D])
            level = np.where(slipping, m.brake_law(w, x), 0.0)
            F[:, I_WL, I_D] -= m.dt * level / p.Jl
            F[:, I_AL, I_D] -= 0.5 * m.dt**2 * level / p.Jl
        F[:, I_WL, I_WL] -= m.dt * slope / p.Jl
        F[:, I_AL, I_WL] -= 0.5 * m.dt**2 * slope / p.Jl
        return F

    def predict(self, u: np.ndarray) -> None:
        """Propagate every trajectory over one period with the voltages u (V, (n,)) held."""
        m, x = self.model, self.x
        F = self.jacobians(x)
        self.P = F @ self.P @ F.transpose(0, 2, 1) + m.Qd
        self.x = m.Ad @ x + m.Bd @ m.known_inputs(x, np.broadcast_to(np.asarray(u, dtype=float), (x.shape[1],)))

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
