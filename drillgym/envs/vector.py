"""Vectorised environment: N rigs stepped in ONE batched call of the compiled core.

``DrillVectorEnv`` is a :class:`gymnasium.vector.VectorEnv` (Gymnasium 1.x conventions:
batched spaces, info as a dict of arrays with ``_key`` masks, ``metadata["autoreset_mode"]``).

Autoreset: ``NEXT_STEP`` (Gymnasium's default): the step after an episode ends resets that rig,
ignores its action and returns its first observation with reward 0 and no termination.
``SAME_STEP``: an ending rig is reset at once; its last observation and info are in
``info["final_obs"]`` / ``info["final_info"]`` (this is what stable-baselines3 expects, see
:mod:`drillgym.envs.sb3`).

Seeding: ``reset(seed=s)`` gives rig i the generator of seed s + i, so rig i reproduces a
single env reset with seed s + i (exactly: same code path, per-rig random streams).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ..errors import InputError
from .base import action_space
from .engine import EpisodeBatch
from .options import U_MAX, EnvOptions
from .rendering import RigRenderer

__all__ = ["DrillVectorEnv"]


class DrillVectorEnv(VectorEnv):
    """N drill-string environments (same options) stepped together in one batched core call.

    Spaces, reward and episode end per rig are those of :class:`drillgym.envs.DrillEnv`, batched:
    actions (N,) or (N, 1) (voltage / 5 V, or V with ``normalize_action=False``), observations
    (N, dim) float32, rewards, terminations and truncations (N,).  Info keys (arrays of length N,
    each with a ``_key`` mask): ``omega_l`` (rad/s), ``stuck``, ``friction_torque`` (N m),
    ``stick_slip_severity``, ``omega_ref`` (rad/s), ``voltage`` (V), ``time`` (s); ``termination`` (why,
    see :class:`drillgym.envs.DrillEnv`), masked by ``_termination`` to the rigs terminated in the step.
    A rig whose state becomes non-finite is terminated like one over a limit and autoreset the same way.
    ``reset(seed=s)`` seeds rig i with s + i, so rig i reproduces a single env reset with seed s + i.

    Parameters
    ----------
    num_envs : int
        Number of rigs N (>= 1).
    configuration : str, optional
        ``"torsional"``, ``"lateral"`` or ``"coupled"``.  Default ``"torsional"``.
    render_mode : str, optional
        ``"rgb_array"`` renders rig 0; None: no rendering.
    autoreset_mode : AutoresetMode or str, optional
        ``NEXT_STEP`` (default: the step after an episode ends resets that rig, ignores its action and
        returns its first observation with reward 0) or ``SAME_STEP`` (an ending rig is reset at once;
        its last observation and info are in ``info["final_obs"]`` / ``info["final_info"]``).
    **options
        Any field of :class:`drillgym.envs.options.EnvOptions`, the same for every rig.
    """

    metadata = {"render_modes": ["rgb_array"], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(
        self,
        num_envs: int,
        configuration: str = "torsional",
        *,
        render_mode: str | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        **options: Any,
    ) -> None:
        if not (isinstance(num_envs, (int, np.integer)) and num_envs >= 1):
            raise InputError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        try:
            mode = AutoresetMode(autoreset_mode)
        except ValueError:
            raise InputError(
                f"autoreset_mode must be AutoresetMode.NEXT_STEP ('NextStep') or AutoresetMode.SAME_STEP "
                f"('SameStep'), got {autoreset_mode!r}"
            ) from None
        if mode is AutoresetMode.DISABLED:
            raise InputError("autoreset_mode DISABLED is not supported; use NEXT_STEP or SAME_STEP")
        self.options = EnvOptions.from_kwargs(configuration=configuration, **options)
        self.num_envs = int(num_envs)
        self.batch = EpisodeBatch(self.options, self.num_envs)
        self.single_action_space = action_space(self.options.normalize_action)
        self.single_observation_space = self.batch.obs_model.space
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.metadata = dict(self.metadata, autoreset_mode=mode)
        self.autoreset_mode = mode
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise InputError(f"render_mode must be 'rgb_array' or None for the vector env, got {render_mode!r}")
        self.render_mode = render_mode
        self._renderer = (
            RigRenderer(render_mode, self.options.render_history, self.options.control_dt, self.options.lateral)
            if render_mode
            else None
        )
        self._scale = U_MAX if self.options.normalize_action else 1.0
        self._autoreset = np.zeros(self.num_envs, dtype=bool)
        self._mask = np.ones(self.num_envs, dtype=bool)

    @property
    def observation_names(self) -> tuple[str, ...]:
        """Layout of an observation row."""
        return self.batch.obs_model.names

    # ------------------------------------------------------------------------
    def reset(
        self, *, seed: int | Sequence[int | None] | None = None, options: dict | None = None
    ) -> tuple[np.ndarray, dict]:
        """Start an episode on every rig.

        Parameters
        ----------
        seed : int or sequence of int, optional
            One seed s (rig i gets s + i) or one per rig.
        options : dict, optional
            Unused (Gymnasium's signature).

        Returns
        -------
        observations : ndarray
            (N, dim) float32.
        infos : dict
            Arrays of length N with ``_key`` masks.
        """
        if seed is None or isinstance(seed, (int, np.integer)):
            super().reset(seed=None if seed is None else int(seed))
            seeds = [None] * self.num_envs if seed is None else [int(seed) + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise InputError(f"reset(seed=...) needs {self.num_envs} seeds, got {len(seeds)}")
        if seed is not None or self.batch.rngs[0] is None:
            self.batch.set_rngs([seeding.np_random(s)[0] for s in seeds])
        self.batch.reset()
        self._autoreset[:] = False
        if self._renderer is not None:
            self._renderer.clear()
            self._record()
        return self.batch.obs.copy(), self._infos()

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        """Hold each rig's voltage over one control period (one batched core call).

        Parameters
        ----------
        actions : array_like
            (N,) or (N, 1) voltages: / 5 V with ``normalize_action``, else in V.

        Returns
        -------
        observations : ndarray
            (N, dim) float32.
        rewards : ndarray
            (N,).
        terminations, truncations : ndarray
            (N,) booleans.
        infos : dict
            Arrays of length N with ``_key`` masks (with ``SAME_STEP`` autoreset, also ``final_obs`` and
            ``final_info`` of the rigs whose episode ended).

        Raises
        ------
        InputError
            Not N actions, or a non-finite one.
        """
        a = np.asarray(actions, dtype=np.float64)
        if a.size != self.num_envs:
            raise InputError(
                f"actions must hold {self.num_envs} voltages (shape ({self.num_envs},) or "
                f"({self.num_envs}, 1)), got shape {a.shape}"
            )
        a = a.reshape(self.num_envs)
        if not np.isfinite(a).all():
            bad = int(np.flatnonzero(~np.isfinite(a))[0])
            raise InputError(f"action (motor voltage) of env {bad} must be finite, got {a[bad]!r}")
        b = self.batch
        u = b.system.u
        np.multiply(a, self._scale, out=u)
        np.clip(u, -U_MAX, U_MAX, out=u)  # amplifier saturation
        if self.autoreset_mode is AutoresetMode.NEXT_STEP:
            pending = np.flatnonzero(self._autoreset)
            b.step(skip=self._autoreset if pending.size else None)
            if pending.size:
                b.reset(pending)
            np.logical_or(b.terminated, b.truncated, out=self._autoreset)
            infos = self._infos()
        else:
            b.step()
            done = np.flatnonzero(b.terminated | b.truncated)
            infos = self._infos()
            if done.size:
                final_obs = np.empty(self.num_envs, dtype=object)
                final_obs[done] = list(b.obs[done].copy())
                final_mask = np.zeros(self.num_envs, dtype=bool)
                final_mask[done] = True
                final_info = {k: v.copy() for k, v in infos.items()}
                term, trunc, rew = b.terminated, b.truncated, b.reward.copy()
                b.reset(done)
                infos = self._infos()
                infos.update(final_obs=final_obs, _final_obs=final_mask, final_info=final_info, _final_info=final_mask)
                obs = b.obs.copy()
                self._after_step()
                return obs, rew, term, trunc, infos
        self._after_step()
        return b.obs.copy(), b.reward.copy(), b.terminated, b.truncated, infos

    def _after_step(self) -> None:
        if self._renderer is not None:
            self._record()

    def _infos(self) -> dict:
        info = self.batch.info_arrays()
        for k in list(info):
            info["_" + k] = self._mask
        if "termination" in info:  # only the terminated rigs have a reason
            info["_termination"] = self.batch.terminated.copy()
        return info

    def _record(self) -> None:
        b = self.batch
        self._renderer.record(float(b.time[0]), float(b.system.omega_u[0]), float(b.system.omega_l[0]))

    def render(self) -> np.ndarray | None:
        """Rig 0 as an RGB image with ``render_mode="rgb_array"``, else None."""
        if self._renderer is None:
            return None
        s = self.batch.system
        X, Y = s.lateral_fixed
        return self._renderer.draw(
            float(s.theta_u[0]),
            float(s.theta_l[0]),
            float(X[0]),
            float(Y[0]),
            float(self.batch.omega_ref[0]),
            bool(s.stuck_l[0]),
        )

    def close_extras(self, **kwargs: Any) -> None:
        if self._renderer is not None:
            self._renderer.close()
