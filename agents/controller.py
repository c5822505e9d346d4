"""A trained agent as a :class:`controllers.Controller`: the harness's (or the rig's) measurements ->
the env's observation -> the exported policy -> the residual voltage.

The observation is built by the environment's own observation model
(:mod:`drillgym.envs.observation`, ``from_readings``), configured with the options
the agent was trained with, so the agent sees on the rig exactly what it saw in
training.  The encoder angles arrive already quantized by the rig (or the
harness), so the model is built with ``counts_per_rev = 0`` (no second quantization).

Agents on a classical base (``base: observer`` or ``base: lqg-2enc`` in their hyperparameters,
:mod:`agents.residual_bases`) build their observation with that base from the encoder angles it reads instead,
in the order of :class:`agents.residual_base_env.ResidualBaseVecEnv`.

Timing matches the env: ``reset(m)`` gives the reset observation (zero speed
history, the target); the first ``act`` answers it; every later ``act`` first adds
the period's readings (encoder angles, the voltage applied over the period).
"""

from __future__ import annotations

import warnings

import numpy as np

from controllers.base import Controller
from drillgym.configurations import N_STATE
from drillgym.envs.observation import make_observation_model
from drillgym.envs.options import U_MAX, EnvOptions
from drillgym.errors import InputError

from .command import SpeedCommand, schedule_of
from .export import ExportedPolicy
from .integral import Z_MAX, advance, wrapped_speed
from .residual import ResidualVoltage
from .residual_bases import make_residual_base
from .switched import TargetSwitchedPolicy

__all__ = ["AgentController", "TargetSwitchedController", "OBSERVATION_KEYS"]

#: env options that shape the observation (the rest is physics/task, irrelevant on the rig)
OBSERVATION_KEYS = ("observation", "motor_history", "velocity_filter_tau", "max_speed", "max_lateral", "control_dt")


