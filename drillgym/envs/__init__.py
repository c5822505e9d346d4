"""Gymnasium environments of the drill-string rig (registered on import).

>>> import gymnasium, drillgym
>>> env = gymnasium.make("drillgym/Torsional-v0", observation="sensors")
>>> venv = drillgym.envs.make_vec("drillgym/Coupled-v0", num_envs=256)   # one batched core call per step
>>> sb3_venv = drillgym.envs.make_sb3_vec("drillgym/Torsional-v0", num_envs=64)  # the same as an SB3 VecEnv

The registered ids (and ``make_vec``) take actions in [-1, 1] (x 5 V); ``normalize_action=False`` gives volts.
``env.spec.max_episode_steps`` is the episode length ``episode_duration / control_dt``.

Structure (physical system separate from the environment, as gym-electric-motor):
``rig_system`` (N rigs on the batched core), ``observation`` (observation models),
``reward``, ``task`` (targets, limits, stick-slip severity), ``engine`` (n episodes stepped
together), ``base`` (the ``gymnasium.Env``), ``vector`` (the ``VectorEnv``), ``rendering``,
``sb3`` (stable-baselines3 adapter), ``options`` (every constructor option), ``tasks`` (the named
benchmark tasks, ``drillgym/Nominal-Motor-v0`` ... : fixed options, plants and evaluation protocol).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import gymnasium

from ..errors import InputError
from .base import CoupledEnv, DrillEnv, LateralEnv, TorsionalEnv
from .observation import FullObservation, MotorObservation, SensorObservation, make_observation_model
from .options import EnvOptions, RewardWeights
from .tasks import TASKS, BenchmarkTask
from .vector import DrillVectorEnv

__all__ = [
    "DrillEnv",
    "TorsionalEnv",
    "LateralEnv",
    "CoupledEnv",
    "DrillVectorEnv",
    "EnvOptions",
    "RewardWeights",
    "FullObservation",
    "SensorObservation",
    "MotorObservation",
    "make_observation_model",
    "make_vec",
    "make_sb3_vec",
    "ENV_IDS",
    "REGISTERED_DEFAULTS",
    "TASKS",
    "BenchmarkTask",
]

#: registered id -> rig configuration
ENV_IDS = {"drillgym/Torsional-v0": "torsional", "drillgym/Lateral-v0": "lateral", "drillgym/Coupled-v0": "coupled"}
_CLASSES = {"torsional": "TorsionalEnv", "lateral": "LateralEnv", "coupled": "CoupledEnv"}


#: options the registered ids set unless given (RL conventions: actions in [-1, 1], x 5 V)
REGISTERED_DEFAULTS = {"normalize_action": True}


def make_vec(env_id: str, num_envs: int, **options: Any) -> DrillVectorEnv:
    """The vectorised env of a registered id: ``num_envs`` rigs in one batched core call per step.

    As ``gymnasium.make`` of the id, actions are normalised to [-1, 1] unless ``normalize_action=False``
    (volts).  For stable-baselines3 use :func:`drillgym.envs.make_sb3_vec` (same options).

    Parameters
    ----------
    env_id : str
        Registered id: ``"drillgym/Torsional-v0"``, ``"drillgym/Lateral-v0"`` or ``"drillgym/Coupled-v0"``.
    num_envs : int
        Number of rigs (>= 1).
    **options
        Any field of :class:`drillgym.envs.EnvOptions`, and ``render_mode`` / ``autoreset_mode`` of
        :class:`drillgym.envs.DrillVectorEnv`.

    Returns
    -------
    DrillVectorEnv
        The Gymnasium vector env of the ``num_envs`` rigs.

    Examples
    --------
    >>> import drillgym
    >>> venv = drillgym.envs.make_vec("drillgym/Coupled-v0", num_envs=256)
    >>> obs, info = venv.reset(seed=0)
    """
    if env_id not in ENV_IDS:
        raise InputError(f"unknown drillgym environment {env_id!r}; expected one of {sorted(ENV_IDS)}")
    return DrillVectorEnv(num_envs, ENV_IDS[env_id], **{**REGISTERED_DEFAULTS, **options})


@dataclass(frozen=True)
class VectorEntry:
    """The vector entry point of one configuration: ``VectorEntry("torsional")(num_envs, **options)``.
    A module-level class, not a closure, so that an env's ``spec`` (and the env) can be pickled."""

    configuration: str

    def __call__(self, num_envs: int, **options: Any) -> DrillVectorEnv:
        return DrillVectorEnv(num_envs, self.configuration, **options)


def make_sb3_vec(env_id: str, num_envs: int, **options: Any):
    """``num_envs`` rigs of a registered id as a stable-baselines3 ``VecEnv``.

    One batched core call per step (see :mod:`drillgym.envs.sb3`); episodes reset in the same step,
    as stable-baselines3 expects.

    Parameters
    ----------
    env_id : str
        Registered id, as :func:`make_vec`.
    num_envs : int
        Number of rigs (>= 1).
    **options
        Any field of :class:`drillgym.envs.EnvOptions`.

    Returns
    -------
    stable_baselines3.common.vec_env.VecEnv
        The rigs as an SB3 vector env.

    Examples
    --------
    >>> from stable_baselines3 import PPO
    >>> model = PPO("MlpPolicy", make_sb3_vec("drillgym/Torsional-v0", 64))
    """
    from .sb3 import make_sb3_vec as _make

    return _make(env_id, num_envs, **options)


for _id, _cfg in ENV_IDS.items():
    if _id not in gymnasium.registry:
        # no TimeLimit wrapper: the env truncates itself after ``episode_duration`` and reports that
        # length as ``env.spec.max_episode_steps`` (DrillEnv.spec)
        gymnasium.register(
            id=_id,
            entry_point=f"drillgym.envs.base:{_CLASSES[_cfg]}",
            vector_entry_point=VectorEntry(_cfg),
            disable_env_checker=False,
            kwargs=dict(REGISTERED_DEFAULTS),
        )

# The named benchmark tasks (drillgym.envs.tasks: fixed options, plants and evaluation protocol), by entry-point
# string: a population task's plants are drawn by the controllers' evaluation package, which the core does not import.
for _id in TASKS:
    if _id not in gymnasium.registry:
        gymnasium.register(
            id=_id,
            entry_point="agents.benchmark_env:make_task_env",
            vector_entry_point="agents.benchmark_env:make_task_vec",
            disable_env_checker=False,
            kwargs={"task": _id},
        )

# The hardware twin (package ``hw``) shares these spaces; its id is registered here too, by entry-point
# string only, so that ``import drillgym`` offers it without the physics core importing ``hw``.
if "drillgym/Hardware-v0" not in gymnasium.registry:
    gymnasium.register(id="drillgym/Hardware-v0", entry_point="hw.env:HardwareEnv", disable_env_checker=True)
