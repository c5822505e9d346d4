"""Run controllers and policies on the hardware environment (``drillgym rig run``).

* Controllers follow the interface of :mod:`controllers.base`: ``reset(measurement)`` then
  ``controller(measurement) -> volts`` once per control period, ``measurement`` a mapping
  with ``t, theta_u, theta_l, x, y, omega_ref`` (SI units).  ``const:V`` is built in
  (:class:`ConstantController`); other names come from the ``controllers`` package
  (imported only when asked for).
* Policies map the observation vector to the action.  A ``.npz`` file with ``W`` (1, dim)
  and ``b`` (1,) is a built-in :class:`LinearPolicy`; anything else is loaded by the
  ``agents`` package (imported only when asked for).
"""

from __future__ import annotations

import importlib
import math
import zipfile
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from drillgym.errors import DataFormatError, InputError, MissingFileError, UnavailableError

__all__ = [
    "ConstantController",
    "PlaybackController",
    "LinearPolicy",
    "make_controller",
    "load_policy",
    "measurement_of",
    "run_episode",
    "EpisodeResult",
]


class ConstantController:
    """A constant voltage, whatever the measurements: ``const:2.0``.

    Parameters
    ----------
    volts : float
        The voltage (V).
    """

    name = "const"

    def __init__(self, volts: float) -> None:
        self.volts = float(volts)

    def reset(self, measurement: Mapping[str, float] | None = None) -> None:
        """Nothing to reset (the controller interface's method)."""

    def __call__(self, measurement: Mapping[str, float]) -> float:
        return self.volts


class PlaybackController:
    """Plays an input file (``t, u``, docs/data_format.md; e.g. ``drillgym signal``) sample-and-hold against
    the episode's time, 0 V after its end: ``play:est.csv`` records an excitation run for
    ``drillgym identify``.

    Parameters
    ----------
    path : str or path
        The input file.

    Raises
    ------
    MissingFileError
        The file does not exist.
    DataFormatError
        The file cannot be read, has no samples or non-finite voltages.
    """

    name = "play"

    def __init__(self, path: str | Path) -> None:
        from drillgym.signals import read_input_file

        path = Path(path)
        if not path.is_file():
            raise MissingFileError(f"controller play:{path}: no such input file")
        try:
            self.t, self.u = read_input_file(path)
        except (OSError, ValueError, KeyError) as exc:
            raise DataFormatError(f"controller play:{path}: not a readable input file ({exc})") from None
        if self.t.size == 0 or not np.all(np.isfinite(self.u)):
            raise DataFormatError(f"controller play:{path}: the input has no samples or non-finite voltages")
        self.path = path

    def reset(self, measurement: Mapping[str, float] | None = None) -> None:
        """Nothing to reset: the playback follows the episode's time ``t``."""

    def __call__(self, measurement: Mapping[str, float]) -> float:
        t = float(measurement.get("t", 0.0))
        if t > self.t[-1]:
            return 0.0
        k = int(np.searchsorted(self.t, t + 1e-12, side="right")) - 1
        return float(self.u[max(k, 0)])


