"""The training VecEnv of a residual policy on a classical controller (:mod:`agents.residual_bases`).

:class:`ResidualBaseVecEnv` wraps a drillgym VecEnv whose action is the voltage: it rebuilds the encoder angles
the base reads from the env's observation, feeds them to the base, and gives the policy the base's features; the
policy's action in [-1, 1] is the residual on the base's voltage.  The angles come from

* a base on the motor encoder alone (``observer``), the ``motor`` observation: the motor angle, as the sum of its
  latest increments (``omega_u_inc_0`` times the control period, 0 at each episode's start, rounded to the
  encoder's grid);
* a base on both encoders (``lqg-2enc``), the ``sensors`` observation: each encoder's wrapped angle
  (``theta_u_wrapped``, ``theta_l_wrapped``, rad), unwrapped from the episode's first reading (as
  :class:`controllers.gym_adapter.ControllerPolicy` does).

Its order of calls is that of :class:`agents.controller.AgentController` on the rig: at a reset
``reset``, ``correct``, ``base``; each period ``voltage``, ``predict``, the env's step, ``correct``, ``base``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

from drillgym.envs.options import U_MAX
from drillgym.errors import InputError
from drillgym.measurement import counts_to_angle

from .batch import episode_batch

__all__ = ["ResidualBaseVecEnv"]


def _encoder_columns(uses: tuple[str, ...], names: list[str]) -> tuple[list[int], bool]:
    """The observation's columns of the encoders ``uses`` and whether they are wrapped angles (rad; else the
    motor-angle increment, rad/s); an encoder the observation lacks is refused in one line."""
    if uses == ("theta_u",):  # the motor encoder alone: its increments (the observer's training)
        if names[0] != "omega_u_inc_0":
            raise InputError("a base reading theta_u alone is trained on the 'motor' observation")
        return [0], False
    missing = [u for u in uses if f"{u}_wrapped" not in names]
    if missing:
        raise InputError(
            f"a base reading {', '.join(uses)} is trained on the 'sensors' observation; this one has no {missing[0]}"
        )
    return [names.index(f"{u}_wrapped") for u in uses], True


class ResidualBaseVecEnv(VecEnvWrapper):
    """SB3 VecEnv wrapper: a residual base (:mod:`agents.residual_bases`, or a per-plant
    :class:`agents.plantwise_residual.PlantwiseResidual`) on a drillgym VecEnv with the action in volts.

    Parameters
    ----------
    venv : VecEnv
        A drillgym SB3 VecEnv in ``motor`` or ``sensors`` mode, ``normalize_action=False``.
    base : object
        The residual base; ``base.uses`` names the encoders it reads.
    """

    def __init__(self, venv: VecEnv, base: Any) -> None:
        if abs(float(venv.action_space.high[0]) - U_MAX) > 1e-6:
            raise InputError("the residual base's env needs the action in volts (normalize_action=False)")
        self.uses: tuple[str, ...] = tuple(base.uses)
        self.cols, self.wrapped = _encoder_columns(self.uses, list(venv.get_attr("observation_names")[0]))
        obs_space = spaces.Box(-10.0, 10.0, shape=(base.dim,), dtype=np.float32)
        super().__init__(
            venv, observation_space=obs_space, action_space=spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
        )
        self.base = base
        opts = venv.get_attr("options")[0]
        self.control_dt, self.counts_per_rev = float(opts.control_dt), int(opts.counts_per_rev)
        self._theta = np.zeros((venv.num_envs, len(self.uses)))  # the unwrapped encoder angles (rad)

    def _readings(self, index: np.ndarray | slice = slice(None)) -> dict[str, np.ndarray]:
        return {k: self._theta[index, j].copy() for j, k in enumerate(self.uses)}

    def _start_angles(self, obs: np.ndarray, index: np.ndarray) -> None:
        """The angles of rigs ``index`` at their episode's start: 0 (increments) or their reset readings."""
        self._theta[index] = obs[index][:, self.cols] if self.wrapped else 0.0

    def _advance(self, last: np.ndarray) -> None:
        """Add the period's change of each encoder read from the observations ``last`` (n, dim)."""
        w = last[:, self.cols].astype(float)
        if self.wrapped:
            self._theta += (w - self._theta + np.pi) % (2.0 * np.pi) - np.pi
            return
        self._theta += w * self.control_dt
        if self.counts_per_rev > 0:  # back onto the encoder's grid (the increments are float32)
            q = counts_to_angle(1, self.counts_per_rev)
            self._theta = counts_to_angle(np.round(self._theta / q), self.counts_per_rev)

    def _plants(self, index: np.ndarray) -> dict:
        """``plants=`` the listed plants rigs ``index`` run, for a base built per plant
        (:class:`agents.plantwise_residual.PlantwiseResidual`); nothing for one base for all rigs."""
        if not getattr(self.base, "per_plant", False):
            return {}
        plants = episode_batch(self.venv).plant_index[index]
        if np.any(plants < 0):
            raise InputError("a base built per plant needs the rigs drawn from a plant list (a population task)")
        return {"plants": plants}

    def reset(self) -> np.ndarray:
        obs = self.venv.reset()
        every = np.arange(self.num_envs)
        self.base.start(self.num_envs)
        self._start_angles(obs, every)
        self.base.reset(every, omega_ref=obs[:, -1], **self._plants(every), **self._readings())
        self.base.correct(**self._readings())
        self.base.base()
        return self.base.features()

    def step_async(self, actions: np.ndarray) -> None:
        u = self.base.voltage(actions)
        self.base.predict(u)
        self.venv.step_async(u.reshape(-1, 1))

    def step_wait(self):
        obs, rew, done, infos = self.venv.step_wait()
        last = obs.copy()
        ended = np.flatnonzero(done)
        for i in ended:  # the ending episode's last reading is in its terminal observation
            last[i] = infos[i]["terminal_observation"]
        self._advance(last)
        self.base.correct(**self._readings())
        if ended.size:
            feats = self.base.features()
            for i in ended:
                infos[i]["terminal_observation"] = feats[i]
            self._start_angles(obs, ended)
            self.base.reset(ended, omega_ref=obs[ended, -1], **self._plants(ended), **self._readings(ended))
            self.base.correct(index=ended, **self._readings(ended))
        self.base.base()
        return self.base.features(), rew, done, infos
