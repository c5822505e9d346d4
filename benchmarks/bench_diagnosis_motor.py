"""Must-show matrix of the diagnosis on the motor side, on recordings of a simulator other than drillgym's.

The rig is the independent scipy rig of ``bench_diagnosis_rig.py`` (docs/model.md written again by hand, smoothed
friction, LSODA, its own measurement chain: 0.1 mrad angle noise, 8000 counts/rev), extended here with
motor-side effects outside drillgym's library, each coded from its physical description:

* ``dead_zone``: the motor sees sign(v) max(|v| − u0, 0) of the voltage v reaching it (u0 = 0.3-0.5 V);
* ``cogging``: a torque −Tcog sin(6 θu + φ) on the upper disc (Tcog = 0.08-0.15 N m, six per revolution);
* ``saturation``: the motor sees v (1 − s v²) (s = 0.008-0.015 /V²: a motor constant falling with the voltage);
* ``voltage_offset``: the motor sees v + u_off (u_off = ±0.1-0.2 V);
* ``backlash``: a gap of ±b between the motor's rotor (a fifth of Ju, the motor's torque on it, its encoder
  θu) and the upper disc (the rest of Ju, the bearing friction and the string), closed by a stiff damped
  coupling (500 N m/rad, 4 N m s/rad: 13 Hz) (b = 0.01-0.03 rad);

each alone and with a library effect (a motor lag, τ = 20-40 ms, before the motor-side effect: the motor sees
f(u_m)), on voltage steps, ramps or quasi-random input (cycled over the rows), with the base parameters
0-5 % off (km, bu, Tcu, Ts, Tc, kθ, Jl each by a factor drawn in [0.95, 1.05]).  Each recording is diagnosed as a
user would (``diagnose(..., discover=True)``: the library's candidates, the base re-identified, discovery and
the candidate's own fit).  Reported per kind:

* ``halved``: the share of recordings where the candidate's own fit at least halves the unexplained variance
  (the final residual's mean square in noise units²);
* ``lag_selected``: with the motor lag hidden, the share where it is in the final model: selected by the
  library's selection, or by the selection run again with the candidate in the model
  (``lag_selected_by_the_selection``: by the first selection alone; ``lag_selected_or_tie``: or
  the input delay selected with a stated lag/delay tie, as ``bench_diagnosis_selection`` counts ties);
* ``silent``: recordings whose final residual (without the candidate) is ≥ 10× the noise on a channel and that
  are reported as explained or as "the base model stands" (must be 0).

    python benchmarks/bench_diagnosis_motor.py [--seeds 1] [--first-seed 0] [--limit N] [--duration 20]
        [--out results.json]

Runs one recording at a time (one core); the default matrix is 8 recordings.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_diagnosis_rig import ENCODER_READINGS, _Rig, encoder_readings, input_signal  # noqa: E402

from drillgym import RigParams  # noqa: E402
from drillgym.io import TimeSeries  # noqa: E402
from drillgym.measurement import quantize_angle  # noqa: E402

KINDS = ("dead_zone", "cogging", "saturation", "voltage_offset", "backlash")
SIGNALS = ("steps", "ramps", "quasi_random")
MISMATCHED = ("km", "bu", "Tcu", "Ts", "Tc", "ktheta", "Jl")


#: the backlash's rotor: its share of Ju, the coupling's stiffness (N m/rad) and damping (N m s/rad)
ROTOR_SHARE, COUPLING_K, COUPLING_C = 0.2, 500.0, 4.0


class MotorRig(_Rig):
    """The independent rig with motor-side effects (``self.fx`` keys: :data:`KINDS` and ``motor_lag``).

    State: θu, θl, ωu, ωl, then the lag's voltage (with ``motor_lag``), then the rotor's angle and speed
    (with ``backlash``; θu is then the upper disc's and the encoder reads the rotor's)."""

    def rotor_index(self) -> int:
        """Where the rotor's angle sits in the state (with ``backlash``)."""
        return 5 if "motor_lag" in self.fx else 4

    def coupling(self, gap_angle: float, gap_speed: float) -> float:
        """The torque from the rotor to the disc across the backlash (N m)."""
        b = self.fx["backlash"]["b"]
        if abs(gap_angle) <= b:
            return 0.0
        return COUPLING_K * (gap_angle - math.copysign(b, gap_angle)) + COUPLING_C * gap_speed

    def motor_voltage(self, v: float) -> float:
        """The voltage the motor turns into torque, from the voltage v reaching it (V)."""
        fx = self.fx
        if "dead_zone" in fx:
            u0 = fx["dead_zone"]["u0"]
            v = math.copysign(max(abs(v) - u0, 0.0), v)
        if "saturation" in fx:
            v = v * (1.0 - fx["saturation"]["s"] * v * v)
        if "voltage_offset" in fx:
            v = v + fx["voltage_offset"]["u_off"]
        return v

    def cogging(self, tu: float) -> float:
        """The cogging torque on the upper disc (N m)."""
        if "cogging" not in self.fx:
            return 0.0
        f = self.fx["cogging"]
        return -f["Tcog"] * math.sin(6.0 * tu + f["phase"])

    def rhs_torsional(self, tt: float, s: np.ndarray) -> list[float]:
        p = self.p
        tu, tl, wu, wl = s[:4]
        lag = "motor_lag" in self.fx
        v = self.motor_voltage(s[4] if lag else self.drive(tt, None))
        S = self.string_torque(tl - tu, wl - wu)
        rotor = None
        if "backlash" in self.fx:
            k = self.rotor_index()
            jm = ROTOR_SHARE * p.Ju
            T = self.coupling(s[k] - tu, s[k + 1] - wu)
            disc = (T - self.upper_friction(wu) + S + self.cogging(tu)) / (p.Ju - jm)
            rotor = [s[k + 1], (p.km * v - T) / jm]
        else:
            disc = (p.km * v - self.upper_friction(wu) + S + self.cogging(tu)) / p.Ju
        out = [wu, wl, disc, (-self.lower_friction(tt, wl, tl) - S) / p.Jl]
        if lag:
            out.append((self.drive(tt, None) - s[4]) / self.fx["motor_lag"]["tau_m"])
        return out + (rotor or [])


