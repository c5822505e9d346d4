"""stable-baselines3 adapter: a :class:`DrillVectorEnv` as an SB3 ``VecEnv`` (no subprocesses,
no per-env Python objects: one batched core call per step).

>>> from stable_baselines3 import PPO
>>> from drillgym.envs.sb3 import make_sb3_vec
>>> venv = make_sb3_vec("drillgym/Torsional-v0", num_envs=64)   # actions in [-1, 1] (x 5 V)
>>> PPO("MlpPolicy", venv).learn(100_000)

SB3 resets finished envs within the same step and expects the last observation in
``infos[i]["terminal_observation"]`` and ``infos[i]["TimeLimit.truncated"]`` for time-limit ends;
the adapter therefore drives the vector env in Gymnasium's ``SAME_STEP`` autoreset mode.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices

from ..errors import InputError, InputTypeError
from .vector import DrillVectorEnv

__all__ = ["SB3VecEnvAdapter", "make_sb3_vec"]


class SB3VecEnvAdapter(VecEnv):
    """Wraps a :class:`DrillVectorEnv` created with ``autoreset_mode=AutoresetMode.SAME_STEP``."""

    def __init__(self, venv: DrillVectorEnv) -> None:
        if not isinstance(venv, DrillVectorEnv):
            raise InputTypeError(f"SB3VecEnvAdapter wraps a DrillVectorEnv, got {type(venv).__name__}")
        if venv.autoreset_mode is not AutoresetMode.SAME_STEP:
            raise InputError(
                "SB3VecEnvAdapter needs a DrillVectorEnv with autoreset_mode=AutoresetMode.SAME_STEP (use make_sb3_vec)"
            )
        self.venv = venv
        self._actions: np.ndarray | None = None
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)

    # ------------------------------------------------------------------------ VecEnv API
    def reset(self) -> np.ndarray:
        seeds = self._seeds
        seed = None if all(s is None for s in seeds) else seeds
        obs, info = self.venv.reset(seed=seed)
        self.reset_infos = self._split(info)
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self):
        obs, rew, term, trunc, info = self.venv.step(self._actions)
        dones = term | trunc
        done_idx = np.flatnonzero(dones)
        infos = self._split(info)
        if done_idx.size:
            final = self._split(info["final_info"])
            for i in done_idx:
                infos[i] = final[i]
                infos[i]["terminal_observation"] = info["final_obs"][i]
                infos[i]["TimeLimit.truncated"] = bool(trunc[i] and not term[i])
        return obs, rew.astype(np.float32), dones, infos

    def close(self) -> None:
        self.venv.close()

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        value = getattr(self.venv, attr_name)
        return [value] * len(self._get_indices(indices))

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        setattr(self.venv, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices: VecEnvIndices = None, **method_kwargs) -> list[Any]:
        result = getattr(self.venv, method_name)(*method_args, **method_kwargs)
        return [result] * len(self._get_indices(indices))

    def env_is_wrapped(self, wrapper_class: type, indices: VecEnvIndices = None) -> list[bool]:
        return [False] * len(self._get_indices(indices))

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [self.venv.render()]

    # ------------------------------------------------------------------------
    _INFO_KEYS = ("omega_l", "stuck", "friction_torque", "stick_slip_severity", "omega_ref", "voltage", "time")

    def _split(self, info: dict) -> list[dict]:
        """Gymnasium's dict of arrays -> SB3's list of per-env dicts (the drillgym info keys, and
        ``termination`` for a terminated rig)."""
        cols = [info[k].tolist() for k in self._INFO_KEYS]
        out = [dict(zip(self._INFO_KEYS, vals)) for vals in zip(*cols)]
        if "termination" in info:
            for i in np.flatnonzero(info["_termination"]):
                out[i]["termination"] = info["termination"][i]
        return out


def make_sb3_vec(env_id: str, num_envs: int, **options: Any) -> SB3VecEnvAdapter:
    """An SB3 VecEnv of ``num_envs`` rigs of a registered drillgym id (options as the env's; actions in
    [-1, 1] unless ``normalize_action=False``, as ``gymnasium.make`` of the id)."""
    from . import ENV_IDS, REGISTERED_DEFAULTS

    options = {**REGISTERED_DEFAULTS, **options}
    if env_id not in ENV_IDS:
        raise InputError(f"unknown drillgym environment {env_id!r}; expected one of {sorted(ENV_IDS)}")
    return SB3VecEnvAdapter(
        DrillVectorEnv(num_envs, ENV_IDS[env_id], autoreset_mode=AutoresetMode.SAME_STEP, **options)
    )
