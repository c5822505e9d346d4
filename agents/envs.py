"""Training environments: the batched :class:`drillgym.envs.DrillVectorEnv` as an SB3 VecEnv,
with the residual action structure, optional frame stacking and episode statistics."""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper, VecFrameStack, VecMonitor, VecNormalize

from drillgym.envs import ENV_IDS
from drillgym.envs.options import U_MAX
from drillgym.envs.sb3 import make_sb3_vec
from drillgym.envs.tasks import PlantListRandomizer
from drillgym.errors import InputError

from .batch import episode_batch
from .command import SpeedCommand, schedule_of
from .integral import Z_MAX, advance, wrapped_speed
from .population import population_env_kwargs, use_population
from .residual import ResidualVoltage
from .residual_base_env import ResidualBaseVecEnv
from .residual_bases import RESIDUAL_BASES, make_residual_base
from .task_training import base_env_id, install_task_plants, task_env_kwargs, task_model_options, task_of

__all__ = [
    "make_training_env",
    "episode_batch",
    "ResidualActionVecEnv",
    "ResidualBaseVecEnv",
    "ObserverResidualVecEnv",
    "MotorIntegralVecEnv",
]

#: the residual base's wrapper by its former name (it wrapped the observer only)
ObserverResidualVecEnv = ResidualBaseVecEnv


class ResidualActionVecEnv(VecEnvWrapper):
    """SB3 VecEnv wrapper: action in [-1, 1] -> ``u_ff(omega_ref, t) + scale * a`` volts
    (:class:`agents.residual.ResidualVoltage`) for a drillgym VecEnv whose action is the voltage
    (``normalize_action=False``); ``t`` counts control periods since each rig's episode began."""

    def __init__(self, venv: VecEnv, residual: ResidualVoltage) -> None:
        hi = float(venv.action_space.high[0])
        if abs(hi - U_MAX) > 1e-6:
            raise InputError("ResidualActionVecEnv needs the env's action in volts (normalize_action=False)")
        super().__init__(venv, action_space=spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32))
        self.residual = residual
        self.control_dt = float(venv.get_attr("options")[0].control_dt)
        self._ref = np.zeros(venv.num_envs)
        self._t = np.zeros(venv.num_envs)  # time since each rig's episode began (s)

    def _remember(self, obs: np.ndarray) -> np.ndarray:
        self._ref = obs[:, -1].astype(float)
        return obs

    def reset(self) -> np.ndarray:
        self._t[:] = 0.0
        return self._remember(self.venv.reset())

    def step_async(self, actions: np.ndarray) -> None:
        self.venv.step_async(self.residual.voltage(actions, self._ref, self._t).reshape(-1, 1))

    def step_wait(self):
        obs, rew, done, infos = self.venv.step_wait()
        self._t += self.control_dt
        self._t[done] = 0.0
        return self._remember(obs), rew, done, infos