def motor_recording(signal: str, duration: float, rate_hz: float, seed: int, effects: dict, scale: dict) -> TimeSeries:
    """A torsional recording of :class:`MotorRig` (the measurement chain of ``bench_diagnosis_rig``)."""
    p = RigParams().scaled(**scale)
    t, u = input_signal(signal, duration, rate_hz, seed, offset=1.0 if signal != "steps" else 1.2, amplitude=1.6)
    rig = MotorRig("torsional", p, effects, t, u)
    y0 = (
        [0.0, 0.0, 0.0, 0.0]
        + ([u[0]] if "motor_lag" in effects else [])
        + ([0.0, 0.0] if "backlash" in effects else [])
    )
    sol = solve_ivp(
        rig.rhs_torsional, (0.0, duration), y0, method="LSODA", t_eval=t, rtol=1e-7, atol=1e-9, max_step=0.01
    )
    if not sol.success:
        raise RuntimeError(f"motor rig: {sol.message}")
    rng = np.random.default_rng(seed + 7)
    read_u, read_l = encoder_readings(sol.y[rig.rotor_index() if "backlash" in effects else 0], sol.y[1], effects)
    cols = {
        "t": t,
        "u": u,
        "theta_u": quantize_angle(read_u + rng.normal(0, 1e-4, t.size)),
        "theta_l": quantize_angle(read_l + rng.normal(0, 1e-4, t.size)),
    }
    meta = {
        "configuration": "torsional",
        "source": "emulator",
        "sample_rate_hz": rate_hz,
        "description": f"independent scipy rig with motor-side effects, {signal}, effects {sorted(effects)}",
    }
    return TimeSeries(cols, meta, "<independent motor rig>")


