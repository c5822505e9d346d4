"""Model predictions of recorded experiments, many parameter sets in one batched simulation.

Multiple shooting: each experiment is cut into segments of ``segment_s``
seconds; every segment is simulated from the state estimated from the data at
its start (:meth:`Experiment.initial_states`).  Stick-slip trajectories drift
in phase over long horizons (a small error in a friction level shifts every
later slip), so a single long run compares phases, not physics; short
segments keep the comparison local while still spanning several stick-slip
cycles.  ``segment_s=None`` gives one free run over the whole record.

The model is a :class:`drillgym.effects.Composition` (the base model and any effects, the
library's or a user's); parameter rows are in its layout (``composition.param_names``: base
parameters, then the effects').  All segments of all experiments for all parameter rows go
into ONE call of the composition's compiled batch kernel (numba threads), which is what
makes a finite-difference Jacobian cheap.

Each segment is exactly the continuation of a run from the record's start:

* its clock starts at the segment's time in the record (the kernel's ``T0``), so effects of
  time (``friction_drift``, a user effect of ``t``) see the record's time;
* a Delay effect's line is pre-filled with the record's input before the segment start,
  so the motor sees u(t − delay) from the first step;
* the library's ``motor_lag`` (when it is the first Input effect) is applied here, not in the
  kernel: the lag is linear in the input, so the input is filtered exactly (first-order
  zero-order-hold discretisation, from the record's start) and the simulated model is the
  composition without it: exact at segment starts and stable for any time constant,
  however small against the step;
* other effect states start from a free run of the whole record with the same parameters (where they are
  all lags driven by the input alone, a dead zone's or a user's, of the input's path only: nothing on it reads
  the discs).

The model's outputs go through the measurement chain of the data: the composition's
Measurement effects of the parameter row (:meth:`Composition.measure`) and, for the LVDT
channels, the offline zero-phase low-pass (:func:`drillgym.measurement.lowpass_zero_phase`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.signal import lfilter, lfilter_zi

from ..configurations import N_STATE, Configuration
from ..effects import Composition
from ..effects.library import MotorLag
from ..errors import FitError, InputError
from ..integrators import OUTPUT_NAMES, fixed_step_tableau
from ..measurement import lowpass_zero_phase
from ..params import N_PARAMS
from ..simulator import LANES_MIN_BATCH
from .effect_states import SegmentStartStates, input_state_columns
from .experiment import Experiment
from .lane_batch import LaneRequest, run_shared
from .predictions import Prediction, as_composition, steps_per_sample
from .speeds import SpeedCorrections

__all__ = ["SegmentedModel", "Prediction", "CHANNELS", "as_composition"]

CHANNELS = ("theta_u", "theta_l", "alpha", "x", "y", "r")
#: LVDT samples within this many periods of the low-pass cut-off (0.2 s at 5 Hz) of a segment's ends are
#: not compared (:meth:`SegmentedModel.measured_segments`)
LVDT_EDGE_PERIODS = 1.0
MAX_DT = 2e-3  # s: simulator step bound (DP5: > 200 steps per lateral period)
_COL = {n: i for i, n in enumerate(OUTPUT_NAMES)}


#: the motor lag's filtered inputs kept per experiment (time constants; a fit's rows share a few)
LAG_MEMO_SIZE = 16


def _lagged_input(base: np.ndarray, dt: float, tau: float) -> tuple[np.ndarray, np.ndarray]:
    """The motor drive on the simulator grid (the mean of u_m over each step) and u_m there, for the input
    ``base`` (V, per step of ``dt`` s) through the library's motor lag of time constant ``tau`` (s): exact
    first-order zero-order-hold discretisation from the record's start; the input itself when ``tau <= 0``."""
    if tau <= 0.0:  # no lag: the motor sees the input itself
        return base, base
    a = math.exp(-dt / tau)
    b_, a_ = [0.0, 1.0 - a], [1.0, -a]  # exact zero-order-hold discretisation
    um = lfilter(b_, a_, base, zi=lfilter_zi(b_, a_) * base[0])[0]
    # exact mean of u_m over each step (ZOH input): -> the input itself as tau -> 0
    drive = base + (um - base) * (tau / dt) * (1.0 - a)
    return drive, um