class MotorIntegralVecEnv(VecEnvWrapper):
    """Appends the motor-angle tracking integral ``z`` (rad) to a drillgym SB3 VecEnv's 'motor' or 'sensors'
    observation (0 at each episode's start; a finished rig's terminal observation carries its last value).

    ``command``: a :class:`agents.command.CommandSchedule`; the observation's target entry is then the
    commanded speed at the observation's time (:class:`agents.command.SpeedCommand`), and ``z`` integrates
    the motor speed against it.  :attr:`target` holds each rig's episode target (rad/s),
    :attr:`command_now` the command the last observation carries (the target without a schedule).
    ``frames`` > 1: the last ``frames`` observations (oldest first, zeros before the episode's start, as SB3's
    ``VecFrameStack``), then ``z`` once: the layout :class:`agents.controller.AgentController` builds.
    :attr:`frame` holds the newest observation (n, dim), the target entry carrying the command."""

    def __init__(
        self, venv: VecEnv, control_dt: float, z_max: float | None = None, command=None, frames: int = 1
    ) -> None:
        names = venv.get_attr("observation_names")[0]
        if names[0] not in ("omega_u_inc_0", "theta_u_wrapped") or names[-1] != "omega_ref":
            raise InputError("the motor-angle integral needs the 'motor' or 'sensors' observation mode")
        if isinstance(frames, bool) or not isinstance(frames, int) or frames < 1:
            raise InputError(f"frame_stack must be an integer >= 1, got {frames!r}")
        self.wrapped = names[0] == "theta_u_wrapped"
        if z_max is None:  # the command schedule's clip, else the default
            z_max = Z_MAX if command is None else command.z_max
        box = venv.observation_space
        space = spaces.Box(
            np.append(np.tile(box.low, frames), -z_max).astype(np.float32),
            np.append(np.tile(box.high, frames), z_max).astype(np.float32),
            dtype=np.float32,
        )
        super().__init__(venv, observation_space=space)
        self.dt, self.z_max, self.frames = float(control_dt), float(z_max), int(frames)
        n, self.dim = venv.num_envs, box.shape[0]
        self.command = None if command is None else SpeedCommand(command, n, self.dt)
        self.z = np.zeros(n)
        self.target, self.command_now = np.zeros(n), np.zeros(n)
        self.prev = np.zeros(n)  # the wrapped motor angle a period ago ('sensors')
        self.stack = np.zeros((n, frames * self.dim), dtype=np.float32)

    @property
    def frame(self) -> np.ndarray:
        """The newest observation of each rig (n, dim) (its target entry: the command)."""
        return self.stack[:, -self.dim :]

    def _put_command(self, obs: np.ndarray, index: np.ndarray | slice = slice(None)) -> None:
        """Write the command into the target entry of ``obs`` (rows ``index``) and :attr:`command_now`."""
        if self.command is not None:
            obs[index, -1] = self.command.value[index]
        self.command_now[index] = obs[index, -1]

    def _push(self, obs: np.ndarray) -> np.ndarray:
        """Stack the observations and append ``z``: the wrapper's output."""
        self.stack[:, : -self.dim] = self.stack[:, self.dim :]
        self.stack[:, -self.dim :] = obs
        return np.hstack([self.stack, self.z[:, None]]).astype(np.float32)

    def reset(self) -> np.ndarray:
        obs = self.venv.reset()
        self.reset_infos = getattr(self.venv, "reset_infos", self.reset_infos)  # for wrappers above (privileged critic)
        self.z[:] = 0.0
        self.target[:] = obs[:, -1]
        self.prev[:] = obs[:, 0]
        if self.command is not None:
            self.command.reset()
        self._put_command(obs)
        self.stack[:] = 0.0
        return self._push(obs)

    def step_wait(self):
        obs, rew, done, infos = self.venv.step_wait()
        if self.command is not None:
            self.command.advance(self.target)
        last = obs.copy()
        for i in np.flatnonzero(done):  # the ending episode's last period is in its terminal observation
            last[i] = infos[i]["terminal_observation"]
        self._put_command(last)
        speed = wrapped_speed(last[:, 0], self.prev, self.dt) if self.wrapped else None
        active = None if self.command is None else self.command.integrating(self.target)
        self.z = advance(self.z, last, self.dt, self.z_max, speed, active)
        self.prev[:] = last[:, 0]
        ended = np.flatnonzero(done)
        out = self._push(last)
        for i in ended:
            infos[i]["terminal_observation"] = out[i].copy()
        if ended.size:
            self.z[ended] = 0.0
            self.target[ended] = obs[ended, -1]
            self.prev[ended] = obs[ended, 0]
            last[ended] = obs[ended]
            if self.command is not None:
                self.command.reset(ended)
            self._put_command(last, ended)
            self.stack[ended] = 0.0
            self.stack[ended, -self.dim :] = last[ended]
            out[ended] = np.append(self.stack[ended], self.z[ended, None], axis=1)
        return out, rew, done, infos


