"""The model of a rig as one value: base parameters, effects, their values, standard errors, provenance.

A :class:`Model` is what identification gives (:func:`drillgym.identify`) and what every part of
drillgym takes as ``model=`` (``simulate``, ``simulate_batch``, the environments, the controllers,
``evaluate``, ``compare``, the bifurcation functions, ``train``) or ``--model FILE`` on the command
line.  It is immutable; :meth:`Model.replace` gives a changed copy.

A model file (JSON or YAML) holds the same structure::

    {"format": "drillgym-model", "version": 2,
     "params": {"Ju": 0.4765, ...},                   # base parameters (SI units)
     "std": {"km": 0.0012},                           # standard errors of base parameters (optional)
     "effects": [                                      # in signal-path order
        {"name": "motor_lag", "spec": "motor_lag", "values": {"tau_m": 0.05}, "std": {"tau_m": 0.001}},
        {"name": "candidate_motor", "spec": "rec_candidate.py:candidate_motor",
         "file": "rec_candidate.py", "sha256": "9f2c...", "values": {...}}],
     "provenance": {"recording": "rec.csv", "recording_sha256": "...", "route": "identify", ...}}

**Effect files are code.**  A model's effects may be user or candidate files; loading the model
imports and runs them, so a model file shared by a colleague is as powerful as a script.  Files are
referenced relative to the model file (a model folder can be copied whole), and :meth:`Model.save`
copies an effect file that lies outside the model's folder into it and records its SHA-256.
:meth:`Model.load` refuses, in one line naming it, an effect file outside the model's folder, one
without a recorded hash, or one changed since the model was written, unless the caller says it
trusts the code (``trust=True``, ``--trust``), as ``torch.load(weights_only=True)`` does.
:func:`code_files` lists the files a model would import, without importing them.

The older model files (``{"params", "effects"[spec, file, values, std], "std"}`` written before this
format, or a file of base parameters only) still read; their effect files carry no hash and need
``trust=True``.

Examples
--------
>>> from drillgym import Model, simulate
>>> m = Model(effects=("motor_lag",), values={"tau_m": 0.05})
>>> traj = simulate("torsional", u=1.0, duration=1.0, model=m)
>>> m.save("out/model.json")
>>> Model.load("out/model.json") == m
True
"""

from __future__ import annotations

import hashlib
import json
import math
import shutil
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from functools import cached_property
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from .effects import Composition, EffectError, compose
from .effects.base import Effect
from .errors import InputError, InputTypeError, MissingFileError
from .io.jsonfile import write_json
from .model_files import (
    FORMAT,
    VERSION,
    CodeFile,
    Encoders,
    Provenance,
    _check_records,
    _code_files,
    _effect_records,
    _read,
    _resolve_spec,
    _sha256,
    _std,
    code_files,
)
from .params import ParameterError, RigParams, number

__all__ = [
    "Model", "Encoders", "Provenance", "CodeFile", "code_files", "as_model", "UntrustedCodeError", "MODEL_SUFFIXES",
]  # fmt: skip

#: the suffixes of a model file
MODEL_SUFFIXES = (".json", ".yaml", ".yml")


class UntrustedCodeError(InputError):
    """A model file names code that is not trusted (outside the model's folder, unhashed or changed)."""


def _numbers(mapping: Any, what: str) -> dict[str, float]:
    """``mapping`` (None: empty) as ``name -> float``, refused unless it maps names to numbers."""
    if mapping is None:
        return {}
    if not isinstance(mapping, Mapping):
        raise InputTypeError(f"Model: {what} must map parameter names to numbers, got {type(mapping).__name__}")
    return {str(k): number(v, f"Model: {what}: {k!r}") for k, v in mapping.items()}


def _frozen(mapping: Mapping[str, float] | None) -> Mapping[str, float]:
    return MappingProxyType({str(k): float(v) for k, v in (mapping or {}).items()})


def _effect_file(effect: type[Effect]) -> str | None:
    return getattr(effect, "__drillgym_file__", None)


