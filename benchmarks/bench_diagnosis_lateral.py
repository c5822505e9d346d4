"""Discovery on the lateral side: a lateral force outside the library, on recordings of a simulator other than
drillgym's.

The rig is the independent scipy rig of ``bench_diagnosis_rig.py`` (coupled: the four Lagrange equations,
smoothed friction, LSODA, its own measurement chain with the LVDTs' 5 Hz zero-phase low-pass), with a lateral
force outside drillgym's library (:data:`bench_diagnosis_rig.OUTSIDE_LATERAL`):

* ``lateral_cubic``: a spring that stiffens with the radius, −k3 r² (X, Y) (k3 = 3-9·10⁷ N/m³: at r = 3 mm
  10-30 % of the linear spring's k r);
* ``lateral_quadratic_damping``: a drag −c2 |V| V (c2 = 500-1200 N s²/m²: at 4 cm/s 0.8-1.9 N, the viscous b V is 1 N);

each alone and with a library effect beside it (``lateral_anisotropy``: dk = 150-300 N/m, db = 2-4 N s/m;
``position_friction``: pf_c1, pf_s1 = ±0.06-0.12), on ramps about 2.6 V (the whirl through its resonance),
12 s at 200 Hz.  Each recording is diagnosed as a user would (``diagnose(..., discover=True)``: the library's
selection, discovery, the candidate's own fit, the selection again with a kept candidate).  Reported per row
and in total:

* ``lateral``: the candidate is the lateral group (``lateral_force``) with the hidden force's shape as its first
  term (r²·(X, Y) for the cubic spring, |V|·(VX, VY) for the drag);
* ``halved``: the candidate's own fit at least halves the LVDTs' misfit (the RMS of x and y in noise units);
  ``halved_again``: the model selected again with the candidate in it (its library effects and the candidate
  refitted with the base) does;
* ``wrong_library``: a library lateral effect that is not in the recording (``lateral_coulomb``, or
  ``lateral_anisotropy`` where it is not beside) is in the final model (the selection again's when it ran);
* ``beside_found``: the library effect beside, when there is one, is in the final model;
* ``residual``: the diagnosed model's worst channel (noise units) before discovery: below
  :data:`drillgym.diagnosis.discovery.MIN_RESIDUAL_UNITS` nothing is left to discover (k and b took the force).

    python benchmarks/bench_diagnosis_lateral.py [--draws 1] [--first-seed 0] [--only KIND] [--out results.json]

One recording at a time (one core); each takes 3-6 minutes.
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

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_diagnosis_rig import rig_recording  # noqa: E402

from drillgym.diagnosis import diagnose  # noqa: E402

#: the hidden force, its size drawn in a range, and the term that has its shape
KINDS = {
    "lateral_cubic": (lambda r: {"k3": round(r.uniform(3e7, 9e7), -5)}, "r²·(X, Y)"),
    "lateral_quadratic_damping": (lambda r: {"c2": round(r.uniform(500.0, 1200.0), 1)}, "|V|·(VX, VY)"),
}
#: the library effect beside it (None: alone)
BESIDE = {
    None: lambda r: {},
    "lateral_anisotropy": lambda r: {"dk": round(r.uniform(150.0, 300.0), 1), "db": round(r.uniform(2.0, 4.0), 2)},
    "position_friction": lambda r: {
        "pf_c1": round(r.choice([-1, 1]) * r.uniform(0.06, 0.12), 3),
        "pf_s1": round(r.choice([-1, 1]) * r.uniform(0.06, 0.12), 3),
    },
}
LATERAL_LIBRARY = ("lateral_coulomb", "lateral_anisotropy")


def _lvdt_rms(unexplained) -> float:
    """The LVDTs' misfit: the RMS of the x and y channels (noise units)."""
    vals = [unexplained.channels[c] for c in ("x", "y") if c in unexplained.channels]
    return math.sqrt(sum(v * v for v in vals) / len(vals)) if vals else math.nan


