"""Constructor options shared by the single and the vectorised environments.

Every option of ``gymnasium.make("drillgym/Torsional-v0", **options)`` and of
:func:`drillgym.envs.make_vec` is a field of :class:`EnvOptions`; bad values
raise :class:`drillgym.errors.InputError` naming the option.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Any

from ..configurations import Configuration, parse_configuration
from ..errors import InputError
from ..measurement import DEFAULT_COUNTS_PER_REV, DEFAULT_LVDT_NOISE
from ..params import BASE_PARAMETERS, RigParams

__all__ = ["EnvOptions", "RewardWeights", "OBSERVATION_MODES", "DEFAULT_ENV_DT", "U_MAX"]

#: Amplifier range of the motor voltage (V).
U_MAX = 5.0
#: Integration step of the environments (s), default min(10 ms, control_dt): one RK4 step per
#: control period.  The core's event-driven RK4 locates every stick/slip switch inside the step,
#: and the smooth dynamics are slow (fastest: the lateral mode, 15 rad/s), so 10 ms agrees with
#: 1 ms over 30 s from rest to max |d omega_l| = 5.5e-8 rad/s (torsional 1 V), 1.6e-7 (coupled
#: 1 V), 1.4e-6 rad/s and |dr| = 1e-8 m (coupled 5 V), 3.4e-7 rad/s (lateral 5 V); stick fractions
#: agree to 3 decimals.  It costs half of dt = 5 ms per env step.
DEFAULT_ENV_DT = 1e-2
OBSERVATION_MODES = ("full", "sensors", "motor")
_ENV_CONFIGURATIONS = (Configuration.TORSIONAL, Configuration.LATERAL, Configuration.COUPLED)


@dataclass(frozen=True)
class RewardWeights:
    """Weights of the reward terms (see :mod:`drillgym.envs.reward`); all >= 0.

    Parameters
    ----------
    track : float, optional
        Weight of the relative tracking error ``|omega_l - omega_ref| / omega_ref``.  Default 1.
    stick : float, optional
        Weight of the lower disc being stuck at the end of the control period.  Default 0.5.
    effort : float, optional
        Weight of ``(u / 5 V)^2``.  Default 0.01.
    rate : float, optional
        Weight of ``((u - u_prev) / 5 V)^2``.  Default 0.05.
    """

    track: float = 1.0  # |omega_l - omega_ref| / omega_ref
    stick: float = 0.5  # lower disc stuck at the end of the control period
    effort: float = 0.01  # (u / 5 V)^2
    rate: float = 0.05  # ((u - u_prev) / 5 V)^2

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise InputError(f"reward weight {f.name!r} must be a finite number >= 0, got {v!r}")


def _range(name: str, value: Any, lo: float = -math.inf, positive: bool = False) -> tuple[float, float]:
    try:
        a, b = (float(v) for v in value)
    except (TypeError, ValueError):
        raise InputError(f"option {name!r} must be a pair (low, high), got {value!r}") from None
    if not (math.isfinite(a) and math.isfinite(b) and a <= b and a >= lo and (not positive or a > 0)):
        raise InputError(
            f"option {name!r} must be a finite pair low <= high{' with low > 0' if positive else ''}, got {value!r}"
        )
    return a, b


@dataclass(frozen=True)
class EnvOptions:
    """All options of the drill-string environments (SI units unless stated).

    Every keyword of ``gymnasium.make("drillgym/Torsional-v0", **options)``, of
    :func:`drillgym.envs.make_vec` and of :class:`drillgym.envs.DrillVectorEnv` is a field here; a bad
    value raises :class:`drillgym.errors.InputError` naming the option.

    Parameters
    ----------
    configuration : str, optional
        Rig configuration: ``"torsional"``, ``"lateral"`` or ``"coupled"``.
    observation : str, optional
        Observation mode: ``"full"`` (true state), ``"sensors"`` (what the rig measures) or ``"motor"``
        (the motor encoder only), see :mod:`drillgym.envs.observation`.
    model : Model, str or path, optional
        The rig's model (:class:`drillgym.Model` or the path of a model file, read with
        :meth:`drillgym.Model.load` without ``trust``): its base parameters, effects and effect values,
        run through the same compiled composition as ``simulate(..., model=m)``.  Refused beside
        ``params``, ``effects`` or ``effect_params`` (the model holds its own).  It is resolved into
        those three fields (the field then reads None; :attr:`rig_model` gives the model back); the
        encoders it carries (:attr:`drillgym.Model.encoders`) set ``counts_per_rev`` unless it is given.
    params : RigParams, optional
        Parameter set of the rig; default the identified set.
    randomize : float, optional
        Domain randomisation, a fraction in [0, 1): each parameter of ``randomize_names`` is drawn per
        episode uniformly in +/- ``randomize`` times its value.  Default 0 (off).
    randomize_names : tuple of str, optional
        Parameters drawn by ``randomize``; default every base parameter.  Effect parameters may be named.
    effects : optional
        Effects added to the base model: names, ``"path/to/file.py:NAME"``, Effect classes or instances
        (see :mod:`drillgym.effects`); the rigs then run that compiled model.
    effect_params : dict, optional
        The effects' parameter values by name; default each parameter's own.
    control_dt : float, optional
        Control period (s), the voltage held over it.  Default 0.01.
    dt : float, optional
        Integration step (s); must divide ``control_dt``.  Default ``min(10 ms, control_dt)``.
    method : str, optional
        Integration method, ``"rk4"`` or ``"dp5"``.
    friction : str, optional
        Friction model, ``"exact"`` (set-valued) or ``"smooth"``.
    normalize_action : bool, optional
        Action in [-1, 1] (x 5 V) instead of [-5, 5] V.  False here; the registered ids set True.
    omega_ref : float, optional
        Fixed target speed of the lower disc (rad/s); None: drawn per episode from ``omega_ref_range``.
    omega_ref_range : tuple of float, optional
        Range (low, high) of the drawn target speed (rad/s).  Default (1, 8).
    alpha0_range : tuple of float, optional
        Range (low, high) of the initial winding (rad).  Default (-1, 1).
    episode_duration : float, optional
        Episode length (s) before truncation.  Default 30.
    max_speed : float, optional
        Termination when |omega_u| or |omega_l| exceeds it (rad/s).  Default 30.
    max_lateral : float, optional
        Termination when the lateral displacement r exceeds it (m).  Default 0.02.
    reward : RewardWeights or dict, optional
        Weights of the reward terms, see :class:`RewardWeights`.
    ssi_window : float, optional
        Window (s) of the running stick-slip severity reported in the info.  Default 5.
    counts_per_rev : int, optional
        Encoder resolution (counts per revolution, both discs; 0: exact angles).  Default: the model's
        encoders' (``model`` carrying :class:`drillgym.Encoders` with a count), else 8000.
    lvdt_noise_std : float, optional
        LVDT noise (m, standard deviation).  Default 3e-6.
    velocity_filter_tau : float, optional
        Time constant (s) of the first-order filter of the encoder speed estimate (0: raw differences).
        Default 0.02.
    motor_history : int, optional
        Number of past control periods H in the ``"motor"`` observation.  Default 16.
    render_history : float, optional
        Length (s) of the rendered strip chart.  Default 10.
    """

    configuration: str = "torsional"
    observation: str = "full"
    model: Any = None
    params: RigParams | None = None
    randomize: float = 0.0
    randomize_names: tuple = BASE_PARAMETERS
    effects: Any = None
    effect_params: Any = None
    control_dt: float = 0.01
    dt: float | None = None
    method: str = "rk4"
    friction: str = "exact"
    normalize_action: bool = False
    omega_ref: float | None = None
    omega_ref_range: tuple = (1.0, 8.0)
    alpha0_range: tuple = (-1.0, 1.0)
    episode_duration: float = 30.0
    max_speed: float = 30.0
    max_lateral: float = 0.02
    reward: RewardWeights = field(default_factory=RewardWeights)
    ssi_window: float = 5.0
    counts_per_rev: int | None = None
    lvdt_noise_std: float = DEFAULT_LVDT_NOISE
    velocity_filter_tau: float = 0.02
    motor_history: int = 16
    render_history: float = 10.0

    def __post_init__(self) -> None:
        cfg = parse_configuration(self.configuration)
        if cfg not in _ENV_CONFIGURATIONS:
            raise InputError(
                f"option 'configuration' must be torsional, lateral or coupled, got {self.configuration!r}"
            )
        object.__setattr__(self, "configuration", cfg.label)
        if self.observation not in OBSERVATION_MODES:
            raise InputError(f"option 'observation' must be one of {OBSERVATION_MODES}, got {self.observation!r}")
        effects_option = "option 'effects'"
        counts = DEFAULT_COUNTS_PER_REV
        if self.model is not None:  # resolved into params, effects, effect_params (refused beside them)
            from ..model import as_model, model_arguments

            effects_option = "option 'model': the model's effects"
            model = as_model(self.model, who="option 'model'")
            if model.encoders is not None and model.encoders.counts_per_rev is not None:
                counts = model.encoders.counts_per_rev
            p, e, v = model_arguments(model, self.params, self.effects, self.effect_params, "option 'model'", cfg.label)
            for name, value in (("params", p), ("effects", e), ("effect_params", v), ("model", None)):
                object.__setattr__(self, name, value)
        if self.counts_per_rev is None:
            object.__setattr__(self, "counts_per_rev", counts)
        if self.params is not None and not isinstance(self.params, RigParams):
            raise InputError(f"option 'params' must be a RigParams, got {type(self.params).__name__}")
        self._positive("control_dt", self.control_dt, hi=1.0)
        if self.dt is None:
            object.__setattr__(self, "dt", min(DEFAULT_ENV_DT, float(self.control_dt)))
        self._positive("dt", self.dt, hi=0.1)
        n_sub = round(self.control_dt / self.dt)
        if n_sub < 1 or abs(n_sub * self.dt - self.control_dt) > 1e-9 * max(1.0, self.control_dt):
            raise InputError(f"option 'dt' ({self.dt}) must divide 'control_dt' ({self.control_dt}) exactly")
        if self.method not in ("rk4", "dp5"):
            raise InputError(f"option 'method' must be 'rk4' or 'dp5', got {self.method!r}")
        if self.friction not in ("exact", "smooth"):
            raise InputError(f"option 'friction' must be 'exact' or 'smooth', got {self.friction!r}")
        if not (isinstance(self.randomize, (int, float)) and 0.0 <= self.randomize < 1.0):
            raise InputError(f"option 'randomize' must be a fraction in [0, 1), got {self.randomize!r}")
        from ..effects.composition import compose

        comp, values = compose(self.effects, self.effect_params)
        comp.refuse_not_acting(cfg.label, effects_option)
        object.__setattr__(self, "effects", comp)
        object.__setattr__(self, "effect_params", dict(values))
        unknown = [n for n in self.randomize_names if n not in comp.param_names]
        if unknown:
            raise InputError(f"option 'randomize_names' has unknown parameters: {unknown}")
        object.__setattr__(self, "randomize_names", tuple(self.randomize_names))
        rng = _range("omega_ref_range", self.omega_ref_range, lo=0.0, positive=True)
        object.__setattr__(self, "omega_ref_range", rng)
        if self.omega_ref is not None:
            self._positive("omega_ref", self.omega_ref, hi=self.max_speed)
        object.__setattr__(self, "alpha0_range", _range("alpha0_range", self.alpha0_range))
        self._positive("episode_duration", self.episode_duration)
        if self.episode_duration < self.control_dt:
            raise InputError("option 'episode_duration' must be at least one control period")
        self._positive("max_speed", self.max_speed)
        if self.omega_ref is None and rng[1] > self.max_speed:
            raise InputError("option 'omega_ref_range' must lie below 'max_speed'")
        self._positive("max_lateral", self.max_lateral)
        if isinstance(self.reward, dict):
            object.__setattr__(self, "reward", RewardWeights(**self.reward))
        elif not isinstance(self.reward, RewardWeights):
            raise InputError(f"option 'reward' must be RewardWeights or a dict, got {self.reward!r}")
        self._positive("ssi_window", self.ssi_window)
        if not (isinstance(self.counts_per_rev, int) and self.counts_per_rev >= 0):
            raise InputError(
                f"option 'counts_per_rev' must be an integer >= 0 (0 = exact), got {self.counts_per_rev!r}"
            )
        if not (math.isfinite(self.lvdt_noise_std) and self.lvdt_noise_std >= 0):
            raise InputError(f"option 'lvdt_noise_std' must be >= 0 m, got {self.lvdt_noise_std!r}")
        if not (math.isfinite(self.velocity_filter_tau) and self.velocity_filter_tau >= 0):
            raise InputError(f"option 'velocity_filter_tau' must be >= 0 s, got {self.velocity_filter_tau!r}")
        if not (isinstance(self.motor_history, int) and self.motor_history >= 1):
            raise InputError(f"option 'motor_history' must be an integer >= 1, got {self.motor_history!r}")
        self._positive("render_history", self.render_history)

    @staticmethod
    def _positive(name: str, value: Any, hi: float = math.inf) -> None:
        if not (isinstance(value, (int, float)) and math.isfinite(value) and 0 < value <= hi):
            raise InputError(f"option {name!r} must be a number in (0, {hi}], got {value!r}")

    # derived quantities ---------------------------------------------------------------
    @property
    def config(self) -> Configuration:
        return parse_configuration(self.configuration)

    @property
    def lateral(self) -> bool:
        """True when the lower disc moves laterally (LVDT signals exist)."""
        return self.config.lateral_free

    @property
    def n_substeps(self) -> int:
        return int(round(self.control_dt / self.dt))

    @property
    def episode_steps(self) -> int:
        return int(round(self.episode_duration / self.control_dt))

    @property
    def rig_params(self) -> RigParams:
        return self.params if self.params is not None else RigParams()

    @property
    def rig_model(self):
        """The rigs' model (:class:`drillgym.Model`): base parameters, effects and their values."""
        from ..model import Model

        return Model.from_composition(self.rig_params, self.effects, dict(self.effect_params))

    @classmethod
    def from_kwargs(cls, **kwargs: Any) -> EnvOptions:
        """Options from keyword arguments.

        Parameters
        ----------
        **kwargs
            Fields of :class:`EnvOptions` by name.

        Returns
        -------
        EnvOptions
            The validated options.

        Raises
        ------
        InputError
            An unknown option (all valid names are listed) or a bad value.
        """
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(kwargs) - names)
        if unknown:
            raise InputError(f"unknown environment option(s) {unknown}; valid: {sorted(names)}")
        return cls(**kwargs)
