"""The Gymnasium environments of the drill-string rig.

All three share :class:`DrillEnv` (its docstring gives the spaces, reward and episode end); they
differ in the rig configuration (docs/model.md): ``drillgym/Torsional-v0`` (lateral motion held, brake on),
``drillgym/Lateral-v0`` (lateral motion free, brake off) and ``drillgym/Coupled-v0`` (lateral motion
free, brake on).  Options: :class:`drillgym.envs.options.EnvOptions`.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.envs.registration import EnvSpec

from ..errors import InputError
from .action import action_voltage
from .engine import C_REW, C_TERM, C_TRUNC, EpisodeBatch
from .options import U_MAX, EnvOptions
from .rendering import RigRenderer

__all__ = ["DrillEnv", "TorsionalEnv", "LateralEnv", "CoupledEnv", "action_space"]

_ROW0 = np.zeros(1, dtype=np.int64)


def _is_model(value: Any) -> bool:
    from ..model import Model

    return isinstance(value, Model)


def action_space(normalize: bool) -> spaces.Box:
    """The motor voltage's action space: Box [-5, 5] V, or [-1, 1] (x 5 V) when ``normalize`` is true."""
    hi = 1.0 if normalize else U_MAX
    return spaces.Box(-hi, hi, shape=(1,), dtype=np.float32)