class AgentController(Controller):
    """Trained policy (exported, numpy) with the env's observation model and the residual voltage structure.

    Parameters
    ----------
    policy : ExportedPolicy
        A policy trained on the ``"sensors"`` or ``"motor"`` observation (:func:`agents.load_policy`).
    omega_ref : float or ndarray, optional
        Target lower-disc speed(s) (rad/s).
    **kw
        ``config``, ``params``, ``dt``, ``u_max`` of :class:`controllers.Controller`; ``dt`` defaults to
        the policy's control period and must equal it.  ``model=`` (a :class:`drillgym.Model` or a model
        file's path, as ``controllers.make("agent:DIR", model=...)``): the network does not read it, its
        weights are what it learned on its training rig (``drillgym train --model FILE --init DIR`` adapts
        them to a model).  A policy on a classical base (``base: observer``, ``base: lqg-2enc``) runs on that
        controller built on the whole model, effects included (as ``controllers.make("observer", model=...)``):
        the identification reaches it as it reaches the controller.  A residual on the base law (``residual``) uses
        the model's base parameters, as ``params`` would be; a plain network ignores the model; the effects
        these two cannot use are named in a warning.

    Raises
    ------
    InputError
        A policy of the ``"full"`` observation, or ``dt`` different from the training's control period.
    """

    name = "agent"

    def __init__(self, policy: ExportedPolicy, omega_ref=None, **kw) -> None:
        model = None
        if kw.get("model") is not None:
            from controllers.model import model_of

            model = model_of(kw.pop("model"), kw.get("params"))
            kw["params"] = model.params
        base_name = policy.config["hyperparams"].get("base")
        if model is not None and model.composition.effects and base_name is None:  # said, not silently dropped
            names = ", ".join(e.name for e in model.composition.effects)
            warnings.warn(
                f"agent: the policy uses the model's base parameters only; its effects ({names}) are not used "
                "(drillgym train --model FILE --init DIR adapts a policy to them)",
                stacklevel=2,
            )
        cfg = policy.config
        hp = cfg["hyperparams"]
        env_kwargs = hp.get("env_kwargs", {})
        self.mode = env_kwargs.get("observation", "full")
        if self.mode == "full":
            raise InputError(
                "agent trained on the 'full' observation (true state) cannot run on measurements; "
                "train with --obs motor or --obs sensors"
            )
        control_dt = policy.control_dt
        kw.setdefault("dt", control_dt)
        if abs(kw["dt"] - control_dt) > 1e-12:
            raise InputError(f"agent was trained at control period {control_dt} s, not {kw['dt']} s")
        super().__init__(omega_ref, **kw)
        self.policy = policy
        self.uses = (
            ("theta_u",)
            if self.mode == "motor"
            else (("theta_u", "theta_l", "x", "y") if self.config.lateral_free else ("theta_u", "theta_l"))
        )
        self.obs_options = EnvOptions.from_kwargs(
            configuration=self.config.label,
            counts_per_rev=0,
            lvdt_noise_std=0.0,
            **{k: (tuple(v) if isinstance(v, list) else v) for k, v in env_kwargs.items() if k in OBSERVATION_KEYS},
        )
        self.frame_stack = int(hp.get("frame_stack", 1))
        self.integral = bool(hp.get("motor_integral", False))  # the motor-angle tracking integral (agents.integral)
        self.schedule = schedule_of(hp.get("command_schedule"), self.integral)  # the speed command (agents.command)
        scale = hp.get("residual")
        self.base = None
        #: whether the model's effects reach the commands (a classical base built on the whole model); else the
        #: network reads none of them
        self.runs_effects = base_name is not None and model is not None
        if base_name is not None:  # observation = the base's features, not the env's model
            if self.frame_stack != 1:
                raise InputError(f"agents on the {base_name} base are trained without frame stacking")
            self.base = make_residual_base(
                base_name, self.config.label, scale, self.params, self.dt, hp.get("observer"), model
            )
            self.uses = tuple(self.base.uses)
            if self.base.dim != policy.obs_dim:
                raise InputError(f"agent expects {policy.obs_dim} inputs; the {base_name} base gives {self.base.dim}")
            return
        self.residual = (
            None if scale is None else ResidualVoltage(self.config.label, scale, self.params, hp.get("startup"))
        )
        self._check_sizes()

    def _check_sizes(self) -> None:
        """Refuse, as the policy loads, a network whose input or output does not fit this rig: its observation
        size against the observation model of the configuration (frames, integral), one action (the voltage)."""
        policy = self.policy
        low = getattr(policy, "low", None)  # (a stand-in policy of a test may have no bounds)
        if low is not None and np.shape(low) != (1,):
            raise InputError(f"agent gives {np.size(low)} actions; the rig takes one (the motor voltage)")
        dim = make_observation_model(1, self.obs_options).dim
        if dim * self.frame_stack + int(self.integral) != policy.obs_dim:
            raise InputError(
                f"agent expects {policy.obs_dim} observation entries; the "
                f"{self.mode!r} model of {self.config.label} gives {dim} x {self.frame_stack}"
                + (" + 1 (integral)" if self.integral else "")
            )

    def _reset(self, m: dict[str, np.ndarray]) -> None:
        n = self.n
        if self.base is not None:
            self.base.start(n)
            read = {k: np.broadcast_to(m.get(k, 0.0), (n,)) for k in self.base.uses}
            self.base.reset(np.arange(n), omega_ref=self.omega_ref, **read)
            return
        self.model = make_observation_model(n, self.obs_options)
        dim = self.model.dim * self.frame_stack
        if dim + int(self.integral) != self.policy.obs_dim:
            raise InputError(
                f"agent expects {self.policy.obs_dim} observation entries; the "
                f"{self.mode!r} model of {self.config.label} gives {self.model.dim} x {self.frame_stack}"
                + (" + 1 (integral)" if self.integral else "")
            )
        Y = np.zeros((n, N_STATE))
        Y[:, 0] = m.get("theta_u", 0.0)
        Y[:, 1] = m.get("theta_l", 0.0)
        index = np.arange(n)
        self.model.reset(index, Y, [None] * n)
        self.obs = self.model.initial(index, Y, self.omega_ref)
        self.command = None
        if self.schedule is not None:
            self.command = SpeedCommand(self.schedule, n, self.dt)
            self.obs[:, -1] = self.command.value
        self.stack = np.zeros((n, dim), dtype=np.float32)
        self.z = np.zeros(n)
        self.prev = self.obs[:, 0].astype(float)  # the wrapped motor angle a period ago ('sensors')
        self._push()
        self._first = True
        self._t = np.zeros(n)  # time since reset (s), counted in control periods as in training

    def _push(self) -> None:
        d = self.model.dim
        self.stack[:, :-d] = self.stack[:, d:]
        self.stack[:, -d:] = self.obs

    def _observe(self, m: dict[str, np.ndarray]) -> None:
        if self.mode == "motor":
            self.model.from_readings(m["theta_u"], self.u_prev, self.omega_ref, self.obs)
        else:
            lat = self.config.lateral_free
            self.model.from_readings(
                m["theta_u"],
                m["theta_l"],
                m["x"] if lat else None,
                m["y"] if lat else None,
                self.u_prev,
                self.omega_ref,
                self.obs,
            )
        if self.command is not None:  # as agents.envs.MotorIntegralVecEnv: the command at this time
            self.command.advance(np.broadcast_to(self.omega_ref, (self.n,)))
            self.obs[:, -1] = self.command.value
        self._push()

    def _act(self, m: dict[str, np.ndarray]) -> np.ndarray:
        if self.base is not None:  # same order as agents.residual_base_env.ResidualBaseVecEnv
            self.base.correct(**{k: m[k] for k in self.base.uses})
            self.base.base()
            u = np.clip(self.base.voltage(self.policy.act(self.base.features())[:, 0]), -self.u_max, self.u_max)
            self.base.predict(u)
            return u
        if not self._first:
            self._observe(m)
            self._t = self._t + self.dt
            if self.integral:
                speed = None if self.mode == "motor" else wrapped_speed(self.obs[:, 0], self.prev, self.dt)
                active = None if self.command is None else self.command.integrating(self.omega_ref)
                z_max = Z_MAX if self.command is None else self.schedule.z_max
                self.z = advance(self.z, self.obs, self.dt, z_max, speed, active)
                self.prev = self.obs[:, 0].astype(float)
        self._first = False
        x = np.hstack([self.stack, self.z[:, None].astype(np.float32)]) if self.integral else self.stack
        a = self.policy.act(x)[:, 0]
        if self.residual is not None:
            return self.residual.voltage(a, self.stack[:, -1], self._t)
        return a * U_MAX  # trained with normalize_action=True


