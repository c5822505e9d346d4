"""docs/EFFECTS.md's numbers and figure: a cubic string found by ``identify --add-effect``.

Two recordings of a torsional rig whose string torque is kθ (α + c3 α³), c3 = 0.015 1/rad²,
25 s of the quasi-random estimation input (offset 1 V, ±5 V) at 250 Hz:

* ``drillgym``: drillgym's simulator with the user file examples/effects/string_cubic.py, then
  the rig's measurement chain (:func:`drillgym.identification.synthetic.synthetic_measurement`:
  encoders quantised to 8000 counts/rev);
* ``scipy``: an independent model written here: the torsional equations of docs/model.md with the cubic
  string, friction signs smoothed (tanh(ω/2e-3 rad/s)), scipy's Radau; Gaussian angle noise
  (0.2 mrad) then the same quantisation.

Each is written as a csv (docs/data_format.md) and identified by the CLI exactly as a user would::

    drillgym identify REC.csv --config torsional \\
        --add-effect examples/effects/string_cubic.py:string_cubic --json --out p.json

Printed: R² before/after per channel, 1 − R² ratio, fitted c3 ± standard error, wall time;
then the same for the backlash example (examples/effects/string_backlash.py, gap 0.05 rad,
a drillgym recording of 20 s, offset 0.5 V).
Figure: docs/figures/effects_cubic_string.png (twist α measured, base model, with the cubic
string; both recordings).

    .venv/bin/python benchmarks/effects_cubic_string.py [--out-dir /tmp/cubic]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

from drillgym import RigParams
from drillgym.io import TimeSeries, write_timeseries
from drillgym.measurement import quantize_angle
from drillgym.signals import quasi_random

ROOT = Path(__file__).resolve().parents[1]
SPEC = "examples/effects/string_cubic.py:string_cubic"
C3 = 0.015
GAP = 0.05  # rad, the backlash example
DURATION, RATE = 25.0, 250.0


def scipy_recording(c3: float = C3, seed: int = 3, eps: float = 2e-3, noise_rad: float = 2e-4) -> TimeSeries:
    """The independent model's recording (see the module docstring)."""
    p = RigParams()
    t, u = quasi_random(DURATION, rate_hz=RATE, seed=seed, amplitude=5.0, offset=1.0)

    def rhs(tt, s):
        tu, tl, wu, wl = s
        a = tl - tu
        string = p.ktheta * (a + c3 * a**3)
        su, sl = np.tanh(wu / eps), np.tanh(wl / eps)
        tfu = (p.Tcu * su + p.dTcu * abs(su)) + p.bu * wu + p.dbu * abs(wu)
        tfl = (p.Tc + (p.Ts - p.Tc) * np.exp(-(abs(wl / p.ws) ** p.delta))) * sl + p.bb * wl
        return [wu, wl, (p.km * np.interp(tt, t, u) - tfu + string) / p.Ju, (-tfl - string) / p.Jl]

    sol = solve_ivp(rhs, (0.0, DURATION), [0.0] * 4, method="Radau", t_eval=t, rtol=1e-7, atol=1e-9, max_step=0.01)
    rng = np.random.default_rng(seed)
    cols = {
        "t": t,
        "u": u,
        "theta_u": quantize_angle(sol.y[0] + rng.normal(0, noise_rad, t.size)),
        "theta_l": quantize_angle(sol.y[1] + rng.normal(0, noise_rad, t.size)),
    }
    return TimeSeries(
        cols,
        {
            "configuration": "torsional",
            "source": "scipy Radau, smoothed friction",
            "sample_rate_hz": RATE,
            "description": f"cubic string c3={c3}",
        },
        "<scipy>",
    )


def drillgym_recording(c3: float = C3, seed: int = 2) -> TimeSeries:
    from drillgym.identification.synthetic import synthetic_measurement

    return synthetic_measurement(
        "torsional",
        duration=DURATION,
        rate_hz=RATE,
        offset=1.0,
        seed=seed,
        effects=[str(ROOT / SPEC)],
        effect_params={"c3": c3},
    )


