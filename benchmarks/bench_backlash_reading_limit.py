"""Why no static reading term can explain a backlash: the best least-squares fit of the encoder's lead, oracle terms.

The independent motor rig of ``bench_diagnosis_motor.py`` with its ``backlash`` (a gap of ±b between the motor's
rotor, a fifth of Ju, and the upper disc, closed by a stiff damped coupling; the motor encoder reads the rotor).
What the motor encoder reads beyond the disc's angle is the rotor's lead d = θr − θu.  Discovery's reading
candidates are static functions of the measured state; this script fits d, by least squares on the true
(noise-free) d, with the static terms below and prints the residual in noise units (0.1 mrad, the rig's):

* ``play``: a constant and b·tanh(ωu / 0.05), discovery's play term (the shaft leads in the direction it turns);
* ``play+u``: and the command u (a lead that grows with the motor's torque);
* ``oracle``: a constant, tanh(T / 0.05) and T, with T the coupling's *true* torque (not measurable): the best a
  static reading of the transmitted torque can do.

Even the oracle leaves 10-40 noise units: what remains is the gap's crossing and the coupling's 13 Hz ringing,
dynamics of a degree of freedom of its own (the rotor), which only an effect with the rotor's angle and speed as
states represents.  No randomness beyond the input's seed.

    python benchmarks/bench_backlash_reading_limit.py [--duration 20] [--seed 3]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_diagnosis_motor import SIGNALS, MotorRig, RigParams, input_signal  # noqa: E402

NOISE = 1e-4  # rad: the rig's angle noise


def residuals(signal: str, b: float, duration: float, seed: int, rate_hz: float = 500.0) -> dict[str, float]:
    """Residual RMS of each term set's least-squares fit of the rotor's lead, in noise units."""
    t, u = input_signal(signal, duration, rate_hz, seed, offset=1.0 if signal != "steps" else 1.2, amplitude=1.6)
    rig = MotorRig("torsional", RigParams(), {"backlash": {"b": b}}, t, u)
    sol = solve_ivp(
        rig.rhs_torsional, (0, duration), [0.0] * 6, method="LSODA", t_eval=t, rtol=1e-7, atol=1e-9, max_step=0.01
    )
    tu, _, wu, _, tr, wr = sol.y
    lead = tr - tu
    torque = np.array([rig.coupling(a, s) for a, s in zip(lead, wr - wu)])
    one = np.ones_like(lead)
    sets = {
        "play": [one, np.tanh(wu / 0.05)],
        "play+u": [one, np.tanh(wu / 0.05), u],
        "oracle": [one, np.tanh(torque / 0.05), torque],
    }
    out = {}
    for name, cols in sets.items():
        a = np.column_stack(cols)
        coef, *_ = np.linalg.lstsq(a, lead, rcond=None)
        out[name] = float(np.sqrt(np.mean((lead - a @ coef) ** 2)) / NOISE)
    out["lead"] = float(np.sqrt(np.mean((lead - lead.mean()) ** 2)) / NOISE)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=20.0)
    ap.add_argument("--seed", type=int, default=3)
    a = ap.parse_args()
    print("residual of the rotor's lead after the best static reading (noise units, 0.1 mrad)")
    print(f"{'input':<14}{'b (rad)':>8}{'lead':>8}{'play':>8}{'play+u':>8}{'oracle':>8}")
    for signal in SIGNALS:
        for b in (0.01, 0.02, 0.03):
            r = residuals(signal, b, a.duration, a.seed)
            print(f"{signal:<14}{b:>8.2f}" + "".join(f"{r[k]:>8.1f}" for k in ("lead", "play", "play+u", "oracle")))


if __name__ == "__main__":
    main()
