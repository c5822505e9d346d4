"""Model predictions of recorded experiments, many parameter sets in one batched simulation.

Multiple shooting: each experiment is cut into segments of ``segment_s``
seconds; every segment is simulated from the state estimated from the data at
its start (:meth:`Experiment.initial_states`).  Stick-slip trajectories drift
in phase over long horizons (a small error in a friction level shifts every
later slip), so a single long run compares phases, not physics; short
segments keep the comparison local while still spanning several stick-slip
cycles.  ``segment_s=None`` gives one free run over the whole record.

All segments of all experiments for all parameter rows go into ONE
:func:`drillgym.simulate_batch` call (``parallel=True``), which is what makes a
finite-difference Jacobian cheap.

Effects that the compiled kernels apply relative to the run's start are made
exact per segment here:

* ``input_delay``: the delayed input u(t − delay) is built from the whole
  record (linear interpolation on the simulator grid, as the core does) and
  the kernel's own delay is switched off;
* ``motor_lag``: the lag is linear in the input, so the (delayed) input is
  filtered here (exact first-order discretisation, from the record's start)
  and the kernel's own lag is switched off: exact at segment starts and
  stable for any time constant, however small against the step;
* ``friction_drift``: the level (1 + drift t) at the segment start t0 is moved
  into the friction parameters (Tcl, bl, Ts, Tc, bb × (1 + drift t0)) and the
  drift rate rescaled (drift / (1 + drift t0)), which is the same law.

The model's lateral outputs go through the measurement chain of the data:
LVDT offset and skew of the parameter row (:func:`drillgym.measurement.lvdt_measure`)
and the offline zero-phase low-pass (:func:`drillgym.measurement.lowpass_zero_phase`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter, lfilter_zi

from ..configurations import Configuration
from ..integrators import OUTPUT_NAMES
from ..measurement import lowpass_zero_phase
from ..params import IDX, N_PARAMS
from ..simulator import simulate_batch
from .experiment import Experiment

__all__ = ["SegmentedModel", "Prediction", "CHANNELS"]

CHANNELS = ("theta_u", "theta_l", "alpha", "x", "y", "r")
MAX_DT = 2e-3  # s: simulator step bound (DP5: > 200 steps per lateral period)
_COL = {n: i for i, n in enumerate(OUTPUT_NAMES)}
_LOWER_LEVEL = (IDX.Tcl, IDX.bl, IDX.Ts, IDX.Tc, IDX.bb)


@dataclass
class Prediction:
    """Model outputs of one parameter row on every experiment: per experiment a dict
    channel -> (n_seg, seg_len) array (NaN beyond the record's end)."""

    outputs: list[dict[str, np.ndarray]]
    model: "SegmentedModel"

    def stitched(self, k: int, channel: str) -> np.ndarray:
        """Experiment k's channel on its comparison grid (segments joined; each segment's first
        sample is the data's own start value)."""
        seg = self.outputs[k][channel]
        return self.model.stitch(k, seg)


class SegmentedModel:
    """Predicts experiments for parameter matrices (B, N_PARAMS) by multiple shooting.

    Args:
        experiments: the recordings (one configuration each; several allowed).
        segment_s: segment length (s); None or <= 0: one free run per experiment.
        method: 'dp5' (default, smooth in the parameters) or 'rk4'.
        max_dt: bound on the simulator step (s).
    """

    def __init__(self, experiments: list[Experiment], segment_s: float | None = 4.0, method: str = "dp5",
                 max_dt: float = MAX_DT) -> None:
        if not experiments:
            raise ValueError("no experiments to compare with")
        self.experiments = list(experiments)
        self.method = method
        self._plans = []
        for ex in self.experiments:
            rec = max(1, int(math.ceil(1.0 / (ex.fs * max_dt) - 1e-9)))
            dt = 1.0 / (ex.fs * rec)
            if segment_s is None or segment_s <= 0 or segment_s * ex.fs >= ex.n - 1:
                L = ex.n - 1
            else:
                L = max(2, int(round(segment_s * ex.fs)))
            starts = np.arange(0, ex.n - 1, L)
            if len(starts) > 1 and ex.n - 1 - starts[-1] < L // 4:  # tiny tail: drop
                starts = starts[:-1]
            self._plans.append({"rec": rec, "dt": dt, "L": L, "starts": starts, "n_steps": L * rec})
        self.n_rows_per_params = sum(len(p["starts"]) for p in self._plans)
        # corrections (rad/s) to the data's speed estimates at each segment start: (n_seg, 2) per experiment
        self.speed_offsets = [np.zeros((len(p["starts"]), 2)) for p in self._plans]

    def refine_initial_speeds(self, vec: np.ndarray, weights: dict[str, float], scales: dict[str, float],
                              iterations: int = 2, h: float = 0.005) -> None:
        """Correct the speeds estimated from the data at the segment starts (nuisance states) by
        Gauss–Newton on the base model's residual, so that noisy derivative estimates of the
        recording do not pass for model error.  Segments are independent, so one batched run
        with all segments' ω_u (resp. ω_l) perturbed gives every segment's sensitivity.
        A disc stuck at a segment's start (speed exactly 0) is left stuck, and a correction never
        exceeds three standard deviations of the estimate's quantization noise
        (``Experiment.speed_noise``): it removes derivative noise, not model error."""
        for _ in range(iterations):
            P = np.repeat(np.asarray(vec, dtype=float)[None, :], 3, axis=0)
            preds = self.predict(P, tuple(weights), dspeed=np.array([[0, 0], [h, 0], [0, h]], dtype=float))
            for k, ex in enumerate(self.experiments):
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
                w0 = np.stack([ex.rates.get("omega_u", np.zeros(ex.n))[starts],
                               ex.rates.get("omega_l", np.zeros(ex.n))[starts]], axis=1) + self.speed_offsets[k]
                free = (w0 != 0.0)
                limit = 3.0 * np.array([ex.speed_noise.get("omega_u", 0.0), ex.speed_noise.get("omega_l", 0.0)])
                if ex.config is Configuration.FREE_VIBRATION:
                    free[:, 0] = False
                if ex.config is Configuration.UPPER:
                    free[:, 1] = False
                for j in range(len(starts)):
                    cols = np.flatnonzero(free[j])
                    if cols.size == 0:
                        continue
                    A = J[j][:, cols]
                    step, *_ = np.linalg.lstsq(A, -e0[j], rcond=None)
                    self.speed_offsets[k][j, cols] = np.clip(self.speed_offsets[k][j, cols] + step,
                                                             -limit[cols], limit[cols])

    # ------------------------------------------------------------------ helpers
    def segments(self, k: int) -> tuple[np.ndarray, int]:
        """Start indices and length (samples) of experiment k's segments."""
        return self._plans[k]["starts"], self._plans[k]["L"]

    def stitch(self, k: int, seg: np.ndarray) -> np.ndarray:
        """Join segment outputs (n_seg, L+1) into a record-length array (NaN where not covered)."""
        ex = self.experiments[k]
        starts, L = self.segments(k)
        out = np.full(ex.n, np.nan)
        for j, s in enumerate(starts):
            e = min(s + L + 1, ex.n)
            out[s:e] = seg[j, :e - s]
        return out

    def measured_segments(self, k: int, channel: str) -> np.ndarray:
        """The data cut like the predictions: (n_seg, L+1), NaN beyond the record."""
        ex = self.experiments[k]
        starts, L = self.segments(k)
        y = ex.channel(channel)
        out = np.full((len(starts), L + 1), np.nan)
        for j, s in enumerate(starts):
            e = min(s + L + 1, ex.n)
            out[j, :e - s] = y[s:e]
        return out

    def _delayed_inputs(self, ex: Experiment, plan: dict, delays: np.ndarray, taus: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray]:
        """Per parameter row: the input on every segment (n_rows, n_seg, n_steps) and u_m at each start."""
        dt, starts, rec, n_steps = plan["dt"], plan["starts"], plan["rec"], plan["n_steps"]
        n_total = (starts[-1] * rec) + n_steps + 1
        base = ex.input_on_grid(dt, n_total, ex.t[0])
        tg = np.arange(n_total) * dt
        U = np.empty((len(delays), len(starts), n_steps))
        UM = np.empty((len(delays), len(starts)))
        cache: dict[tuple[float, float], tuple[np.ndarray, np.ndarray]] = {}
        for i, (d, tau) in enumerate(zip(delays, taus)):
            key = (float(d), float(tau))
            if key not in cache:
                ud = base if d <= 0 else np.interp(tg - d, tg, base)
                if tau > 0:
                    a = math.exp(-dt / tau)
                    b_, a_ = [0.0, 1.0 - a], [1.0, -a]  # exact zero-order-hold discretisation
                    um = lfilter(b_, a_, ud, zi=lfilter_zi(b_, a_) * ud[0])[0]
                    # exact mean of u_m over each step (ZOH input): -> the input itself as tau -> 0
                    drive = ud + (um - ud) * (tau / dt) * (1.0 - a)
                else:
                    um = drive = ud
                seg = np.stack([drive[s * rec:s * rec + n_steps] for s in starts])
                cache[key] = (seg, um[starts * rec])
            U[i], UM[i] = cache[key]
        return U, UM

    # ------------------------------------------------------------------ prediction
    def predict(self, P: np.ndarray, channels: tuple[str, ...] = CHANNELS,
                dspeed: np.ndarray | None = None) -> list[Prediction]:
        """Model outputs for each parameter row of P (B, N_PARAMS) -> list of B Predictions.

        ``dspeed`` (B, 2): extra (ω_u, ω_l) added to every segment's initial speeds of that row
        (used to compute sensitivities in :meth:`refine_initial_speeds`)."""
        P = np.atleast_2d(np.asarray(P, dtype=float))
        if P.shape[1] != N_PARAMS:
            raise ValueError(f"parameter matrix must have {N_PARAMS} columns")
        B = P.shape[0]
        per_exp = []
        for k, (ex, plan) in enumerate(zip(self.experiments, self._plans)):
            starts, L, rec, dt = plan["starts"], plan["L"], plan["rec"], plan["dt"]
            ns = len(starts)
            U, UM = self._delayed_inputs(ex, plan, P[:, IDX.delay], P[:, IDX.tau_m])
            rows = np.repeat(P, ns, axis=0)
            t0 = np.tile(starts / ex.fs, B)
            rows[:, IDX.delay] = 0.0
            rows[:, IDX.tau_m] = 0.0
            drift = rows[:, IDX.drift]
            f = 1.0 + drift * t0
            if np.any(drift != 0):
                if np.any(f <= 0):
                    raise ValueError("friction_drift makes the lower friction level negative within the record")
                for j in _LOWER_LEVEL:
                    rows[:, j] *= f
                rows[:, IDX.drift] = drift / f
            X0 = self._x0(ex, starts, P)
            X0[:, 2:4] += np.tile(self.speed_offsets[k], (B, 1))
            if dspeed is not None:
                X0[:, 2:4] += np.repeat(np.asarray(dspeed, dtype=float), ns, axis=0)
            X0[:, 8] = UM.reshape(-1)
            D = self._simulate(ex.config, U.reshape(B * ns, -1), L / ex.fs, dt, rows, X0, rec, ns)[:, :L + 1]
            out = {}
            col = _COL
            out["theta_u"] = D[..., col["theta_u"]]
            out["theta_l"] = D[..., col["theta_l"]]
            if ex.config.lateral_free:
                Xs, Ys = D[..., col["x"]], D[..., col["y"]]
                skew = rows[:, IDX.lvdt_skew][:, None]
                xm = Xs + rows[:, IDX.lvdt_x0][:, None]
                ym = Ys * np.cos(skew) + Xs * np.sin(skew) + rows[:, IDX.lvdt_y0][:, None]
                if ex.lvdt_lowpass_hz:
                    xm = lowpass_zero_phase(xm, ex.fs, ex.lvdt_lowpass_hz)
                    ym = lowpass_zero_phase(ym, ex.fs, ex.lvdt_lowpass_hz)
                out["x"], out["y"] = xm, ym
            out = {c: v.reshape(B, ns, L + 1) for c, v in out.items()}
            if "theta_l" in ex.meas:
                out["alpha"] = out["theta_l"] - out["theta_u"]
            if "x" in out:
                out["r"] = np.hypot(out["x"], out["y"])
            keep = [c for c in channels if c in out and (c in ex.meas or c in ("alpha", "r"))]
            if ex.config is Configuration.UPPER:
                keep = [c for c in keep if c == "theta_u"]
            valid = self.measured_segments(k, "theta_u")
            mask = np.isnan(valid)
            for c in keep:
                out[c][:, mask] = np.nan
            per_exp.append({c: out[c] for c in keep})
        return [Prediction([per_exp[k] and {c: v[b] for c, v in per_exp[k].items()} for k in range(len(per_exp))],
                           self) for b in range(B)]

    def _simulate(self, config, U, duration, dt, rows, X0, rec, ns) -> np.ndarray:
        """One batched call; if a parameter row makes the kernel fail (e.g. a non-physical value
        tried by the optimiser), rerun per parameter row and give failing rows NaN outputs."""
        try:
            return simulate_batch(config, U, duration, dt=dt, params=rows, x0=X0, method=self.method,
                                  record_every=rec, parallel=True).data
        except (SystemError, ZeroDivisionError, FloatingPointError, ValueError):
            if rows.shape[0] == ns:
                n_rec = int(round(duration / dt)) // rec + 1
                return np.full((ns, n_rec, len(OUTPUT_NAMES)), np.nan)
            parts = [self._simulate(config, U[i:i + ns], duration, dt, rows[i:i + ns], X0[i:i + ns], rec, ns)
                     for i in range(0, rows.shape[0], ns)]
            return np.concatenate(parts)

    def _x0(self, ex: Experiment, starts: np.ndarray, P: np.ndarray) -> np.ndarray:
        B, ns = P.shape[0], len(starts)
        idx = np.tile(starts, B)
        rows = np.repeat(P, ns, axis=0)
        return ex.initial_states(idx, rows)
