"""The rig's parameter set: typed, immutable, with units and sources, validated.

``RigParams`` holds every physical parameter of the base model of
docs/model.md.  Effects (:mod:`drillgym.effects`) carry their own
parameters.  The simulator's compiled kernels take the parameters as a flat
float64 vector: the base parameters in the layout of :meth:`RigParams.to_vector`
and ``IDX`` (a kernel reads ``p[IDX.Ts]``), then the effects' parameters.

Files: JSON or YAML (by extension), a flat mapping ``name -> value``.  A file
may be partial: the names it gives override the defaults (the identified set),
the others keep their default (``drillgym params --out FILE`` writes a full file
to start from).  Unknown names, non-finite values and values outside physical
bounds are refused with an error that names the parameter.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

from .errors import ParameterError

__all__ = ["RigParams", "ParameterError", "PARAM_INFO", "IDX", "N_PARAMS", "BASE_PARAMETERS", "number"]


def number(value: Any, what: str) -> float:
    """``value`` as a float, or a one-line refusal naming ``what``.

    Parameters
    ----------
    value : object
        A number read from a file or given by a caller (a bool, a text or None is not one).
    what : str
        How the refusal names the value, e.g. ``"parameter 'Jl'"``.

    Returns
    -------
    float
        The value (not checked for finiteness: ``nan`` and ``inf`` are floats).

    Raises
    ------
    ParameterError
        Not a number, or an integer too large for a float (``1`` followed by 400 zeros in a JSON file).
    """
    if value is None or isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise ParameterError(f"{what} must be a number, got {value!r}")
    try:
        return float(value)
    except OverflowError:
        raise ParameterError(f"{what} is not finite (an integer of {len(str(abs(int(value))))} digits)") from None


def _p(value: float, unit: str, source: str, lo: float = -math.inf, hi: float = math.inf, doc: str = "") -> Any:
    return field(default=value, metadata={"unit": unit, "source": source, "lo": lo, "hi": hi, "doc": doc})


@dataclass(frozen=True)
class RigParams:
    """Physical parameters of the drill-string rig (SI units).

    Defaults are the identified set of docs/model.md (the source of each value is in
    ``PARAM_INFO[name]["source"]`` and :meth:`describe`).  Instances are immutable: use :meth:`replace`
    or :meth:`scaled`.  Every value is checked against its physical range.

    Parameters
    ----------
    Ju : float, optional
        Upper disc + motor inertia (kg m^2).  Default 0.4765.
    km : float, optional
        Motor constant, torque per volt (N m/V).  Default 4.3228.
    Tcu : float, optional
        Upper Coulomb friction level (N m).  Default 0.37975.
    dTcu : float, optional
        Upper Coulomb asymmetry (N m).  Default -0.00575.
    bu : float, optional
        Upper viscous friction (N m s/rad).  Default 2.4245.
    dbu : float, optional
        Upper viscous asymmetry (N m s/rad).  Default -0.0084.
    Jl : float, optional
        Lower disc inertia about its centre B (kg m^2).  Default 0.0414.
    ktheta : float, optional
        Torsional stiffness of the string (N m/rad).  Default 0.0775.
    Tcl : float, optional
        Bearing Coulomb friction (N m).  Default 0.0092.
    bl : float, optional
        Bearing viscous friction (N m s/rad).  Default 0.0171.
    Ts : float, optional
        Brake static friction (N m).  Default 0.2781.
    Tc : float, optional
        Brake Coulomb (slip) friction (N m).  Default 0.0473.
    ws : float, optional
        Stribeck velocity (rad/s).  Default 1.4302.
    delta : float, optional
        Stribeck exponent.  Default 2.0575.
    bb : float, optional
        Brake viscous friction (N m s/rad).  Default 0.0105.
    mr : float, optional
        Mass of the lower disc, rotating (kg).  Default 9.9137.
    mt : float, optional
        Translating mass: constraints, LVDT cores (kg).  Default 3.2302.
    k : float, optional
        Lateral stiffness (N/m).  Default 2974.25.
    b : float, optional
        Lateral viscous damping (N s/m).  Default 25.
    e : float, optional
        Mass unbalance eccentricity (m).  Default 0.0048917.

    Raises
    ------
    ParameterError
        A value that is not a finite number, lies outside its physical range, ``Ts < Tc`` or
        ``|dTcu| > Tcu``.

    Examples
    --------
    >>> from drillgym import RigParams
    >>> p = RigParams().replace(Ts=0.3)
    >>> round(p.stick_voltage, 3)  # V
    0.156
    """

    # --- upper part: DC motor, upper disc, asymmetric Coulomb + viscous friction (3.4), (3.5)
    Ju: float = _p(0.4765, "kg m^2", "report 3.2.2", 1e-6, 100, "upper disc + motor inertia")
    km: float = _p(4.3228, "N m/V", "rebuilt table 3.1", 1e-6, 1e3, "motor constant (torque per volt)")
    Tcu: float = _p(0.37975, "N m", "rebuilt table 3.1", 0.0, 100, "upper Coulomb friction level")
    dTcu: float = _p(-0.00575, "N m", "rebuilt table 3.1", -100, 100, "upper Coulomb asymmetry")
    bu: float = _p(2.4245, "N m s/rad", "rebuilt table 3.1", 0.0, 100, "upper viscous friction")
    dbu: float = _p(-0.0084, "N m s/rad", "rebuilt table 3.1", -100, 100, "upper viscous asymmetry")
    # --- lower part: disc, string
    Jl: float = _p(0.0414, "kg m^2", "table 3.4", 1e-6, 100, "lower disc inertia about its centre B")
    ktheta: float = _p(0.0775, "N m/rad", "table 3.4", 1e-6, 1e3, "torsional stiffness of the string")
    # --- lower bearing friction (brake off) (3.10), (3.11)
    Tcl: float = _p(0.0092, "N m", "table 3.4", 0.0, 100, "bearing Coulomb friction")
    bl: float = _p(0.0171, "N m s/rad", "table 3.4", 0.0, 100, "bearing viscous friction")
    # --- brake friction, Stribeck law (3.21), (3.22)
    Ts: float = _p(0.2781, "N m", "rebuilt table 3.7", 0.0, 100, "brake static friction")
    Tc: float = _p(0.0473, "N m", "rebuilt table 3.7", 0.0, 100, "brake Coulomb (slip) friction")
    ws: float = _p(1.4302, "rad/s", "rebuilt table 3.7", 1e-6, 1e3, "Stribeck velocity")
    delta: float = _p(2.0575, "-", "rebuilt table 3.7", 0.1, 20, "Stribeck exponent")
    bb: float = _p(0.0105, "N m s/rad", "rebuilt table 3.7", 0.0, 100, "brake viscous friction")
    # --- lateral part
    mr: float = _p(9.9137, "kg", "table 3.6", 1e-6, 1e3, "mass of the lower disc (rotating)")
    mt: float = _p(3.2302, "kg", "table 3.6", 0.0, 1e3, "translating mass (constraints, LVDT cores)")
    k: float = _p(2974.25, "N/m", "table 3.6", 1e-6, 1e7, "lateral stiffness")
    b: float = _p(25.0, "N s/m", "table 3.6", 0.0, 1e5, "lateral viscous damping")
    e: float = _p(0.0048917, "m", "table 3.6", 0.0, 0.05, "mass unbalance eccentricity")

    # ------------------------------------------------------------------ API
    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            v = number(v, f"parameter {f.name!r}")
            object.__setattr__(self, f.name, v)
            if not math.isfinite(v):
                raise ParameterError(f"parameter {f.name!r} is not finite ({v})")
            lo, hi = f.metadata["lo"], f.metadata["hi"]
            if not (lo <= v <= hi):
                raise ParameterError(
                    f"parameter {f.name!r} = {v} {f.metadata['unit']} is outside its physical range [{lo}, {hi}]"
                )
        if self.Ts < self.Tc:
            raise ParameterError(f"parameter 'Ts' = {self.Ts} must be >= 'Tc' = {self.Tc} (static >= slip friction)")
        if abs(self.dTcu) > self.Tcu:
            raise ParameterError(f"parameter 'dTcu' = {self.dTcu}: |dTcu| must not exceed Tcu = {self.Tcu}")

    @classmethod
    def default(cls) -> RigParams:
        """The identified parameter set of docs/model.md."""
        return cls()

    def replace(self, **changes: float) -> RigParams:
        """A copy with some parameters changed (validated).

        Parameters
        ----------
        **changes : float
            New values by parameter name, in the parameter's unit.

        Returns
        -------
        RigParams
            The changed copy.

        Raises
        ------
        ParameterError
            An unknown name or a value outside its physical range.
        """
        unknown = set(changes) - set(PARAM_INFO)
        if unknown:
            raise ParameterError(f"unknown parameter(s): {', '.join(sorted(unknown))}")
        return replace(self, **changes)

    def scaled(self, **factors: float) -> RigParams:
        """A copy with parameters multiplied by factors, e.g. ``scaled(Ts=1.2, Tc=1.2)``.

        Parameters
        ----------
        **factors : float
            Dimensionless factor by parameter name.

        Returns
        -------
        RigParams
            The scaled copy (validated as :meth:`replace`).
        """
        return self.replace(**{k: getattr(self, k) * f for k, f in factors.items()})

    def to_dict(self) -> dict[str, float]:
        """Every parameter by name, in SI units."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, source: str = "mapping", partial: bool = False) -> RigParams:
        """Build from a mapping of parameter names to numbers.

        Parameters
        ----------
        data : mapping
            ``name -> value`` (SI units), or a mapping with such a mapping under ``"params"``.
        source : str, optional
            Where the mapping comes from, named in error messages.
        partial : bool, optional
            False (default): every base parameter must be present.  True: the names given override the
            defaults (the identified set), the others keep their default.

        Returns
        -------
        RigParams
            The validated parameter set.

        Raises
        ------
        ParameterError
            An unknown or missing name, a value that is not a number or lies outside its physical range.
        """
        if not isinstance(data, Mapping):
            raise ParameterError(f"{source}: expected a mapping of parameter names to numbers")
        if ("params" in data and isinstance(data["params"], Mapping)) or isinstance(data.get("effects"), list):
            effects = data.get("effects")
            if effects:  # a model file: its effects would be dropped without a word
                names = ", ".join(str(e.get("name", e.get("spec"))) for e in effects if isinstance(e, Mapping))
                names = names or repr(effects)
                raise ParameterError(
                    f"{source}: a model file with effects ({names}), read here for base parameters "
                    "only: give it as a model (--model FILE, model=)"
                )
            data = data.get("params", {})
        unknown = set(data) - set(PARAM_INFO)
        if unknown:
            raise ParameterError(f"{source}: unknown parameter(s): {', '.join(sorted(unknown))}")
        if not partial:
            missing = [n for n in BASE_PARAMETERS if n not in data]
            if missing:
                raise ParameterError(f"{source}: missing parameter(s): {', '.join(missing)}")
        values = {}
        for name, v in data.items():
            values[name] = number(v, f"{source}: parameter {name!r}")
        try:
            return cls(**values)
        except ParameterError as exc:
            raise ParameterError(f"{source}: {exc}") from None

    @classmethod
    def from_file(cls, path: str | Path, *, partial: bool = True) -> RigParams:
        """Load from JSON (``.json``) or YAML (``.yaml``/``.yml``).

        Parameters
        ----------
        path : str or path
            A flat mapping ``name -> value`` (SI units) in JSON or YAML, by extension.
        partial : bool, optional
            True (default): the file may name only some parameters; those override the defaults (the
            identified set of docs/model.md), the rest keep their default.  False: a file missing a base
            parameter is refused.  Unknown names are refused either way.

        Returns
        -------
        RigParams
            The validated parameter set.

        Raises
        ------
        ParameterError
            The file cannot be read or parsed, or holds an unknown name or an invalid value.
        """
        path = Path(path)
        try:
            text = path.read_text(encoding="utf-8")
        except OSError as exc:
            raise ParameterError(f"{path}: cannot read parameter file ({exc.strerror})") from None
        except UnicodeDecodeError:
            raise ParameterError(
                f"{path}: not a parameter file (not UTF-8 text); give a JSON or YAML file of name: value"
            ) from None
        try:
            from .io.structured import load_structured

            data = load_structured(text, path.suffix)
        except Exception as exc:  # noqa: BLE001 - report any parse error with the file name
            from .io import describe_parse_error

            raise ParameterError(
                f"{path}: not valid {path.suffix.lstrip('.') or 'JSON'}: {describe_parse_error(exc)}"
            ) from None
        return cls.from_dict(data, source=str(path), partial=partial)

    def to_file(self, path: str | Path) -> Path:
        """Save as JSON or YAML (by extension); :meth:`from_file` reads it back exactly.

        Parameters
        ----------
        path : str or path
            Output file; ``.yaml``/``.yml`` writes YAML, anything else JSON.

        Returns
        -------
        Path
            The path written.
        """
        path = Path(path)
        data = self.to_dict()
        if path.suffix.lower() in (".yaml", ".yml"):
            import yaml

            path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
        else:
            from .io.jsonfile import write_json

            write_json(path, data, nonfinite="refuse")
        return path

    def to_vector(self) -> np.ndarray:
        """Flat float64 vector in the kernel layout (see ``IDX``)."""
        return np.array([getattr(self, n) for n in PARAM_NAMES], dtype=np.float64)

    @classmethod
    def from_vector(cls, vec: np.ndarray) -> RigParams:
        """Build from a flat vector in the kernel layout (the inverse of :meth:`to_vector`)."""
        vec = np.asarray(vec, dtype=float)
        if vec.shape != (N_PARAMS,):
            raise ParameterError(f"parameter vector must have shape ({N_PARAMS},), got {vec.shape}")
        return cls(**dict(zip(PARAM_NAMES, vec.tolist())))

    # derived quantities
    @property
    def m(self) -> float:
        """Total translating mass mr + mt (kg)."""
        return self.mr + self.mt

    @property
    def lateral_eigenfrequency(self) -> float:
        """sqrt(k / (mr + mt)) in rad/s (docs/model.md, R6)."""
        return math.sqrt(self.k / self.m)

    @property
    def stick_voltage(self) -> float:
        """us = (Tcu + dTcu + Ts) / km: below it the stick set is globally stable (R4), in V."""
        return (self.Tcu + self.dTcu + self.Ts) / self.km

    def describe(self) -> str:
        """A table of all parameters with units and sources."""
        rows = [f"{'name':<10} {'value':>14} {'unit':<11} source"]
        for n in PARAM_NAMES:
            info = PARAM_INFO[n]
            rows.append(f"{n:<10} {getattr(self, n):>14.6g} {info['unit']:<11} {info['source']}")
        return "\n".join(rows)


PARAM_NAMES: tuple[str, ...] = tuple(f.name for f in fields(RigParams))
PARAM_INFO: dict[str, dict[str, Any]] = {f.name: dict(f.metadata) for f in fields(RigParams)}
BASE_PARAMETERS: tuple[str, ...] = tuple(n for n in PARAM_NAMES if not PARAM_INFO[n]["source"].startswith("effect"))
N_PARAMS = len(PARAM_NAMES)
IDX = SimpleNamespace(**{n: i for i, n in enumerate(PARAM_NAMES)})
