"""Time-series files of the rig (../shared/DATA_FORMAT.md): read, validate, write, stream.

One format for measurements, recordings and simulations:

* CSV: ``#`` comment lines first (``# meta: {json}`` holds metadata), then a
  header and comma-separated rows.  Columns in SI units, any order; unknown
  columns are kept.  Required: ``t``, ``u``, ``theta_u``; ``theta_l`` for every
  configuration but ``upper``; ``x``, ``y`` (fixed frame) for ``lateral`` and
  ``coupled``.
* MATLAB ``.mat`` as Simulink writes it (arrays, "structure with time", or
  a timeseries-like struct), columns mapped by name (aliases accepted) or an
  explicit ``mapping={"column": "matlab_name"}``.  A variable with several
  columns (a muxed ``signals.values`` of shape (N, k), several signals of a
  "structure with time", a matrix) offers them as ``name:1`` … ``name:k``
  (1-based, as in MATLAB), e.g. ``mapping={"theta_u": "ScopeData:2"}``; a
  signal's ``label`` is a name too.  The CLI's ``--map theta_u=ScopeData:2``.
* ``mapping`` works for CSV too: ``{"theta_u": "enc1"}`` reads column ``enc1``
  as ``theta_u``.

A file that cannot be used raises :class:`DataFormatError` naming the file,
the line or column and what is wrong.  Nothing is dropped or guessed.
"""

from __future__ import annotations

import csv
import json
import math
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

import numpy as np

from .configurations import Configuration, parse_configuration
from .errors import DataFormatError, InputError, OutputPathError

__all__ = [
    "TimeSeries",
    "read_timeseries",
    "read_input_signal",
    "read_csv",
    "read_mat",
    "write_timeseries",
    "write_trajectory_csv",
    "StreamingCsvWriter",
    "required_columns",
    "DataFormatError",
    "U_LIMIT_FILE",
    "XY_LIMIT_FILE",
    "create_directory",
    "describe_parse_error",
]

U_LIMIT_FILE = 50.0  # V: larger |u| in a file is refused
XY_LIMIT_FILE = 0.05  # m: larger |x|, |y| in a file is refused
KNOWN_COLUMNS = ("t", "u", "theta_u", "theta_l", "x", "y", "omega_u", "omega_l")

# names accepted in .mat files for each column (lower case)
MAT_ALIASES = {
    "t": ("t", "time", "tout"),
    "u": ("u", "voltage", "input", "u_motor", "vin"),
    "theta_u": ("theta_u", "thetau", "th_u", "phi_u", "theta_upper", "enc_u", "encoder_upper"),
    "theta_l": ("theta_l", "thetal", "th_l", "phi_l", "theta_lower", "enc_l", "encoder_lower"),
    "x": ("x", "lvdt_x", "x_lvdt"),
    "y": ("y", "lvdt_y", "y_lvdt"),
    "omega_u": ("omega_u", "omegau", "w_u", "wu"),
    "omega_l": ("omega_l", "omegal", "w_l", "wl"),
}


def required_columns(config: Configuration | None) -> tuple[str, ...]:
    """Columns a file must have for a configuration.

    Parameters
    ----------
    config : Configuration or None
        The configuration; None: the minimum ``t``, ``u``, ``theta_u``.

    Returns
    -------
    tuple of str
        ``t``, ``u``, ``theta_u``; ``theta_l`` but for ``upper``; ``x``, ``y`` for ``lateral`` and ``coupled``.
    """
    cols = ["t", "u", "theta_u"]
    if config is not None and config is not Configuration.UPPER:
        cols.append("theta_l")
    if config is not None and config.lateral_free:
        cols += ["x", "y"]
    return tuple(cols)