class SegmentedModel(SpeedCorrections, SegmentStartStates):
    """Predicts experiments for parameter matrices (B, composition.n_params) by multiple shooting.

    Parameters
    ----------
    experiments : list of Experiment
        The recordings (one configuration each; several allowed).
    segment_s : float or None, optional
        Segment length (s); None or <= 0: one free run per experiment.  Default 4.
    method : str, optional
        ``'dp5'`` (default, smooth in the parameters) or ``'rk4'``.
    max_dt : float, optional
        Bound on the simulator step (s).
    composition : Composition or effects, optional
        The model (a Composition or effects as for :func:`drillgym.effects.compose`; default the base model).
    input_aligned : bool, optional
        Choose the step so that the recorded input changes only at step boundaries when one of at most four
        times as many steps allows it (:func:`steps_per_sample`).  Default False.

    Raises
    ------
    InputError
        No experiments.
    """

    def __init__(
        self,
        experiments: list[Experiment],
        segment_s: float | None = 4.0,
        method: str = "dp5",
        max_dt: float = MAX_DT,
        composition: Any = None,
        input_aligned: bool = False,
    ) -> None:
        if not experiments:
            raise InputError("no experiments to compare with")
        self.experiments = list(experiments)
        self.method = method
        self._set_composition(composition)
        self._plans = []
        for ex in self.experiments:
            rec = steps_per_sample(ex, max_dt, input_aligned)
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
        #: runs of the last prediction whose states became non-finite: (experiment, parameter row, time in s
        #: of the first non-finite sample on the recording's clock, or None when the kernel failed)
        self.diverged: list[tuple[int, int, float | None]] = []
        self._exp_k = 0

    def _set_composition(self, composition: Any) -> None:
        """The model and the composition actually simulated (the library's motor lag, when it is the
        first Input effect, is applied to the input here instead; see the module docstring)."""
        self.composition = comp = as_composition(composition)
        inputs = [e for e in comp.effects if e.kind == "input"]
        self._lag = inputs[0] if inputs and inputs[0] is MotorLag else None
        sim = tuple(e for e in comp.effects if e is not self._lag)
        self._sim = comp if self._lag is None else Composition(sim)
        self._sim_cols = np.array([comp.param_index(n) for n in self._sim.param_names], dtype=int)
        self._tau_col = comp.param_index("tau_m") if self._lag is not None else None
        self._state_cols = input_state_columns(self._sim) if self._sim.n_states else None
        #: every effect state a declared lag the input alone drives: their free run is the input's path only
        self._lags_only = self._state_cols is not None and len(self._sim.lag_state_columns) == self._sim.n_states
        self._state_memo: dict[tuple, np.ndarray] = {}

    def with_composition(self, composition: Any) -> SegmentedModel:
        """The same experiments, segments and speed corrections with another model.

        Parameters
        ----------
        composition : Composition or effects
            A composition that extends this one (the diagnosis tries each candidate effect so).

        Returns
        -------
        SegmentedModel
            The model.
        """
        other = object.__new__(SegmentedModel)
        other.__dict__.update(self.__dict__)
        other._plans = [dict(p) for p in self._plans]
        other.speed_offsets = self.speeds_snapshot()
        SegmentedModel._set_composition(other, composition)
        return other

    # ------------------------------------------------------------------ helpers
    def segments(self, k: int) -> tuple[np.ndarray, int]:
        """An experiment's segments.

        Parameters
        ----------
        k : int
            The experiment.

        Returns
        -------
        tuple of (numpy.ndarray, int)
            The segments' start indices and their length (samples).
        """
        return self._plans[k]["starts"], self._plans[k]["L"]

    def stitch(self, k: int, seg: np.ndarray) -> np.ndarray:
        """Join segment outputs into a record-length array.

        Parameters
        ----------
        k : int
            The experiment.
        seg : numpy.ndarray
            The segments' outputs (n_seg, L+1).

        Returns
        -------
        numpy.ndarray
            The record-length array (NaN where not covered).
        """
        ex = self.experiments[k]
        starts, L = self.segments(k)
        out = np.full(ex.n, np.nan)
        for j, s in enumerate(starts):
            e = min(s + L + 1, ex.n)
            out[s:e] = seg[j, : e - s]
        return out

    def measured_segments(self, k: int, channel: str) -> np.ndarray:
        """The data cut like the predictions: (n_seg, L+1), NaN beyond the record.  LVDT channels that
        went through the zero-phase low-pass are also NaN (not compared) within
        :data:`LVDT_EDGE_PERIODS` periods of its cut-off from either end of a segment: the data were
        filtered over the whole record, a segment's prediction can only be filtered within the segment,
        and the two differ there by the filter's edge transient (on an independent rig's coupled
        recordings the LVDT misfit fell from 9 noise units to the noise without those samples).

        Parameters
        ----------
        k : int
            The experiment.
        channel : str
            The channel.

        Returns
        -------
        numpy.ndarray
            (n_seg, L+1), NaN beyond the record and where not compared.
        """
        ex = self.experiments[k]
        starts, L = self.segments(k)
        y = ex.channel(channel)
        out = np.full((len(starts), L + 1), np.nan)
        for j, s in enumerate(starts):
            e = min(s + L + 1, ex.n)
            out[j, : e - s] = y[s:e]
        if channel in ("x", "y", "r") and ex.lvdt_lowpass_hz and ex.config.lateral_free and len(starts) > 1:
            edge = int(math.ceil(LVDT_EDGE_PERIODS * ex.fs / ex.lvdt_lowpass_hz))
            if 0 < edge and 4 * edge < L:
                for j in range(len(starts)):
                    valid = np.flatnonzero(~np.isnan(out[j]))
                    out[j, valid[: edge + 1]] = np.nan  # the first sample is never compared
                    out[j, valid[-edge:]] = np.nan
        return out

    def matrix(self, P: Any) -> np.ndarray:
        """Parameter rows of the composition.

        Parameters
        ----------
        P : numpy.ndarray or RigParams
            A matrix, a vector or RigParams (effects at their defaults when the rows hold only the base
            parameters).

        Returns
        -------
        numpy.ndarray
            (B, composition.n_params).
        """
        if not isinstance(P, np.ndarray):
            return self.composition.matrix(P, 1)
        P = np.atleast_2d(np.asarray(P, dtype=float))
        if P.shape[1] == N_PARAMS and self.composition.n_params != N_PARAMS:
            return self.composition.matrix(P, P.shape[0])
        if P.shape[1] != self.composition.n_params:
            raise InputError(
                f"parameter matrix must have {self.composition.n_params} columns "
                f"({', '.join(self.composition.param_names)}), got {P.shape[1]}"
            )
        return P

    def _inputs(self, ex: Experiment, plan: dict, taus: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """The motor drive on the simulator grid from the record's start, per parameter row
        (n_rows, n_total), and u_m there (the library's motor lag applied here; else the input)."""
        dt, starts, rec, n_steps = plan["dt"], plan["starts"], plan["rec"], plan["n_steps"]
        n_total = (starts[-1] * rec) + n_steps + 1
        base = plan.get("input")
        if base is None or len(base) != n_total:  # once per segment layout (place_segment_starts may move it)
            base = plan["input"] = ex.input_on_grid(dt, n_total, ex.t[0])
        if taus is None:
            return base[None, :], base[None, :]
        D = np.empty((len(taus), n_total))
        UM = np.empty((len(taus), n_total))
        memo = plan.get("lagged")
        if memo is None or memo[0] is not base:  # the filtered inputs of this input, shared by the model's copies
            memo = plan["lagged"] = (base, {})
        cache = memo[1]
        for i, tau in enumerate(taus):
            key = float(tau)
            found = cache.get(key)
            if found is None:
                found = _lagged_input(base, dt, key)
                if len(cache) >= LAG_MEMO_SIZE:
                    cache.clear()
                cache[key] = found
            D[i], UM[i] = found
        return D, UM

    # ------------------------------------------------------------------ prediction
    def predict(
        self, P: np.ndarray, channels: tuple[str, ...] = CHANNELS, dspeed: np.ndarray | None = None
    ) -> list[Prediction]:
        """The model's outputs for each parameter row.

        Parameters
        ----------
        P : numpy.ndarray
            Parameter rows (B, composition.n_params).
        channels : tuple of str, optional
            The channels predicted.
        dspeed : numpy.ndarray, optional
            (B, 2): extra (ω_u, ω_l) added to every segment's initial speeds of that row (rad/s; the
            sensitivities of :meth:`refine_initial_speeds`).

        Returns
        -------
        list of Prediction
            One per row.
        """
        per_exp = self.predict_arrays(P, channels, dspeed)
        B = np.atleast_2d(P).shape[0]
        return [
            Prediction([per_exp[k] and {c: v[b] for c, v in per_exp[k].items()} for k in range(len(per_exp))], self)
            for b in range(B)
        ]

    def predict_arrays(
        self, P: np.ndarray, channels: tuple[str, ...] = CHANNELS, dspeed: np.ndarray | None = None
    ) -> list[dict[str, np.ndarray]]:
        """:meth:`predict`'s outputs for all rows at once.

        Parameters
        ----------
        P : numpy.ndarray
            Parameter rows (B, composition.n_params).
        channels : tuple of str, optional
            The channels predicted.
        dspeed : numpy.ndarray, optional
            (B, 2) speed offsets, as :meth:`predict`.

        Returns
        -------
        list of dict of str to numpy.ndarray
            Per experiment, channel -> (B, n_seg, seg_len).
        """
        P = self.matrix(P)
        B = P.shape[0]
        S = np.ascontiguousarray(P[:, self._sim_cols])  # rows of the simulated composition
        sim = self._sim
        per_exp = []
        self.diverged = []
        for k, (ex, plan) in enumerate(zip(self.experiments, self._plans)):
            self._exp_k = k
            starts, L, rec, dt, n_steps = plan["starts"], plan["L"], plan["rec"], plan["dt"], plan["n_steps"]
            ns = len(starts)
            taus = P[:, self._tau_col] if self._tau_col is not None else None
            drive, um = self._inputs(ex, plan, taus)
            pick = np.arange(B) if drive.shape[0] == B else np.zeros(B, dtype=int)
            rows = np.repeat(S, ns, axis=0)
            U = np.stack([drive[pick[b], s * rec : s * rec + n_steps] for b in range(B) for s in starts])
            X0 = np.zeros((B * ns, sim.n_state))
            X0[:, :N_STATE] = self._x0(ex, starts, P)
            X0[:, 2:4] += np.tile(self.speed_offsets[k], (B, 1))
            if dspeed is not None:
                X0[:, 2:4] += np.repeat(np.asarray(dspeed, dtype=float), ns, axis=0)
            if sim.n_states:
                X0[:, N_STATE:] = self._shared_effect_states(ex, plan, S, drive[pick], starts, taus)
            T0 = np.tile(ex.clock_start + starts / ex.fs, B)  # the run's clock (time-dependent effects)
            HIST, HEAD = self._delay_lines(rows, drive[pick], starts, rec, dt, ns)
            D = self._simulate(ex.config, U, dt, rows, X0, T0, HIST, HEAD, rec, n_steps, ns)[:, : L + 1]
            out = {}
            tu, tl = D[..., _COL["theta_u"]], D[..., _COL["theta_l"]]
            Xs, Ys = D[..., _COL["x"]], D[..., _COL["y"]]
            if sim.has_measurement:
                tu, tl, Xs, Ys = (np.array(a) for a in (tu, tl, Xs, Ys))
                for b in range(B):  # a parameter row's segments at once (they share its measurement)
                    i = slice(b * ns, (b + 1) * ns)
                    wu, wl = D[i, :, _COL["omega_u"]], D[i, :, _COL["omega_l"]]
                    tu[i], tl[i], Xs[i], Ys[i] = sim.measure(tu[i], tl[i], Xs[i], Ys[i], S[b], wu, wl)
            out["theta_u"], out["theta_l"] = tu, tl
            if ex.config.lateral_free:
                xm, ym = Xs, Ys
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
            mask = self._not_measured(k, plan)
            for c in keep:
                out[c][:, mask] = np.nan
            per_exp.append({c: out[c] for c in keep})
        return per_exp

    def _not_measured(self, k: int, plan: dict) -> np.ndarray:
        """(n_seg, L+1): where experiment k's segments have no upper-disc reading (beyond the record), kept with
        the segment layout it was found for."""
        memo = plan.get("not_measured")
        if memo is None or memo[0] is not plan["starts"] or memo[1] != plan["L"]:
            memo = plan["not_measured"] = (plan["starts"], plan["L"], np.isnan(self.measured_segments(k, "theta_u")))
        return memo[2]

    def check_finite(self, what: str, vector: np.ndarray | None = None) -> None:
        """Refuse the last prediction if one of its runs became non-finite (:attr:`diverged`).

        Parameters
        ----------
        what : str
            The result that needs the prediction (``"compare"``, ``"stage 'brake'"``), named first.
        vector : numpy.ndarray, optional
            The parameter row predicted, for the effects' values in the message.

        Raises
        ------
        FitError
            Names the model, its effects' values, the recording and the time of the first non-finite state.
        """
        if not self.diverged:
            return
        k, _, t = min(self.diverged, key=lambda d: (d[2] is None, d[2] or 0.0, d[0]))
        values = ""
        if vector is not None and self.composition.effects:
            vals = self.composition.split(np.asarray(vector, dtype=float))[1]
            values = " (" + ", ".join(f"{n} = {v:.4g}" for n, v in vals.items()) + ")"
        when = f"from t = {t:.6g} s" if t is not None else "(the kernel failed)"
        raise FitError(
            f"{what}: the model {self.composition.label}{values} gives non-finite states on "
            f"{self.experiments[k].name} {when}: its statistics cannot be computed; check the effects' "
            "formulas and parameter values"
        )

    def _delay_lines(
        self, rows: np.ndarray, drive: np.ndarray, starts: np.ndarray, rec: int, dt: float, ns: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """Delay lines (B*ns, L) pre-filled with the drive before each segment start (newest last),
        heads at the newest entry; without a Delay effect, empty lines (head -1)."""
        n = rows.shape[0]
        if not self._sim.has_delay:
            return np.zeros((n, 1)), np.full(n, -1, dtype=np.int64)
        Ld = self._sim.delay_line_length(rows, dt)
        back = np.arange(-Ld, 0)
        idx = np.clip(np.asarray(starts)[:, None] * rec + back[None, :], 0, None)  # (ns, Ld) grid indices
        lane = np.arange(n)
        H = drive[(lane // ns)[:, None], idx[lane % ns]]  # lane i: its row's drive before its segment
        return H, np.full(n, Ld - 1, dtype=np.int64)

    def _full_rows(self, S: np.ndarray) -> np.ndarray:
        """Rows of the whole composition from rows of the simulated one (the lag's column at its default)."""
        if self._sim is self.composition:
            return S
        P = self.composition.matrix(None, S.shape[0])
        P[:, self._sim_cols] = S
        return P

    def _simulate(
        self,
        config: Configuration,
        U: np.ndarray,
        dt: float,
        rows: np.ndarray,
        X0: np.ndarray,
        T0: np.ndarray,
        HIST: np.ndarray,
        HEAD: np.ndarray,
        rec: int,
        n_steps: int,
        ns: int,
    ) -> np.ndarray:
        """One batched kernel call (B*ns, n_rec, n_outputs).  Rows that fail or diverge (a non-physical
        value tried by the optimiser) get NaN outputs; an exception reruns per parameter row."""
        sim = self._sim
        n_rec = n_steps // rec + 1
        try:
            Y = np.ascontiguousarray(X0, dtype=np.float64)
            if not config.lateral_free:
                Y[:, 4:8] = 0.0
            MODE = np.zeros((Y.shape[0], 2), dtype=np.int64)
            A, b, c = fixed_step_tableau(self.method, "identification")
            U = np.ascontiguousarray(U, dtype=np.float64)
            rows = np.ascontiguousarray(rows)
            T0 = np.ascontiguousarray(T0, dtype=np.float64)
            # the SIMD lane kernel, chunks over the cores (as simulate_batch): the coupled diagnose of
            # benchmarks/bench_diagnose_time.py took 71 s instead of 100 s
            if Y.shape[0] >= LANES_MIN_BATCH:  # with the other workers' runs (lane_batch), when there are some
                key = (id(sim.kernels.lanes.lanes_run), int(config), float(dt), int(rec), int(n_steps), U.shape[1])
                key += (self.method,)  # delay lines of any length: lane_batch lengthens the shorter ones
                lanes = (Y, MODE, U, rows, HIST, HEAD, T0)
                scalars = (int(config), float(dt), int(rec), int(n_steps), (A, b, c))
                OUT = run_shared(
                    LaneRequest(key, sim.kernels.lanes.lanes_run, lanes, scalars, (n_rec, len(sim.output_names)))
                )
                OUT = OUT.transpose(2, 0, 1)
            else:
                OUT = np.full((Y.shape[0], n_rec, len(sim.output_names)), np.nan)
                sim.kernels.stepping.run_batch_parallel(
                    Y,
                    MODE,
                    U,
                    rows,
                    int(config),
                    float(dt),
                    T0,
                    0.0,
                    A,
                    b,
                    c,
                    int(rec),
                    OUT,
                    True,
                    int(n_steps),
                    HIST,
                    HEAD,
                )
        except (SystemError, ZeroDivisionError, FloatingPointError, ValueError):
            if rows.shape[0] <= ns:
                self.diverged += [(self._exp_k, r, None) for r in range(rows.shape[0] // ns)]
                return np.full((rows.shape[0], n_rec, len(sim.output_names)), np.nan)
            parts = [
                self._simulate(
                    config,
                    U[i : i + ns],
                    dt,
                    rows[i : i + ns],
                    X0[i : i + ns],
                    T0[i : i + ns],
                    HIST[i : i + ns],
                    HEAD[i : i + ns],
                    rec,
                    n_steps,
                    ns,
                )
                for i in range(0, rows.shape[0], ns)
            ]
            return np.concatenate(parts)
        bad = ~np.all(np.isfinite(OUT[:, -1, 2:10]), axis=1)
        for i in np.flatnonzero(bad):  # rare: a parameter row the optimiser tried, or a broken effect
            first = int(np.argmax(~np.all(np.isfinite(OUT[i, :, 2:10]), axis=1)))
            self.diverged.append((self._exp_k, int(i) // ns, float(T0[i]) + first * rec * dt))
        OUT[bad] = np.nan
        return OUT

    def _x0(self, ex: Experiment, starts: np.ndarray, P: np.ndarray) -> np.ndarray:
        B, ns = P.shape[0], len(starts)
        idx = np.tile(starts, B)
        rows = np.repeat(P, ns, axis=0)
        return ex.initial_states(idx, rows, self.composition)