@dataclass(frozen=True, eq=False)
class Model:
    """The model of a rig: base parameters, effects in signal-path order, their values and standard errors.

    Parameters
    ----------
    params : RigParams, optional
        Base parameters (default: the identified set of the model page).
    effects : sequence, optional
        The effects: library names (``"motor_lag"``), file specs (``"path/file.py:NAME"``) or Effect
        classes, in signal-path order (command side first).
    values : mapping of str to float, optional
        Effect parameter values by name (each parameter's unit); the others take their defaults.
    std : mapping of str to float, optional
        Standard errors by parameter name, base or effect (absent: unknown).
    provenance : Provenance, optional
        Where the model came from.
    encoders : Encoders, optional
        The angle encoders the recording showed (resolution, noise beside the counts); the controllers built on
        the model expect them (None: unknown, each controller's own design).

    Raises
    ------
    EffectError, ParameterError
        An unknown effect, an unknown effect parameter or a value outside its bounds.
    """

    params: RigParams = field(default_factory=RigParams)
    effects: tuple[str | type[Effect], ...] = ()
    values: Mapping[str, float] = field(default_factory=dict)
    std: Mapping[str, float] = field(default_factory=dict)
    provenance: Provenance = field(default_factory=Provenance)
    encoders: Encoders | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.params, RigParams):
            raise InputError(f"Model: params must be a RigParams, got {type(self.params).__name__}")
        effects = self.effects
        if isinstance(effects, (str, Composition)) or isinstance(effects, type):
            effects = effects.effects if isinstance(effects, Composition) else (effects,)
        if effects is None or isinstance(effects, (bytes, Mapping)) or not hasattr(effects, "__iter__"):
            raise InputTypeError(
                "Model: effects must be a sequence of effects (library names, 'path/file.py:NAME' or Effect "
                f"classes), got {type(effects).__name__}"
            )
        if not isinstance(self.provenance, Provenance):
            raise InputTypeError(f"Model: provenance must be a Provenance, got {type(self.provenance).__name__}")
        if self.encoders is not None and not isinstance(self.encoders, Encoders):
            raise InputTypeError(f"Model: encoders must be an Encoders or None, got {type(self.encoders).__name__}")
        object.__setattr__(self, "effects", tuple(effects))
        given = _numbers(self.values, "values")
        std = _numbers(self.std, "std")
        negative = [k for k, v in std.items() if v < 0]
        if negative:
            raise ParameterError(
                f"Model: std: the standard error of {negative[0]!r} must be >= 0, got {std[negative[0]]}"
            )
        comp, values = compose(list(self.effects), given)
        object.__setattr__(self, "values", _frozen(values))
        object.__setattr__(self, "std", _frozen({k: v for k, v in std.items() if math.isfinite(v)}))
        object.__setattr__(self, "_composition", comp)

    # ------------------------------------------------------------------ views
    @property
    def composition(self) -> Composition:
        """The effects' composition (compiled once per composition and process)."""
        return self._composition  # type: ignore[attr-defined]

    @cached_property
    def vector(self) -> np.ndarray:
        """The composition's parameter vector (base, then effect parameters)."""
        v = self.composition.vector(self.params, dict(self.values))
        v.setflags(write=False)
        return v

    @property
    def label(self) -> str:
        """``base`` or the effects' names joined by ``+``."""
        return self.composition.label

    @property
    def specs(self) -> list[str]:
        """The effects as ``--add-effect`` takes them: library names, or ``path/file.py:NAME`` for a file's."""
        return [r["spec"] for r in self.records()]

    @property
    def names(self) -> list[str]:
        """The effects' names, in order."""
        return [e.name for e in self.composition.effects]

    @cached_property
    def _effects_key(self) -> tuple:
        """The effects as compared: a library effect by its class, a file's by its name and the file's content
        (a model and its copy saved in another folder are equal)."""
        return tuple(_effect_key(e) for e in self.composition.effects)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Model):
            return NotImplemented
        return (
            self.params == other.params
            and self._effects_key == other._effects_key
            and dict(self.values) == dict(other.values)
            and dict(self.std) == dict(other.std)
            and self.encoders == other.encoders
        )

    def __hash__(self) -> int:
        return hash((self.params, self._effects_key, tuple(sorted(self.values.items()))))

    def __repr__(self) -> str:
        vals = ", ".join(f"{k}={v:.4g}" for k, v in self.values.items())
        return f"Model({self.label}{': ' + vals if vals else ''})"

    def __reduce__(self) -> tuple:
        """Pickled by its parts (effects by spec: a library name or ``path.py:NAME``), so a model crosses process
        boundaries (vector envs, Ray, multiprocessing) and ``copy.deepcopy`` works."""
        effects = tuple(
            r["spec"] if _effect_file(e) is not None or _library_effect(e) is e else e
            for r, e in zip(self.records(), self.composition.effects)
        )
        return (Model, (self.params, effects, dict(self.values), dict(self.std), self.provenance, self.encoders))

    def replace(self, **changes: Any) -> Model:
        """A copy with fields changed (``params``, ``effects``, ``values``, ``std``, ``provenance``)."""
        kw = {f.name: getattr(self, f.name) for f in fields(self)}
        unknown = set(changes) - set(kw)
        if unknown:
            raise InputError(f"Model.replace: unknown field(s): {', '.join(sorted(unknown))}")
        kw.update(changes)
        return Model(**kw)

    @classmethod
    def from_composition(
        cls,
        params: RigParams,
        composition: Composition,
        values: Mapping[str, float],
        std: Mapping[str, float] | None = None,
        provenance: Provenance | None = None,
    ) -> Model:
        """A model from a composition and its values (the effects keep the composition's order)."""
        return cls(params, tuple(composition.effects), values, std or {}, provenance or Provenance())

    def in_configuration(self, configuration: str) -> Model:
        """The model as a run of ``configuration`` (a label such as ``"free_vibration"``) uses it: without the
        effects that do not act there (a motor lag when the motor is disconnected), each left out with a warning
        that names it; the model itself when all act.

        Parameters
        ----------
        configuration : str
            The run's configuration label.

        Returns
        -------
        Model
            The model without the idle effects, their values and standard errors.
        """
        idle = self.composition.not_acting_in(configuration)
        if not idle:
            return self
        for e in idle:
            warnings.warn(
                f"the model's effect {e.name} does not act in the {configuration} configuration (it acts in "
                f"{', '.join(e.configurations)}): the run leaves it out",
                stacklevel=3,
            )
        kept = [e for e in self.composition.effects if e not in idle]
        dropped = {p.name for e in idle for p in e.parameters}
        return Model(
            self.params,
            tuple(kept),
            {k: v for k, v in self.values.items() if k not in dropped},
            {k: v for k, v in self.std.items() if k not in dropped},
            self.provenance,
            self.encoders,
        )

    def simulation_arguments(self) -> dict[str, Any]:
        """``params``, ``effects`` and ``effect_params`` as the simulator takes them."""
        return {"params": self.params, "effects": self.composition, "effect_params": dict(self.values)}

    # ------------------------------------------------------------------ files
    def records(self) -> list[dict[str, Any]]:
        """One record per effect: ``name``, ``spec``, ``kind``, ``values``, ``std`` (and ``file`` for a file)."""
        out = []
        for e in self.composition.effects:
            rec: dict[str, Any] = {"name": e.name, "kind": e.kind, "spec": e.name}
            f = _effect_file(e)
            if f is not None:
                rec["file"] = f
                rec["spec"] = f"{f}:{e.name}"
            rec["values"] = {p.name: float(self.values[p.name]) for p in e.parameters}
            std = {p.name: self.std[p.name] for p in e.parameters if p.name in self.std}
            if std:
                rec["std"] = std
            out.append(rec)
        return out

    def save(self, path: str | Path) -> Path:
        """Write the model file (JSON or YAML by suffix), copying effect files into its folder.

        An effect file outside the model file's folder is copied into it (under its own name, or with a
        hash suffix when another file of that name is there); the record names it relative to the model
        file with its SHA-256, so the folder can be copied whole.

        Parameters
        ----------
        path : str or path
            The file (``.json``, ``.yaml`` or ``.yml``); its folder is created.

        Returns
        -------
        pathlib.Path
            The file written.

        Raises
        ------
        InputError
            A suffix other than a model file's, or an effect defined in Python code rather than in a file or
            the library (it cannot be written).
        """
        path = _as_path(path, "Model.save: path")
        if path.suffix.lower() not in MODEL_SUFFIXES:
            raise InputError(f"{path}: a model file must end in .json, .yaml or .yml")
        from .io.outputs import check_output_file

        check_output_file(path, "Model.save:", MODEL_SUFFIXES)  # before an effect file is copied beside it
        folder = path.parent
        folder.mkdir(parents=True, exist_ok=True)
        records = []
        for rec in self.records():
            e_file = rec.pop("file", None)
            if e_file is not None:
                rel = _place_in(Path(e_file), folder)
                rec["spec"] = f"{rel.as_posix()}:{rec['name']}"
                rec["file"] = rel.as_posix()
                rec["sha256"] = _sha256(folder / rel)
            else:
                cls = next(e for e in self.composition.effects if e.name == rec["name"])
                if _library_effect(cls) is not cls:
                    raise InputError(
                        f"effect {rec['name']!r} is defined in Python code, not in a file or the library: write it "
                        "to a file (path/file.py) to save a model with it"
                    )
            records.append(rec)
        base_std = {k: v for k, v in self.std.items() if k in RigParams.__dataclass_fields__}
        data: dict[str, Any] = {"format": FORMAT, "version": VERSION, "params": self.params.to_dict()}
        if base_std:
            data["std"] = base_std
        data["effects"] = records
        if self.encoders is not None:
            data["encoders"] = self.encoders.to_json()
        data["provenance"] = self.provenance.to_json()
        if path.suffix.lower() in (".yaml", ".yml"):
            import yaml

            from .io.paths import written_whole

            with written_whole(path, "the model file") as fh:
                fh.write(yaml.safe_dump(json.loads(json.dumps(data)), sort_keys=False))
        else:
            write_json(path, data, nonfinite="refuse")
        return path

    @classmethod
    def load(cls, path: str | Path, *, trust: bool = False) -> Model:
        """Read a model file (this format, an older model file, or a file of base parameters).

        Parameters
        ----------
        path : str or path
            The file (JSON or YAML).
        trust : bool, optional
            Import effect files the model names even when they lie outside its folder, carry no recorded
            hash or changed since it was written (default False: refused).  Only for files you trust:
            importing an effect file runs it.

        Returns
        -------
        Model

        Raises
        ------
        MissingFileError
            The file does not exist.
        UntrustedCodeError
            An effect file that is not trusted (the message names it and why), without ``trust``.
        ParameterError
            A file that cannot be used (the message names the file).
        """
        path = _as_path(path, "Model.load: path")
        _as_flag(trust, "Model.load: trust")
        # effect files resolve beside the file itself, not beside a link to it (a linked model file still runs)
        return cls.from_mapping(_read(path), path.resolve(), trust=trust, where=str(path))

    @classmethod
    def from_mapping(
        cls, data: Mapping[str, Any], path: str | Path, *, trust: bool = False, where: str = "", hashed: bool = True
    ) -> Model:
        """A model from the mapping a model file holds (``params``, ``std``, ``effects``, ``provenance``), e.g. one
        entry of a file that holds several (the plants of ``evaluate --plants-file``).

        Parameters
        ----------
        data : mapping
            The model's keys, as in a model file.
        path : str or path
            The file it was read from: effect files resolve relative to its folder, and must lie in it (the trust
            rule of :meth:`load`).
        trust : bool, optional
            As :meth:`load`.
        where : str, optional
            How errors name the mapping (default ``path``), e.g. ``"plants.yaml: plant 'worn' (#1)"``.
        hashed : bool, optional
            True (default): an effect file must carry its recorded SHA-256 to be trusted (files :meth:`save`
            wrote); False: a file written by hand, an effect file in its folder is trusted unless a recorded
            hash differs.

        Returns
        -------
        Model

        Raises
        ------
        UntrustedCodeError, ParameterError
            As :meth:`load`, the messages led by ``where``.
        """
        path, where = _as_path(path, "Model.from_mapping: path"), where or str(path)
        _as_flag(trust, "Model.from_mapping: trust")
        if not isinstance(data, Mapping):
            raise InputTypeError(f"{where}: a model is a mapping (params, effects, ...), got {type(data).__name__}")
        records = _effect_records(data, where)  # malformed records: named by ``where`` before the files are listed
        missing = [c for c in _code_files(data, path) if not c.path.is_file()]
        if missing:  # not a question of trust: --trust would not bring the file back
            raise MissingFileError(
                f"{where}: effect {missing[0].effect!r}: its file {missing[0].path} is not found (a model's effect "
                "files lie in its folder: copy the whole folder)"
            )
        if not trust:
            ok = (lambda c: c.trusted) if hashed else (lambda c: c.inside and (c.recorded_sha256 is None or c.matches))
            bad = [c for c in _code_files(data, path) if not ok(c)]
            if bad:
                c = bad[0]
                why = "outside the file's folder" if not c.inside and not hashed else c.why_untrusted()
                raise UntrustedCodeError(
                    f"{where}: effect {c.effect!r} is code in {c.path} ({why}); loading it would run it: pass "
                    "trust=True (--trust) if you trust that file"
                )
        params = RigParams.from_dict(data.get("params", {}), source=where, partial=True)
        std = _std(data.get("std", {}), where, "'std'")
        specs: list[str] = []
        values: dict[str, float] = {}
        for k, rec in enumerate(records):
            specs.append(_resolve_spec(rec, path))
            vals = rec.get("values", {})
            if not isinstance(vals, Mapping):
                raise ParameterError(f"{where}: effect record {k}: 'values' must map parameter names to numbers")
            for name, v in vals.items():
                values[str(name)] = number(v, f"{where}: effect record {k}: {name!r}")
            std.update(_std(rec.get("std", {}), where, f"effect record {k}: 'std'"))
        prov = Provenance.from_json(data["provenance"], where) if "provenance" in data else Provenance()
        try:
            model = cls(params, tuple(specs), values, std, prov, Encoders.from_json(data.get("encoders"), where))
        except (EffectError, ParameterError) as exc:
            raise ParameterError(f"{where}: {exc}") from None
        _check_records(records, data.get("std", {}), model, where)
        return model


