"""Reading time-series files: CSV (docs/data_format.md) and Simulink/MATLAB ``.mat``, checked on the way in."""

from __future__ import annotations

import csv
import json
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from ..configurations import Configuration, parse_configuration
from ..errors import DataFormatError
from .timeseries import KNOWN_COLUMNS, TimeSeries, check_columns

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
    """Read and validate a CSV of the time-series format (docs/data_format.md).

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
    check_columns(cols, cfg_obj, src, lines, required)
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
        A CSV (docs/data_format.md) or a MATLAB/Simulink ``.mat`` file.
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
        Any CSV (docs/data_format.md) or ``.mat`` file with at least the columns ``t`` and ``u``.

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
