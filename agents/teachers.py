"""Privileged teachers for distillation (training only): laws that see the simulated *true* state.

:class:`FlatnessTeacher` is a hand-made full-state law: the feedback-linearising tracking law of
:class:`controllers.flatness.FlatnessLaw` (designed on the nominal model) evaluated on the simulator's
true (omega_u, alpha, omega_l), with an integral of the true lower-speed error (rad, clipped to
+/- ``z_max``) so that its mean speed tracks the target on rigs that differ from the model.  It is what
the motor-side student imitates (:mod:`agents.distill`); it never runs on the rig (it needs omega_l and
the winding, which the rig's motor side cannot measure) and nothing of it is inside the deployed network.

Measured on the simulated nominal rig from rest (60 s, last 20 s): SSI 0.00 and mean speed within
0.1 % at 1.5 ... 6 rad/s; with Ts, Tc, ws, delta, Jl, ktheta, km, bu, Tcu each +/- 20 %: every rig from
2.0 rad/s (tests/test_agents_distill.py checks a short version).

``per_plant=True`` designs the law on each rig's *true* base parameters (the simulator's, read when the rig's
episode starts: :meth:`FlatnessTeacher.set_plants`) instead of the nominal set: a privileged teacher for a
population of plants, whose labels damp each plant as its own model-based law would (it still does not
know the lags, delays or position friction the population adds).

The teacher is stateful per rig (the reference's three lags, the integral); :meth:`reset` starts the
rigs ``index`` of a batch (e.g. those whose episode just ended) towards their new targets.

:class:`ShadowTeacher` is not privileged: a classical controller (``lqg-2enc``, ``observer``) run in shadow on
what the student's observation carries (the 'sensors' wrapped encoder angles, unwrapped here as
:class:`controllers.gym_adapter.ControllerPolicy` does; the 'motor' motor-angle increments, summed), its state
estimate predicted with the voltage actually executed; its voltage is the label.  A student with the same
readings and enough memory can reproduce it.
"""

from __future__ import annotations

import numpy as np

from drillgym import RigParams
from drillgym.envs.options import U_MAX
from drillgym.errors import InputError
from drillgym.friction import brake_law, upper_law
from drillgym.params import PARAM_NAMES

__all__ = ["FlatnessTeacher", "ShadowTeacher", "TEACHERS"]

#: teachers known by name to ``drillgym train --teacher NAME`` (otherwise a path to an exported policy)
TEACHERS = ("flatness", "lqg-2enc", "observer")
#: classical controllers that run in shadow as a teacher (they restart single rigs and take the applied input)
SHADOW_CONTROLLERS = ("lqg-2enc", "observer")


class FlatnessTeacher:
    """Batched full-state teacher: true state -> voltage normalised to [-1, 1].

    Parameters
    ----------
    n : int
        Number of rigs.
    params : RigParams, optional
        The law's design model (default the nominal set).
    dt : float, optional
        Control period (s).
    bandwidth : float, optional
        Closed-loop bandwidth of the lower-speed error chain (rad/s).
    tau_ref : float, optional
        Time constant (s) of each of the reference's three lags (a gentle start from rest).
    integral : float, optional
        Weight of the speed error's integral (:func:`controllers.flatness.chain_gain`).
    z_max : float, optional
        Clip of the integral state (rad), an anti-windup.
    per_plant : bool, optional
        Design the law on each rig's true base parameters (:meth:`set_plants`), not ``params``.
    """

    def __init__(
        self,
        n: int,
        params: RigParams | None = None,
        dt: float = 0.01,
        *,
        bandwidth: float = 2.5,
        tau_ref: float = 1.0,
        integral: float = 1.0,
        z_max: float = 2.0,
        per_plant: bool = False,
    ) -> None:
        from controllers.flatness import FlatnessLaw

        if not (isinstance(n, int) and n >= 1):
            raise InputError(f"the teacher needs n >= 1 rigs, got {n!r}")
        if not (np.isfinite(z_max) and z_max > 0):
            raise InputError(f"z_max must be a positive angle (rad), got {z_max!r}")
        self.n, self.dt, self.z_max = int(n), float(dt), float(z_max)
        law = _per_plant_law(FlatnessLaw) if per_plant else FlatnessLaw
        self.law = law(
            params or RigParams(), self.dt, bandwidth=bandwidth, tau_ref=tau_ref, low_speed=0.0, integral_high=integral
        )
        self.per_plant = bool(per_plant)
        if per_plant:
            self.law.p = _PlantArrays(params or RigParams(), self.n)
        self.law.reset(np.zeros(self.n))
        self.z = np.zeros(self.n)

    def reset(self, index: np.ndarray, targets: np.ndarray) -> None:
        """Rigs ``index`` start from rest towards ``targets`` (rad/s)."""
        index = np.asarray(index, dtype=np.int64)
        self.law.target = self.law.target.copy()
        self.law.target[index] = np.asarray(targets, dtype=float)
        self.law.y[:, index] = 0.0
        self.z[index] = 0.0

    def set_plants(self, index: np.ndarray, base: np.ndarray) -> None:
        """The rigs ``index`` now run the plants of base-parameter rows ``base`` ((k, N_PARAMS), the
        :class:`~drillgym.RigParams` vector layout); a ``per_plant`` teacher designs its law on them."""
        if not self.per_plant:
            raise ValueError("set_plants needs a per_plant teacher")
        self.law.p.set(np.asarray(index, dtype=np.int64), np.asarray(base, dtype=float))

    def act(
        self,
        omega_u: np.ndarray,
        alpha: np.ndarray,
        omega_l: np.ndarray,
        z: np.ndarray | None = None,
        target: np.ndarray | None = None,
    ) -> np.ndarray:
        """Normalised voltages (n,) for the true speeds (rad/s) and winding alpha = theta_l - theta_u (rad);
        advances the reference and the integral by one period.  ``z`` (rad, (n,)): an integral to use
        instead of the teacher's own (e.g. the student's observable motor-angle integral, :mod:`agents.integral`).
        ``target`` (rad/s, (n,)): a new target of each rig (a speed command that changes in time,
        :mod:`agents.command`), followed through the reference's lags."""
        if target is not None:
            self.law.target = np.asarray(target, dtype=float).copy()
        r = self.law.y[2].copy()  # the reference the law uses now
        zz = self.z if z is None else np.asarray(z, dtype=float)
        u = self.law(
            np.asarray(omega_u, dtype=float),
            np.asarray(alpha, dtype=float),
            np.asarray(omega_l, dtype=float),
            np.zeros(self.n),
            z=zz,
        )
        self.z = np.clip(self.z + self.dt * (omega_l - r), -self.z_max, self.z_max)
        return np.clip(u / U_MAX, -1.0, 1.0)


