"""The speeds at the segment starts of a multiple-shooting model: nuisance states corrected for the model.

:class:`SpeedCorrections` is the part of :class:`~drillgym.identification.segmented.SegmentedModel` that
keeps, snapshots and refines the corrections (rad/s) to the data's speed estimates at each segment start.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np

from ..configurations import Configuration
from .experiment import SPEED_WINDOW_S

__all__ = ["SpeedCorrections"]


class SpeedCorrections:
    """The segment-start speed corrections of a segmented model (``speed_offsets``: (n_seg, 2) per experiment,
    rad/s); the model provides ``experiments``, ``segments``, ``measured_segments`` and ``predict``."""

    speed_offsets: list[np.ndarray]

    def speeds_snapshot(self) -> list[np.ndarray]:
        """A copy of the speed corrections at the segment starts (rad/s, (n_seg, 2) per experiment)."""
        return [o.copy() for o in self.speed_offsets]

    @contextmanager
    def speeds_kept(self) -> Iterator[None]:
        """Within the block the speed corrections may change (a trial fit refines them); on leaving it
        they are those of its start again."""
        saved = self.speeds_snapshot()
        try:
            yield
        finally:
            self.speed_offsets = saved

    def refine_initial_speeds(
        self,
        vec: np.ndarray,
        weights: dict[str, float],
        scales: dict[str, float],
        iterations: int = 2,
        h: float = 0.005,
        fresh: bool = False,
    ) -> None:
        """Correct the speeds estimated from the data at the segment starts (nuisance states) by
        Gauss–Newton on the base model's residual, so that noisy derivative estimates of the
        recording do not pass for model error.  Segments are independent, so one batched run
        with all segments' ω_u (resp. ω_l) perturbed gives every segment's sensitivity.
        A disc stuck at a segment's start (speed exactly 0) is left stuck, and a correction never
        exceeds three standard deviations of the estimate's quantization noise
        (``Experiment.speed_noise``): it removes derivative noise, not model error.

        Parameters
        ----------
        vec : numpy.ndarray
            The model's parameter vector.
        weights : dict of str to float
            The channels' weights.
        scales : dict of str to float
            The channels' residual scales.
        iterations : int, optional
            Gauss–Newton iterations.  Default 2.
        h : float, optional
            Speed step of the sensitivities (rad/s).  Default 0.005.
        fresh : bool, optional
            Start from the data's estimates (earlier corrections, made for another parameter vector,
            dropped).  Default False.
        """
        if fresh:
            self.speed_offsets = [np.zeros_like(o) for o in self.speed_offsets]
        for _ in range(iterations):
            P = np.repeat(np.asarray(vec, dtype=float)[None, :], 3, axis=0)
            preds = self.predict(P, tuple(weights), dspeed=np.array([[0, 0], [h, 0], [0, h]], dtype=float))
            for k in range(len(self.experiments)):
                starts, L = self.segments(k)
                r = [[], [], []]
                for c, w in weights.items():
                    if c not in preds[0].outputs[k]:
                        continue
                    m = self.measured_segments(k, c)[:, 1:]
                    for b in range(3):
                        e = (preds[b].outputs[k][c][:, 1:] - m) * (w / scales[c])
                        r[b].append(np.nan_to_num(e))
                if not r[0]:
                    continue
                e0, e1, e2 = (np.concatenate(x, axis=1) for x in r)
                J = np.stack([(e1 - e0) / h, (e2 - e0) / h], axis=2)  # (n_seg, M, 2)
                free, limit = self._correctable_speeds(k)
                for j in range(len(starts)):
                    cols = np.flatnonzero(free[j])
                    if cols.size == 0:
                        continue
                    A = J[j][:, cols]
                    step, *_ = np.linalg.lstsq(A, -e0[j], rcond=None)
                    self.speed_offsets[k][j, cols] = np.clip(
                        self.speed_offsets[k][j, cols] + step, -limit[j, cols], limit[j, cols]
                    )

    def _correctable_speeds(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """Experiment k's segment-start speeds that may be corrected, (n_seg, 2) booleans for (ω_u, ω_l), and
        the bound of each correction (rad/s, (n_seg, 2)): three standard deviations of the estimate's
        quantization noise.  Left out: a disc the data show stuck at the start (speed estimate exactly 0), the
        upper disc of a free-vibration test and the lower disc of an upper-disc test.

        A start whose differentiation window reaches the recording's first sample has a one-sided estimate
        (the Savitzky–Golay fit extrapolated to its edge: 0.046 rad/s read for a motor starting from rest, 4 times
        the centred estimate's noise): it may move by as much as its estimate too.

        When the model's reading depends on a disc's speed (``Composition.measurement_reads_speeds``: free play
        between an encoder's shaft and its disc), the reading changes by itself where that speed changes sign,
        and the data's rate there holds that change (a 0.02 rad play read as 2 rad/s at a start from rest): a
        start whose differentiation window holds a reversal, a stop or the recording's first sample may move by
        as much as its estimate too."""
        ex = self.experiments[k]
        starts, _ = self.segments(k)
        rates = np.stack([ex.rates.get(c, np.zeros(ex.n)) for c in ("omega_u", "omega_l")], axis=1)
        w0 = rates[starts]
        noise = np.array([ex.speed_noise.get("omega_u", 0.0), ex.speed_noise.get("omega_l", 0.0)])
        limit = np.tile(3.0 * noise, (len(starts), 1))
        if self.composition.measurement_reads_speeds:
            limit += np.where(_sign_change_near(rates, starts, ex.fs), np.abs(w0), 0.0)
        else:
            one_sided = starts < math.ceil(0.5 * SPEED_WINDOW_S * ex.fs)
            limit += np.where(one_sided[:, None], np.abs(w0), 0.0)
        free = w0 != 0.0
        if ex.config is Configuration.FREE_VIBRATION:
            free[:, 0] = False
        if ex.config is Configuration.UPPER:
            free[:, 1] = False
        return free, limit

    def speed_variables(self) -> list[tuple[int, int, int, float]]:
        """The segment-start speeds a fit may correct (:meth:`_correctable_speeds`, as
        :meth:`refine_initial_speeds` corrects them), as (experiment, segment, component, limit): component 0
        is ω_u, 1 is ω_l; ``limit`` (rad/s) bounds the correction (a component whose bound is 0 cannot move and
        is left out)."""
        out = []
        for k in range(len(self.experiments)):
            free, limit = self._correctable_speeds(k)
            out += [
                (k, j, c, float(limit[j, c]))
                for j in range(free.shape[0])
                for c in (0, 1)
                if free[j, c] and limit[j, c] > 0.0
            ]
        return out


#: how far (s) from a segment start a reversal or stop makes the data's speed there unsure under a speed-dependent
#: reading: the speed estimates' differentiation window on each side
_READING_WINDOW_S = 0.06


def _sign_change_near(rates: np.ndarray, starts: np.ndarray, fs: float) -> np.ndarray:
    """(n_seg, 2): whether each disc's speed estimate is 0 or of the other sign somewhere within
    :data:`_READING_WINDOW_S` of each start, or the window reaches the recording's first sample."""
    m = max(1, int(np.ceil(_READING_WINDOW_S * fs)))
    out = np.zeros((len(starts), 2), dtype=bool)
    for j, s0 in enumerate(starts):
        window = rates[max(0, s0 - m) : s0 + m + 1]
        out[j] = np.any(window * np.sign(rates[s0]) <= 0.0, axis=0) | (s0 - m < 0)
    return out
