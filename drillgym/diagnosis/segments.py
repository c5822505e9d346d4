"""Conditioning of a recording for the diagnosis: noise levels and where segments start.

* :func:`robust_noise` — the experiment with the speed limits of the
  start-speed refinement (rad/s) recomputed from the readings' noise
  (:func:`drillgym.identification.reading_noise.angle_noise`: the encoder's count,
  robust to the ~1e-11 rad round-off differences that interpolation leaves between
  samples of equal count, or the scatter of a reading off any lattice of counts),
  and the residual scales (noise units) the diagnosis compares in;
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

from dataclasses import replace

import numpy as np
from scipy.signal import savgol_coeffs

from ..identification.experiment import SPEED_WINDOW_S, Experiment
from ..identification.reading_noise import ANGLE_FLOOR_RAD, finest_angle_noise
from ..identification.segmented import SegmentedModel

__all__ = ["robust_noise", "place_segment_starts"]

QUALITY_CAP_S = 0.4  # s: a start this far from any stick/slip transition is as good as any other


def robust_noise(ex: Experiment) -> tuple[Experiment, dict[str, float]]:
    """An experiment's noise read robustly: its speed-noise limits and its channels' residual scales.

    Angle scale: the finer reading's noise (one encoder count / √12, or the scatter of a reading off any
    lattice of counts; at least 1e-4 rad, as :func:`drillgym.identification.fitting.default_scales`); LVDT
    channels 10 µm.
    Speed limit of the start-speed refinement: that noise through a Savitzky–Golay derivative
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
    # one encoder type on both discs: the finer reading is the count (or the scatter); never below the given level
    finest = finest_angle_noise(ex.meas[a] for a in ("theta_u", "theta_l") if a in ex.meas)
    if finest is not None:
        for om in ("omega_u", "omega_l"):
            if om in ex.rates:
                noise[om] = max(float(noise.get(om, 0.0)), finest * gain)
    sa = max(finest or 0.0, ANGLE_FLOOR_RAD)
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
