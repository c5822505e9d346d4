"""The time series of the rig: named columns in SI units with metadata, and their checks."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..configurations import Configuration, parse_configuration
from ..errors import DataFormatError, InputError
from .limits import KNOWN_COLUMNS, U_LIMIT_FILE, XY_LIMIT_FILE


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
        check_columns(self.columns, config if config is not None else self.configuration, self.source, None)
        return self


def check_columns(
    cols: Mapping[str, np.ndarray],
    config: Configuration | None,
    source: str,
    line_of_row: Sequence[int] | None,
    required: Sequence[str] | None = None,
) -> None:
    """Check columns: the required ones present, finite values, increasing time, physical ranges.

    Parameters
    ----------
    cols : mapping of str to ndarray
        The columns by name.
    config : Configuration or None
        The configuration that sets the required columns.
    source : str
        The file or source named in the message.
    line_of_row : sequence of int or None
        The file's line of each row, named in the message; None: the sample index is named.
    required : sequence of str, optional
        Required columns instead of the configuration's.

    Raises
    ------
    DataFormatError
        A check fails; the message names the column and the line or sample.
    """

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
