"""Residual policy on the two-encoder LQG: the agent corrects the ``lqg-2enc`` voltage.

Structure (residual policy learning on a model-based controller, as :mod:`agents.observer_residual` on the
observer)::

    u_base  = LQG(theta_u, theta_l)                    the ``lqg-2enc`` controller's voltage (V): its Kalman
                                                        correction, its law, its prediction with u_base
    obs     = features(x^, r, omega_ref)                what the policy sees (:data:`FEATURES`)
    u       = clip(u_base + scale * a, -5 V, 5 V)       a = policy(obs) in [-1, 1]
    LQG.applied(u)                                      the filter's prediction redone with the voltage applied

The filter, the law and the reference (targets below 3 rad/s reached from above) are a
:class:`controllers.two_encoder.TwoEncoderLQG` itself (:meth:`~controllers.two_encoder.TwoEncoderLQG.act` and
:meth:`~controllers.two_encoder.TwoEncoderLQG.applied`, the route :class:`agents.teachers.ShadowTeacher` runs it
by), so ``a = 0`` *is* that controller, to the bit.  Built on a model (``model=``, a :class:`drillgym.Model`:
e.g. the rig's identified one), the base is ``controllers.make("lqg-2enc", model=...)``, every effect included.
Everything the policy sees is a function of the two encoder angles and the applied voltages.

Batched over n rigs with per-rig resets, so one object serves the training VecEnv
(:class:`agents.residual_base_env.ResidualBaseVecEnv`), the exported policy's
:class:`agents.controller.AgentController` and the rig.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from controllers.two_encoder import TwoEncoderLQG
from drillgym import RigParams
from drillgym.envs.options import U_MAX
from drillgym.errors import InputError

__all__ = ["TwoEncoderResidual", "FEATURES", "TOP"]

FEATURES = (
    "omega_l_err",
    "omega_u_err",
    "omega_l_to_reference",
    "reference",
    "angle_lead",
    "string_torque",
    "lower_torque",
    "u_base",
    "phase",
    "omega_ref",
)
"""Policy inputs: omega^_l - omega_ref, omega^_u - omega_ref, omega^_l - r, r - omega_ref (rad/s; r the
controller's reference, which comes down from 3 rad/s to a low target), theta^_u - theta_ref (rad, the motor
angle's lead over the reference's integral), k_theta alpha^ / Ts and the estimated lower-disc torque d^ / Ts
(dimensionless), base voltage / 5 V, time since the start / 30 s (at most 1), omega_ref / 8 rad/s.  The
estimates are the filter's after its period (predicted with the base voltage)."""

PHASE_TIME = 30.0  # s, time scale of the phase input
#: the highest target (rad/s) any rig of a batch may get later (:meth:`TwoEncoderResidual.reset`): the designs'
#: grid covers it from the start (the task's targets go up to 8 rad/s)
TOP = 8.0