@dataclass
class TimeSeries:
    """A validated time series: named columns of one length, SI units, with metadata.

    Attribute access gives a known column (``ts.theta_l``: ``t``, ``u``, ``theta_u``, ``theta_l``,
    ``x``, ``y``, ``omega_u``, ``omega_l``) or None when the file has none.

    Parameters
    ----------
    columns : dict of str to ndarray
        Column name -> 1-D float array, all the same length: ``t`` (s), ``u`` (V), angles (rad),
        ``x``, ``y`` (m, fixed frame), speeds (rad/s); unknown columns are kept.
    meta : dict, optional
        Metadata (``configuration``, ``sample_rate_hz``, ``source``, ``description``, ...).
    source : str, optional
        Where the series comes from (a file name), named in error messages.
    """

    columns: dict[str, np.ndarray]
    meta: dict = field(default_factory=dict)
    source: str = "<memory>"

    def __getattr__(self, name: str):
        if name in KNOWN_COLUMNS and "columns" in self.__dict__:
            return self.columns.get(name)
        raise AttributeError(name)

    def __len__(self) -> int:
        return len(self.columns["t"])

    def __contains__(self, name: str) -> bool:
        return name in self.columns

    @property
    def configuration(self) -> Configuration | None:
        """The rig configuration named in the metadata, or None."""
        c = self.meta.get("configuration")
        return parse_configuration(c) if c else None

    @property
    def sample_rate_hz(self) -> float:
        """Median sample rate (Hz)."""
        return float(1.0 / np.median(np.diff(self.columns["t"])))

    @property
    def duration(self) -> float:
        """Time from the first to the last sample (s)."""
        t = self.columns["t"]
        return float(t[-1] - t[0])

    @property
    def r(self) -> np.ndarray | None:
        """Lateral displacement sqrt(x^2 + y^2) (m), or None without ``x`` and ``y``."""
        if "x" in self.columns and "y" in self.columns:
            return np.hypot(self.columns["x"], self.columns["y"])
        return None

    def resample(self, rate_hz: float) -> TimeSeries:
        """The series on a uniform grid from the first sample.

        Parameters
        ----------
        rate_hz : float
            Sample rate of the grid (Hz).

        Returns
        -------
        TimeSeries
            ``u`` held between samples (zero-order, as commanded), the other columns interpolated
            linearly; ``meta["sample_rate_hz"]`` set to ``rate_hz``.
        """
        if not (rate_hz > 0 and math.isfinite(rate_hz)):
            raise InputError(f"resample rate must be a positive number of Hz, got {rate_hz!r}")
        t = self.columns["t"]
        n = int(math.floor((t[-1] - t[0]) * rate_hz + 1e-9)) + 1
        tn = t[0] + np.arange(n) / rate_hz
        out = {"t": tn}
        for name, v in self.columns.items():
            if name == "t":
                continue
            if name == "u":
                idx = np.clip(np.searchsorted(t, tn + 1e-9 / rate_hz, side="right") - 1, 0, len(t) - 1)
                out[name] = v[idx]
            else:
                out[name] = np.interp(tn, t, v)
        meta = dict(self.meta, sample_rate_hz=rate_hz)
        return TimeSeries(out, meta, self.source)

    def window(self, t0: float, t1: float) -> TimeSeries:
        """The samples with t0 <= t <= t1 (s), times unchanged."""
        t = self.columns["t"]
        sel = (t >= t0) & (t <= t1)
        return TimeSeries({k: v[sel] for k, v in self.columns.items()}, dict(self.meta), self.source)

    def validate(self, config: Configuration | None = None) -> TimeSeries:
        """Check required columns, finiteness, increasing time and physical ranges.

        Parameters
        ----------
        config : Configuration, optional
            Rig configuration that sets the required columns; default the metadata's.

        Returns
        -------
        TimeSeries
            This series.

        Raises
        ------
        DataFormatError
            A check fails; the message names the column and the sample.
        """
        _validate(self.columns, config if config is not None else self.configuration, self.source, None)
        return self