class ShadowTeacher:
    """A classical controller run in shadow on the student's sensor readings: labels in [-1, 1].

    Parameters
    ----------
    name : str
        The controller (:data:`SHADOW_CONTROLLERS`), built on its default (nominal) model as the benchmark
        builds it, or on ``model`` among ``options`` (the rigs' model of a run given one).
    n : int
        Number of rigs.
    dt : float
        Control period (s): the env's.
    names : sequence of str
        The layout of the student's observation: for each encoder the controller ``uses`` (``theta_u``,
        ``theta_l``), its wrapped angle (``theta_u_wrapped``, 'sensors') or its newest increment over the
        period (``omega_u_inc_0``, rad/s, 'motor': the angle changes by it times ``dt``) is read.
    top : float, optional
        The highest target any rig will get (rad/s): the controller's designs cover it.  Default 8.
    given_integral : bool, optional
        The controller's law takes its integral state from :meth:`act`'s ``z`` (the student's motor-angle
        integral, rad, :mod:`agents.integral`) instead of integrating its own estimated speed error, so that its
        voltage is a function of what the student sees (``observer`` only: a law with an integral state).
    **options
        Keywords of the controller (e.g. ``approach``, ``hold``, ``ramp``, ``tau_ref`` of ``lqg-2enc``).

    Raises
    ------
    InputError
        An unknown controller, or an observation without an encoder the controller uses.
    """

    def __init__(
        self, name: str, n: int, dt: float, names, *, top: float = 8.0, given_integral: bool = False, **options
    ) -> None:
        from controllers import make

        if name not in SHADOW_CONTROLLERS:
            raise InputError(f"shadow teacher must be one of {', '.join(SHADOW_CONTROLLERS)}, got {name!r}")
        if given_integral and name != "observer":
            raise InputError(f"given_integral needs a law with an integral state (observer), not {name!r}")
        self.n, self.dt = int(n), float(dt)
        self.controller = make(name, dt=self.dt, **options)
        self.uses = tuple(self.controller.uses)
        self.cols, self.wrapped = _encoder_columns(name, self.uses, list(names))
        self.theta = np.zeros((self.n, len(self.uses)))  # the unwrapped encoder angles (rad)
        self.fresh = np.ones(self.n, dtype=bool)  # rigs whose angle is that of their reset observation
        self.controller.reset(self._measurement(np.full(self.n, top)))
        self.given = _GivenIntegral(self.controller.law) if given_integral else None
        if self.given is not None:
            self.controller.law = self.given

    def _measurement(self, targets: np.ndarray) -> dict[str, np.ndarray]:
        m = {k: self.theta[:, j] for j, k in enumerate(self.uses)}
        m["omega_ref"] = np.asarray(targets, float)
        return m

    def reset(self, index: np.ndarray, obs: np.ndarray, targets: np.ndarray) -> None:
        """Rigs ``index`` start an episode: ``obs`` (n, dim) the batch's observations after their reset,
        ``targets`` (rad/s, (n,)) the episodes' targets (increments: the angles restart from 0)."""
        index = np.asarray(index, dtype=np.int64)
        self.theta[index] = np.where(self.wrapped, np.asarray(obs, dtype=float)[index][:, self.cols], 0.0)
        self.fresh[index] = True
        self.controller.reset_rigs(index, self._measurement(targets))

    def act(self, obs: np.ndarray, targets: np.ndarray, z: np.ndarray | None = None) -> np.ndarray:
        """Labels (normalised voltages, (n,)) for the batch's observations ``obs`` (n, dim) of this period;
        advances the controller by one period (its own voltage assumed until :meth:`applied`).  ``z`` (rad, (n,)):
        the integral state of a ``given_integral`` teacher's law."""
        if (z is None) != (self.given is None):
            raise InputError("a given_integral teacher needs the integral z, and only it takes one")
        if self.given is not None:
            self.given.z = np.asarray(z, dtype=float)
        w = np.asarray(obs, dtype=float)[:, self.cols]
        change = np.where(self.wrapped, (w - self.theta + np.pi) % (2.0 * np.pi) - np.pi, w * self.dt)
        self.theta += np.where(self.fresh[:, None] & ~self.wrapped, 0.0, change)  # the change since the last reading
        self.fresh[:] = False
        return np.asarray(self.controller.act(self._measurement(targets))) / U_MAX

    def applied(self, actions: np.ndarray) -> None:
        """The normalised actions (n,) the rigs execute over the period just begun."""
        self.controller.applied(np.asarray(actions, dtype=float) * U_MAX)


