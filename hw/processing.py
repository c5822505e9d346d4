"""The rig's measurement processing on the host: encoder counts to angles, LVDT calibration.

* :class:`CounterUnwrap`: the firmware's 32-bit counters (wrapping) to unbounded counts.
* :class:`LvdtProcessor`: raw LVDT values to metres (scale from the firmware's CONFIG), offset
  taken at rest, then a causal Butterworth low-pass (default 5 Hz, the report's LVDT cut-off;
  causal because the environment acts on it online).
"""

from __future__ import annotations

import numpy as np
from scipy import signal

from drillgym.errors import InputError

__all__ = ["CounterUnwrap", "LvdtProcessor"]

_WRAP = 1 << 32


class CounterUnwrap:
    """Unbounded counts from a wrapping signed 32-bit counter (call once per sample)."""

    def __init__(self) -> None:
        self.value: int | None = None

    def reset(self) -> None:
        """Forget the history: the next sample starts the count."""
        self.value = None

    def update(self, raw: int) -> int:
        """The unbounded count after one more raw sample of the 32-bit counter."""
        if self.value is None:
            self.value = int(raw)
        else:
            d = (int(raw) - self.value) % _WRAP
            self.value += d - _WRAP if d >= _WRAP // 2 else d
        return self.value


class LvdtProcessor:
    """Raw LVDT values (x, y) -> metres, offset removed, low-passed causally.

    Parameters
    ----------
    m_per_lsb : float
        LVDT scale (m per raw count).
    sample_rate_hz : float
        Rate of the samples (Hz).
    cutoff_hz : float, optional
        Low-pass cut-off (Hz); no filtering at or above the Nyquist frequency.
    order : int, optional
        Butterworth order.
    """

    def __init__(self, m_per_lsb: float, sample_rate_hz: float, cutoff_hz: float = 5.0, order: int = 2) -> None:
        if not (m_per_lsb > 0 and sample_rate_hz > 0 and cutoff_hz > 0):
            raise InputError("LVDT scale, sample rate and cut-off must be > 0")
        self.scale = float(m_per_lsb)
        self.offset = np.zeros(2)  # m
        self.sos = (
            signal.butter(order, cutoff_hz, fs=sample_rate_hz, output="sos") if cutoff_hz < sample_rate_hz / 2 else None
        )
        self._zi = None

    def calibrate_rest(self, raw_x: np.ndarray, raw_y: np.ndarray) -> np.ndarray:
        """Take the offset (m) as the mean of readings at rest; restart the filter at rest (0 m)."""
        self.offset = np.array([np.mean(raw_x), np.mean(raw_y)], dtype=float) * self.scale
        self._zi = None if self.sos is None else np.zeros((self.sos.shape[0], 2, 2))
        return self.offset

    def update(self, raw_x: int, raw_y: int) -> tuple[np.ndarray, np.ndarray]:
        """One sample: (calibrated [x, y] in m, low-passed [x, y] in m)."""
        xy = np.array([raw_x, raw_y], dtype=float) * self.scale - self.offset
        if self.sos is None:
            return xy, xy.copy()
        if self._zi is None:
            self._zi = np.zeros((self.sos.shape[0], 2, 2))
        lp, self._zi = signal.sosfilt(self.sos, xy[None, :], axis=0, zi=self._zi)
        return xy, lp[0]