class TwoEncoderResidual:
    """Batched ``lqg-2enc`` controller as the base of a residual policy (see the module docstring).

    Parameters
    ----------
    config : str
        Rig configuration the controller is designed for.
    scale : float
        Voltage of a full action (V), > 0.
    params : RigParams, optional
        The design model's base parameters (default: the identified set); unused with ``model``.
    dt : float, optional
        Control period (s).
    options : dict, optional
        Keywords of :class:`controllers.two_encoder.TwoEncoderLQG` (``approach``, ``hold``, ``ramp``,
        ``tau_ref``, ``design``, ...); default its own settings, as the identified task builds it.
    model : drillgym.Model or str or path, optional
        The design model with its effects (a model file's path is read as ``controllers.make`` reads it).
    """

    uses = ("theta_u", "theta_l")  # the readings :meth:`reset` and :meth:`correct` take, by name

    def __init__(
        self,
        config: str,
        scale: float,
        params: RigParams | None = None,
        dt: float = 0.01,
        options: dict[str, Any] | None = None,
        model: Any = None,
    ) -> None:
        if not (np.isfinite(scale) and scale > 0):
            raise InputError(f"residual scale must be a positive voltage, got {scale!r}")
        design = {"params": params} if model is None else {"model": model}  # a model holds its own parameters
        self._ctrl = TwoEncoderLQG(config=config, dt=dt, **design, **(options or {}))
        self.scale, self.params, self.dt = float(scale), self._ctrl.params, self._ctrl.dt
        self.model = self._ctrl.effects  # the design model (a drillgym.Model)
        self.n = 0

    @property
    def dim(self) -> int:
        """Number of policy inputs."""
        return len(FEATURES)

    def start(self, n: int) -> None:
        """Allocate n rigs (call :meth:`reset` for all of them before :meth:`correct`)."""
        self.n = int(n)
        self.u_base = np.zeros(self.n)
        self._m = {k: np.zeros(self.n) for k in self.uses}  # the readings of the period (rad)
        self._started = False

    def reset(self, index: np.ndarray, theta_u: np.ndarray, omega_ref: np.ndarray, theta_l: np.ndarray) -> None:
        """Rigs ``index`` start at rest at encoder angles theta_u, theta_l (rad) towards targets omega_ref (rad/s).

        The first call resets the whole batch (its designs cover targets up to :data:`TOP` or the highest
        given); the rigs then restart as the controller's ``reset_rigs`` restarts them.
        """
        idx = np.atleast_1d(np.asarray(index, dtype=np.int64))
        ref = np.full(self.n, TOP)
        ref[idx] = np.broadcast_to(np.asarray(omega_ref, dtype=float), idx.shape)
        for k, v in (("theta_u", theta_u), ("theta_l", theta_l)):
            self._m[k][idx] = np.broadcast_to(np.asarray(v, dtype=float), idx.shape)
        m = {**{k: v.copy() for k, v in self._m.items()}, "omega_ref": ref}
        if not self._started:  # the controller's batch starts with every rig
            if idx.size != self.n or np.unique(idx).size != self.n:
                raise InputError(f"reset every rig of the batch ({self.n}) first, got {idx.size}")
            self._ctrl.reset({**m, "omega_ref": np.full(self.n, max(TOP, float(ref.max())))})
            self._started = True
        self._ctrl.reset_rigs(idx, m)

    def correct(self, theta_u: np.ndarray, index: np.ndarray | slice = slice(None), *, theta_l: np.ndarray) -> None:
        """The encoder angles (rad) of rigs ``index`` this period (the filter corrects with them in :meth:`base`)."""
        self._m["theta_u"][index] = theta_u
        self._m["theta_l"][index] = theta_l

    @property
    def x(self) -> np.ndarray:
        """Estimates (n, dim) of the rigs: (theta_u, omega_u, alpha, omega_l, u_a, d), then the delay line."""
        return self._ctrl.x

    @property
    def target(self) -> np.ndarray:
        """The rigs' targets (rad/s, (n,))."""
        return self._ctrl.omega_ref

    def features(self) -> np.ndarray:
        """Policy inputs (n, :attr:`dim`) from the current estimates, float32 (see :data:`FEATURES`)."""
        c, x, ref, Ts = self._ctrl, self.x, self.target, self.params.Ts
        f = np.stack(
            [
                x[:, 3] - ref,
                x[:, 1] - ref,
                x[:, 3] - c.r,
                c.r - ref,
                x[:, 0] - c.theta_ref,
                self.params.ktheta * x[:, 2] / Ts,
                x[:, 5] / Ts,
                self.u_base / U_MAX,
                np.minimum(c.t / PHASE_TIME, 1.0),
                ref / 8.0,
            ],
            axis=1,
        )
        return np.clip(f, -10.0, 10.0).astype(np.float32)

    def base(self) -> np.ndarray:
        """The controller's voltage (V, (n,)) for the period's readings; advances its filter (predicted with this
        voltage until :meth:`predict`), its reference and its clock by one period."""
        self.u_base = np.asarray(self._ctrl.act(self._m), dtype=float).copy()
        return self.u_base

    def voltage(self, action: np.ndarray) -> np.ndarray:
        """Applied voltages (V, (n,)) for policy actions (n,) or (n, 1) in [-1, 1]."""
        a = np.clip(np.asarray(action, dtype=float).reshape(-1), -1.0, 1.0)
        return np.clip(self.u_base + self.scale * a, -U_MAX, U_MAX)

    def predict(self, u: np.ndarray) -> None:
        """Redo the filter's prediction over the period with the applied voltages u (V, (n,))."""
        self._ctrl.applied(np.asarray(u, dtype=float).reshape(-1))
