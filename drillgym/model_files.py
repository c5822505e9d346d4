"""Model files read without building the model: their records, their effect files and the code those hold.

The parts of :meth:`drillgym.Model.load` that read a file (or one entry of a file that holds several, as the
plants of ``evaluate --plants-file``) and list the effect files it names, without importing them.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from .errors import MissingFileError
from .io.paths import describe_parse_error
from .io.structured import load_structured
from .params import ParameterError, RigParams, number

__all__ = ["CodeFile", "Encoders", "Provenance", "code_files", "FORMAT", "VERSION", "check_not_model_with_effects"]

#: the format tag and version written by :meth:`drillgym.Model.save`
FORMAT, VERSION = "drillgym-model", 2

#: the keys of an effect record (one effect of a model file)
RECORD_KEYS = ("name", "kind", "spec", "file", "sha256", "values", "std")


@dataclass(frozen=True)
class CodeFile:
    """An effect file a model file names (listed without importing it).

    Attributes
    ----------
    effect : str
        The effect's name.
    path : pathlib.Path
        Where the file is (resolved).
    inside : bool
        True when the file lies in the model file's folder (or below it).
    recorded_sha256 : str or None
        The hash the model file records (None: none recorded, an older file).
    matches : bool
        True when the file exists and its content has the recorded hash.
    """

    effect: str
    path: Path
    inside: bool
    recorded_sha256: str | None
    matches: bool

    @property
    def trusted(self) -> bool:
        """True when loading may import it without the user's word: inside the folder and unchanged."""
        return self.inside and self.matches

    def why_untrusted(self) -> str:
        if not self.path.is_file():
            return "not found"
        if not self.inside:
            return "outside the model's folder"
        if self.recorded_sha256 is None:
            return "no hash recorded in the model file"
        return "changed since the model was written (its SHA-256 differs)"


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _read(path: Path) -> Mapping[str, Any]:
    if not path.exists():
        raise MissingFileError(f"{path}: model file not found")
    if path.is_dir():
        raise ParameterError(f"{path}: is a folder, not a model file")
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ParameterError(f"{path}: cannot read the model file ({exc.strerror})") from None
    except UnicodeDecodeError:
        raise ParameterError(f"{path}: not a model file (not UTF-8 text)") from None
    try:
        data = load_structured(text, path.suffix)
    except Exception as exc:  # noqa: BLE001 - any parse error, one line with the file name
        raise ParameterError(
            f"{path}: not valid {path.suffix.lstrip('.') or 'JSON'}: {describe_parse_error(exc)}"
        ) from None
    if not isinstance(data, Mapping):
        raise ParameterError(f"{path}: a model file holds a mapping (params, effects), got {type(data).__name__}")
    if "format" in data and data["format"] != FORMAT:
        raise ParameterError(f"{path}: 'format' is {data['format']!r}, not {FORMAT!r}")
    version = data.get("version", VERSION)
    if isinstance(version, bool) or not isinstance(version, int) or not 1 <= version <= VERSION:
        raise ParameterError(
            f"{path}: 'version' is {version!r}; this drillgym reads model files of version 1 to {VERSION}"
            + (" (the file was written by a later drillgym)" if isinstance(version, int) and version > VERSION else "")
        )
    if "params" not in data and "effects" not in data and "std" not in data:
        data = {"params": data}  # a file of base parameters only: a model without effects
    known = {"format", "version", "params", "std", "effects", "encoders", "provenance", "warnings"}
    unknown = set(data) - known
    if unknown:
        raise ParameterError(f"{path}: unknown key(s) in a model file: {', '.join(sorted(map(str, unknown)))}")
    return data


def _effect_records(data: Mapping[str, Any], path: str | Path) -> list[Mapping[str, Any]]:
    effects = data.get("effects", [])
    if not isinstance(effects, list):
        raise ParameterError(f"{path}: 'effects' must be a list of {{spec, values}} records")
    for k, rec in enumerate(effects):
        if not isinstance(rec, Mapping) or not isinstance(rec.get("spec", rec.get("name")), str):
            raise ParameterError(f"{path}: effect record {k} needs a 'spec' (name or file.py:NAME)")
        unknown = set(rec) - set(RECORD_KEYS)
        if unknown:
            raise ParameterError(
                f"{path}: effect record {k}: unknown key(s) {', '.join(sorted(map(str, unknown)))}; a record has "
                f"{', '.join(RECORD_KEYS)}"
            )
    return effects


