"""Observer-based active damping: Kalman filter on the motor angle + feedback on the estimates, and an LQG design.

Both controllers read only the motor-side encoder (``theta_u``).  The estimators
(:mod:`controllers.kalman`) return the motor speed, the string winding alpha,
the lower speed omega_l and the brake law's estimated deviation d (relative level or torque).

* :class:`ObserverController` (``observer``, 500 Hz): extended Kalman filter (filterpy's
  equations, batched; the brake's local slope in the covariance propagation) + the feedback-linearising law of
  :mod:`controllers.flatness` (LQR on the lower speed's error chain, smooth reference from
  rest; targets below 2 rad/s approached from 2.5 rad/s with a slower chain and integral action).
  The law cancels the brake's negative slope with the friction law and the estimates.
* :class:`LQGController` (``lqg``): the linear design.  Stationary Kalman gain from
  ``control.dlqe``; state feedback about the operating point the friction estimate defines::

      alpha* = -d^ / k_theta                         (winding that carries the friction)
      u*     = (Tcu+ + du omega_ref + d^) / km       (voltage of that equilibrium)
      u      = u* - K [alpha^ - alpha*, omega_u^ - omega_ref, omega_l^ - omega_ref]

  K from python-control ``dlqr`` on the discretised linearisation at omega_ref
  (:func:`drillgym.equilibria.linearise`) with the brake's slope set to the steepest negative
  slope of the Stribeck law.
"""

from __future__ import annotations

from functools import lru_cache

import control
import numpy as np
from scipy.optimize import minimize_scalar

from drillgym import Configuration, RigParams
from drillgym.equilibria import linearise, lower_damping, slip_equilibrium
from drillgym.errors import InputError

from .base import Controller
from .flatness import TRIM_BAND, TRIM_CLIP, FlatnessLaw
from .kalman import (
    I_AL,
    I_D,
    I_DU,
    I_TU,
    I_WL,
    I_WU,
    ExtendedKalmanObserver,
    compensate,
    disturbance_model,
    steady_state_gain,
)
from .margin import check_margins

__all__ = ["ObserverController", "LQGController", "lqr_gain", "steepest_brake_slope"]

DEFAULT_LQR_WEIGHTS = (1.0, 10.0, 10.0)  # state weights on (alpha, omega_u, omega_l) errors
DEFAULT_LQR_R = 100.0  # input weight (1/V^2)


def steepest_brake_slope(params: RigParams) -> float:
    """Most negative slope dTfl/domega of the brake law (N m s/rad) and nothing above 0."""
    res = minimize_scalar(lambda w: float(lower_damping(w, params)), bounds=(1e-3, 10 * params.ws), method="bounded")
    return min(float(res.fun), 0.0)


@lru_cache(maxsize=256)
def _lqr_gain_cached(omega_ref: float, params: RigParams, dt: float, q: tuple, r: float, slope: float) -> np.ndarray:
    eq = slip_equilibrium(Configuration.TORSIONAL, omega_ref, params, with_eigenvalues=False)
    lin = linearise(eq, "reduced")
    names = list(lin.state_labels)
    A = np.array(lin.A)
    iwl = names.index("omega_l")
    A[iwl, iwl] += (lower_damping(omega_ref, params) - slope) / params.Jl  # design slope instead of the local one
    sysd = control.c2d(control.ss(A, lin.B, np.eye(3), np.zeros((3, 1))), dt, method="zoh")
    order = [names.index(s) for s in ("alpha", "omega_u", "omega_l")]
    Q = np.diag(np.asarray(q, dtype=float)[np.argsort(order)])  # weights in the linearisation's state order
    K, _, _ = control.dlqr(sysd.A, sysd.B, Q, np.array([[r]]))
    return np.asarray(K)[0, order]  # gains on (alpha, omega_u, omega_l)


def lqr_gain(
    omega_ref: float,
    params: RigParams | None = None,
    dt: float = 0.01,
    *,
    weights: tuple[float, float, float] = DEFAULT_LQR_WEIGHTS,
    r: float = DEFAULT_LQR_R,
    slope: float | None = None,
) -> np.ndarray:
    """LQR gain (V per rad, V s/rad, V s/rad) on the errors of (alpha, omega_u, omega_l) at omega_ref.

    ``slope`` (N m s/rad): brake slope of the design model; default the steepest one
    (:func:`steepest_brake_slope`).
    """
    p = params or RigParams()
    s = steepest_brake_slope(p) if slope is None else float(slope)
    return _lqr_gain_cached(float(omega_ref), p, float(dt), tuple(float(w) for w in weights), float(r), s)


