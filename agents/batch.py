"""The drillgym episode batch under an SB3 VecEnv and any wrappers of it."""

from __future__ import annotations

__all__ = ["episode_batch"]


def episode_batch(venv):
    """The drillgym episode batch (rigs, targets, parameters) under an SB3 VecEnv.

    Parameters
    ----------
    venv : stable_baselines3.common.vec_env.VecEnv
        A VecEnv built on :func:`drillgym.envs.sb3.make_sb3_vec`, or any stack of wrappers of one.

    Returns
    -------
    object
        The ``batch`` attribute of the innermost drillgym VecEnv.
    """
    while not hasattr(venv, "batch"):
        venv = venv.venv
    return venv.batch