@dataclass(frozen=True)
class LinearPolicy:
    """action = W @ obs + b (deterministic; the env clips it to the action space).

    Parameters
    ----------
    W : ndarray
        Weights (act_dim, obs_dim).
    b : ndarray
        Offsets (act_dim,).
    """

    W: np.ndarray
    b: np.ndarray

    @classmethod
    def load(cls, path: str | Path) -> LinearPolicy:
        """The policy in a ``.npz`` with arrays ``W`` and ``b``; InputError when they are missing or disagree."""
        try:
            z = np.load(path, allow_pickle=False)
        except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
            raise InputError(
                f"{path}: not a linear policy file (.npz with arrays W and b; numpy could not read it: "
                f"{npz_problem(exc)})"
            ) from None
        if not hasattr(z, "files"):  # a single .npy array
            raise InputError(f"{path}: a linear policy file needs arrays 'W' (1, obs_dim) and 'b' (1,)")
        with z:
            if "W" not in z or "b" not in z:
                raise InputError(f"{path}: a linear policy file needs arrays 'W' (1, obs_dim) and 'b' (1,)")
            W, b = np.atleast_2d(z["W"]), np.atleast_1d(z["b"])
        if W.dtype.kind not in "fiu" or b.dtype.kind not in "fiu" or W.ndim != 2 or b.ndim != 1:
            raise InputError(f"{path}: a linear policy file needs arrays 'W' (1, obs_dim) and 'b' (1,) of numbers")
        W, b = W.astype(float), b.astype(float)
        if W.shape[0] != b.shape[0]:
            raise InputError(f"{path}: W has {W.shape[0]} rows but b has {b.shape[0]} entries")
        if W.shape[0] != 1 or W.shape[1] < 1:
            raise InputError(f"{path}: W is {W.shape}; a linear policy gives one action (the voltage): W (1, obs_dim)")
        if not (np.isfinite(W).all() and np.isfinite(b).all()):
            raise InputError(f"{path}: W or b holds non-finite values (NaN or inf)")
        return cls(W, b)

    def save(self, path: str | Path) -> None:
        """Write ``W`` and ``b`` to a ``.npz``."""
        np.savez(path, W=self.W, b=self.b)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        obs = np.asarray(obs, dtype=float)
        if obs.shape != (self.W.shape[1],):
            raise InputError(f"linear policy expects an observation of {self.W.shape[1]} values, got {obs.shape}")
        return (self.W @ obs + self.b).astype(np.float32)


def npz_problem(exc: BaseException) -> str:
    """What is wrong with a file ``numpy.load(..., allow_pickle=False)`` refused, in a few words (not numpy's advice
    about pickles: a policy file is never unpickled)."""
    if isinstance(exc, zipfile.BadZipFile):
        return f"a damaged .npz archive ({exc})"
    if isinstance(exc, EOFError):
        return "empty or cut short"
    if isinstance(exc, OSError):
        return exc.strerror or str(exc) or type(exc).__name__
    text = " ".join(str(exc).split())
    if "pickle" in text:
        return "neither a .npz archive nor a .npy array"
    return text or type(exc).__name__


def _optional(module: str, what: str):
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise UnavailableError(
            f"{what} needs the '{module}' package, which cannot be imported ({exc}); use the built-in ones instead"
        ) from None


def make_controller(spec: str, configuration: str, omega_ref: float | None, control_dt: float, params: Any = None):
    """A controller from its command-line spec.

    Parameters
    ----------
    spec : str
        ``const:V``, ``play:FILE`` or a name known to :func:`controllers.make` (``agent:PATH`` included).
    configuration : str
        Rig configuration.
    omega_ref : float or None
        Target lower-disc speed (rad/s), when the controller needs one.
    control_dt : float
        Control period (s).
    params : RigParams or model, optional
        The design model (e.g. the identified one: a :class:`drillgym.Model` or what
        :func:`controllers.model.model_of` gives); default the controller's.

    Returns
    -------
    object
        A controller: ``reset(measurement)``, then ``controller(measurement) -> volts``.

    Raises
    ------
    InputError
        A malformed spec.
    UnavailableError
        The ``controllers`` package cannot be imported.
    """
    if spec.startswith("play:"):
        return PlaybackController(spec.split(":", 1)[1])
    if spec.startswith("const:"):
        try:
            volts = float(spec.split(":", 1)[1])
        except ValueError:
            raise InputError(f"controller {spec!r}: expected const:<volts>, e.g. const:2.0") from None
        if not math.isfinite(volts):
            raise InputError(f"controller {spec!r}: the voltage must be a finite number of volts, e.g. const:2.0")
        return ConstantController(volts)
    mod = _optional("controllers", f"controller {spec!r}")
    make = getattr(mod, "make", None)
    if make is None:
        raise InputError(f"controller {spec!r}: the controllers package has no make(); only const:<volts> is available")
    kwargs: dict[str, Any] = {"config": configuration, "dt": control_dt}
    if params is not None:  # base parameters, or a model with effects (a learned policy takes it whole)
        from drillgym.params import RigParams

        kwargs["params" if isinstance(params, RigParams) else "model"] = params
    if omega_ref is not None:
        kwargs["omega_ref"] = omega_ref
    return make(spec, **kwargs)


