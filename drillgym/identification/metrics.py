"""Fit-quality figures: the report's R² (its eq. 3.2) and RMS, per channel."""

from __future__ import annotations

import numpy as np

__all__ = ["r2", "rms", "channel_metrics"]


def r2(y: np.ndarray, y_hat: np.ndarray) -> float:
    """R² = 1 − Σ(y − ŷ)² / Σ(y − ȳ)² (report eq. 3.2); NaN samples are ignored.

    Parameters
    ----------
    y, y_hat : numpy.ndarray
        Measured and predicted samples.

    Returns
    -------
    float
        R² (NaN for a constant ``y``).
    """
    y = np.asarray(y, dtype=float).ravel()
    y_hat = np.asarray(y_hat, dtype=float).ravel()
    ok = np.isfinite(y) & np.isfinite(y_hat)
    y, y_hat = y[ok], y_hat[ok]
    den = float(np.sum((y - y.mean()) ** 2))
    if den == 0.0:
        return float("nan")
    return 1.0 - float(np.sum((y - y_hat) ** 2)) / den


def rms(e: np.ndarray) -> float:
    """Root mean square of the finite samples.

    Parameters
    ----------
    e : numpy.ndarray
        The samples.

    Returns
    -------
    float
        The RMS (NaN without finite samples).
    """
    e = np.asarray(e, dtype=float).ravel()
    e = e[np.isfinite(e)]
    return float(np.sqrt(np.mean(e**2))) if e.size else float("nan")


def channel_metrics(measured: dict[str, np.ndarray], predicted: dict[str, np.ndarray]) -> dict[str, dict[str, float]]:
    """R² and RMS error of every channel present in both mappings.

    Parameters
    ----------
    measured, predicted : dict of str to numpy.ndarray
        Channel -> samples.

    Returns
    -------
    dict of str to dict
        ``{channel: {"r2": ..., "rms": ...}}``.
    """
    return {
        c: {"r2": r2(measured[c], predicted[c]), "rms": rms(np.asarray(measured[c]) - predicted[c])}
        for c in measured
        if c in predicted
    }