class DrillEnv(gym.Env):
    """Hold the lower disc of the drill-string rig at ``omega_ref`` without stick-slip.

    One rig of the given configuration, driven by the motor voltage and stepped one control period
    (``control_dt``, 10 ms) at a time.  The voltage is held over the period and integrated in sub-steps
    of ``dt`` (default 10 ms: one event-driven RK4 step, accurate to < 2e-6 rad/s, see
    :data:`drillgym.envs.options.DEFAULT_ENV_DT`).  :class:`TorsionalEnv`, :class:`LateralEnv` and
    :class:`CoupledEnv` fix the configuration; :func:`drillgym.envs.make_vec` steps many rigs at once.

    Parameters
    ----------
    configuration : str, optional
        Rig configuration: ``"torsional"`` (lateral motion held, brake on), ``"lateral"`` (lower disc
        free to whirl, brake off) or ``"coupled"`` (both).  Default ``"torsional"``.
    render_mode : str, optional
        ``"human"`` (a window) or ``"rgb_array"`` (:meth:`render` returns an image); None: no rendering.
    **options
        Any field of :class:`drillgym.envs.options.EnvOptions` (observation mode, control period,
        target speed, episode length, limits, reward weights, domain randomisation, effects, sensor
        noise, ...).  Bad values raise :class:`drillgym.errors.InputError` naming the option.
        ``model=`` (a :class:`drillgym.Model` or a model file's path) runs that model's base parameters
        and effects (the same compiled composition as ``simulate(..., model=m)``); it is refused beside
        ``params``, ``effects`` or ``effect_params``.  With ``randomize`` the drawn parameters vary around
        the model's values.

    Notes
    -----
    **Action space.** ``Box(-1, 1, (1,), float32)``: the motor voltage / 5 V when ``normalize_action``
    is true (the default of the registered ids), else ``Box(-5, 5, (1,), float32)`` in V (the class's
    own default).  Out-of-range actions are clipped as the amplifier does; a NaN or infinite action
    raises :class:`drillgym.errors.InputError`.

    **Observation space** (float32; values are clipped into the Box).  ``observation="full"``, the true
    state:

    | Index | Observation                            | Min | Max | Unit  |
    |-------|----------------------------------------|-----|-----|-------|
    | 0     | ``omega_u``, upper disc speed          | -60 | 60  | rad/s |
    | 1     | ``omega_l``, lower disc speed          | -60 | 60  | rad/s |
    | 2     | ``alpha = theta_l - theta_u``, winding | -50 | 50  | rad   |
    | 3     | ``u_prev``, voltage of the last period | -5  | 5   | V     |
    | 4     | ``omega_ref``, target speed            | 0   | 30  | rad/s |

    The speed bounds are 2 ``max_speed`` (default 30 rad/s), the target's ``max_speed``.  The lateral and coupled
    configurations insert ``X``, ``Y`` (mm, fixed frame) and ``dX``, ``dY`` (mm/s) after ``alpha``.
    Dimensions per mode:

    | Id                      | full | sensors | motor  |
    |-------------------------|------|---------|--------|
    | drillgym/Torsional-v0   | 5    | 7       | 2H + 1 |
    | drillgym/Lateral-v0     | 9    | 9       | 2H + 1 |
    | drillgym/Coupled-v0     | 9    | 9       | 2H + 1 |

    ``"sensors"`` is what the rig measures (wrapped quantized encoder angles, measured winding, filtered
    speed estimates, LVDT readings, ``u_prev``, ``omega_ref``); ``"motor"`` only the motor encoder: the
    last H = ``motor_history`` (default 16) speed increments and voltages, then ``omega_ref``.  The
    layouts are in :mod:`drillgym.envs.observation`; :attr:`observation_names` names the entries.

    **Reward** per control period, with u the voltage over it (weights: option ``reward``,
    :class:`drillgym.envs.options.RewardWeights`; see :mod:`drillgym.envs.reward`)::

        r = -(|omega_l - omega_ref| / omega_ref + 0.5 stuck + 0.01 (u / 5 V)^2 + 0.05 ((u - u_prev) / 5 V)^2)

    **Starting state.** Rest, with initial winding ``alpha0`` drawn from U(``alpha0_range``) = U(-1, 1) rad;
    ``omega_ref`` drawn from U(``omega_ref_range``) = U(1, 8) rad/s, or fixed by ``omega_ref``; with
    ``randomize = x`` every parameter of ``randomize_names`` is drawn per episode in +/- x of its value.

    **Episode end.** Terminated when |omega_u| or |omega_l| exceeds ``max_speed`` (30 rad/s), the lateral
    displacement r exceeds ``max_lateral`` (20 mm), or a state is no longer finite (an effect's formula gave
    NaN or inf: the observation, the reward and the info values are then the last finite ones).
    Truncated after ``episode_duration`` (30 s = 3000
    steps, ``env.spec.max_episode_steps``); the env truncates itself (no ``TimeLimit`` wrapper).

    **Info.** ``omega_l`` (rad/s), ``stuck`` (lower disc stuck), ``friction_torque`` (lower friction,
    N m), ``stick_slip_severity`` (running severity over ``ssi_window`` = 5 s), ``omega_ref`` (rad/s),
    ``voltage`` (V), ``time`` (s); when terminated, ``termination``: why, in one line naming the state, its
    value, the limit and the time (``"over-speed: omega_l = 31.2 rad/s beyond max_speed = 30 rad/s at t =
    4.56 s"``, ``"lateral displacement: ..."``, ``"non-finite state: omega_l = nan, ... in the control period
    ending at t = 0.5 s ..."``).

    Examples
    --------
    >>> import gymnasium, drillgym
    >>> env = gymnasium.make("drillgym/Torsional-v0", observation="sensors", omega_ref=4.0)
    >>> obs, info = env.reset(seed=0)
    >>> obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    >>> env = gymnasium.make("drillgym/Torsional-v0", model=drillgym.Model.load("out/model.json"))
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 25}
    _spec: EnvSpec | None = None

    @property
    def spec(self) -> EnvSpec | None:
        """The registration spec (set by ``gymnasium.make``) with ``max_episode_steps`` = this env's
        episode length in steps (``episode_duration / control_dt``; the env truncates there itself)."""
        return self._spec

    @spec.setter
    def spec(self, value: EnvSpec | None) -> None:
        if value is not None and value.max_episode_steps != self.options.episode_steps:
            value = dataclasses.replace(value, max_episode_steps=self.options.episode_steps)
        if value is not None and _is_model(value.kwargs.get("model")) and "task" not in value.kwargs:
            # a Model object in the spec's kwargs does not pickle: its parts do, and make the same env
            kw = {k: v for k, v in value.kwargs.items() if k != "model"}
            o = self.options
            kw.update(params=o.params, effects=o.effects.specs(), effect_params=dict(o.effect_params))
            value = dataclasses.replace(value, kwargs=kw)
        self._spec = value

    def __init__(self, configuration: str = "torsional", render_mode: str | None = None, **options: Any) -> None:
        self.options = EnvOptions.from_kwargs(configuration=configuration, **options)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise InputError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        self.render_mode = render_mode
        self.batch = EpisodeBatch(self.options, 1)
        self.action_space = action_space(self.options.normalize_action)
        self.observation_space = self.batch.obs_model.space
        self._scale = 1.0 if not self.options.normalize_action else U_MAX
        self._high = float(self.action_space.high[0])
        self._u = self.batch.system.u  # (1,) voltage buffer of the core
        self._renderer = (
            RigRenderer(render_mode, self.options.render_history, self.options.control_dt, self.options.lateral)
            if render_mode
            else None
        )

    @property
    def observation_names(self) -> tuple[str, ...]:
        """Layout of the observation vector."""
        return self.batch.obs_model.names

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        """Start an episode from rest with a new target and initial winding.

        Parameters
        ----------
        seed : int, optional
            Seed of the episode's random draws (target, winding, randomised parameters, sensor noise).
        options : dict, optional
            Unused (Gymnasium's signature).

        Returns
        -------
        observation : ndarray
            The first observation (float32).
        info : dict
            The info keys of the class docstring.
        """
        super().reset(seed=seed)
        b = self.batch
        b.rngs[0] = self.np_random
        b.reset(_ROW0)
        if self._renderer is not None:
            self._renderer.clear()
            self._record()
            if self.render_mode == "human":
                self.render()
        return b.obs[0].copy(), self._info()

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict]:
        """Hold the action's voltage over one control period.

        Parameters
        ----------
        action : array_like
            One voltage, shape (1,) or a scalar: / 5 V with ``normalize_action``, else in V.

        Returns
        -------
        observation : ndarray
            The observation at the end of the period (float32).
        reward : float
            The period's reward.
        terminated : bool
            A speed or the lateral displacement left its limits, or a state is not finite (``info["termination"]``
            says which).
        truncated : bool
            The episode reached ``episode_duration``.
        info : dict
            The info keys of the class docstring.

        Raises
        ------
        InputError
            An action that is not one finite number.
        """
        v = action_voltage(action, self._high) * self._scale
        self._u[0] = U_MAX if v > U_MAX else (-U_MAX if v < -U_MAX else v)  # amplifier saturation
        b = self.batch
        b.step()
        if self._renderer is not None:
            self._record()
            if self.render_mode == "human":
                self.render()
        v = b.S[0].tolist()
        return b.obs[0].copy(), v[C_REW], v[C_TERM] > 0.5, v[C_TRUNC] > 0.5, b.info_row(0, v)

    def _info(self) -> dict:
        return self.batch.info_row(0)

    def _record(self) -> None:
        b = self.batch
        self._renderer.record(float(b.time[0]), float(b.system.omega_u[0]), float(b.system.omega_l[0]))

    def render(self) -> np.ndarray | None:
        """The rig drawn from above with a strip chart of the speeds (``"rgb_array"``: an RGB image)."""
        if self._renderer is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
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

    def close(self) -> None:
        """Close the render window, if any."""
        if self._renderer is not None:
            self._renderer.close()


class TorsionalEnv(DrillEnv):
    """Torsional configuration (``drillgym/Torsional-v0``): lateral motion held, brake on (stick-slip).

    Spaces, reward and episode end as :class:`DrillEnv`; the 'full' observation has 5 entries.

    Parameters
    ----------
    render_mode : str, optional
        ``"human"``, ``"rgb_array"`` or None, as :class:`DrillEnv`.
    **options
        Any field of :class:`drillgym.envs.options.EnvOptions`.
    """

    def __init__(self, render_mode: str | None = None, **options: Any) -> None:
        super().__init__("torsional", render_mode, **options)


class LateralEnv(DrillEnv):
    """Lateral configuration (``drillgym/Lateral-v0``): lower disc free to whirl, brake off (bearing friction).

    Observation ('full'): omega_u, omega_l, alpha, X, Y (mm), dX, dY (mm/s), u_prev, omega_ref.
    Terminated also when r = sqrt(X^2 + Y^2) > ``max_lateral``.  Otherwise as :class:`DrillEnv`.

    Parameters
    ----------
    render_mode : str, optional
        ``"human"``, ``"rgb_array"`` or None, as :class:`DrillEnv`.
    **options
        Any field of :class:`drillgym.envs.options.EnvOptions`.
    """

    def __init__(self, render_mode: str | None = None, **options: Any) -> None:
        super().__init__("lateral", render_mode, **options)


class CoupledEnv(DrillEnv):
    """Coupled configuration (``drillgym/Coupled-v0``): lateral whirl and brake stick-slip together.

    Observation ('full'): omega_u, omega_l, alpha, X, Y (mm), dX, dY (mm/s), u_prev, omega_ref.
    Terminated also when r = sqrt(X^2 + Y^2) > ``max_lateral``.  Otherwise as :class:`DrillEnv`.

    Parameters
    ----------
    render_mode : str, optional
        ``"human"``, ``"rgb_array"`` or None, as :class:`DrillEnv`.
    **options
        Any field of :class:`drillgym.envs.options.EnvOptions`.
    """

    def __init__(self, render_mode: str | None = None, **options: Any) -> None:
        super().__init__("coupled", render_mode, **options)