class ObserverController(Controller):
    """Extended Kalman filter on the motor angle (filterpy's equations) + feedback-linearising LQR law on the estimates.

    Samples the motor encoder and updates the voltage at 500 Hz by default (``dt`` = 2 ms, within the
    500 Hz-1 kHz of the rig's Simulink set-up, docs/model.md).  Why not the environments' 10 ms: below
    2 rad/s the brake's negative slope makes the lower disc unstable (pole up to +3.1 1/s) and its
    speed is seen only through the winding's tiny effect on the heavily damped motor, so the
    estimate's error is set by how many quantized angles the filter gets per unstable time
    constant.  The linear LQG bound at 1 rad/s (8000 counts/rev) is a lower-speed standard
    deviation of 0.033 rad/s at 10 ms and 0.016 rad/s at 2 ms (SSI ~ 0.1 versus ~ 0.05).  The
    filter assumes small model error (``sigma_*``): in the nominal plant the model is right, and
    a filter that trusts it averages the quantization out.  Its disturbance state is the brake
    law's relative level (``disturbance='scale'``), so a brake 20 % off its identified level is
    estimated and cancelled with its slope.

    Parameters
    ----------
    omega_ref : float or ndarray, optional
        Target lower-disc speed(s) (rad/s), as :class:`controllers.Controller`.
    counts_per_rev : int, optional
        Encoder resolution the filter expects (counts/rev).  Default 8000.
    angle_noise : float, optional
        Angle noise the filter expects (rad, standard deviation).
    sigma_d : float, optional
        Random-walk intensity of the disturbance state (1/sqrt(s) for 'scale', N m/sqrt(s) for 'offset').
    sigma_upper, sigma_lower : float, optional
        White torque noise on the discs (N m/sqrt(Hz)), model error.
    noise_floor : float, optional
        Angle noise (rad) the filter assumes on top of quantization and ``angle_noise``.
    bandwidth, tau_ref, low_speed, approach, hold, ramp, low_bandwidth, integral : float, optional
        The law's options (:class:`controllers.flatness.FlatnessLaw`; rad/s, s).
    disturbance : str, optional
        What the filter's fifth state is: ``"scale"`` (default: the brake law's level is off by a factor
        1 + d, as with the oil's temperature; the law then also corrects the slope it cancels) or
        ``"offset"`` (a torque added to the law).
    sigma_du : float, optional
        > 0 adds an upper-disc disturbance torque state (N m) with this random-walk intensity
        (N m/sqrt(s)), cancelled by the motor.  Default 0 (none).
    p0_du : float, optional
        Prior standard deviation of that state (N m).
    fallback : bool, optional
        Drive with ``descent`` the targets its model is not accurate enough for (:mod:`controllers.margin`:
        the model file's standard error of km against the motor-angle limit); default False: warn only.
    angle_integral : bool, optional
        Integral action on the estimated motor angle against the target's, outside the law: the law's target
        moves by ``-angle_gain`` x that error (rad/s per rad), within ``TRIM_CLIP`` of the target, so an identified
        model's torque errors leave no offset in the mean speed.  It starts once the approach is over and the
        estimated lower speed is within ``TRIM_BAND`` of the target: started during the approach's overshoot it
        would pay the angle gained there back below the target, into the brake's sticking region.  Default: on
        for a model with effects, off for base parameters.
    angle_gain : float, optional
        Gain of that integral (1/s): the time constant of the offset's decay.  Default 0.05.
    **kw
        ``config``, ``params``, ``dt``, ``u_max`` of :class:`controllers.Controller`.
    """

    name = "observer"
    uses = ("theta_u",)
    default_dt = 0.002
    uses_effects = True

    def __init__(
        self,
        omega_ref=None,
        *,
        counts_per_rev: int = 8000,
        angle_noise: float = 0.0,
        sigma_d: float = 0.01,
        sigma_upper: float = 1e-3,
        sigma_lower: float = 1e-3,
        noise_floor: float = 0.0,
        bandwidth: float = 2.5,
        tau_ref: float = 1.0,
        low_speed: float = 2.0,
        approach: float = 2.5,
        hold: float = 12.0,
        ramp: float = 15.0,
        low_bandwidth: float = 1.0,
        integral: float = 0.1,
        disturbance: str = "scale",
        sigma_du: float = 0.0,
        p0_du: float = 0.1,
        fallback: bool = False,
        angle_integral: bool | None = None,
        angle_gain: float = 0.05,
        **kw,
    ) -> None:
        super().__init__(omega_ref, **kw)
        self.fallback = bool(fallback)
        if not (np.isfinite(angle_gain) and angle_gain >= 0):
            raise InputError(f"angle_gain must be a non-negative rate (1/s), got {angle_gain!r}")
        self.angle_gain = float(angle_gain)
        self.angle_integral = bool(self.effects.composition.effects) if angle_integral is None else bool(angle_integral)
        self.model = disturbance_model(
            self.params,
            self.dt,
            counts_per_rev=counts_per_rev,
            angle_noise=float(np.hypot(angle_noise, noise_floor)),
            sigma_d=sigma_d,
            sigma_upper=sigma_upper,
            sigma_lower=sigma_lower,
            disturbance=disturbance,
            sigma_du=sigma_du,
            model=self.effects,
        )
        self.p0_du = float(p0_du)
        # targets below low_speed (rad/s): reached from `approach` by a ramp down, slower error chain with
        # integral action (see controllers.flatness); the ramp ends at hold + ramp = 27 s, 13 s before the
        # steady window (last 20 s) of the 60 s evaluation runs
        self.law_options = {
            "bandwidth": float(bandwidth),
            "tau_ref": float(tau_ref),
            "low_speed": float(low_speed),
            "approach": float(approach),
            "hold": float(hold),
            "ramp": float(ramp),
            "low_bandwidth": float(low_bandwidth),
            "integral": float(integral),
            "disturbance": disturbance,
        }
        FlatnessLaw(self.params, self.dt, **self.law_options)  # check the options now

    def _reset(self, m: dict[str, np.ndarray]) -> None:
        self.observer = ExtendedKalmanObserver(self.model, p0_du=self.p0_du)
        self.observer.reset(np.broadcast_to(m.get("theta_u", 0.0), (self.n,)))
        self.law = self.new_law(self.omega_ref)
        self.margins, self._short, self._descent = check_margins(self, m, self.fallback)
        self._settle = np.broadcast_to(np.asarray(self.approach_time(self.omega_ref), dtype=float), (self.n,)).copy()
        self._integrating = np.zeros(self.n, dtype=bool)
        self._theta0 = np.zeros(self.n)  # estimated motor angle when the integral starts (rad)
        self._t_int = np.zeros(self.n)  # time since then (s)

    def _trim(self, x: np.ndarray) -> None:
        """Move the law's target against the integral of the speed error (rad) from the motor angle: the estimated
        motor angle (the reading through the model's Measurement effects) against the target's, from when each
        rig's approach is over and its estimated lower speed near the target (``angle_integral``)."""
        ref = self.omega_ref
        near = np.abs(x[I_WL] - ref) <= TRIM_BAND * np.abs(ref)
        start = (self.law.t >= self._settle) & ~self._integrating & near
        self._theta0 = np.where(start, x[I_TU], self._theta0)
        self._integrating |= start
        self._t_int = np.where(self._integrating, self._t_int + self.dt, 0.0)
        z = np.where(self._integrating, x[I_TU] - self._theta0 - ref * self._t_int, 0.0)
        reach = TRIM_CLIP * np.abs(ref)
        self.law.target = np.clip(ref - self.angle_gain * z, ref - reach, ref + reach)

    def _restart_rigs(self, index: np.ndarray, m: dict[str, np.ndarray]) -> None:
        theta = np.broadcast_to(np.asarray(m.get("theta_u", 0.0), dtype=float), (self.n,))[index]
        self.observer.reset(theta, index=index)
        self.law.restart(index, self.omega_ref[index])
        self._settle[index] = np.asarray(self.approach_time(self.omega_ref[index]), dtype=float)
        self._integrating[index], self._t_int[index] = False, 0.0

    def applied(self, voltage) -> None:
        """The voltage (V) actually held over the period just begun, when it differs from this controller's
        own output (the controller run in shadow, e.g. as a teacher): the filter predicts again with it.

        Parameters
        ----------
        voltage : float or ndarray
            Applied voltage of each rig (V), clipped to [-u_max, u_max]; call after :meth:`act`.
        """
        u = np.clip(np.broadcast_to(np.asarray(voltage, dtype=float), (self.n,)), -self.u_max, self.u_max)
        self.observer.x, self.observer.P = self._updated
        self.observer.predict(u)
        self.u_prev = u.copy()

    def _compiled_law(self):
        """The filter and the law compiled from the current state (:mod:`controllers.compiled.observer_law`, on a
        model with effects :mod:`controllers.compiled.model_law`); None for the ``descent`` fallback, a Measurement
        effect on the motor angle or a subclass with its own ``act`` (the step-by-step loop runs them)."""
        from .compiled.model_law import compiled_law

        return compiled_law(self, "observer")

    def approach_time(self, omega_ref: float | np.ndarray) -> np.ndarray:
        """Time (s) the law's reference needs: six lag time constants, after the hold and the ramp down
        for targets below ``low_speed`` (27 + 6 s with the defaults)."""
        o = self.law_options
        w = np.asarray(omega_ref, dtype=float)
        return np.where(w < o["low_speed"], o["hold"] + o["ramp"], 0.0) + 6.0 * o["tau_ref"]

    def new_law(self, target: np.ndarray) -> FlatnessLaw:
        """A fresh law with this controller's options, started from rest towards ``target`` (rad/s, (n,))."""
        known = bool(self.effects.composition.effects)  # the model's torques at the estimate, else the base laws
        law = FlatnessLaw(
            self.params,
            self.dt,
            brake=self._brake if known else None,
            upper=self._upper if known else None,
            **self.law_options,
        )
        law.reset(target)
        return law

    def _brake(self, w: np.ndarray, shift: float = 0.0) -> np.ndarray:
        """The model's torque against the lower disc besides kθ α (N m) at speeds w (rad/s), at the estimate with
        the lower angle moved by ``shift`` (rad; the motor angle moved, the twist kept)."""
        x = self.observer.x
        if shift:
            x = x.copy()
            x[I_TU] += shift
        return self.model.brake_law(w, x)

    def _upper(self, w: np.ndarray) -> np.ndarray:
        """The model's torque against the upper disc besides the motor and kθ α (N m) at speeds w (rad/s)."""
        return self.model.upper_law(w, self.observer.x)

    def _command(self, v: np.ndarray) -> np.ndarray:
        """The command (V) that gives the motor the voltage v (V): the model's static input map inverted where it
        is monotone (a dead zone, an offset), else v."""
        return compensate(self.model, self.observer.x, v, self.u_max)

    @property
    def estimate(self) -> np.ndarray:
        """Current estimates (5, n): theta_u, omega_u, alpha, omega_l (rad, rad/s) and friction d (N m)."""
        return self.observer.x

    def _act(self, m: dict[str, np.ndarray]) -> np.ndarray:
        u = self.voltage_at(self.observer.update(m["theta_u"]), m)
        self._updated = (self.observer.x.copy(), self.observer.P.copy())  # for applied()
        self.observer.predict(u)
        return u

    def voltage_at(self, x: np.ndarray, m: dict[str, np.ndarray]) -> np.ndarray:
        """The command (V, (n,)) at the corrected estimates x: the law's voltage, less the estimated upper-disc
        torque the model misses, through the model's inverted input map, clipped; ``descent`` on the targets the
        model is not accurate enough for.  Advances the law (and the angle integral) one period.

        Parameters
        ----------
        x : ndarray
            The estimates after the period's measurement update ((dim, n), :attr:`estimate`'s rows).
        m : dict of str to ndarray
            The period's measurements (what the ``descent`` fallback reads).

        Returns
        -------
        ndarray
            The voltages (V), in [-u_max, u_max].
        """
        if self.angle_integral:
            self._trim(x)
        u = self.law(x[I_WU], x[I_AL], x[I_WL], x[I_D])
        if self.model.has_du:  # the estimated upper-disc torque the model misses, cancelled by the motor
            u = u - x[I_DU] / self.params.km
        u = np.clip(self._command(u), -self.u_max, self.u_max)
        if self._descent is not None:  # targets the model is not accurate enough for
            u = np.where(self._short, self._descent.act(m), u)
        return u