def make_training_env(
    env_id: str,
    n_envs: int,
    *,
    seed: int = 0,
    env_kwargs: dict[str, Any] | None = None,
    residual: float | None = None,
    startup: tuple | None = None,
    base: str | None = None,
    observer: dict[str, Any] | None = None,
    frame_stack: int = 1,
    normalize_reward: bool = False,
    normalize_obs: bool = False,
    gamma: float = 0.99,
    monitor: bool = True,
    privileged: bool = False,
    motor_integral: bool = False,
    command: dict[str, float] | None = None,
    population: str | None = None,
    nominal_fraction: float = 0.0,
    nominal_below: float = 0.0,
    identified: dict[str, Any] | None = None,
) -> VecEnv:
    """An SB3 VecEnv of ``n_envs`` rigs in one batched core call per step.

    Parameters
    ----------
    env_id : str
        A drillgym environment id, e.g. ``"drillgym/Torsional-v0"``, or a benchmark task id
        (``"drillgym/Population-Motor-v0"``): its base env with the task's options, the episodes' rigs drawn
        from its training plants (:mod:`agents.task_training`).
    n_envs : int
        Number of rigs.
    seed : int, optional
        Rig ``i`` gets seed ``seed + i``.
    env_kwargs : dict, optional
        Options of the environment (:class:`drillgym.envs.EnvOptions`); ``model`` (a :class:`drillgym.Model`
        or a model file's path) is the rigs' model, on a task id the task's nominal model
        (:mod:`agents.benchmark_env`), with ``population`` the nominal rig the plants are drawn around.
    residual : float, optional
        Scale (V) of a residual action: the action in [-1, 1] is a correction ``residual * a`` on
        the feedforward voltage (:mod:`agents.residual`). None: the action is the voltage
        normalised to [-1, 1].
    startup : tuple, optional
        ``(kick V, hold s, ramp s)`` start-up schedule of the feedforward (with ``residual``).
    base : str, optional
        A classical controller the residual corrects instead (:mod:`agents.residual_bases`; needs
        ``residual``): ``"observer"`` (:mod:`agents.observer_residual`, the ``"motor"`` or ``"sensors"``
        observation) or ``"lqg-2enc"`` (:mod:`agents.two_encoder_residual`, the ``"sensors"`` observation).
    observer : dict, optional
        Keywords of the ``observer`` controller (with ``base="observer"``; ``lqg-2enc`` runs its own settings).
    frame_stack : int, optional
        Number of stacked observations (1 = none).
    normalize_reward : bool, optional
        Scale rewards by a running standard deviation of the ``gamma``-discounted return (SB3
        ``VecNormalize``).
    normalize_obs : bool, optional
        Standardise observations by running statistics (SB3 ``VecNormalize``); the exported policy
        carries the frozen statistics (:mod:`agents.export`).
    gamma : float, optional
        Discount of the return that ``normalize_reward`` scales by.
    monitor : bool, optional
        Record episode returns and lengths (SB3 ``VecMonitor``).
    privileged : bool, optional
        Append the critic's privileged entries (:class:`agents.privileged.PrivilegedObsVecEnv`).
    motor_integral : bool, optional
        Append the motor-angle tracking integral (:class:`MotorIntegralVecEnv`, :mod:`agents.integral`;
        ``"motor"`` or ``"sensors"`` observation, no residual structure); with ``frame_stack`` the wrapper
        stacks the frames and appends the integral once.
    command : dict, optional
        Settings of the command schedule (:class:`agents.command.CommandSchedule`; needs
        ``motor_integral``).
    population : str, optional
        Draw every episode's rig from this uncertainty set (``"default"`` or a YAML path,
        :mod:`agents.population`); plain actions only.
    nominal_fraction : float, optional
        With ``population``: the probability of the nominal rig.
    nominal_below : float, optional
        With ``population``: targets below this speed (rad/s) get the nominal rig.
    identified : dict, optional
        On an identified task with a ``base``: ``{"plants": P, "folder": DIR}``, every episode runs one of the
        first P training plants and its rig's base is that controller built on that plant's identified model
        (:mod:`agents.plantwise_residual`; the identifications read from ``DIR``, the missing ones identified
        and written there, :func:`agents.identified_plants.identified_plants`).

    Returns
    -------
    stable_baselines3.common.vec_env.VecEnv
        The wrapped, seeded vector environment.

    Raises
    ------
    InputError
        An unknown environment, ``n_envs < 1``, or options that do not go together.
    """
    task = task_of(env_id)
    env_id = base_env_id(env_id)  # a task is its base env with the task's options and plants
    if not (isinstance(n_envs, int) and n_envs >= 1):
        raise InputError(f"n_envs must be an integer >= 1, got {n_envs!r}")
    kw = dict(env_kwargs or {})
    model = kw.pop("model", None) if task is not None else None  # a task's nominal model (benchmark_env)
    if task is not None:
        if population is not None or nominal_fraction or nominal_below:
            raise InputError(f"task {task.id} fixes its plants: no population, nominal_fraction or nominal_below")
        kw = {**task_env_kwargs(task, kw), **task_model_options(task, model)}
    if base is not None and base not in RESIDUAL_BASES:
        raise InputError(f"base must be {' or '.join(map(repr, RESIDUAL_BASES))} (or absent), got {base!r}")
    if base is not None:
        if residual is None:
            raise InputError(f"base {base!r} needs a residual scale (V)")
        if observer is not None and base != "observer":
            raise InputError(f"observer settings apply to base 'observer', not {base!r}")
        kw["normalize_action"] = False
        venv = make_sb3_vec(env_id, n_envs, **kw)
        o = venv.venv.options
        design = (env_kwargs or {}).get("model")  # the model the user gave (a train --model): the base's too
        if identified is not None:
            from .plantwise_residual import plantwise_base

            base_law: Any = plantwise_base(task, identified, base, ENV_IDS[env_id], residual, o.control_dt, observer)
        else:
            base_law = make_residual_base(base, ENV_IDS[env_id], residual, o.params, o.control_dt, observer, design)
        venv = ResidualBaseVecEnv(venv, base_law)
    elif residual is not None:
        kw["normalize_action"] = False
        venv: VecEnv = make_sb3_vec(env_id, n_envs, **kw)
        venv = ResidualActionVecEnv(venv, ResidualVoltage(ENV_IDS[env_id], residual, venv.venv.options.params, startup))
    else:
        kw["normalize_action"] = True
        if population is not None:
            kw = population_env_kwargs(kw, population)
        venv = make_sb3_vec(env_id, n_envs, **kw)
        if population is not None:
            use_population(venv, population, nominal_fraction, nominal_below)
    if population is not None and (residual is not None or base is not None):
        raise InputError("a plant population is drawn for plain actions only (no residual or base controller)")
    if identified is not None and base is None:
        raise InputError(
            "identified (bases built on each plant's identified model) needs base "
            + " or ".join(repr(b) for b in RESIDUAL_BASES)
        )
    if task is not None:
        install_task_plants(venv, task, model)
        if identified is not None:  # the episodes run the identified plants only
            batch = episode_batch(venv)
            batch.randomizer = PlantListRandomizer(batch.randomizer.matrix[: int(identified["plants"])])
    schedule = schedule_of(command, motor_integral)
    if motor_integral:
        if residual is not None or base is not None:
            raise InputError("the motor-angle integral works without a residual structure")
        venv = MotorIntegralVecEnv(
            venv, float(venv.get_attr("options")[0].control_dt), command=schedule, frames=frame_stack
        )
    if privileged:
        if frame_stack > 1 or base is not None:
            raise InputError("the privileged critic works without frame stacking and without a base controller")
        from .privileged import PrivilegedObsVecEnv

        venv = PrivilegedObsVecEnv(venv)
    if monitor:
        venv = VecMonitor(venv)
    if frame_stack > 1 and not motor_integral:  # with the integral its wrapper stacks the frames
        venv = VecFrameStack(venv, frame_stack)
    if normalize_reward or normalize_obs:
        venv = VecNormalize(venv, norm_obs=normalize_obs, norm_reward=normalize_reward, gamma=gamma)
    venv.seed(seed)
    return venv
