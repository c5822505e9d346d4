"""Identify, then control, per plant: an excitation run, then :func:`drillgym.identify` on its recording.

For ``evaluate --scenarios plants --identify``: each plant of the population gets

1. an **excitation run** through the path every closed-loop run of the harness takes
   (:func:`.runner.run_closed_loop`: the plant's composition, its encoders' quantisation and noise),
   playing the quasi-random estimation signal (:func:`drillgym.signals.quasi_random`) and recording
   what the sensors report (motor and lower encoder angles) at the recording rate;
2. **identification** by :func:`drillgym.identify`, the one front every route takes (``diagnose
   --model-out``, ``drillgym identify``, ``rig tune``): diagnosis, a candidate outside the library when one
   earns its place, the library selected again beside it, everything refitted jointly;
3. the :class:`drillgym.Model` every controller of the evaluation is built on.

The identification never sees the plant's values; :class:`IdentifiedPlant` keeps them side by side
for the results.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from drillgym.closed_loop.abi import MEASUREMENT_ROWS
from drillgym.configurations import parse_configuration
from drillgym.errors import InputError
from drillgym.io import TimeSeries
from drillgym.io.jsonfile import write_json
from drillgym.model import Model
from drillgym.signals import quasi_random

from ..base import Controller
from .runner import run_closed_loop

__all__ = [
    "EXCITATION_S",
    "ExcitationOptions",
    "IdentifiedPlant",
    "excitation_recording",
    "identify_plant",
    "save_identified",
    "load_identified",
]


#: default length of the excitation (s) per configuration: long enough for the lower disc to turn the
#: revolutions a position-dependent friction needs to be told from noise (on 30 s of torsional excitation a
#: 5 % friction harmonic was skipped as "not the same in both halves" on some plants), short enough that the
#: identification stays within a minute on 2 cores (idle machine, the slowest plants of the documented
#: population: torsional 60 s -> 14-29 s; coupled, whose model runs about three times slower, 30 s -> 45-49 s,
#: 60 s -> 77 s)
EXCITATION_S = {"torsional": 60.0, "coupled": 30.0}


@dataclass(frozen=True)
class ExcitationOptions:
    """The excitation run and the identification's settings.

    Attributes
    ----------
    duration : float or None
        Length of the excitation (s); None: the configuration's default (:data:`EXCITATION_S`).
    rate_hz : float
        Recording rate (Hz): the encoders are read and the command updated at this rate.
    amplitude, offset : float
        The quasi-random signal spans offset +- (amplitude - |offset|) (V).
    compare_rate_hz : float
        Comparison grid of the diagnosis and the fit (Hz).
    max_nfev : int
        Least-squares evaluations of the final fit.
    """

    duration: float | None = None
    rate_hz: float = 500.0
    amplitude: float = 5.0
    offset: float = 2.5
    compare_rate_hz: float = 50.0
    max_nfev: int = 30

    def length(self, config: str) -> float:
        """The excitation's length (s) in a configuration: ``duration``, or the configuration's default."""
        if self.duration is not None:
            return float(self.duration)
        return EXCITATION_S.get(parse_configuration(config).label, max(EXCITATION_S.values()))


class _Playback(Controller):
    """Plays a voltage sequence and keeps what the sensors reported at each period: the encoders, and the
    LVDTs in a configuration with the lateral motion.  Its compiled law (:mod:`controllers.compiled.playback_law`)
    does the same in the compiled closed loop."""

    name = "playback"
    uses = ("theta_u", "theta_l", "x", "y")

    def __init__(self, u: np.ndarray, dt: float, channels: tuple[str, ...] = ("theta_u", "theta_l")) -> None:
        super().__init__(1.0, dt=dt)
        self.u = np.asarray(u, dtype=float)
        self.k = 0
        self.channels = channels
        self.seen: dict[str, list[np.ndarray]] = {c: [] for c in channels}
        self._law_state: np.ndarray | None = None

    def _act(self, m: dict[str, np.ndarray]) -> np.ndarray:
        for key in self.seen:
            self.seen[key].append(np.array(m[key], dtype=float))
        u = self.u[min(self.k, self.u.size - 1)]
        self.k += 1
        return np.full(self.n, u)

    def _compiled_law(self):
        from ..compiled import CompiledLaw
        from ..compiled.playback_law import playback_state, playback_step

        self._law_state = playback_state(self.u.size, self.n)
        return CompiledLaw(playback_step, self._law_state, np.ascontiguousarray(self.u))

    def reports(self) -> dict[str, np.ndarray]:
        """Channel -> what the sensors reported at each period of the first run (rad, m)."""
        if self._law_state is None:
            return {k: np.array([v[0] for v in vals]) for k, vals in self.seen.items()}
        from ..compiled.playback_law import played_measurements

        kept = played_measurements(self._law_state)  # the loop's measurement rows, in their order
        return {k: kept[:, MEASUREMENT_ROWS.index(k), 0].copy() for k in self.channels}


def excitation_recording(
    plant: np.ndarray,
    composition,
    counts_per_rev: float,
    angle_noise: float,
    seed: int,
    options: ExcitationOptions | None = None,
    config: str = "torsional",
) -> TimeSeries:
    """The recording of one plant's excitation run.

    Parameters
    ----------
    plant : ndarray
        The plant's parameter row (base, then its effects' parameters: ``composition``'s layout).
    composition : Composition
        The plant's effects.
    counts_per_rev, angle_noise : float
        The plant's encoders (counts/rev; rad, standard deviation).
    seed : int
        Seed of the signal and of the encoder noise.
    options : ExcitationOptions, optional
        The run's settings.
    config : str, optional
        The configuration.

    Returns
    -------
    TimeSeries
        ``t``, ``u``, ``theta_u``, ``theta_l`` (and ``x``, ``y`` with the lateral motion) at ``rate_hz``, as the
        sensors reported them.
    """
    o = options or ExcitationOptions()
    dt = 1.0 / o.rate_hz
    duration = o.length(config)
    t, u = quasi_random(duration, rate_hz=o.rate_hz, seed=seed, amplitude=o.amplitude, offset=o.offset)
    lateral = parse_configuration(config).lateral_free
    play = _Playback(u, dt, ("theta_u", "theta_l", "x", "y") if lateral else ("theta_u", "theta_l"))
    run = run_closed_loop(
        play,
        config,
        np.ones(1),
        duration,
        params=np.atleast_2d(plant),
        counts_per_rev=counts_per_rev,
        angle_noise=angle_noise,
        seed=seed,
        effects=composition,
    )
    cols = {"t": run.t, "u": run.u[0]}
    cols.update(play.reports())
    meta = {
        "configuration": config,
        "source": "simulation",
        "sample_rate_hz": o.rate_hz,
        "description": "excitation run of a plant (quasi-random input)",
        "counts_per_rev": int(counts_per_rev),
    }
    return TimeSeries(cols, meta, "<excitation>")


@dataclass
class IdentifiedPlant:
    """What identification made of one plant.

    Attributes
    ----------
    model : drillgym.Model
        The identified model (base parameters, the selected effects, standard errors).
    selected : list of str
        The effects of the identified model.
    seconds : float
        Wall-clock time of the diagnosis and the fit (s), the excitation run excluded.
    values : dict of str to float
        Identified value of each parameter the plant's uncertainty varies (NaN for an effect not selected).
    warnings : list of str
        The diagnosis's and the fit's warnings.
    """

    model: Model
    selected: list[str]
    seconds: float
    values: dict[str, float] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    def columns(self) -> dict[str, float | str]:
        """Result columns: ``id_<name>`` per identified value, ``selected``, ``identify_s``."""
        out: dict[str, float | str] = {f"id_{k}": v for k, v in self.values.items()}
        out["selected"] = "+".join(self.selected) or "none"
        out["identify_s"] = self.seconds
        return out


def identify_plant(
    recording: TimeSeries, names: list[str], options: ExcitationOptions | None = None
) -> IdentifiedPlant:
    """Identify the recording (:func:`drillgym.identify`, the route every command takes).

    Parameters
    ----------
    recording : TimeSeries
        The excitation run's recording.
    names : list of str
        Parameters whose identified values to report (base or effect names).
    options : ExcitationOptions, optional
        The comparison grid and the fit's evaluations.

    Returns
    -------
    IdentifiedPlant
        The model and what was found.
    """
    from drillgym import identify

    o = options or ExcitationOptions()
    found = identify(recording, compare_rate_hz=o.compare_rate_hz, max_nfev=o.max_nfev)
    m = found.model
    values = {**m.params.to_dict(), **m.values}
    return IdentifiedPlant(
        m,
        list(m.names),
        found.seconds,
        {n: float(values.get(n, math.nan)) for n in names},
        list(found.warnings),
    )


#: the file beside each plant's model that holds the rest of its :class:`IdentifiedPlant`
SUMMARY_FILE = "identification.json"


def save_identified(identified: Mapping[int, IdentifiedPlant], folder: str | Path) -> Path:
    """Write each plant's identification to ``folder/plant_<k>/`` (``model.json`` by :meth:`drillgym.Model.save`,
    with any candidate effect file beside it, and ``identification.json``: the effects selected, the time, the
    identified values, the warnings), so the models can be read, reused and copied.

    Parameters
    ----------
    identified : mapping of int to IdentifiedPlant
        Plant index -> its identification.
    folder : str or path
        The folder (created).

    Returns
    -------
    pathlib.Path
        The folder.
    """
    root = Path(folder)
    for k, plant in sorted(identified.items()):
        d = root / f"plant_{int(k)}"
        plant.model.save(d / "model.json")
        summary = {
            "plant": int(k),
            "selected": plant.selected,
            "seconds": plant.seconds,
            "values": {n: (v if math.isfinite(v) else None) for n, v in plant.values.items()},  # None: not selected
            "warnings": plant.warnings,
        }
        write_json(d / SUMMARY_FILE, summary, nonfinite="refuse")
    return root


def load_identified(folder: str | Path, plants: int) -> dict[int, IdentifiedPlant]:
    """Read back what :func:`save_identified` wrote for plants ``0..plants-1``; a plant without its two files
    is left out (the caller identifies it).

    Raises
    ------
    InputError
        A plant folder with a model but no summary (or the reverse), naming it.
    """
    root, out = Path(folder), {}
    for k in range(int(plants)):
        d = root / f"plant_{k}"
        have = [(d / "model.json").is_file(), (d / SUMMARY_FILE).is_file()]
        if not any(have):
            continue
        if not all(have):
            raise InputError(f"{d}: holds {'model.json' if have[0] else SUMMARY_FILE} only; remove the folder")
        with open(d / SUMMARY_FILE, encoding="utf-8") as fh:
            summary = json.load(fh)
        values = {n: (math.nan if v is None else float(v)) for n, v in summary["values"].items()}
        out[k] = IdentifiedPlant(
            Model.load(d / "model.json"), list(summary["selected"]), float(summary["seconds"]), values,
            list(summary["warnings"]),
        )  # fmt: skip
    return out