class _GivenIntegral:
    """A :class:`controllers.flatness.FlatnessLaw` called with the integral state ``z`` (rad, (n,)) set from
    outside (its other attributes and methods the law's own)."""

    def __init__(self, law) -> None:
        self.law = law
        self.z = np.zeros(law.target.size)

    def __getattr__(self, name: str):
        return getattr(self.law, name)

    def __call__(
        self, omega_u: np.ndarray, alpha: np.ndarray, omega_l: np.ndarray, d: np.ndarray, z: np.ndarray | None = None
    ) -> np.ndarray:
        """The law with the integral set from outside (the caller's own ``z`` is replaced by it)."""
        return self.law(omega_u, alpha, omega_l, d, z=self.z)


def _encoder_columns(name: str, uses: tuple[str, ...], names: list[str]) -> tuple[list[int], np.ndarray]:
    """The observation's columns of the encoders ``uses`` (theta_u, theta_l), and whether each is a wrapped
    angle (rad; else the increment over the period, rad/s)."""
    cols, wrapped = [], []
    for enc in uses:
        inc = enc.replace("theta", "omega") + "_inc_0"
        if f"{enc}_wrapped" in names:
            cols.append(names.index(f"{enc}_wrapped"))
            wrapped.append(True)
        elif inc in names:
            cols.append(names.index(inc))
            wrapped.append(False)
        else:
            raise InputError(f"teacher {name!r} reads {', '.join(uses)}: the observation {names[:3]}... has no {enc}")
    return cols, np.array(wrapped)


class _PlantArrays:
    """Base parameters of n rigs as attributes holding arrays (n,) (the RigParams names), so that the
    flatness law's arithmetic (Jl, Ju, km, ktheta ...) is per rig."""

    def __init__(self, params: RigParams, n: int) -> None:
        for name in PARAM_NAMES:
            setattr(self, name, np.full(n, float(getattr(params, name))))

    def set(self, index: np.ndarray, rows: np.ndarray) -> None:
        if rows.ndim != 2 or rows.shape[0] != index.size or rows.shape[1] < len(PARAM_NAMES):
            raise ValueError(
                f"base parameter rows must have shape ({index.size}, >= {len(PARAM_NAMES)}), got {rows.shape}"
            )
        for j, name in enumerate(PARAM_NAMES):
            getattr(self, name)[index] = rows[:, j]


_brake = np.vectorize(brake_law, otypes=[float])
_upper = np.vectorize(upper_law, otypes=[float])


def _per_plant_law(base: type) -> type:
    """The flatness law class with the friction laws evaluated on each rig's own parameters."""

    class PerPlantFlatnessLaw(base):
        def lower_friction(self, w: np.ndarray) -> np.ndarray:
            p = self.p
            return _brake(np.abs(w), np.sign(w), p.Ts, p.Tc, p.ws, p.delta, p.bb)

        def upper_friction(self, w: np.ndarray) -> np.ndarray:
            p = self.p
            return _upper(np.abs(w), np.sign(w), p.Tcu, p.dTcu, p.bu, p.dbu)

    return PerPlantFlatnessLaw