def _validate(
    cols: Mapping[str, np.ndarray],
    config: Configuration | None,
    source: str,
    line_of_row: Sequence[int] | None,
    required: Sequence[str] | None = None,
) -> None:
    def where(i: int) -> str:
        return f"line {line_of_row[i]}" if line_of_row is not None else f"sample {i}"

    missing = [c for c in (required if required is not None else required_columns(config)) if c not in cols]
    if missing:
        cfg = f" for configuration '{config.label}'" if config is not None else ""
        raise DataFormatError(f"{source}: missing column(s) {', '.join(missing)}{cfg}")
    n = len(cols["t"])
    if n < 2:
        raise DataFormatError(f"{source}: needs at least 2 samples, has {n}")
    for name, v in cols.items():
        if name not in KNOWN_COLUMNS:
            continue
        bad = np.flatnonzero(~np.isfinite(v))
        if bad.size:
            raise DataFormatError(f"{source}: {where(bad[0])}, column '{name}': value is NaN or infinite")
    dt = np.diff(cols["t"])
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        i = bad[0] + 1
        raise DataFormatError(
            f"{source}: {where(i)}, column 't': time is not strictly increasing "
            f"({float(cols['t'][i - 1])!r} then {float(cols['t'][i])!r})"
        )
    limits = {"u": U_LIMIT_FILE, "x": XY_LIMIT_FILE, "y": XY_LIMIT_FILE}
    for name, lim in limits.items():
        if name in cols:
            bad = np.flatnonzero(np.abs(cols[name]) > lim)
            if bad.size:
                unit = "V" if name == "u" else "m"
                raise DataFormatError(
                    f"{source}: {where(bad[0])}, column '{name}': {float(cols[name][bad[0]])!r} {unit} "
                    f"is outside the physical range |{name}| <= {lim} {unit}"
                )


def _check_mapping(mapping: Mapping[str, str] | None, src: str) -> dict[str, str]:
    """The mapping column -> file name, its columns checked against the known ones."""
    mapping = dict(mapping or {})
    bad = sorted(set(mapping) - set(KNOWN_COLUMNS))
    if bad:
        raise DataFormatError(
            f"{src}: mapping names unknown column(s) {', '.join(bad)}; expected some of {', '.join(KNOWN_COLUMNS)}"
        )
    return mapping


def _rename(header: list[str], mapping: Mapping[str, str], src: str) -> list[str]:
    """CSV header with the mapped file columns renamed to drillgym's names."""
    out = list(header)
    for col, name in mapping.items():
        if name not in header:
            raise DataFormatError(
                f"{src}: mapping names column '{name}' for '{col}', but the file has only: {', '.join(header)}"
            )
        if col in header and col != name and col not in mapping.values():
            raise DataFormatError(
                f"{src}: mapping reads '{name}' as '{col}', but the file has a column '{col}' "
                f"too; map that one as well or leave '{col}' out of the mapping"
            )
        out[header.index(name)] = col
    return out