def run_one(kind: str, beside: str | None, seed: int, tmp: Path) -> dict:
    """One recording diagnosed: what was hidden, what was found, the candidate's fit on the LVDTs."""
    rng = np.random.default_rng(1000 + seed)
    draw, shape = KINDS[kind]
    effects = {kind: draw(rng)}
    if beside is not None:
        effects[beside] = BESIDE[beside](rng)
    ts = rig_recording("coupled", "ramps", 12.0, 200.0, seed, effects, {}, 2.6, 1.5)
    t0 = time.perf_counter()
    d = diagnose(ts, discover=True, candidate_out=tmp / f"cand_{kind}_{beside}_{seed}.py")
    final = d.final()  # the model with every kept candidate
    c = d.candidate
    fit = c.fit if c is not None else None
    before = _lvdt_rms(fit.before) if fit is not None else math.nan
    after = _lvdt_rms(fit.after) if fit is not None else math.nan
    wrong = [e for e in final.selected if e in LATERAL_LIBRARY and e != beside]
    again = _lvdt_rms(final.unexplained) if final is not d and final.unexplained else None
    return {
        "kind": kind,
        "beside": beside,
        "seed": seed,
        "effects": effects,
        "candidate": None if c is None else c.expression(),
        "group": None if c is None else c.group,
        "explained": None if c is None else round(c.explained, 3),
        "lateral": c is not None and c.group == "lateral_force" and next(iter(c.terms), None) == shape,
        "lvdt_before": before,
        "lvdt_after": after,
        "halved": bool(after <= 0.5 * before),
        "lvdt_again": again,
        "halved_again": again is not None and bool(again <= 0.5 * before),
        "residual": round(d.unexplained.worst, 2) if d.unexplained is not None else None,
        "selected": list(d.selected),
        "selected_again": None if d.reselection is None else list(d.reselection.selected),
        "wrong_library": wrong,
        "beside_found": None if beside is None else beside in final.selected,
        "seconds": round(time.perf_counter() - t0, 1),
    }


def main(argv: list[str] | None = None) -> list[dict]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=1, help="draws of the sizes per row")
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--only", choices=sorted(KINDS), help="one hidden force only")
    ap.add_argument("--out", type=Path, help="write the rows as JSON")
    args = ap.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for kind in [args.only] if args.only else list(KINDS):
            for beside in BESIDE:
                for k in range(args.draws):
                    seed = args.first_seed + k
                    row = run_one(kind, beside, seed, Path(tmp))
                    rows.append(row)
                    print(
                        f"{kind:<26}{beside or '-':<20}seed {seed:<3} worst channel {row['residual']:<6} "
                        f"{row['group'] or '-':<15} "
                        f"lateral {row['lateral']!s:<6} LVDTs {row['lvdt_before']:.3g} -> {row['lvdt_after']:.3g} "
                        f"halved {row['halved']!s:<6} selected again {row['lvdt_again'] or math.nan:.3g} "
                        f"wrong library {','.join(row['wrong_library']) or '-':<20}"
                        f"beside found {row['beside_found']!s:<6} {row['seconds']:.0f} s",
                        flush=True,
                    )
    n = len(rows)
    with_beside = [r for r in rows if r["beside"] is not None]
    print(
        f"total {n}: lateral candidate with the right shape {sum(r['lateral'] for r in rows)}/{n}, "
        f"LVDT misfit halved by the candidate's fit {sum(r['halved'] for r in rows)}/{n}, "
        f"by the model selected again with it {sum(r['halved_again'] for r in rows)}/{n}, "
        f"wrong library effect named {sum(bool(r['wrong_library']) for r in rows)}/{n}, "
        f"library effect beside found {sum(bool(r['beside_found']) for r in with_beside)}/{len(with_beside)}"
    )
    if args.out:
        args.out.write_text(json.dumps(rows, indent=1, default=str))
    return rows


if __name__ == "__main__":
    main()
