"""Privileged critic (asymmetric actor-critic) for PPO: the value function also sees simulated quantities
the rig cannot measure, the actor (the deployed policy) only the rig's observation.

Training only: the critic is thrown away at export, so the deployed network still maps the motor side's
observation to the voltage.  :class:`PrivilegedObsVecEnv` appends :data:`PRIVILEGED` (from the env's
``info``: lower-disc speed, stuck flag, running stick-slip severity) to each observation;
:class:`PrivilegedCriticPolicy` gives the actor the observation with those entries zeroed (so its first
layer's weights on them never change from their zero gradient, and the export keeps only the first
``actor_dim`` columns: :func:`agents.export.policy_layers`), the critic the whole vector.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.policies import ActorCriticPolicy
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

__all__ = ["PRIVILEGED", "PrivilegedObsVecEnv", "PrivilegedCriticPolicy", "MaskedFlatten"]

#: info entries appended for the critic: lower-disc speed (rad/s), stuck (0/1), running SSI
PRIVILEGED = ("omega_l", "stuck", "stick_slip_severity")
_LOW = np.array([-60.0, 0.0, 0.0], dtype=np.float32)
_HIGH = np.array([60.0, 1.0, 100.0], dtype=np.float32)


class PrivilegedObsVecEnv(VecEnvWrapper):
    """Appends the :data:`PRIVILEGED` info entries to the observations of a drillgym SB3 VecEnv
    (terminal observations get those of the episode's last step)."""

    def __init__(self, venv: VecEnv) -> None:
        box = venv.observation_space
        self.actor_dim = int(box.shape[0])
        space = spaces.Box(np.concatenate([box.low, _LOW]), np.concatenate([box.high, _HIGH]), dtype=np.float32)
        super().__init__(venv, observation_space=space)

    @staticmethod
    def _extra(info: dict) -> np.ndarray:
        return np.array([float(info[k]) for k in PRIVILEGED], dtype=np.float32)

    def reset(self) -> np.ndarray:
        obs = self.venv.reset()
        infos = getattr(self.venv, "reset_infos", None) or [{k: 0.0 for k in PRIVILEGED}] * self.num_envs
        return np.hstack([obs, np.stack([self._extra(i) for i in infos])])

    def step_wait(self):
        obs, rew, done, infos = self.venv.step_wait()
        extra = np.stack([self._extra(i) for i in infos])  # a finished rig's info is its last step's
        for i in np.flatnonzero(done):
            infos[i]["terminal_observation"] = np.concatenate([infos[i]["terminal_observation"], extra[i]])
            extra[i] = 0.0  # the new episode starts at rest (omega_l = 0), stuck
            extra[i, 1] = 1.0
        return np.hstack([obs, extra]), rew, done, infos


class MaskedFlatten(BaseFeaturesExtractor):
    """Flattened observation with every entry from ``actor_dim`` on set to 0 (the actor's view)."""

    def __init__(self, observation_space: spaces.Box, actor_dim: int) -> None:
        n = int(np.prod(observation_space.shape))
        super().__init__(observation_space, n)
        mask = th.zeros(n)
        mask[:actor_dim] = 1.0
        self.register_buffer("mask", mask)

    def forward(self, obs: th.Tensor) -> th.Tensor:
        return th.flatten(obs, 1) * self.mask


class PrivilegedCriticPolicy(ActorCriticPolicy):
    """``MlpPolicy`` whose actor sees the first ``actor_dim`` observation entries and whose critic sees all."""

    def __init__(self, *args: Any, actor_dim: int, **kwargs: Any) -> None:
        kwargs["share_features_extractor"] = False
        self.actor_dim = int(actor_dim)
        super().__init__(*args, **kwargs)
        self.pi_features_extractor = MaskedFlatten(self.observation_space, self.actor_dim)
        self.features_extractor = self.pi_features_extractor

    def _get_constructor_parameters(self) -> dict[str, Any]:
        data = super()._get_constructor_parameters()
        data["actor_dim"] = self.actor_dim
        return data
