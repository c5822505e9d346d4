"""n episodes of the task stepped together: the machinery shared by the single env (n = 1)
and the vector env, so both follow exactly the same code path.

One control period is ONE compiled call (:mod:`.period_kernel`, specialised for the rig's
composition of effects): the core's ``advance_batch``
(voltage held over the sub-steps, all rigs), then per rig the reward (:mod:`.reward`), the
stick-slip severity and safety limits (:mod:`.task`) and, in 'full' mode, the observation
(:mod:`.observation`).  The 'sensors' and 'motor' observations are a second compiled call
(:mod:`.sensor_kernel`, specialised for the composition: its Measurement effects, then the
encoders and LVDTs).  Keeping the Python work per period this small is what makes a
single env faster than Pendulum-v1 in every mode.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .columns import (
    C_REF,
    C_REW,
    C_SSI,
    C_STEPS,
    C_STUCK,
    C_TERM,
    C_TFL,
    C_TIME,
    C_TRUNC,
    C_U,
    C_WL,
    INFO_COLUMNS,
    S_COLUMNS,
    TERM_NONFINITE,
)
from .observation import make_observation_model
from .options import EnvOptions
from .rig_system import ParameterRandomizer, RigSystem
from .task import SpeedTrackingTask, StickSlipMonitor

__all__ = ["EpisodeBatch", "INFO_COLUMNS", "S_COLUMNS"]


class EpisodeBatch:
    """State and results of n concurrent episodes.

    Inputs: ``system.u`` (n,) voltages (V, finite, clipped) written by the env before :meth:`step`;
    ``rngs`` one ``numpy.random.Generator`` per rig (episode draws and sensor noise).
    Outputs after :meth:`reset` / :meth:`step`: ``obs`` (n, dim) float32 and ``S`` (n, 11), the
    quantities of ``S_COLUMNS``: voltage applied over the last period (V), omega_ref (rad/s),
    reward, stick-slip severity, omega_l (rad/s), lower friction torque (N m), stuck (0/1),
    time (s), steps, terminated (0: running, 1: a safety limit, 2: a non-finite state), truncated (0/1).
    :meth:`termination_reason` says why a rig's episode was terminated.
    """

    def __init__(self, options: EnvOptions, n: int) -> None:
        o = options
        self.options = o
        self.n = int(n)
        self.system = RigSystem(
            o.configuration,
            self.n,
            params=o.rig_params,
            dt=o.dt,
            n_substeps=o.n_substeps,
            method=o.method,
            friction=o.friction,
            effects=o.effects,
            effect_params=o.effect_params,
        )
        self.randomizer = ParameterRandomizer(
            self.system.params_matrix[0], o.randomize, o.randomize_names, self.system.composition
        )
        self._period_kernel = self.system.composition.kernels.client("drillgym.envs.period_kernel").period_kernel
        self.task = SpeedTrackingTask(o)
        self.obs_model = make_observation_model(self.n, o, self.system.params_matrix)  # live: randomised rows
        self.monitor = StickSlipMonitor(self.n, o.ssi_window, o.control_dt)
        self.rngs: list = [None] * self.n
        #: the listed plant each rig's episode runs (its index in the list of a
        #: :class:`drillgym.envs.tasks.PlantListRandomizer`); -1 when the rig's parameters are not drawn from a list
        self.plant_index = np.full(self.n, -1, dtype=np.int64)
        self.S = np.zeros((self.n, len(S_COLUMNS)))
        self.obs = np.zeros((self.n, self.obs_model.dim), dtype=np.float32)
        self._obs_prev = np.zeros_like(self.obs)  # the last observations, kept for a rig whose state is not finite
        self.all = np.arange(self.n)
        w, om = o.reward, self.obs_model
        self._tv = np.concatenate(
            [
                [
                    w.track,
                    w.stick,
                    w.effort,
                    w.rate,
                    o.max_speed,
                    o.max_lateral,
                    float(o.lateral),
                    self.task.max_steps,
                    self.monitor.block_len,
                    o.control_dt,
                    float(om.compiled),
                ],
                om.low,
                om.high,
            ]
        )
        self._bind()

    def _bind(self) -> None:
        """The period kernel's arguments (the system's persistent arrays, then the episode arrays)."""
        self._system_args = self.system.kernel_args
        self._kernel_args = (*self._system_args, self.S, self.monitor.W, self.monitor.C, self._tv, self.obs)

    # ------------------------------------------------------------------------
    def reset(self, index: np.ndarray | None = None) -> None:
        """Start new episodes for rigs ``index`` (default all), drawing from their generators:
        omega_ref, alpha0, then (domain randomisation) the parameters, then sensor noise."""
        index = self.all if index is None else np.asarray(index, dtype=np.int64)
        alpha0 = np.empty(index.size)
        params = np.empty((index.size, self.system.params_matrix.shape[1])) if self.randomizer.active else None
        for j, i in enumerate(index):
            rng = self.rngs[i]
            if rng is None:
                raise RuntimeError(f"rig {i} has no random generator; seed the environment with reset()")
            self.S[i, C_REF], alpha0[j] = self.task.sample(rng)
            if params is not None:
                params[j] = self.randomizer.sample(rng, float(self.S[i, C_REF]))
                self.plant_index[i] = getattr(self.randomizer, "last_index", -1)
        s = self.system
        s.reset(index, alpha0, params)
        if s.kernel_args is not self._system_args:  # delay lines lengthened for a drawn delay
            self._bind()
        S = self.S
        for col in (C_U, C_REW, C_SSI, C_TIME, C_STEPS, C_TERM, C_TRUNC):
            S[index, col] = 0.0
        S[index, C_WL] = s.omega_l[index]
        S[index, C_TFL] = s.friction_l[index]
        S[index, C_STUCK] = s.stuck_l[index]
        self.monitor.reset(index)
        self.obs_model.reset(index, s.Y, self.rngs)
        self.obs[index] = self.obs_model.initial(index, s.Y, S[:, C_REF])

    def step(self, skip: np.ndarray | None = None) -> None:
        """One control period for every rig at the voltages ``system.u``.  Rigs flagged in
        ``skip`` (about to be reset by the caller) draw no random numbers."""
        self._period_kernel(*self._kernel_args)
        if not self.obs_model.compiled:
            S = self.S
            np.copyto(self._obs_prev, self.obs)
            self.obs_model.observe(self.system.Y, S[:, C_U], S[:, C_REF], self.obs, self.rngs, skip)
            bad = S[:, C_TERM] == TERM_NONFINITE
            if bad.any():  # the compiled 'full' observation keeps the last finite one itself
                self.obs[bad] = self._obs_prev[bad]

    # ------------------------------------------------------------------------
    @property
    def reward(self) -> np.ndarray:
        return self.S[:, C_REW]

    @property
    def omega_ref(self) -> np.ndarray:
        return self.S[:, C_REF]

    @property
    def time(self) -> np.ndarray:
        return self.S[:, C_TIME]

    @property
    def terminated(self) -> np.ndarray:
        return self.S[:, C_TERM] > 0.5

    @property
    def truncated(self) -> np.ndarray:
        return self.S[:, C_TRUNC] > 0.5

    def termination_reason(self, k: int) -> str:
        """Why rig ``k``'s episode was terminated, one line naming the state, its value, the limit and the time.

        Parameters
        ----------
        k : int
            The rig.

        Returns
        -------
        str
            ``"non-finite state: omega_l = nan, ... at t = 1.23 s (...)"``, ``"over-speed: ..."`` or
            ``"lateral displacement: ..."``; empty when the episode was not terminated.
        """
        code, t = self.S[k, C_TERM], self.S[k, C_TIME]
        y = self.system.Y[k]
        if code == TERM_NONFINITE:
            names = self.system.composition.full_state_names
            bad = [f"{n} = {float(v)}" for n, v in zip(names, y) if not np.isfinite(v)]
            return (
                f"non-finite state: {', '.join(bad)} in the control period ending at t = {t:.6g} s "
                "(the model's formulas, an effect's, gave NaN or inf; observation and reward are the last finite ones)"
            )
        if code < 0.5:
            return ""
        o = self.options
        for name, w in (("omega_u", y[2]), ("omega_l", y[3])):
            if abs(w) > o.max_speed:
                return f"over-speed: {name} = {w:.4g} rad/s beyond max_speed = {o.max_speed:g} rad/s at t = {t:.6g} s"
        r = float(np.hypot(y[4], y[5]))
        return (
            f"lateral displacement: r = {r * 1e3:.4g} mm beyond max_lateral = {o.max_lateral * 1e3:g} mm "
            f"at t = {t:.6g} s"
        )

    def info_arrays(self) -> dict[str, np.ndarray]:
        """Info entries of all rigs (copies): omega_l (rad/s), stuck (bool), friction_torque (N m, lower
        disc), stick_slip_severity, omega_ref (rad/s), voltage (V, applied over the last period), time (s);
        with ``termination`` (str, empty for a running rig) when a rig's episode was terminated."""
        S = self.S
        info = {
            "omega_l": S[:, C_WL].copy(),
            "stuck": S[:, C_STUCK] > 0.5,
            "friction_torque": S[:, C_TFL].copy(),
            "stick_slip_severity": S[:, C_SSI].copy(),
            "omega_ref": S[:, C_REF].copy(),
            "voltage": S[:, C_U].copy(),
            "time": S[:, C_TIME].copy(),
        }
        done = np.flatnonzero(S[:, C_TERM] > 0.5)
        if done.size:
            reasons = np.full(self.n, "", dtype=object)
            for k in done:
                reasons[k] = self.termination_reason(int(k))
            info["termination"] = reasons
        return info

    def info_row(self, k: int, v: list | None = None) -> dict:
        """Info of rig k as Python scalars (the single env's ``info``); ``v`` = ``S[k].tolist()`` if known."""
        if v is None:
            v = self.S[k].tolist()
        info = {
            "omega_l": v[C_WL],
            "stuck": v[C_STUCK] > 0.5,
            "friction_torque": v[C_TFL],
            "stick_slip_severity": v[C_SSI],
            "omega_ref": v[C_REF],
            "voltage": v[C_U],
            "time": v[C_TIME],
        }
        if v[C_TERM] > 0.5:
            info["termination"] = self.termination_reason(k)
        return info

    def set_rngs(self, rngs: Sequence[np.random.Generator]) -> None:
        if len(rngs) != self.n:
            raise ValueError(f"need {self.n} random generators, got {len(rngs)}")
        self.rngs = list(rngs)