def _record_file(rec: Mapping[str, Any], where: Path) -> Path | None:
    """The effect file a record names (resolved), or None for a library effect."""
    spec = rec.get("spec") or rec["name"]
    if ".py:" not in spec:
        return None
    fpath = Path(spec.rpartition(":")[0])
    cands = [fpath] if fpath.is_absolute() else [where.parent / fpath]
    if isinstance(rec.get("file"), str):
        f = Path(rec["file"])
        cands.append(f if f.is_absolute() else where.parent / f)
    for c in cands:
        if c.is_file():
            return c.resolve()
    return cands[0].resolve()


def _resolve_spec(rec: Mapping[str, Any], where: Path) -> str:
    spec = rec.get("spec") or rec["name"]
    file = _record_file(rec, where)
    if file is None:
        return spec
    return f"{file}:{spec.rpartition(':')[2]}"


def _code_files(data: Mapping[str, Any], path: Path) -> list[CodeFile]:
    folder = path.parent.resolve()
    out = []
    for rec in _effect_records(data, path):
        f = _record_file(rec, path)
        if f is None:
            continue
        recorded = rec.get("sha256") if isinstance(rec.get("sha256"), str) else None
        matches = f.is_file() and recorded is not None and _sha256(f) == recorded
        out.append(CodeFile(str(rec.get("name") or rec["spec"]), f, f.is_relative_to(folder), recorded, matches))
    return out


def code_files(path: str | Path) -> list[CodeFile]:
    """The effect files a model file would import, without importing them.

    Parameters
    ----------
    path : str or path
        The model file.

    Returns
    -------
    list of CodeFile
        One per file effect: where it is, whether it lies in the model's folder, whether its hash matches.
    """
    path = Path(path)
    return _code_files(_read(path), path.resolve())


def _std(raw: Any, path: str | Path, what: str) -> dict[str, float]:
    """Standard errors ``name -> number`` (null: unknown, left out)."""
    if not isinstance(raw, Mapping):
        raise ParameterError(f"{path}: {what} must map parameter names to standard errors")
    out = {}
    for k, v in raw.items():
        if v is None:
            continue
        x = number(v, f"{path}: {what}: the standard error of {k!r}")
        if not x >= 0:
            raise ParameterError(f"{path}: {what}: the standard error of {k!r} must be a number >= 0, got {v!r}")
        out[str(k)] = x
    return out


def check_not_model_with_effects(path: str | Path, option: str) -> None:
    """Refuse to write base parameters only over a model file that holds effects (they would be lost).

    Parameters
    ----------
    path : str or path
        The parameter file a command is about to write.
    option : str
        The option that named it, for the message.

    Raises
    ------
    OutputPathError
        ``path`` is a model file with effects (a file that does not read as one is left to the other checks).
    """
    from .errors import OutputPathError

    path = Path(path)
    if not path.is_file():
        return
    try:
        data = _read(path)
        effects = data.get("effects") if isinstance(data, Mapping) else None
    except Exception:  # noqa: BLE001 - not a model file: nothing of a model to lose
        return
    if isinstance(effects, list) and effects:
        names = ", ".join(str(e.get("name", e.get("spec"))) for e in effects if isinstance(e, Mapping)) or "?"
        raise OutputPathError(
            f"{option} {path} is a model file with effects ({names}): writing base parameters over it would lose "
            "them; choose another name"
        )


@dataclass(frozen=True)
class Provenance:
    """Where a model came from.

    Attributes
    ----------
    route : str
        What made it: ``"identify"`` (:func:`drillgym.identify`, every route to it), ``"user"``.
    recording : str or None
        The recording identified on (its path as given).
    recording_sha256 : str or None
        SHA-256 of the recording file's bytes (None: not a file).
    settings : mapping
        The identification's settings (JSON-ready values).
    version : str
        The drillgym version that made it.
    """

    route: str = "user"
    recording: str | None = None
    recording_sha256: str | None = None
    settings: Mapping[str, Any] = field(default_factory=dict)
    version: str = ""

    def to_json(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in fields(self)} | {"settings": dict(self.settings)}

    @classmethod
    def from_json(cls, data: Any, where: str) -> Provenance:
        if not isinstance(data, Mapping):
            raise ParameterError(f"{where}: 'provenance' must be a mapping")
        known = {f.name for f in fields(cls)}
        unknown = set(data) - known
        if unknown:
            raise ParameterError(f"{where}: 'provenance' has unknown key(s): {', '.join(sorted(unknown))}")
        for k, v in data.items():
            ok, what = _PROVENANCE_TYPES[k]
            if not ok(v):
                raise ParameterError(f"{where}: 'provenance': {k!r} must be {what}, got {v!r}")
        return cls(**{k: (dict(v) if k == "settings" else v) for k, v in data.items()})