def _effect_key(effect: type[Effect]) -> Any:
    """An effect as :meth:`Model.__eq__` compares it: its class, or for a file's (name, digest of the file)."""
    f = _effect_file(effect)
    if f is None:
        return effect
    try:
        return (effect.name, hashlib.sha256(Path(f).read_bytes()).hexdigest())
    except OSError:  # the file is gone: its path is all that is left to compare
        return (effect.name, f)


def _as_path(value: Any, who: str) -> Path:
    """``value`` as a path, refused unless it is a text or path-like."""
    if isinstance(value, (str, Path)) or hasattr(value, "__fspath__"):
        return Path(value)
    raise InputTypeError(f"{who} must be a file's path (text or path-like), got {type(value).__name__}")


def _as_flag(value: Any, who: str) -> None:
    """Refuse a ``trust`` that is not True or False: ``trust="no"`` would run the code it names."""
    if not isinstance(value, (bool, np.bool_)):
        raise InputTypeError(f"{who} must be True or False, got {value!r}")


def _library_effect(cls: type[Effect]) -> Any:
    from .effects.library import LIBRARY

    return LIBRARY.get(cls.name)


def _place_in(file: Path, folder: Path) -> Path:
    """The effect file's path relative to ``folder``, copying it there when it lies outside."""
    file = file.resolve()
    folder_r = folder.resolve()
    if file.is_relative_to(folder_r):
        return file.relative_to(folder_r)
    target = folder_r / file.name
    # a link there is not the file's copy: loading would resolve it outside the folder and refuse it
    if target.is_symlink() or (target.exists() and _sha256(target) != _sha256(file)):
        target = folder_r / f"{file.stem}_{_sha256(file)[:8]}{file.suffix}"
    if target.is_symlink():
        raise InputError(f"{target}: a symbolic link where the model's copy of {file} goes; save the model elsewhere")
    if not target.exists():
        shutil.copy2(file, target)
    return target.relative_to(folder_r)