class TargetSwitchedController(Controller):
    """Learned networks chosen by the target (:mod:`agents.switched`): each rig runs, as its own
    :class:`AgentController`, the network whose band holds its target; nothing else computes the voltage.

    Parameters
    ----------
    policy : TargetSwitchedPolicy
        The networks and their band edges (rad/s).
    omega_ref : float or ndarray, optional
        Target lower-disc speed(s) (rad/s).
    **kw
        Options of :class:`AgentController`.
    """

    name = "agent"

    def __init__(self, policy: TargetSwitchedPolicy, omega_ref=None, **kw) -> None:
        self.switched = policy
        self.members = [
            AgentController(p, omega_ref, **kw) for p in policy.members
        ]  # one control period (the policy's check)
        kw.setdefault("dt", self.members[0].dt)
        super().__init__(omega_ref, **kw)
        self.uses = tuple(dict.fromkeys(u for m in self.members for u in m.uses))
        self.groups: list[tuple[int, np.ndarray]] = []

    def describe(self) -> str:
        """One line: the networks, their target bands (rad/s) and the measurements they read."""
        edges = self.switched.edges
        bands = [
            f"< {hi:g}" if lo is None else f">= {lo:g}" if hi is None else f"{lo:g}-{hi:g}"
            for lo, hi in zip((None, *edges), (*edges, None))
        ]
        return (
            f"agent: {len(self.members)} learned networks chosen by the target (rad/s: {', '.join(bands)}) "
            f"(reads: {', '.join(self.uses)})"
        )

    def approach_time(self, omega_ref: float | np.ndarray) -> np.ndarray:
        """The approach time of the network serving each target."""
        ref = np.asarray(omega_ref, dtype=float)
        k = self.switched.member_of(ref)
        out = np.zeros(np.shape(ref))
        for i, m in enumerate(self.members):
            sel = k == i
            if np.any(sel):
                out[sel] = np.asarray(m.approach_time(ref[sel]), dtype=float)
        return out

    @staticmethod
    def _rows(m: dict[str, np.ndarray], rows: np.ndarray) -> dict[str, np.ndarray]:
        return {key: np.asarray(v)[rows] for key, v in m.items()}

    def _reset(self, m: dict[str, np.ndarray]) -> None:
        k = self.switched.member_of(self.omega_ref)
        self.groups = [(i, np.flatnonzero(k == i)) for i in range(len(self.members)) if np.any(k == i)]
        for i, rows in self.groups:
            sub = self._rows(m, rows)
            sub["omega_ref"] = self.omega_ref[rows]
            self.members[i].reset(sub)

    def _act(self, m: dict[str, np.ndarray]) -> np.ndarray:
        u = np.zeros(self.n)
        for i, rows in self.groups:
            u[rows] = self.members[i].act(self._rows(m, rows))
        return u
