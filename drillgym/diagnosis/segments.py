"""Conditioning of a recording for the diagnosis: noise levels and where segments start.

* :func:`encoder_quantum` — the encoder count (rad) of a recorded angle, robust
  to the ~1e-11 rad round-off differences that interpolation leaves between
  samples of equal count (taking the smallest nonzero difference would read
  such round-off as the resolution and make the noise level vanish);
* :func:`robust_noise` — the experiment with the speed limits of the
  start-speed refinement (rad/s) recomputed from that count, and the residual
  scales (noise units) the diagnosis compares in;
* :func:`place_segment_starts` — multiple-shooting segments re-started where
  the data's state is well known: far from stick/slip transitions of either
  disc.  A segment that starts just before a slip begins, or while the lower
  disc passes slowly through zero speed, hangs on a speed estimate the
  Savitzky–Golay derivative smears (a 60 ms window across a kink): the exact
  model then slips too early or too late and the residual of that one segment
  dominates the record, which an effect with a few free parameters can partly
  "explain".  In the interior of a stick phase the lower disc's state is exact
  (ωl = 0), in a long slip the derivative is accurate.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from scipy.signal import savgol_coeffs

from ..identification.experiment import SPEED_WINDOW_S, Experiment
from ..identification.segmented import SegmentedModel

__all__ = ["encoder_quantum", "robust_noise", "place_segment_starts", "MIN_COUNT_RAD"]

MIN_COUNT_RAD = 1e-7  # rad: differences below this are round-off, not encoder counts (1e-7 rad ~ 6e7 counts/rev)
QUALITY_CAP_S = 0.4  # s: a start this far from any stick/slip transition is as good as any other


def encoder_quantum(theta: np.ndarray, max_multiple: int = 50) -> float | None:
    """The encoder count (rad) of a recorded angle.

    Every difference between samples of a quantized angle is a whole number of counts, but on a
    coarse grid (or when the disc never stops) even the smallest difference can be several counts:
    the count is the largest ``d_min / k`` (k <= ``max_multiple``) of which all differences are whole
    multiples, ``d_min`` the smallest difference above round-off (``MIN_COUNT_RAD``).

    Parameters
    ----------
    theta : numpy.ndarray
        The angle (rad).
    max_multiple : int, optional
        The largest number of counts the smallest difference may hold.  Default 50.

    Returns
    -------
    float or None
        The count (rad), or None if the angle never changes.
    """
    d = np.abs(np.diff(np.asarray(theta, dtype=float)))
    d = d[d > MIN_COUNT_RAD]
    if not d.size:
        return None
    d_min = float(d.min())
    for k in range(1, max_multiple + 1):
        q = d_min / k
        m = d / q
        if np.max(np.abs(m - np.round(m))) < 1e-3 * max(1.0, float(m.max()) * 1e-3):
            return q
    return d_min  # not quantized (or not recognisably): the smallest difference is an upper bound


def robust_noise(ex: Experiment) -> tuple[Experiment, dict[str, float]]:
    """An experiment's noise read robustly: its speed-noise limits and its channels' residual scales.

    Angle scale: one encoder count / √12 (at least 1e-4 rad, as
    :func:`drillgym.identification.fitting.default_scales`); LVDT channels 10 µm.
    Speed limit of the start-speed refinement: the quantization noise of a Savitzky–Golay derivative
    on the comparison grid (``ex.fs``), i.e. the speed resolution the comparison itself has.  It is
    deliberately wider than the noise of the data-rate estimate (the speed estimates also carry the
    smoothing error of the derivative at stick/slip kinks): limiting the corrections to the data-rate
    quantization noise left exact models at up to 2.4 noise units on 500 Hz–1 kHz recordings.

    Parameters
    ----------
    ex : Experiment
        The experiment.

    Returns
    -------
    tuple of (Experiment, dict of str to float)
        The experiment with corrected ``speed_noise``, and the residual scale of each channel.
    """
    fs = ex.fs
    win = max(5, int(round(SPEED_WINDOW_S * fs)) | 1)
    gain = float(np.linalg.norm(savgol_coeffs(win, min(3, win - 1), deriv=1, delta=1.0 / fs)))
    noise = dict(ex.speed_noise)
    qs = []
    for ang, _om in (("theta_u", "omega_u"), ("theta_l", "omega_l")):
        if ang not in ex.meas:
            continue
        q = encoder_quantum(ex.meas[ang])
        if q is not None:
            qs.append(q)
    if qs:  # one encoder type on both discs: the finer reading is the count; never below the given level
        for om in ("omega_u", "omega_l"):
            if om in ex.rates:
                noise[om] = max(float(noise.get(om, 0.0)), min(qs) / math.sqrt(12.0) * gain)
    sa = max(min(qs) / math.sqrt(12.0) if qs else 0.0, 1e-4)
    scales = {"theta_u": sa, "theta_l": sa, "alpha": sa, "x": 1e-5, "y": 1e-5, "r": 1e-5}
    return replace(ex, speed_noise=noise), scales


def _transition_distance(ex: Experiment) -> np.ndarray:
    """Per grid sample: time (s) to the nearest stick/slip transition of either disc (capped)."""
    n = ex.n
    dist = np.full(n, QUALITY_CAP_S)
    idx = np.arange(n)
    for om in ("omega_u", "omega_l"):
        w = ex.rates.get(om)
        if w is None:
            continue
        moving = w != 0.0
        # a transition: stuck <-> moving, or a sign change of the speed (reversal through zero)
        sw = np.flatnonzero((moving[1:] != moving[:-1]) | (np.sign(w[1:]) * np.sign(w[:-1]) < 0)) + 0.5
        if sw.size == 0:
            continue
        j = np.clip(np.searchsorted(sw, idx), 1, sw.size) - 1
        d = np.abs(idx - sw[j])
        j2 = np.clip(j + 1, 0, sw.size - 1)
        d = np.minimum(d, np.abs(idx - sw[j2])) / ex.fs
        dist = np.minimum(dist, d)
    return dist


def place_segment_starts(model: SegmentedModel, min_step: float = 0.6) -> None:
    """Move a segmented model's segment starts (in place) to well-conditioned samples.

    Segments keep their length L; each next start is the sample in [prev + min_step L, prev + L]
    farthest from a stick/slip transition (ties: the latest, the least overlap), so segments never
    leave a gap and overlap by at most (1 − min_step) L.  A free run (one segment) is left alone.

    Parameters
    ----------
    model : SegmentedModel
        The model.
    min_step : float, optional
        The shortest step between starts, as a share of the segment length.  Default 0.6.
    """
    for k, ex in enumerate(model.experiments):
        plan = model._plans[k]
        L = plan["L"]
        if L >= ex.n - 1:
            continue
        q = _transition_distance(ex)
        if all(ex.rates[o][0] == 0.0 for o in ("omega_u", "omega_l") if o in ex.rates):
            q[0] = QUALITY_CAP_S  # the record starts at rest: an exactly known state
        # the first start: the best sample in the first quarter segment (the record may begin mid-slip)
        cand = np.arange(0, max(1, L // 4))
        s = int(cand[np.argmax(q[cand] - 1e-9 * cand)])
        starts = [s]
        while ex.n - 1 - (s + L) >= L // 4:  # the uncovered tail is worth another segment
            cand = np.arange(s + max(1, int(min_step * L)), min(s + L, ex.n - 2) + 1)
            s = int(cand[np.argmax(q[cand] + 1e-9 * cand)])
            starts.append(s)
        plan["starts"] = np.asarray(starts, dtype=int)
        model.speed_offsets[k] = np.zeros((len(starts), 2))
    model.n_rows_per_params = sum(len(p["starts"]) for p in model._plans)