def as_model(model: Any, *, trust: bool = False, who: str = "model") -> Model:
    """A :class:`Model` from what a caller gives: a Model, or the path of a model file.

    Parameters
    ----------
    model : Model, str or path
        The model or its file.
    trust : bool, optional
        Passed to :meth:`Model.load` for a path.
    who : str, optional
        The argument's name in error messages.

    Raises
    ------
    InputTypeError
        Neither a Model nor a path.
    """
    if isinstance(model, Model):
        return model
    if isinstance(model, (str, Path)) or hasattr(model, "__fspath__"):
        return Model.load(Path(model), trust=trust)
    from .errors import InputTypeError

    raise InputTypeError(f"{who} must be a drillgym.Model or the path of a model file, got {type(model).__name__}")


def model_arguments(
    model: Any,
    params: Any = None,
    effects: Any = None,
    effect_params: Any = None,
    who: str = "simulate",
    configuration: str | None = None,
) -> tuple[Any, Any, Any]:
    """``(params, effects, effect_params)`` of a run given ``model=`` (or the three as given without one); with a
    ``configuration`` label, the model's effects that do not act there left out (:meth:`Model.in_configuration`).

    Raises
    ------
    InputError
        A model given beside ``params``, ``effects`` or ``effect_params`` (the model holds them).
    """
    if model is None:
        return params, effects, effect_params
    given = [
        n for n, v in (("params", params), ("effects", effects), ("effect_params", effect_params)) if v is not None
    ]
    if given:
        raise InputError(f"{who}: give model= or {', '.join(given)}, not both (the model holds its own)")
    m = as_model(model, who=f"{who}: model")
    if configuration is not None:
        m = m.in_configuration(configuration)
    return m.params, m.composition, dict(m.values)