#: what each field of a model file's provenance holds: (check, how a refusal names it)
_PROVENANCE_TYPES: dict[str, tuple[Any, str]] = {
    "route": (lambda v: isinstance(v, str), "a text"),
    "recording": (lambda v: v is None or isinstance(v, str), "a path (text) or null"),
    "recording_sha256": (lambda v: v is None or isinstance(v, str), "a SHA-256 (text) or null"),
    "settings": (lambda v: isinstance(v, Mapping), "a mapping of setting names to values"),
    "version": (lambda v: isinstance(v, str), "a version (text)"),
}


@dataclass(frozen=True)
class Encoders:
    """The rig's angle encoders as a recording shows them: what a controller built on the model expects to read.

    Attributes
    ----------
    counts_per_rev : int or None
        The encoders' resolution (counts/rev); None where the readings lie on no lattice of counts (noise added
        after the count, an interpolated reading): then ``angle_noise`` is the reading's whole error.
    angle_noise : float
        White angle noise beside the counts (rad, standard deviation); 0 on a reading of whole counts.
    """

    counts_per_rev: int | None = None
    angle_noise: float = 0.0

    def __post_init__(self) -> None:
        cpr, noise = self.counts_per_rev, self.angle_noise
        whole = isinstance(cpr, (int, float)) and not isinstance(cpr, bool) and cpr >= 1 and cpr == int(cpr)
        if cpr is not None and not whole:
            raise ParameterError(f"encoders: counts_per_rev must be a whole number >= 1, got {cpr!r}")
        real = isinstance(noise, (int, float)) and not isinstance(noise, bool) and math.isfinite(noise)
        if not (real and noise >= 0):
            raise ParameterError(f"encoders: angle_noise must be a finite number >= 0 (rad), got {noise!r}")
        object.__setattr__(self, "counts_per_rev", None if cpr is None else int(cpr))
        object.__setattr__(self, "angle_noise", float(noise))

    def controller_keywords(self) -> dict[str, Any]:
        """``counts_per_rev`` and ``angle_noise`` as the controllers that take them are given them; nothing where
        the count is not known (a controller's own design then stands)."""
        if self.counts_per_rev is None:
            return {}
        return {"counts_per_rev": self.counts_per_rev, "angle_noise": self.angle_noise}

    def to_json(self) -> dict[str, Any]:
        return {"counts_per_rev": self.counts_per_rev, "angle_noise": self.angle_noise}

    @classmethod
    def from_json(cls, data: Any, where: str) -> Encoders | None:
        if data is None:
            return None
        if not isinstance(data, Mapping):
            raise ParameterError(f"{where}: 'encoders' must be a mapping (counts_per_rev, angle_noise)")
        unknown = set(data) - {"counts_per_rev", "angle_noise"}
        if unknown:
            raise ParameterError(f"{where}: 'encoders' has unknown key(s): {', '.join(sorted(map(str, unknown)))}")
        try:
            return cls(data.get("counts_per_rev"), data.get("angle_noise", 0.0))
        except ParameterError as exc:
            raise ParameterError(f"{where}: {exc}") from None


def _check_records(records: list[Mapping[str, Any]], base_std: Mapping[str, Any], model: Any, where: str) -> None:
    """Refuse a record whose name or kind is not its effect's, or that gives a value or standard error of a
    parameter its effect does not have (a value filed under the wrong effect would be read as if it were right)."""
    effect_params = set(model.values)
    unknown = sorted(set(map(str, base_std)) - set(RigParams.__dataclass_fields__) - effect_params)
    if unknown:
        raise ParameterError(f"{where}: 'std': unknown parameter(s) {', '.join(unknown)}")
    for k, (rec, effect) in enumerate(zip(records, model.composition.effects)):
        for key, real in (("name", effect.name), ("kind", effect.kind)):
            if key in rec and rec[key] != real:
                raise ParameterError(
                    f"{where}: effect record {k}: {key!r} is {rec[key]!r} but its spec gives the effect "
                    f"{effect.name!r} ({key} {real!r})"
                )
        own = {p.name for p in effect.parameters}
        for key in ("values", "std"):
            other = sorted(set(map(str, rec.get(key) or {})) - own)
            if other:
                raise ParameterError(
                    f"{where}: effect record {k} ({effect.name}): {key} names {', '.join(other)}, not a parameter "
                    f"of {effect.name} (it has {', '.join(sorted(own)) or 'none'})"
                )
