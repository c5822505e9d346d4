"""Staged identification with the segment-start speeds held at the data's estimates against fitted
with the parameters (``identify_stage(..., refine_speeds=False / True)``), measured in the same run.

Recordings:
* drillgym's simulator through the rig's measurement chain (``synthetic_measurement``: encoders quantised
  to 8000 counts/rev, LVDT noise and 5 Hz filter), the identified parameters, at 250 Hz and 100 Hz: the
  free-vibration, lower (brake off), lateral and brake stages of ``tests/test_identification_stages.py``,
  each started from the same perturbed guesses;
* the independent rig of ``benchmarks/bench_diagnosis_rig.py`` (scipy LSODA, smoothed friction, its own
  noise and quantisation): the brake stage on three torsional recordings at different initial windings,
  at 500 Hz and 200 Hz.

Printed per case and mode: wall time, RSS, the relative error (%) of each identified parameter against the
truth (the free-vibration stage holds kθ at the geometry value 0.0813, so its Jl is expected at +4.9 %).

    NUMBA_NUM_THREADS=1 .venv/bin/python benchmarks/bench_staged_speeds.py
"""

from __future__ import annotations

import sys
import time
import warnings
from pathlib import Path

from drillgym import RigParams
from drillgym.identification.staged import identify_stage
from drillgym.identification.synthetic import synthetic_measurement

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_diagnosis_rig import rig_recording  # noqa: E402

TRUE = RigParams()


def _drillgym(config: str, seed: int, rate: float, signal: str = "quasi_random", **kw):
    return synthetic_measurement(
        config, TRUE, duration=kw.pop("duration", 20.0), rate_hz=rate, seed=seed, signal=signal, **kw
    )


def cases():
    """(name, stage, estimation recordings, start parameters, parameters to score)."""
    out = []
    brake_start = TRUE.scaled(Ts=1.15, Tc=0.85, ws=1.2, delta=0.9, bb=1.3)
    brake = ("Ts", "Tc", "ws", "delta", "bb")
    for rate in (250.0, 100.0):
        fv = synthetic_measurement("free_vibration", TRUE, duration=15.0, rate_hz=rate, u=0.0, alpha0=3.0)
        out.append(
            (
                f"drillgym free_vibration {rate:.0f} Hz",
                "free_vibration",
                fv,
                TRUE.scaled(Jl=1.3, bl=0.7, Tcl=1.5),
                ("Jl", "bl", "Tcl"),
            )
        )
        out.append(
            (
                f"drillgym lower {rate:.0f} Hz",
                "lower",
                _drillgym("torsional_bearing", 1, rate, offset=0.5),
                TRUE.scaled(Jl=1.1, ktheta=0.9, bl=1.3, Tcl=1.2),
                ("Jl", "ktheta", "bl", "Tcl"),
            )
        )
        out.append(
            (
                f"drillgym lateral {rate:.0f} Hz",
                "lateral",
                _drillgym("lateral", 1, rate, offset=3.0),
                TRUE.scaled(k=0.8, b=1.3, e=1.2, mt=0.8),
                ("k", "b", "e"),
            )
        )
        out.append(
            (
                f"drillgym brake {rate:.0f} Hz",
                "brake",
                [_drillgym("torsional", s, rate, offset=1.0, alpha0=a) for s, a in ((1, 0.0), (2, 2.0), (3, -2.0))],
                brake_start,
                brake,
            )
        )
    for rate in (500.0, 200.0):
        recs = [
            rig_recording("torsional", duration=20.0, rate_hz=rate, seed=s, alpha0=a)
            for s, a in ((1, 0.0), (2, 2.0), (3, -2.0))
        ]
        out.append((f"independent brake {rate:.0f} Hz", "brake", recs, brake_start, brake))
    return out


def main() -> None:
    for name, stage, est, start, scored in cases():
        for refine in (False, True):
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                r = identify_stage(stage, est, start, refine_speeds=refine)
            dt = time.perf_counter() - t0
            errs = " ".join(
                f"{n} {100 * (r.fit.values[n] / getattr(TRUE, n) - 1):+.2f}%" for n in scored if n in r.fit.values
            )
            mode = "fitted" if refine else "held"
            print(f"{name:32s} speeds {mode:6s} {dt:6.1f} s  RSS {r.fit.rss_after:10.4g}  {errs}", flush=True)


if __name__ == "__main__":
    main()