def identify(csv: Path, out: Path, spec: str = SPEC) -> tuple[dict, float]:
    from typer.testing import CliRunner

    from drillgym.cli import app

    t0 = time.perf_counter()
    r = CliRunner().invoke(
        app,
        ["identify", str(csv), "--config", "torsional", "--add-effect", str(ROOT / spec), "--json", "--out", str(out)],
    )
    if r.exit_code != 0:
        raise SystemExit(r.output)
    return json.loads(r.output), time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out-dir", default=None)
    ap.add_argument("--figure", default=str(ROOT / "docs" / "figures" / "effects_cubic_string.png"))
    a = ap.parse_args()
    work = Path(a.out_dir or tempfile.mkdtemp(prefix="cubic_"))
    work.mkdir(parents=True, exist_ok=True)
    results = {}
    for name, make in (("drillgym", drillgym_recording), ("scipy", scipy_recording)):
        csv = write_timeseries(work / f"{name}.csv", make())
        js, dt = identify(csv, work / f"{name}_model.json")
        results[name] = (csv, js)
        print(
            f"{name} recording ({DURATION:g} s at {RATE:g} Hz, c3 = {C3}): identify {dt:.1f} s, "
            f"fitted c3 = {js['fitted']['c3']:.5f} ± {js['std']['c3']:.1g}"
        )
        for c in js["r2_before"]:
            b, f = js["r2_before"][c], js["r2_after"][c]
            print(f"  {c:<8} R² {b:.5f} -> {f:.5f}   1 - R²: {1 - b:.3g} -> {1 - f:.3g} (x{(1 - f) / (1 - b):.3f})")
    figure(results, Path(a.figure))
    from drillgym.identification.synthetic import synthetic_measurement

    spec = "examples/effects/string_backlash.py:string_backlash"
    ts = synthetic_measurement(
        "torsional",
        duration=20.0,
        rate_hz=RATE,
        offset=0.5,
        seed=4,
        effects=[str(ROOT / spec)],
        effect_params={"gap": GAP},
    )
    js, dt = identify(write_timeseries(work / "backlash.csv", ts), work / "backlash_model.json", spec)
    print(
        f"backlash recording (drillgym, 20 s at {RATE:g} Hz, gap = {GAP} rad): identify {dt:.1f} s, "
        f"fitted gap = {js['fitted']['gap']:.5f} ± {js['std']['gap']:.1g} rad"
    )
    for c in js["r2_before"]:
        b, f = js["r2_before"][c], js["r2_after"][c]
        print(f"  {c:<8} R² {b:.5f} -> {f:.5f}   1 - R²: {1 - b:.3g} -> {1 - f:.3g}")
    print(f"figure: {a.figure}; recordings and models in {work}")


def figure(results: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from drillgym.diagnosis.compare import compare
    from drillgym.identification import prepare_experiment
    from drillgym.io import read_timeseries
    from drillgym.model import Model

    fig, axes = plt.subplots(2, 2, figsize=(12, 6), sharex=True, gridspec_kw={"height_ratios": [2, 1]})
    for j, (name, (csv, js)) in enumerate(results.items()):
        ex = prepare_experiment(read_timeseries(csv), compare_rate_hz=50.0)
        model = Model.load(csv.with_name(f"{name}_model.json"))
        before = compare(ex, RigParams(), segment_s=4.0)
        after = compare(ex, model.params, segment_s=4.0, effects=model.specs, effect_params=model.values)
        t = ex.t - ex.t[0]
        a = ex.channel("alpha")
        ax = axes[0, j]
        ax.plot(t, a, "k", lw=1.2, label="measured")
        ax.plot(t, before.predicted["alpha"], "C3--", lw=1, label=f"base model (R² {js['r2_before']['alpha']:.4f})")
        ax.plot(
            t,
            after.predicted["alpha"],
            "C0",
            lw=1,
            label=f"+ string_cubic, c3 = {js['fitted']['c3']:.4f} (R² {js['r2_after']['alpha']:.5f})",
        )
        ax.set(ylabel="twist α (rad)", title=f"{name} recording (c3 = {C3}), 4 s segments")
        ax.legend(loc="best", fontsize=8, framealpha=0.8)
        ax = axes[1, j]
        ax.plot(t, before.predicted["alpha"] - a, "C3", lw=0.8, label="base model")
        ax.plot(t, after.predicted["alpha"] - a, "C0", lw=0.8, label="+ string_cubic")
        ax.set(xlabel="t (s)", ylabel="α error (rad)")
        ax.legend(loc="lower left", fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)


if __name__ == "__main__":
    main()