class LQGController(Controller):
    """LQG: stationary Kalman gain (control.dlqe) + LQR gain (control.dlqr), estimates from the motor angle.

    Parameters
    ----------
    omega_ref : float or ndarray, optional
        Target lower-disc speed(s) (rad/s), as :class:`controllers.Controller`.
    counts_per_rev : int, optional
        Encoder resolution the filter expects (counts/rev).  Default 8000.
    angle_noise : float, optional
        Angle noise the filter expects (rad, standard deviation).
    sigma_d : float, optional
        Random-walk intensity of the friction disturbance state (N m/sqrt(s)).
    sigma_upper, sigma_lower : float, optional
        White torque noise on the discs (N m/sqrt(Hz)), model error.
    weights : tuple of float, optional
        LQR state weights on the (alpha, omega_u, omega_l) errors.  Default (1, 10, 10).
    r : float, optional
        LQR input weight (1/V^2).  Default 100.
    outer_gain : float, optional
        Integral action on the measured motor angle (1/s): the target moves by -outer_gain x the angle
        error.  Default 0 (none).
    outer_start : float, optional
        Time after reset from which the integral acts (s).  Default 5.
    fallback : bool, optional
        Drive with ``descent`` the targets its model is not accurate enough for (:mod:`controllers.margin`).
    **kw
        ``config``, ``params``, ``dt``, ``u_max`` of :class:`controllers.Controller`.
    """

    name = "lqg"
    uses = ("theta_u",)
    uses_effects = True

    def __init__(
        self,
        omega_ref=None,
        *,
        counts_per_rev: int = 8000,
        angle_noise: float = 0.0,
        sigma_d: float = 0.02,
        sigma_upper: float = 0.03,
        sigma_lower: float = 0.005,
        weights: tuple[float, float, float] = DEFAULT_LQR_WEIGHTS,
        r: float = DEFAULT_LQR_R,
        outer_gain: float = 0.0,
        outer_start: float = 5.0,
        fallback: bool = False,
        **kw,
    ) -> None:
        super().__init__(omega_ref, **kw)
        self.fallback = bool(fallback)
        if not (np.isfinite(outer_gain) and outer_gain >= 0 and np.isfinite(outer_start) and outer_start >= 0):
            raise InputError(
                f"outer_gain (1/s) and outer_start (s) must be non-negative, got {outer_gain!r}, {outer_start!r}"
            )
        self.outer_gain, self.outer_start = float(outer_gain), float(outer_start)
        self.model = disturbance_model(
            self.params,
            self.dt,
            counts_per_rev=counts_per_rev,
            angle_noise=angle_noise,
            sigma_d=sigma_d,
            sigma_upper=sigma_upper,
            sigma_lower=sigma_lower,
            model=self.effects,
        )
        self.weights = tuple(weights)
        self.r = float(r)
        self.slope = steepest_brake_slope(self.params)
        self.K = np.zeros((1, 3))

    def _reset(self, m: dict[str, np.ndarray]) -> None:
        refs = np.unique(self.omega_ref)
        gains = {w: lqr_gain(w, self.params, self.dt, weights=self.weights, r=self.r, slope=self.slope) for w in refs}
        self.K = np.stack([gains[w] for w in self.omega_ref])  # (n, 3)
        self.Kf, _ = steady_state_gain(self.model)
        self._x = np.zeros((self.model.Ad.shape[0], self.n))
        self._x[I_TU] = np.broadcast_to(m.get("theta_u", 0.0), (self.n,))
        self._t = 0.0
        self._theta0 = self._x[I_TU].copy()
        self.margins, self._short, self._descent = check_margins(self, m, self.fallback)

    @property
    def estimate(self) -> np.ndarray:
        """Current estimates (5, n): theta_u, omega_u, alpha, omega_l (rad, rad/s) and friction d (N m)."""
        return self._x

    def _act(self, m: dict[str, np.ndarray]) -> np.ndarray:
        p, mdl = self.params, self.model
        x = self._x = self._x + self.Kf @ (np.atleast_2d(m["theta_u"]) - mdl.H @ self._x)
        d_hat = mdl.lower_friction(x)  # estimated lower friction torque (N m)
        alpha_star = -d_hat / p.ktheta
        ref = self.omega_ref
        self._t += self.dt
        if self.outer_gain > 0:  # integral action on the measured motor angle: the mean speed on target
            if self._t <= self.outer_start:
                self._theta0 = np.asarray(m["theta_u"], dtype=float).copy()
            z = m["theta_u"] - self._theta0 - self.omega_ref * max(self._t - self.outer_start, 0.0)  # rad
            ref = np.clip(self.omega_ref - self.outer_gain * z, 0.5 * self.omega_ref, 1.5 * self.omega_ref)
        if self.effects.composition.effects:  # the model's upper torque at the reference speed
            u_star = (mdl.upper_law(ref, x) + d_hat) / p.km
        else:
            u_star = (mdl.upper_coulomb + mdl.upper_damping * ref + d_hat) / p.km
        err = np.stack([x[I_AL] - alpha_star, x[I_WU] - ref, x[I_WL] - ref])
        u = u_star - np.einsum("nk,kn->n", self.K, err)
        u = np.clip(compensate(mdl, x, u, self.u_max), -self.u_max, self.u_max)
        if self._descent is not None:  # targets the model is not accurate enough for
            u = np.where(self._short, self._descent.act(m), u)
        self._x = mdl.predict_mean(x, u)
        return u

    def _compiled_law(self):
        """The filter and the law compiled from the current state (:mod:`controllers.compiled.lqg_law`, on a model
        with effects :mod:`controllers.compiled.model_law`); None for the ``descent`` fallback or a subclass with
        its own ``act`` (the step-by-step loop runs them)."""
        from .compiled.model_law import compiled_law

        return compiled_law(self, "lqg")
