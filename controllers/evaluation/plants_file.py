"""A population of plants the user writes: ``evaluate --scenarios plants --plants-file FILE``.

Instead of drawing plants from an uncertainty set (:mod:`.population`), the user lists them, each a
:class:`drillgym.Model` (base parameters, effects and their values, read as a model file's entry is:
:meth:`drillgym.Model.from_mapping`) and the encoder the plant's controller reads, not told to it::

    plants:
      - name: worn-brake                  # optional; default "plant K" (K: its place in the list, from 0)
        params: {Ts: 0.9, Tc: 0.7}        # base parameters (RigParams names, SI units); absent ones nominal
        effects:                          # in signal-path order, as a model file's records
          - motor_lag                     # a library effect with its default values
          - {spec: input_delay, values: {delay: 0.01}}
          - {spec: my_effects.py:backlash, values: {gap: 0.002}}   # an effect file beside this file
        encoders: {counts_per_rev: 2048, angle_noise: 5.0e-4}     # default 8000 counts/rev, no noise (rad)

``encoders`` is the model file's key (:attr:`drillgym.Model.encoders`); the older spelling ``encoder`` is read too.

An effect file is code: it must lie in the plants file's folder (or below it), unless the caller trusts it
(``trust=True``, ``--trust``), and when its record gives a ``sha256`` the file must still have it.

The plants may differ in their effects: :meth:`PlantSet.groups` gathers them by composition, so each group
runs as one batch through one compiled composition.

    >>> from controllers.evaluation.plants_file import load_plants
    >>> plants = load_plants("examples/plants.yaml")
    >>> [p.name for p in plants.plants], plants.groups()
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from drillgym import RigParams
from drillgym.errors import InputError, InputTypeError, MissingFileError
from drillgym.io import describe_parse_error
from drillgym.io.structured import load_yaml
from drillgym.measurement import DEFAULT_COUNTS_PER_REV
from drillgym.model import Model

from .population import PlantPopulation

__all__ = ["Plant", "PlantSet", "load_plants"]

#: the keys of one plant of the file
_KEYS = ("name", "params", "effects", "encoders")
#: the encoders' key as files written before the model file named it
_OLD_ENCODERS_KEY = "encoder"


@dataclass(frozen=True)
class Plant:
    """One plant of a plants file.

    Attributes
    ----------
    name : str
        Its name in reports and messages (default ``"plant K"``, K its place in the file from 0).
    model : drillgym.Model
        Base parameters, effects and effect values.
    counts_per_rev : int
        Resolution of its encoders (counts/rev).
    angle_noise : float
        White noise on its measured angles (rad, standard deviation).
    given : tuple of str
        The base parameters the file sets (the others are nominal).
    """

    name: str
    model: Model
    counts_per_rev: int = DEFAULT_COUNTS_PER_REV
    angle_noise: float = 0.0
    given: tuple[str, ...] = ()

    def columns(self) -> dict[str, float]:
        """The plant's values for the results: the base parameters the file sets, the effects' values
        (each parameter's unit), ``counts_per_rev`` and ``angle_noise`` (rad)."""
        out = {n: float(getattr(self.model.params, n)) for n in self.given}
        out.update({k: float(v) for k, v in self.model.values.items()})
        return out | {"counts_per_rev": float(self.counts_per_rev), "angle_noise": float(self.angle_noise)}


@dataclass(frozen=True)
class PlantSet:
    """The plants of a plants file (read by :func:`load_plants`).

    Attributes
    ----------
    plants : tuple of Plant
        The plants, in the file's order (their index is their place in it, from 0).
    source : str
        The file, named in messages.
    """

    plants: tuple[Plant, ...]
    source: str = "inline"

    @property
    def n(self) -> int:
        """Number of plants."""
        return len(self.plants)

    def label(self, k: int) -> str:
        """``plant 'worn-brake' (1 of 2 in plants.yaml)``: plant ``k`` as reports and errors name it."""
        return f"plant {self.plants[k].name!r} ({k} of {self.n} in {self.source})"

    def groups(self) -> list[list[int]]:
        """The plants' indices gathered by composition (the effects, in order), groups in order of first
        appearance: each group runs through one compiled composition."""
        out: dict[Any, list[int]] = {}
        for k, p in enumerate(self.plants):
            out.setdefault(p.model.composition, []).append(k)
        return list(out.values())

    def population(self, index: Sequence[int]) -> PlantPopulation:
        """The plants ``index`` (one composition) as a :class:`.population.PlantPopulation`.

        Raises
        ------
        InputError
            Plants of different compositions (run them as :meth:`groups`).
        """
        sel = [self.plants[int(k)] for k in index]
        comp = sel[0].model.composition
        if any(p.model.composition != comp for p in sel):
            raise InputError(f"{self.source}: plants of different effects cannot run as one batch")
        return PlantPopulation(
            comp,
            np.array([p.model.vector for p in sel]),
            np.array([p.counts_per_rev for p in sel]),
            np.array([p.angle_noise for p in sel], dtype=float),
            [p.columns() for p in sel],
            None,
            [p.name for p in sel],
        )

    def refuse_not_acting(self, configuration: str) -> None:
        """Refuse, naming the file and the plant, an effect that does not act in ``configuration`` (it would
        change nothing, silently)."""
        for k, p in enumerate(self.plants):
            p.model.composition.refuse_not_acting(configuration, f"{_where(self.source, k, {'name': p.name})}: effect")


def _where(source: str, k: int, entry: Any) -> str:
    name = entry.get("name") if isinstance(entry, Mapping) else None
    return f"{source}: plant {name!r} (#{k})" if isinstance(name, str) and name else f"{source}: plant #{k}"


def _read(path: Path) -> Any:
    import yaml

    if not path.exists():
        raise MissingFileError(f"{path}: plants file not found")
    if path.is_dir():
        raise InputError(f"{path}: is a folder, not a plants file")
    try:
        return load_yaml(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(f"{path}: cannot read the plants file ({exc.strerror})") from None
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not a plants file (not UTF-8 text, byte {exc.start})") from None
    except yaml.YAMLError as exc:
        raise InputError(f"{path}: not valid YAML ({describe_parse_error(exc)})") from None


def _encoder(raw: Any, where: str) -> tuple[int, float]:
    if raw is None:
        return DEFAULT_COUNTS_PER_REV, 0.0
    if not isinstance(raw, Mapping) or set(raw) - {"counts_per_rev", "angle_noise"}:
        raise InputError(f"{where}: 'encoders' holds counts_per_rev and angle_noise, got {raw!r}")
    cpr = raw.get("counts_per_rev", DEFAULT_COUNTS_PER_REV)
    if isinstance(cpr, bool) or not isinstance(cpr, int) or cpr < 1:
        raise InputError(f"{where}: encoder counts_per_rev must be an integer >= 1 (counts/rev), got {cpr!r}")
    noise = raw.get("angle_noise", 0.0)
    if isinstance(noise, bool) or not isinstance(noise, (int, float)) or not (math.isfinite(noise) and noise >= 0):
        raise InputError(f"{where}: encoder angle_noise must be a finite number >= 0 (rad), got {noise!r}")
    return int(cpr), float(noise)


def _plant(entry: Any, k: int, path: Path, source: str, trust: bool, params: RigParams | None) -> Plant:
    where = _where(source, k, entry)
    if not isinstance(entry, Mapping):
        raise InputError(f"{where}: a plant is a mapping ({', '.join(_KEYS)}), got {entry!r}")
    unknown = sorted(map(str, set(entry) - set(_KEYS) - {_OLD_ENCODERS_KEY}))
    if unknown:
        raise InputError(f"{where}: unknown key {unknown[0]!r}; a plant has {', '.join(_KEYS)}")
    name = entry.get("name", f"plant {k}")
    if not isinstance(name, str) or not name.strip():
        raise InputError(f"{where}: 'name' must be a non-empty text, got {name!r}")
    effects = entry.get("effects") or []
    if not isinstance(effects, list):
        raise InputError(f"{where}: 'effects' must be a list (names, path.py:NAME, or {{spec, values}})")
    records = [{"spec": e} if isinstance(e, str) else e for e in effects]  # a name alone: its default values
    given = entry.get("params") or {}
    model = Model.from_mapping(
        {"params": given, "effects": records}, path, trust=trust, where=where, hashed=False
    )  # the model file's reading: parameters, effect records, effect files and the trust rule
    if params is not None and isinstance(given, Mapping):  # absent base parameters: the run's nominal ones
        try:
            model = model.replace(params=params.replace(**{n: getattr(model.params, n) for n in given}))
        except InputError as exc:
            raise InputError(f"{where}: {exc}") from None
    if "encoders" in entry and _OLD_ENCODERS_KEY in entry:
        raise InputError(f"{where}: give 'encoders' once ('{_OLD_ENCODERS_KEY}' is its older spelling)")
    cpr, noise = _encoder(entry.get("encoders", entry.get(_OLD_ENCODERS_KEY)), where)
    return Plant(name.strip(), model, cpr, noise, tuple(map(str, given)))


def load_plants(path: str | Path, *, trust: bool = False, params: RigParams | None = None) -> PlantSet:
    """Read a plants file (YAML or JSON; format in the module's docstring).

    Parameters
    ----------
    path : str or path
        The file.
    trust : bool, optional
        Import effect files that lie outside the file's folder or whose recorded SHA-256 differs (default
        False: refused).  Importing an effect file runs it.
    params : RigParams, optional
        The nominal base parameters a plant keeps where the file sets none; default the identified set.

    Returns
    -------
    PlantSet
        The plants.

    Raises
    ------
    MissingFileError
        The file does not exist.
    InputError
        A file that is not YAML, holds no plant, or a plant with an unknown key, an unknown base parameter,
        an unknown effect or effect parameter, a bad value, an untrusted effect file or a repeated name: one
        line naming the file, the plant (its name and its place ``#K`` from 0) and what is wrong.
    InputTypeError
        ``path`` that is not a path, or ``params`` that are not RigParams.
    """
    if not (isinstance(path, (str, Path)) or hasattr(path, "__fspath__")):
        raise InputTypeError(
            f"plants_file: the plants file must be a path (text or path-like), got {type(path).__name__}"
        )
    if params is not None and not isinstance(params, RigParams):
        raise InputTypeError(f"plants_file: params must be RigParams, got {type(params).__name__}")
    path = Path(path)
    raw = _read(path)
    source = str(path)
    entries = raw.get("plants") if isinstance(raw, Mapping) else None
    if not isinstance(raw, Mapping) or set(raw) - {"plants"} or not isinstance(entries, list):
        raise InputError(f"{source}: a plants file holds one key, 'plants': a list of plants (name, {_KEYS[1]}, ...)")
    if not entries:
        raise InputError(f"{source}: 'plants' is empty; list at least one plant")
    real = Path(path).resolve()  # effect files resolve beside the file itself, not beside a link to it
    plants = tuple(_plant(e, k, real, source, trust, params) for k, e in enumerate(entries))
    seen: dict[str, int] = {}
    for k, p in enumerate(plants):
        if p.name in seen:
            raise InputError(f"{source}: plant {p.name!r} (#{k}): plant #{seen[p.name]} has that name already")
        seen[p.name] = k
    return PlantSet(plants, source)