def load_policy(path: str | Path) -> Callable[[np.ndarray], np.ndarray]:
    """A policy (observation -> action) from a file.

    Parameters
    ----------
    path : str or path
        A ``.npz`` linear policy (:class:`LinearPolicy`), else any file :func:`agents.load_policy` reads.

    Returns
    -------
    callable
        ``policy(observation) -> action``.

    Raises
    ------
    MissingFileError
        The file does not exist.
    UnavailableError
        The ``agents`` package cannot be imported.
    """
    p = Path(path)
    if not p.exists():
        raise MissingFileError(f"policy file {p} does not exist")
    if p.suffix == ".npz":
        return LinearPolicy.load(p)
    mod = _optional("agents", f"policy {p}")
    loader = getattr(mod, "load_policy", None)
    if loader is None:
        raise InputError(f"policy {p}: the agents package has no load_policy(); use a .npz linear policy")
    return loader(p)


def measurement_of(info: Mapping[str, Any]) -> dict[str, float]:
    """The controller measurement (controllers.base.MEASUREMENTS) from a HardwareEnv info dict."""
    m = info["measurement"]
    return {
        "t": m["t"],
        "theta_u": m["theta_u"],
        "theta_l": m["theta_l"],
        "x": m["x_lp"],
        "y": m["y_lp"],
        "omega_ref": info["omega_ref"],
    }


@dataclass
class EpisodeResult:
    """Outcome of one episode on the rig.

    Parameters
    ----------
    steps : int
        Control periods run.
    total_reward : float
        Sum of the rewards.
    terminated, truncated : bool
        How the episode ended.
    recording : str
        The episode's recording file.
    safety_stop : str or None
        The safety stop that ended it, if any.
    tick_errors : ndarray
        Pacing error of each period (s).
    round_trips : ndarray
        Round trip of each SET_VOLTAGE/SAMPLE exchange (s).
    overruns : int
        Periods the loop ran more than one period late (the schedule restarted from then).
    """

    steps: int
    total_reward: float
    terminated: bool
    truncated: bool
    recording: str
    safety_stop: str | None
    tick_errors: np.ndarray
    round_trips: np.ndarray
    overruns: int = 0


def run_episode(
    env,
    *,
    controller=None,
    policy=None,
    seed: int | None = None,
    max_steps: int | None = None,
    on_step: Callable[[int, dict], None] | None = None,
) -> EpisodeResult:
    """One episode of a controller (measurements -> volts) or a policy (observation -> action).

    Parameters
    ----------
    env : HardwareEnv
        The rig's environment (possibly wrapped).
    controller : object, optional
        A controller (:func:`make_controller`); give this or ``policy``.
    policy : callable, optional
        ``policy(observation) -> action`` (:func:`load_policy`).
    seed : int, optional
        Seed of the reset.
    max_steps : int, optional
        Stop after this many control periods (the episode is then ended cleanly).
    on_step : callable, optional
        ``on_step(step, info)`` after every period.

    Returns
    -------
    EpisodeResult
        Steps, return, how the episode ended, the recording file and the timing.
    """
    if (controller is None) == (policy is None):
        raise ValueError("give exactly one of controller or policy")
    obs, info = env.reset(seed=seed)
    if controller is not None:
        controller.reset(measurement_of(info))
    steps, total, term, trunc, stop = 0, 0.0, False, False, None
    ticks, rtts = [], []
    try:
        while not (term or trunc) and (max_steps is None or steps < max_steps):
            action = (
                np.array([controller(measurement_of(info))], dtype=np.float32)
                if controller is not None
                else policy(obs)
            )
            obs, r, term, trunc, info = env.step(action)
            steps += 1
            total += r
            ticks.append(info["tick_error_s"])
            rtts.append(info["round_trip_s"])
            stop = info.get("safety_stop", stop)
            if on_step is not None:
                on_step(steps, info)
    finally:
        if not (term or trunc):
            env.unwrapped.end_episode()
    overruns = int(info.get("overruns", 0))
    return EpisodeResult(steps, total, term, trunc, info["recording"], stop, np.array(ticks), np.array(rtts), overruns)