def read_csv(
    path: str | Path,
    config: str | Configuration | None = None,
    required: Sequence[str] | None = None,
    mapping: Mapping[str, str] | None = None,
) -> TimeSeries:
    """Read and validate a DATA_FORMAT CSV.

    Parameters
    ----------
    path : str or path
        The CSV file.
    config : str or Configuration, optional
        Rig configuration, used when the file's metadata names none; it sets the required columns.
    required : sequence of str, optional
        Required columns instead of the configuration's, e.g. ``("t", "u")`` for an input signal.
    mapping : mapping of str to str, optional
        File columns read under drillgym's names, e.g. ``{"theta_u": "enc1"}``.

    Returns
    -------
    TimeSeries
        The validated columns and the file's metadata.

    Raises
    ------
    DataFormatError
        The file cannot be read or used; the message names the file, line or column and the problem.
    """
    path = Path(path)
    src = str(path)
    mapping = _check_mapping(mapping, src)
    try:
        fh = path.open("r", encoding="utf-8", newline="")
    except OSError as exc:
        raise DataFormatError(f"{src}: cannot open ({exc.strerror})") from None
    meta: dict = {}
    rows: list[list[float]] = []
    lines: list[int] = []
    header: list[str] | None = None
    with fh:
        try:
            for lineno, raw in enumerate(fh, start=1):
                line = raw.strip()
                if not line:
                    continue
                if line.startswith("#"):
                    body = line[1:].strip()
                    if body.startswith("meta:"):
                        try:
                            meta.update(json.loads(body[5:]))
                        except json.JSONDecodeError as exc:
                            raise DataFormatError(
                                f"{src}: line {lineno}: metadata is not valid JSON ({exc.msg})"
                            ) from None
                    continue
                fields = next(csv.reader([line]))
                if header is None:
                    header = [f.strip() for f in fields]
                    dup = {h for h in header if header.count(h) > 1}
                    if dup:
                        raise DataFormatError(f"{src}: line {lineno}: duplicate column(s) {', '.join(sorted(dup))}")
                    continue
                if len(fields) != len(header):
                    raise DataFormatError(f"{src}: line {lineno}: {len(fields)} fields, header has {len(header)}")
                try:
                    rows.append([float(f) for f in fields])
                except ValueError:
                    col = next(h for h, f in zip(header, fields) if not _is_float(f))
                    bad = fields[header.index(col)]
                    raise DataFormatError(f"{src}: line {lineno}, column '{col}': {bad!r} is not a number") from None
                lines.append(lineno)
        except UnicodeDecodeError as exc:
            raise DataFormatError(f"{src}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    if header is None:
        raise DataFormatError(f"{src}: no header line (empty file?)")
    if mapping:
        header = _rename(header, mapping, src)
    data = np.array(rows, dtype=np.float64).reshape(-1, len(header))
    cols = {h: data[:, i].copy() for i, h in enumerate(header)}
    return _finish(cols, meta, src, config, lines, required)


def _is_float(s: str) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False


def _finish(cols: dict, meta: dict, src: str, config, lines, required=None) -> TimeSeries:
    if config is not None:
        cfg = parse_configuration(config)
        if "configuration" in meta and parse_configuration(meta["configuration"]) is not cfg:
            raise DataFormatError(
                f"{src}: file says configuration '{meta['configuration']}', but '{cfg.label}' was requested"
            )
        meta.setdefault("configuration", cfg.label)
    try:
        cfg_obj = parse_configuration(meta["configuration"]) if meta.get("configuration") else None
    except ValueError as exc:
        raise DataFormatError(f"{src}: metadata 'configuration': {exc}") from None
    _validate(cols, cfg_obj, src, lines, required)
    return TimeSeries(cols, meta, src)


def read_mat(
    path: str | Path, config: str | Configuration | None = None, mapping: Mapping[str, str] | None = None
) -> TimeSeries:
    """Read and validate a Simulink/MATLAB ``.mat`` file.

    Parameters
    ----------
    path : str or path
        The ``.mat`` file: arrays, a "structure with time" or a timeseries-like struct.
    config : str or Configuration, optional
        Rig configuration, used when the file names none; it sets the required columns.
    mapping : mapping of str to str, optional
        Variables read under drillgym's names, e.g. ``{"theta_u": "ScopeData:2"}`` (column 2 of a muxed
        variable, 1-based); other columns are found by name (``MAT_ALIASES``).

    Returns
    -------
    TimeSeries
        The validated columns (SI units).

    Raises
    ------
    DataFormatError
        The file cannot be read or a required column cannot be found or used.
    """
    import scipy.io

    path = Path(path)
    src = str(path)
    try:
        raw = scipy.io.loadmat(str(path), squeeze_me=True, struct_as_record=False)
    except FileNotFoundError:
        raise DataFormatError(f"{src}: file not found") from None
    except Exception as exc:  # noqa: BLE001 - any loader failure means the file is unusable
        raise DataFormatError(f"{src}: not a readable MATLAB .mat file ({exc})") from None
    variables = {k: v for k, v in raw.items() if not k.startswith("__")}
    flat: dict[str, np.ndarray] = {}
    time_from_struct = None
    for name, v in variables.items():
        key = name.lower()
        if hasattr(v, "_fieldnames"):  # struct (Simulink "structure with time" or timeseries-like)
            fns = v._fieldnames
            if "time" in fns and np.size(v.time) > 1:
                time_from_struct = np.asarray(v.time, dtype=float).ravel()
            if "signals" in fns:
                _add_signals(flat, key, v.signals, src)
            elif "Data" in fns:
                _add_array(flat, key, v.Data)
                if "Time" in fns:
                    time_from_struct = np.asarray(v.Time, dtype=float).ravel()
        else:
            _add_array(flat, key, v)
    cols: dict[str, np.ndarray] = {}
    mapping = {k: v.lower() for k, v in _check_mapping(mapping, src).items()}
    for col in KNOWN_COLUMNS:
        names = (mapping[col],) if col in mapping else MAT_ALIASES[col]
        for n in names:
            if n in flat:
                arr = flat[n]
                if arr.ndim == 2 and col != "t":
                    if 1 in arr.shape:
                        arr = arr.ravel()
                    else:
                        raise DataFormatError(
                            f"{src}: variable '{n}' for column '{col}' has {min(arr.shape)} "
                            f"columns; choose one: --map {col}={n}:K (mapping={{'{col}': "
                            f"'{n}:K'}}), K = 1..{min(arr.shape)}"
                        )
                cols[col] = np.asarray(arr, dtype=float).ravel()
                break
        else:
            if col in mapping:
                raise DataFormatError(
                    f"{src}: mapping names variable '{mapping[col]}' for column '{col}', "
                    f"but the file has only: {', '.join(sorted(flat))}"
                )
    if "t" not in cols and time_from_struct is not None:
        cols["t"] = time_from_struct
    lengths = {k: len(v) for k, v in cols.items()}
    if lengths and len(set(lengths.values())) > 1:
        raise DataFormatError(f"{src}: variables have different lengths: {lengths}")
    meta = {"source": "rig"}
    try:
        return _finish(cols, meta, src, config, None)
    except DataFormatError as exc:
        if "missing column" not in str(exc):
            raise
        unused = [n for n in sorted(flat) if not any(flat[n] is c for c in cols.values())]
        raise DataFormatError(
            f"{exc}; the file has {', '.join(unused) or 'no other variable'}: name the columns "
            f"with --map COLUMN=NAME (mapping= in Python)"
        ) from None


def _add_array(flat: dict, key: str, value) -> None:
    """A numeric variable under its name; a matrix's columns also as ``key:1`` … ``key:k``."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return
    flat[key] = arr
    if arr.ndim == 2 and min(arr.shape) > 1:
        by_col = arr if arr.shape[0] >= arr.shape[1] else arr.T  # samples along the longer axis
        for k in range(by_col.shape[1]):
            flat[f"{key}:{k + 1}"] = by_col[:, k]


def _add_signals(flat: dict, key: str, signals, src: str) -> None:
    """A "structure with time"'s ``signals``: one struct or an array of them, each ``values`` (N,) or (N, k).
    Their columns in order are ``key:1`` … (all signals together); a one-column signal's ``label`` names it."""
    items = list(np.atleast_1d(signals)) if isinstance(signals, np.ndarray) else [signals]
    columns: list[np.ndarray] = []
    for s in items:
        if not hasattr(s, "values"):
            raise DataFormatError(f"{src}: '{key}.signals' has no 'values' field (not a Simulink structure with time)")
        try:
            vals = np.asarray(s.values, dtype=float)
        except (TypeError, ValueError):
            raise DataFormatError(f"{src}: '{key}.signals.values' is not numeric") from None
        block = vals.reshape(-1, 1) if vals.ndim <= 1 else vals
        columns += [block[:, k] for k in range(block.shape[1])]
        label = getattr(s, "label", "")
        label = "" if not isinstance(label, str) else label.strip().lower()  # MATLAB '' loads as an empty array
        if label and block.shape[1] == 1:
            flat.setdefault(label, block[:, 0])
    if len(items) == 1 and len(columns) > 1:
        flat[key] = np.column_stack(columns)
    elif len(columns) == 1:
        flat[key] = columns[0]
    if len(columns) > 1:
        for k, c in enumerate(columns):
            flat[f"{key}:{k + 1}"] = c


def read_timeseries(
    path: str | Path, config: str | Configuration | None = None, mapping: Mapping[str, str] | None = None
) -> TimeSeries:
    """Read a CSV or .mat time series (by extension) and validate it.

    Parameters
    ----------
    path : str or path
        A DATA_FORMAT CSV or a MATLAB/Simulink ``.mat`` file.
    config : str or Configuration, optional
        Rig configuration (``"upper"``, ``"torsional"``, ``"lateral"``, ``"coupled"``), used when the
        file's metadata names none; it sets the required columns (``t``, ``u``, ``theta_u``; ``theta_l``
        but for ``upper``; ``x``, ``y`` for ``lateral`` and ``coupled``).
    mapping : mapping of str to str, optional
        Columns or ``.mat`` variables read under drillgym's names, e.g. ``{"theta_u": "enc1"}`` or
        ``{"theta_u": "ScopeData:2"}`` (column 2 of a muxed variable, 1-based).

    Returns
    -------
    TimeSeries
        The validated series: columns in SI units (s, V, rad, m, rad/s) and the metadata.

    Raises
    ------
    DataFormatError
        A missing or unusable file; the message names the file, the line or column and what is wrong.

    Examples
    --------
    >>> from drillgym.io import read_timeseries
    >>> ts = read_timeseries("recording.csv", config="torsional")  # doctest: +SKIP
    >>> ts.t, ts.theta_l  # doctest: +SKIP
    """
    path = Path(path)
    if not path.exists():
        raise DataFormatError(f"{path}: file not found")
    if path.suffix.lower() == ".mat":
        return read_mat(path, config, mapping)
    return read_csv(path, config, mapping=mapping)


def read_input_signal(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Read the voltage table of an input-signal file.

    Parameters
    ----------
    path : str or path
        Any DATA_FORMAT CSV or ``.mat`` file with at least the columns ``t`` and ``u``.

    Returns
    -------
    t : ndarray
        Times (s).
    u : ndarray
        Motor voltage (V) at those times.

    Raises
    ------
    DataFormatError
        A missing or unusable file.
    """
    path = Path(path)
    if not path.exists():
        raise DataFormatError(f"{path}: file not found")
    if path.suffix.lower() == ".mat":
        ts = read_mat(path)
    else:
        ts = read_csv(path, required=("t", "u"))
    return ts.columns["t"], ts.columns["u"]


def describe_parse_error(exc: BaseException) -> str:
    """Where and what a YAML or JSON parser found wrong, on one line.

    Parameters
    ----------
    exc : BaseException
        The parser's error (:class:`json.JSONDecodeError`, a ``yaml.YAMLError`` or anything else).

    Returns
    -------
    str
        ``"line L, column C: problem"`` when the parser says where, else its message on one line.
    """
    if isinstance(exc, json.JSONDecodeError):
        return f"line {exc.lineno}, column {exc.colno}: {exc.msg}"
    mark, problem = getattr(exc, "problem_mark", None), getattr(exc, "problem", None)
    if mark is not None and problem:
        context = getattr(exc, "context", None)
        return f"line {mark.line + 1}, column {mark.column + 1}: {problem}" + (f" ({context})" if context else "")
    return " ".join(str(exc).split()) or type(exc).__name__


def create_directory(directory: str | Path, for_path: str | Path | None = None) -> Path:
    """Create ``directory`` and its missing parents (nothing if it exists).

    Parameters
    ----------
    directory : str or path-like
        The directory to create.
    for_path : str or path-like, optional
        The output the directory is made for, named in the message. Default: ``directory``.

    Returns
    -------
    pathlib.Path
        ``directory``.

    Raises
    ------
    OutputPathError
        If a file is in the way or the directory cannot be created (no permission, read-only).
    """
    directory = Path(directory)
    for_path = directory if for_path is None else Path(for_path)
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        raise OutputPathError(
            f"{for_path}: cannot create directory {directory}: a file of that name is in the way"
        ) from None
    except OSError as exc:
        raise OutputPathError(f"{for_path}: cannot create directory {directory} ({exc.strerror})") from None
    return directory


def _fmt(v: float) -> str:
    return repr(float(v))


def write_timeseries(path: str | Path, ts: TimeSeries) -> Path:
    """Write a TimeSeries as DATA_FORMAT CSV (full float precision, round-trips exactly).

    Parameters
    ----------
    path : str or path
        Output file.
    ts : TimeSeries
        The series; its ``meta`` goes into the ``# meta:`` comment line.

    Returns
    -------
    Path
        The path written.
    """
    path = Path(path)
    names = list(ts.columns)
    with path.open("w", encoding="utf-8", newline="") as fh:
        fh.write(f"# meta: {json.dumps(ts.meta)}\n")
        fh.write(",".join(names) + "\n")
        data = np.column_stack([ts.columns[n] for n in names])
        for row in data:
            fh.write(",".join(_fmt(v) for v in row) + "\n")
    return path


def trajectory_to_timeseries(traj, description: str = "") -> TimeSeries:
    """A simulated Trajectory as a TimeSeries in the interchange columns."""
    cfg = traj.config
    cols = {"t": traj.t, "u": traj.u, "theta_u": traj.theta_u}
    if cfg is not Configuration.UPPER:
        cols["theta_l"] = traj.theta_l
    if cfg.lateral_free:
        cols["x"] = traj.x
        cols["y"] = traj.y
    cols["omega_u"] = traj.omega_u
    if cfg is not Configuration.UPPER:
        cols["omega_l"] = traj.omega_l
    cols["Tfu"] = traj.Tfu
    cols["Tfl"] = traj.Tfl
    cols["stick_l"] = traj.stick_l
    meta = {
        "configuration": cfg.label,
        "source": "simulation",
        "sample_rate_hz": 1.0 / (traj.t[1] - traj.t[0]) if len(traj.t) > 1 else None,
        "dt": traj.dt,
        "method": traj.method,
        "description": description,
    }
    return TimeSeries({k: np.asarray(v, dtype=float) for k, v in cols.items()}, meta, "<simulation>")


def write_trajectory_csv(traj, path: str | Path, description: str = "") -> Path:
    """Write a simulated run in the interchange format (so it compares with a measured one).

    Parameters
    ----------
    traj : Trajectory
        A run of :func:`drillgym.simulate`.
    path : str or path
        Output CSV file.
    description : str, optional
        Free text stored in the metadata.

    Returns
    -------
    Path
        The path written.
    """
    return write_timeseries(path, trajectory_to_timeseries(traj, description))


class StreamingCsvWriter:
    """Append rows to a DATA_FORMAT CSV as they arrive, flushed to disk in blocks.

    At most ``flush_interval_s`` of samples (by their ``t`` column) is held in
    memory, so a killed process loses at most that much.  Each flush ends with
    ``os.fsync``.  Use as a context manager; ``close()`` flushes the rest.

    Parameters
    ----------
    path : str or path
        The CSV file (overwritten).
    columns : sequence of str
        Column names, ``t`` among them.
    meta : mapping, optional
        Metadata written in the ``# meta:`` line.
    flush_interval_s : float, optional
        Longest time of samples held in memory (s, by the ``t`` column).  Default 0.5.
    """

    def __init__(
        self, path: str | Path, columns: Sequence[str], meta: Mapping | None = None, flush_interval_s: float = 0.5
    ) -> None:
        if "t" not in columns:
            raise ValueError("a recording needs a 't' column")
        self.path = Path(path)
        self.columns = list(columns)
        self.flush_interval_s = float(flush_interval_s)
        self._buf: list[str] = []
        self._t_last_flush: float | None = None
        self._fh: IO[str] | None = self.path.open("w", encoding="utf-8", newline="")
        self._fh.write(f"# meta: {json.dumps(dict(meta or {}))}\n")
        self._fh.write(",".join(self.columns) + "\n")
        self.flush()

    def write(self, row: Mapping[str, float] | Sequence[float]) -> None:
        """Append one row: a mapping by column name, or values in column order."""
        if self._fh is None:
            raise ValueError(f"{self.path}: recording already closed")
        if isinstance(row, Mapping):
            values = [row[c] for c in self.columns]
        else:
            values = list(row)
            if len(values) != len(self.columns):
                raise ValueError(f"row has {len(values)} values, recording has {len(self.columns)} columns")
        self._buf.append(",".join(_fmt(v) for v in values))
        t = float(values[self.columns.index("t")])
        if self._t_last_flush is None:
            self._t_last_flush = t
        if t - self._t_last_flush >= self.flush_interval_s:
            self.flush()
            self._t_last_flush = t

    def write_many(self, rows: Iterable[Sequence[float]]) -> None:
        """Append rows of values in column order."""
        for r in rows:
            self.write(r)

    def flush(self) -> None:
        """Write the held rows and ``fsync`` the file."""
        if self._fh is None:
            return
        if self._buf:
            self._fh.write("\n".join(self._buf) + "\n")
            self._buf.clear()
        self._fh.flush()
        os.fsync(self._fh.fileno())

    def close(self) -> None:
        """Flush the rest and close the file (idempotent)."""
        if self._fh is not None:
            self.flush()
            self._fh.close()
            self._fh = None

    def __enter__(self) -> StreamingCsvWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
