"""Model files: the base parameters and the effects with their values, reusable by every command.

Written by ``drillgym identify --out p.json`` and read by ``--params`` of the identification
commands (``identify``, ``compare``, ``diagnose``)::

    {"params": {"Ju": 0.4765, ...},                      # RigParams (the others keep their default)
     "effects": [{"name": "string_cubic",
                  "spec": "examples/effects/string_cubic.py:string_cubic",
                  "file": "/abs/path/examples/effects/string_cubic.py",
                  "values": {"c3": 0.0151},
                  "std": {"c3": 0.0004}}],                 # optional: standard errors of the values
     "std": {"km": 0.0012}}                               # optional: standard errors of base parameters

A file of RigParams only (the older format, or ``{"params": {...}}`` alone) is a model without
effects.  YAML (``.yaml``/``.yml``) holds the same structure.  An effect's ``spec`` is what
``--add-effect`` accepts; when it names a file that does not exist relative to the working
directory, the file is looked for next to the model file, then at ``file``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..effects import Composition, EffectError, compose
from ..errors import MissingFileError
from ..io.jsonfile import write_json
from ..params import ParameterError, RigParams

__all__ = ["ModelFile", "read_model", "write_model"]


@dataclass
class ModelFile:
    """A model read from a file: base parameters, effect specs (in order), all effect values, and the
    standard errors the identification reported (by parameter name, base or effect; absent: unknown)."""

    params: RigParams
    specs: list[str] = field(default_factory=list)
    values: dict[str, float] = field(default_factory=dict)
    std: dict[str, float] = field(default_factory=dict)

    def composition(self) -> tuple[Composition, dict[str, float]]:
        return compose(self.specs, self.values)


def _load(path: Path) -> Any:
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ParameterError(f"{path}: cannot read parameter file ({exc.strerror})") from None
    except UnicodeDecodeError:
        raise ParameterError(
            f"{path}: not a parameter file (not UTF-8 text); give a JSON or YAML file of name: value"
        ) from None
    try:
        if path.suffix.lower() in (".yaml", ".yml"):
            import yaml

            return yaml.safe_load(text)
        return json.loads(text)
    except Exception as exc:  # noqa: BLE001 - any parse error, one line with the file name
        raise ParameterError(f"{path}: not valid {path.suffix.lstrip('.') or 'JSON'}: {exc}") from None


def _resolve_spec(spec: str, file: str | None, where: Path) -> str:
    if ".py:" not in spec:
        return spec
    fpath, _, name = spec.rpartition(":")
    for cand in (Path(fpath), where.parent / fpath, Path(file) if file else None):
        if cand is not None and cand.is_file():
            return f"{cand}:{name}"
    return spec  # compose reports the missing file in one line


def read_model(path: str | Path) -> ModelFile:
    """The model in a parameter file (see the module docstring).

    Parameters
    ----------
    path : str or path
        The file (JSON or YAML).

    Returns
    -------
    ModelFile
        Base parameters, effect specs and their values.

    Raises
    ------
    MissingFileError
        The file does not exist.
    ParameterError
        A file that cannot be used (the message names the file).
    """
    path = Path(path)
    if not path.exists():
        raise MissingFileError(f"{path}: parameter file not found")
    data = _load(path)
    if isinstance(data, Mapping) and "params" not in data and ("effects" in data or "std" in data):
        data = {**data, "params": {}}  # effects alone: on the default base parameters
    params = RigParams.from_dict(data, source=str(path), partial=True)  # a partial file: the rest keep their default
    specs: list[str] = []
    values: dict[str, float] = {}
    std = _std(data.get("std", {}) if isinstance(data, Mapping) else {}, path, "'std'")
    effects = data.get("effects", []) if isinstance(data, Mapping) else []
    if not isinstance(effects, list):
        raise ParameterError(f"{path}: 'effects' must be a list of {{spec, values}} records")
    for k, rec in enumerate(effects):
        if not isinstance(rec, Mapping) or not isinstance(rec.get("spec", rec.get("name")), str):
            raise ParameterError(f"{path}: effect record {k} needs a 'spec' (name or file.py:NAME)")
        specs.append(_resolve_spec(rec.get("spec") or rec["name"], rec.get("file"), path))
        vals = rec.get("values", {})
        if not isinstance(vals, Mapping):
            raise ParameterError(f"{path}: effect record {k}: 'values' must map parameter names to numbers")
        values.update(vals)
        std.update(_std(rec.get("std", {}), path, f"effect record {k}: 'std'"))
    try:
        compose(specs, values)
    except (EffectError, ParameterError) as exc:
        raise ParameterError(f"{path}: {exc}") from None
    return ModelFile(params, specs, {k: float(v) for k, v in values.items()}, std)


def _std(raw: Any, path: Path, what: str) -> dict[str, float]:
    """Standard errors ``name -> number`` (null: unknown, left out)."""
    if not isinstance(raw, Mapping):
        raise ParameterError(f"{path}: {what} must map parameter names to standard errors")
    out = {}
    for k, v in raw.items():
        if v is None:
            continue
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not v >= 0:
            raise ParameterError(f"{path}: {what}: the standard error of {k!r} must be a number >= 0, got {v!r}")
        out[str(k)] = float(v)
    return out


def write_model(
    path: str | Path,
    params: RigParams,
    records: Sequence[Mapping[str, Any]] = (),
    std: Mapping[str, float] | None = None,
) -> Path:
    """Write base parameters and effect records as JSON or YAML.

    Parameters
    ----------
    path : str or path
        The file (``.json``, ``.yaml`` or ``.yml``).
    params : RigParams
        The base parameters.
    records : sequence of mapping, optional
        Effect records ``{"name", "spec", "file", "values"}`` (optionally ``"std"``: their standard errors).
    std : mapping of str to float, optional
        Standard errors of base parameters (their units); non-finite ones are left out (unknown).

    Returns
    -------
    pathlib.Path
        The file written.
    """
    path = Path(path)
    data: dict[str, Any] = {"params": params.to_dict(), "effects": [dict(r) for r in records]}
    known = {k: float(v) for k, v in (std or {}).items() if math.isfinite(v)}
    if known:
        data["std"] = known
    if path.suffix.lower() in (".yaml", ".yml"):
        import yaml

        path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    else:
        write_json(path, data, nonfinite="refuse")
    return path