def draw(kind: str, rng: np.random.Generator) -> dict[str, float]:
    """The hidden effect's parameters."""
    if kind == "dead_zone":
        return {"u0": float(rng.uniform(0.3, 0.5))}
    if kind == "cogging":
        return {"Tcog": float(rng.uniform(0.08, 0.15)), "phase": float(rng.uniform(0, 2 * math.pi))}
    if kind == "saturation":
        return {"s": float(rng.uniform(0.008, 0.015))}
    if kind == "backlash":
        return {"b": float(rng.uniform(0.01, 0.03))}
    if kind in ("motor_encoder_scale", "lower_encoder_scale"):  # 0.3-2 % either way
        return {ENCODER_READINGS[kind]: float(rng.choice([-1, 1]) * rng.uniform(0.003, 0.02))}
    if kind == "lower_encoder_offset":  # 5-30 mrad either way (6-38 counts)
        return {ENCODER_READINGS[kind]: float(rng.choice([-1, 1]) * rng.uniform(0.005, 0.03))}
    return {"u_off": float(rng.choice([-1, 1]) * rng.uniform(0.1, 0.2))}


def rows(seeds: int) -> list[dict]:
    """The matrix: every kind alone and with a motor lag, per seed; the input cycles over :data:`SIGNALS`.

    Each row's draws come from its index among the rows of its kind's generation (the first four kinds, then
    ``backlash`` added later), so adding a kind leaves the earlier rows as they were."""
    out = []
    first = KINDS[:4]
    counters = {"first": 0, "later": 0}
    for seed in range(seeds):
        for kind in KINDS:
            for with_lag in (False, True):
                group = "first" if kind in first else "later"
                i = counters[group] + (0 if group == "first" else 10_000)
                counters[group] += 1
                rng = np.random.default_rng(1000 * seed + 17 * i + 3)
                effects = {kind: draw(kind, rng)}
                if with_lag:
                    effects["motor_lag"] = {"tau_m": float(rng.uniform(0.02, 0.04))}
                scale = {k: float(1.0 + rng.uniform(-0.05, 0.05)) for k in MISMATCHED}
                out.append(
                    {"kind": kind, "lag": with_lag, "signal": SIGNALS[i % 3], "seed": seed + i, "effects": effects}
                    | {"scale": scale}
                )
    return out


def run_row(row: dict, duration: float, rate_hz: float, work: Path) -> dict:
    """Diagnose one recording; what the matrix counts."""
    from drillgym.diagnosis import diagnose

    ts = motor_recording(row["signal"], duration, rate_hz, row["seed"], row["effects"], row["scale"])
    t0 = time.perf_counter()
    d = diagnose(ts, discover=True, candidate_out=work / f"cand_{row['seed']}.py")
    seconds = time.perf_counter() - t0
    un = d.unexplained
    text = d.text()
    c = d.candidate
    fit = c.fit if c is not None else None
    again = d.final() if d.reselection is not None else None  # the model with every kept candidate
    return {
        **{k: row[k] for k in ("kind", "lag", "signal", "seed")},
        "hidden": row["effects"],
        "selected": d.selected,
        "reselected": again.selected if again is not None else None,
        "ties": {s.effect: s.note for s in d.ranking if s.note and s.effect in d.selected},
        "reselection_ties": {s.effect: s.note for s in again.ranking if s.note and s.effect in again.selected}
        if again is not None
        else {},
        "ratio": un.ratio_to_noise,
        "worst": un.worst,
        "verdict": un.verdict,
        "says_stands": "stands" in text,
        "silent": bool(un.worst >= 10.0 and (un.explained or "stands" in text or text.startswith("explained"))),
        "candidate": c.expression() if c is not None else None,
        "candidate_group": c.group if c is not None else None,
        "candidate_cut": fit.variance_cut if fit is not None else None,
        "candidate_with": list(fit.with_library) if fit is not None else [],
        "candidate_values": fit.values if fit is not None else None,
        "ratio_with_candidate": fit.after.ratio_to_noise if fit is not None else None,
        "halved": bool(fit is not None and fit.variance_cut >= 0.5),
        "seconds": seconds,
    }


