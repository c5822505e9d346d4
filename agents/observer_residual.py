"""Residual policy on the classical observer controller: the agent corrects the ``observer`` voltage.

Structure (residual policy learning on a model-based controller)::

    x^      = EKF(theta_u, past voltages)               estimates (omega_u, alpha, omega_l, d), motor angle only
    u_base  = FlatnessLaw(x^, omega_ref)                the ``observer`` controller's voltage (V)
    obs     = features(x^, omega_ref)                   what the policy sees (:data:`FEATURES`)
    u       = clip(u_base + scale * a, -5 V, 5 V)       a = policy(obs) in [-1, 1]
    EKF.predict(u)                                      the filter propagates with the voltage applied

The estimator and the law are an :class:`controllers.observer.ObserverController` itself (its filter, its
law, its corrections: :meth:`~controllers.observer.ObserverController.voltage_at`), so ``a = 0`` *is* the
observer controller and training starts at its performance.  Built on a model (``model=``, a
:class:`drillgym.Model`: e.g. the rig's identified one), the base is the observer controller built on that
model, every effect of it included (an input delay in its filter, a dead zone inverted in the command), as
``controllers.make("observer", model=...)`` builds it.  Everything the policy sees is a function of the motor
angle and the applied voltages: the agent observes only the motor encoder.

:class:`ObserverResidual` is batched over n rigs (the controller's batched
:class:`controllers.kalman.ExtendedKalmanObserver` and :class:`controllers.flatness.FlatnessLaw`), with per-rig
resets (the controller's ``reset_rigs``), so one object serves the training VecEnv
(:class:`agents.envs.ObserverResidualVecEnv`), the exported policy's :class:`agents.controller.AgentController`
and the rig.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from controllers.kalman import I_AL, I_WL, I_WU
from controllers.observer import ObserverController
from drillgym import RigParams
from drillgym.envs.options import U_MAX
from drillgym.errors import InputError

__all__ = ["ObserverResidual", "FEATURES"]

FEATURES = ("omega_l_err", "omega_u_err", "string_torque", "friction", "u_base", "phase", "omega_ref")
"""Policy inputs: omega^_l - omega_ref, omega^_u - omega_ref (rad/s), k_theta alpha^ / Ts and
estimated lower friction / Ts (dimensionless), base voltage / 5 V, time since the start / 30 s (at
most 1; the law's start-up phase), omega_ref / 8 rad/s."""

PHASE_TIME = 30.0  # s, time scale of the phase input


class ObserverResidual:
    """Batched ``observer`` controller as the base of a residual policy (see the module docstring).

    Parameters
    ----------
    config : str
        Rig configuration the observer is designed for.
    scale : float
        Voltage of a full action (V), > 0.
    params : RigParams, optional
        The design model's base parameters (default: the identified set); unused with ``model``.
    dt : float, optional
        Control period (s).
    observer : dict, optional
        Keywords of :class:`controllers.observer.ObserverController` (noise settings, law bandwidth, start-up
        shaping, ...).
    model : drillgym.Model or str or path, optional
        The design model with its effects (a model file's path is read as ``controllers.make`` reads it).
    """

    uses = ("theta_u",)  # the readings :meth:`reset` and :meth:`correct` take, by name

    def __init__(
        self,
        config: str,
        scale: float,
        params: RigParams | None = None,
        dt: float = 0.01,
        observer: dict[str, Any] | None = None,
        model: Any = None,
    ) -> None:
        if not (np.isfinite(scale) and scale > 0):
            raise InputError(f"residual scale must be a positive voltage, got {scale!r}")
        design = {"params": params} if model is None else {"model": model}  # a model holds its own parameters
        self._ctrl = ObserverController(1.0, config=config, dt=dt, **design, **(observer or {}))
        self.scale, self.params, self.dt, self.model = float(scale), self._ctrl.params, self._ctrl.dt, self._ctrl.model
        self.n = 0

    @property
    def dim(self) -> int:
        """Number of policy inputs."""
        return len(FEATURES)

    def start(self, n: int) -> None:
        """Allocate n rigs (call :meth:`reset` for all of them before :meth:`correct`)."""
        self.n = int(n)
        self.t = np.zeros(self.n)  # time since each rig's start (s)
        self.u_base = np.zeros(self.n)
        self._theta = np.zeros(self.n)  # the motor angles of the period (rad)
        self._started = False

    def reset(self, index: np.ndarray, theta_u: np.ndarray, omega_ref: np.ndarray) -> None:
        """Rigs ``index`` start at rest at motor angles theta_u (rad) towards targets omega_ref (rad/s)."""
        idx = np.atleast_1d(np.asarray(index, dtype=np.int64))
        th, ref = np.zeros(self.n), np.ones(self.n)
        th[idx] = np.broadcast_to(np.asarray(theta_u, dtype=float), idx.shape)
        ref[idx] = np.broadcast_to(np.asarray(omega_ref, dtype=float), idx.shape)
        if not self._started:  # the controller's batch starts with every rig
            if idx.size != self.n or np.unique(idx).size != self.n:
                raise InputError(f"reset every rig of the batch ({self.n}) first, got {idx.size}")
            self._ctrl.reset({"theta_u": th, "omega_ref": ref})
            self._started = True
        else:
            self._ctrl.reset_rigs(idx, {"theta_u": th, "omega_ref": ref})
        self._theta[idx], self.t[idx] = th[idx], 0.0

    def correct(self, theta_u: np.ndarray, index: np.ndarray | slice = slice(None)) -> None:
        """Kalman measurement update of rigs ``index`` with their motor angles (rad)."""
        self._ctrl.observer.update(theta_u, index)
        self._theta[index] = theta_u

    @property
    def x(self) -> np.ndarray:
        """Estimates (dim, n) of the rigs (:data:`controllers.kalman.STATES`, then the model's own)."""
        return self._ctrl.observer.x

    @property
    def target(self) -> np.ndarray:
        """The rigs' targets (rad/s, (n,))."""
        return self._ctrl.omega_ref

    def features(self) -> np.ndarray:
        """Policy inputs (n, :attr:`dim`) from the current estimates, float32 (see :data:`FEATURES`)."""
        x, ref, Ts = self.x, self.target, self.params.Ts
        d = self.model.lower_friction(x)
        f = np.stack(
            [
                x[I_WL] - ref,
                x[I_WU] - ref,
                self.params.ktheta * x[I_AL] / Ts,
                d / Ts,
                self.u_base / U_MAX,
                np.minimum(self.t / PHASE_TIME, 1.0),
                ref / 8.0,
            ],
            axis=1,
        )
        return np.clip(f, -10.0, 10.0).astype(np.float32)

    def base(self) -> np.ndarray:
        """The observer controller's voltage (V, (n,)) at the current estimates; advances its law and the rigs'
        clocks by one period."""
        self.u_base = self._ctrl.voltage_at(self.x, {"theta_u": self._theta.copy()})
        self.t += self.dt
        return self.u_base

    def voltage(self, action: np.ndarray) -> np.ndarray:
        """Applied voltages (V, (n,)) for policy actions (n,) or (n, 1) in [-1, 1]."""
        a = np.clip(np.asarray(action, dtype=float).reshape(-1), -1.0, 1.0)
        return np.clip(self.u_base + self.scale * a, -U_MAX, U_MAX)

    def predict(self, u: np.ndarray) -> None:
        """Propagate the estimates over one period with the applied voltages u (V, (n,))."""
        self._ctrl.observer.predict(u)