def _lag_found(r: dict) -> bool:
    """The motor lag in the model: fitted with the candidate whose terms were found through it
    (``candidate_with``), else selected by the library's selection, or by the selection run again with the
    candidate in the model (``reselected``), which replaces the first one's when it ran."""
    if "motor_lag" in r.get("candidate_with", ()):
        return True
    final = r["reselected"] if r.get("reselected") is not None else r["selected"]
    return "motor_lag" in final


def _lag_or_tie(r: dict) -> bool:
    """The motor lag selected, or the input delay selected with a stated lag/delay tie (the data cannot tell them
    apart, as the selection benchmark counts a stated tie)."""
    if _lag_found(r):
        return True
    again = r.get("reselected") is not None
    final, ties = (r["reselected"], r["reselection_ties"]) if again else (r["selected"], r.get("ties") or {})
    return "input_delay" in final and "motor_lag" in ties.get("input_delay", "")


def summary(results: list[dict]) -> dict:
    """Per kind: halved, lag_selected (rows with the lag), silent; and the totals."""
    out = {}
    for kind in KINDS:
        rs = [r for r in results if r["kind"] == kind]
        if not rs:
            continue
        lag = [r for r in rs if r["lag"]]
        out[kind] = {
            "n": len(rs),
            "halved": sum(r["halved"] for r in rs) / len(rs),
            "lag_selected": (sum(_lag_found(r) for r in lag) / len(lag)) if lag else None,
            "lag_selected_or_tie": (sum(_lag_or_tie(r) for r in lag) / len(lag)) if lag else None,
            "lag_selected_by_the_selection": (sum("motor_lag" in r["selected"] for r in lag) / len(lag))
            if lag
            else None,
            "silent": sum(r["silent"] for r in rs),
        }
    out["total"] = {
        "n": len(results),
        "kinds_halved_in_most": sum(1 for k in KINDS if k in out and out[k]["halved"] >= 0.5),
        "silent": sum(r["silent"] for r in results),
        "seconds": sum(r["seconds"] for r in results),
    }
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=1, help="repetitions of the matrix (new draws each)")
    ap.add_argument(
        "--first-seed", type=int, default=0, help="skip the repetitions before this one (fresh draws, same rows)"
    )
    ap.add_argument("--limit", type=int, default=0, help="run only the first N recordings (0: all)")
    ap.add_argument("--duration", type=float, default=20.0, help="recording length (s)")
    ap.add_argument("--rate", type=float, default=250.0, help="sample rate (Hz)")
    ap.add_argument("--jobs", type=int, default=1, help="only 1: one recording at a time")
    ap.add_argument("--out", type=Path, default=None, help="write every row and the summary as JSON")
    a = ap.parse_args()
    if a.jobs != 1:
        ap.error("--jobs: only 1 (one recording at a time, one core)")
    per_repetition = 2 * len(KINDS)
    matrix = rows(a.first_seed + a.seeds)[a.first_seed * per_repetition :]
    if a.limit:
        matrix = matrix[: a.limit]
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for row in matrix:
            r = run_row(row, a.duration, a.rate, Path(tmp))
            results.append(r)
            cut = "-" if r["candidate_cut"] is None else f"{r['candidate_cut']:.0%}"
            print(
                f"{r['kind']:<15}{'+lag' if r['lag'] else '':<5}{r['signal']:<13} residual {r['worst']:9.3g}x noise "
                f"({r['verdict']}); selected {r['selected']}; with the candidate in, selected {r['reselected']} "
                f"(ties {sorted(r['reselection_ties'])}); "
                f"candidate {r['candidate_group']} cut {cut}; "
                f"silent {r['silent']}; {r['seconds']:.0f} s",
                flush=True,
            )
    s = summary(results)
    print(json.dumps(s, indent=1))
    if a.out:
        a.out.write_text(json.dumps({"rows": results, "summary": s}, indent=1, default=str), encoding="utf-8")


if __name__ == "__main__":
    main()
