"""Discovery on the lateral side: a lateral force outside the library, on recordings of a simulator other than
drillgym's.

The rig is the independent scipy rig of ``bench_diagnosis_rig.py`` (coupled: the four Lagrange equations,
smoothed friction, LSODA, its own measurement chain with the LVDTs' 5 Hz zero-phase low-pass), with a lateral
force outside drillgym's library (:data:`bench_diagnosis_rig.OUTSIDE_LATERAL`):

* ``lateral_cubic``: a spring that stiffens with the radius, −k3 r² (X, Y) (k3 = 3-9·10⁷ N/m³: at r = 3 mm
  10-30 % of the linear spring's k r);
* ``lateral_quadratic_damping``: a drag −c2 |V| V (c2 = 500-1200 N s²/m²: at 4 cm/s 0.8-1.9 N, the viscous b V is 1 N);
* ``brake_contact``: a brake pad on the lower disc's rim at a fixed angle φ of the LVDTs' frame (drawn): its normal
  force N = 1-2.5 N pushes the centre away from the pad (N / k = 0.34-0.84 mm) and its friction, the lower disc's
  friction torque over the pad's radius R_pad = 6-10 cm (1-3 N, following the brake's torque), along the tangent;
* ``lvdt_scale``: an LVDT whose gain is off by ±2-8 % (the x LVDT on even seeds, the y LVDT on odd ones), a
  reading outside the library (:data:`bench_diagnosis_rig.OUTSIDE_READING`);

each alone and with a library effect beside it (``lateral_anisotropy``: dk = 150-300 N/m, db = 2-4 N s/m;
``position_friction``: pf_c1, pf_s1 = ±0.06-0.12), on ramps about 2.6 V (the whirl through its resonance),
12 s at 200 Hz; and two outside effects at once, alone (:data:`PAIRS`, diagnosed with ``max_candidates=2``):
``cubic+drag`` (the two lateral forces above) and ``string_cubic+lateral_cubic`` (a stiffening string,
c3 = 0.008-0.02 rad⁻², beside the stiffening lateral spring).  Each recording is diagnosed as a user would
(``diagnose(..., discover=True)``: the library's selection, discovery, the candidate's own fit, the selection again
with a kept candidate).  Reported per row and in total:

* ``lateral``: the candidate is the lateral group (``lateral_force``) with the hidden force's shape as its first
  term (r²·(X, Y) for the cubic spring, |V|·(VX, VY) for the drag); for ``brake_contact`` a lateral candidate with
  a constant force (1, 0) or (0, 1) or the pad's friction T_fl·(1, 0), T_fl·(0, 1) among its
  terms; for ``lvdt_scale`` that LVDT's reading (``lvdt_x`` /
  ``lvdt_y``) with its gain error k within 30 %; for a pair, the first candidate holds one of the two;
* ``two_found`` (pairs): both hidden effects are among the candidates kept (one lateral group may hold both
  lateral forces); ``spurious_second``: a second candidate kept that is neither; ``final_halved``: the model with
  every kept candidate halves the LVDTs' misfit;
* ``halved``: the candidate's own fit at least halves the LVDTs' misfit (the RMS of x and y in noise units) it was
  found on (the first candidate in turn: where discovery named a library effect first, the one found beside it);
  ``halved_again``: the model selected again with the candidate in it (its library effects and the candidate
  refitted with the base) does;
* ``wrong_library``: a library lateral or LVDT effect that is not in the recording (``lateral_coulomb``,
  ``lvdt_offset``, ``lvdt_skew``, or ``lateral_anisotropy`` where it is not beside) is in the final model (the
  selection again's when it ran), except ``tied_library``: one the diagnosis states it cannot tell from a part of
  the hidden effect (:data:`TIED`); ``other_library``: any other library effect there that is not hidden;
* ``silent``: a diagnosis in turn whose residual is ≥ 10× the noise on a channel and that is reported as explained
  or as "the base model stands" (must be 0);
* ``beside_found``: the library effect beside, when there is one, is in the final model;
* ``residual``: the diagnosed model's worst channel (noise units) before discovery: below
  :data:`drillgym.diagnosis.discovery.MIN_RESIDUAL_UNITS` nothing is left to discover (k and b took the force).

    python benchmarks/bench_diagnosis_lateral.py [--draws 1] [--first-seed 0] [--only KIND ...]
        [--beside none|lateral_anisotropy|position_friction ...] [--out results.json]

One recording at a time (one core); each takes 5 s to 2 minutes of diagnosis (3-6 minutes on a busy machine).
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
from drillgym.diagnosis.effects import EFFECTS, label_effects  # noqa: E402

#: the hidden force, its size drawn in a range, and the term that has its shape (a kind whose draw returns
#: {effect: params} of several effects hides them all: see :data:`PAIRS`)
KINDS = {
    "lateral_cubic": (lambda r: {"k3": round(r.uniform(3e7, 9e7), -5)}, "r²·(X, Y)"),
    "lateral_quadratic_damping": (lambda r: {"c2": round(r.uniform(500.0, 1200.0), 1)}, "|V|·(VX, VY)"),
    # a brake pad on the rim at a fixed angle: N / k = 0.34-0.84 mm, its friction T_fl / R_pad 1-3 N turning
    "brake_contact": (
        lambda r: {
            "N": round(r.uniform(1.0, 2.5), 2),
            "phi": round(r.uniform(0.0, 2 * math.pi), 3),
            "R_pad": round(r.uniform(0.06, 0.10), 3),
        },
        ("(1, 0)", "(0, 1)", "T_fl·(1, 0)", "T_fl·(0, 1)"),
    ),
    # one LVDT's gain off by 2-8 % either way: the x LVDT's on even seeds, the y LVDT's on odd ones
    "lvdt_scale": (lambda r, seed=0: _lvdt_scale(r, seed), "reading"),
    # two outside effects at once, found in turn (max_candidates=2), alone only
    "cubic+drag": (
        lambda r: {
            "lateral_cubic": {"k3": round(r.uniform(3e7, 9e7), -5)},
            "lateral_quadratic_damping": {"c2": round(r.uniform(500.0, 1200.0), 1)},
        },
        ("r²·(X, Y)", "|V|·(VX, VY)"),
    ),
    "string_cubic+lateral_cubic": (
        lambda r: {
            "string_cubic": {"c3": round(r.uniform(0.008, 0.02), 4)},
            "lateral_cubic": {"k3": round(r.uniform(3e7, 9e7), -5)},
        },
        ("string", "r²·(X, Y)"),
    ),
}
#: the kinds that hide two outside effects (diagnosed with max_candidates=2, alone only)
PAIRS = ("cubic+drag", "string_cubic+lateral_cubic")
#: the library effect beside it (None: alone)
BESIDE = {
    None: lambda r: {},
    "lateral_anisotropy": lambda r: {"dk": round(r.uniform(150.0, 300.0), 1), "db": round(r.uniform(2.0, 4.0), 2)},
    "position_friction": lambda r: {
        "pf_c1": round(r.choice([-1, 1]) * r.uniform(0.06, 0.12), 3),
        "pf_s1": round(r.choice([-1, 1]) * r.uniform(0.06, 0.12), 3),
    },
}
LATERAL_LIBRARY = ("lateral_coulomb", "lateral_anisotropy", "lvdt_offset", "lvdt_skew")
#: a library effect a hidden effect holds a part of that no recording of these inputs tells from it, with the
#: diagnosis' statement of the tie: a brake pad's normal force is a constant force on the centre, which shifts the
#: disc by F / k as an LVDT offset reads (the diagnosis states every selected offset as that force, and the
#: experiment that tells them apart)
TIED = {"lvdt_offset": ("brake_contact", "reads as a constant lateral force")}


def _lvdt_scale(r: np.random.Generator, seed: int) -> dict[str, float]:
    """One LVDT whose gain is off by ±2-8 %: the x LVDT on even seeds, the y LVDT on odd ones."""
    axis = "lvdt_kx" if seed % 2 == 0 else "lvdt_ky"
    return {axis: round(float(r.choice([-1, 1]) * r.uniform(0.02, 0.08)), 4)}


def _final_values(final) -> dict[str, float]:
    """The final model's parameters outside the base (its library effects', a kept candidate's, as refitted)."""
    if final.composition is None or final.vector is None:
        return {}
    from drillgym.params import N_PARAMS

    names = final.composition.param_names[N_PARAMS:]
    vals = final.composition.named(final.vector)
    return {n: vals[n] for n in names if vals[n] != 0.0}


def _silent(d) -> bool:
    """A residual ≥ 10× the noise on a channel reported as explained or as "the base model stands", in any
    diagnosis in turn."""
    for step in d.in_turn():
        un = step.unexplained
        if un is None or un.worst < 10.0:
            continue
        text = step.text()
        if un.explained or "stands" in text or text.startswith("explained"):
            return True
    return False


def _hidden(kind: str, rng: np.random.Generator, seed: int) -> dict[str, dict[str, float]]:
    draw = KINDS[kind][0]
    if kind == "lvdt_scale":
        return {kind: draw(rng, seed)}
    return draw(rng) if kind in PAIRS else {kind: draw(rng)}


def _shape_ok(kind: str, effects: dict, c) -> bool:
    """Whether the (first) candidate is the hidden effect's: its group, and its first term the hidden force's shape
    (brake_contact: a constant force or the brake torque's term among its terms; lvdt_scale: that LVDT's reading,
    k within 30 %)."""
    if c is None:
        return False
    shape = KINDS[kind][1]
    if kind == "lvdt_scale":
        f = effects["lvdt_scale"]
        axis, k = ("x", f["lvdt_kx"]) if "lvdt_kx" in f else ("y", f["lvdt_ky"])
        return c.group == f"lvdt_{axis}" and abs(c.terms.get(axis, 0.0) - k) <= 0.3 * abs(k)
    if kind == "brake_contact":
        return c.group == "lateral_force" and any(t in c.terms for t in shape)
    if kind in PAIRS:
        return bool(_pair_parts(c) & set(shape))
    return c.group == "lateral_force" and next(iter(c.terms), None) == shape


def _pair_parts(c) -> set[str]:
    """Which hidden effects of a pair a candidate holds: its lateral terms (one lateral group may carry both
    lateral forces), or its group ('string' for the string group)."""
    if c is None:
        return set()
    return set(c.terms) if c.group == "lateral_force" else {c.group}


def _in_model(final) -> list[str]:
    """The library effects the final model holds: those selected, and those held beside a kept candidate (where the
    selection run again ended worse than the candidate's own fit, the effects the candidate's fit held)."""
    held = [n for n in label_effects(final.model) if n in EFFECTS]
    return list(dict.fromkeys([*final.selected, *held]))


def _lvdt_rms(unexplained) -> float:
    """The LVDTs' misfit: the RMS of the x and y channels (noise units)."""
    vals = [unexplained.channels[c] for c in ("x", "y") if c in unexplained.channels]
    return math.sqrt(sum(v * v for v in vals) / len(vals)) if vals else math.nan


def run_one(kind: str, beside: str | None, seed: int, tmp: Path) -> dict:
    """One recording diagnosed: what was hidden, what was found, the candidate's fit on the LVDTs."""
    rng = np.random.default_rng(1000 + seed)
    effects = _hidden(kind, rng, seed)
    if beside is not None:
        effects[beside] = BESIDE[beside](rng)
    ts = rig_recording("coupled", "ramps", 12.0, 200.0, seed, effects, {}, 2.6, 1.5)
    t0 = time.perf_counter()
    more = {"max_candidates": 2} if kind in PAIRS else {}
    d = diagnose(ts, discover=True, candidate_out=tmp / f"cand_{kind}_{beside}_{seed}.py", **more)
    seconds = round(time.perf_counter() - t0, 1)
    final = d.final()  # the model with every kept candidate
    # the first outside candidate in turn (a library effect discovery named in its place takes no candidate's turn)
    c = d.candidate if kind in PAIRS else next((st.candidate for st in d.in_turn() if st.candidate), None)
    fit = c.fit if c is not None else None
    before = _lvdt_rms(fit.before) if fit is not None else _lvdt_rms(d.unexplained) if d.unexplained else math.nan
    after = _lvdt_rms(fit.after) if fit is not None else math.nan
    named = _in_model(final)
    tied = [e for e in named if e in TIED and TIED[e][0] in effects and any(TIED[e][1] in w for w in final.warnings)]
    wrong = [e for e in named if e in LATERAL_LIBRARY and e not in effects and e not in tied]
    other = [e for e in named if e not in effects and e not in LATERAL_LIBRARY and "candidate" not in e]
    again = _lvdt_rms(final.unexplained) if final is not d and final.unexplained else None
    c2 = d.reselection.candidate if d.reselection is not None else None
    kept_2 = d.reselection is not None and d.reselection.reselection is not None  # the second candidate entered
    row = {
        "kind": kind,
        "beside": beside,
        "seed": seed,
        "effects": effects,
        "candidate": None if c is None else c.expression(),
        "group": None if c is None else c.group,
        "first_term": None if c is None else next(iter(c.terms), None),
        "terms": None if c is None else dict(c.terms),
        "explained": None if c is None else round(c.explained, 3),
        "lateral": _shape_ok(kind, effects, c),
        "lvdt_before": before,
        "lvdt_after": after,
        "cut": None if fit is None else round(fit.variance_cut, 3),
        "worst_after": None if fit is None else round(fit.after.worst, 2),
        "halved": bool(after <= 0.5 * before),
        "lvdt_again": again,
        "halved_again": again is not None and bool(again <= 0.5 * before),
        "residual": round(d.unexplained.worst, 2) if d.unexplained is not None else None,
        "channels_before": None
        if d.unexplained is None
        else {k: round(v, 2) for k, v in d.unexplained.channels.items()},
        "channels_final": None
        if final.unexplained is None
        else {k: round(v, 2) for k, v in final.unexplained.channels.items()},
        "selected": list(d.selected),
        "selected_again": None if d.reselection is None else list(d.reselection.selected),
        "wrong_library": wrong,
        "tied_library": tied,
        "other_library": other,
        "beside_found": None if beside is None else beside in named,
        "silent": _silent(d),
        "worst_in_turn": [None if st.unexplained is None else round(st.unexplained.worst, 2) for st in d.in_turn()],
        "rest": None if c is None else {k: round(v, 3) for k, v in c.rest.items()},
        "alternative": None
        if c is None or c.alternative is None
        else {
            "expression": c.alternative.expression(),
            "cut": None if c.alternative.fit is None else round(c.alternative.fit.variance_cut, 3),
        },
        "final_values": _final_values(final),
        "text": "\n".join([d.text(), *d.candidate_lines()]),
        "warnings": list(d.warnings),
        "advice": list(d.advice),
        "seconds": seconds,
    }
    if kind in PAIRS:
        shape = set(KINDS[kind][1])
        row.update(
            {
                "candidate_2": None if c2 is None else c2.expression(),
                "group_2": None if c2 is None else c2.group,
                "cut_2": None if c2 is None or c2.fit is None else round(c2.fit.variance_cut, 3),
                # both hidden effects among the candidates kept (in one lateral group or in two candidates)
                "two_found": shape <= (_pair_parts(c) | (_pair_parts(c2) if kept_2 else set())),
                # a second candidate kept that is neither hidden effect
                "spurious_second": bool(kept_2 and not (_pair_parts(c2) & shape)),
                "n_kept": len(d.in_turn()) - 1,
                "selected_in_turn": [list(s.selected) for s in d.in_turn()],
                "worst_final": None if final.unexplained is None else round(final.unexplained.worst, 2),
                "final_halved": again is not None and bool(again <= 0.5 * before),
            }
        )
    return row


def _sizes(effects: dict) -> str:
    return "; ".join(f"{e} " + ",".join(f"{k}={v:g}" for k, v in p.items()) for e, p in effects.items())


def main(argv: list[str] | None = None) -> list[dict]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=1, help="draws of the sizes per row")
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--only", choices=sorted(KINDS), action="append", help="this hidden force only (repeatable)")
    ap.add_argument("--beside", choices=["none", *[b for b in BESIDE if b]], action="append", help="this row only")
    ap.add_argument("--out", type=Path, help="write the rows as JSON")
    args = ap.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for kind in args.only or list(KINDS):
            for beside in [None] if kind in PAIRS else BESIDE:
                if args.beside and (beside or "none") not in args.beside:
                    continue
                for k in range(args.draws):
                    seed = args.first_seed + k
                    row = run_one(kind, beside, seed, Path(tmp))
                    rows.append(row)
                    print(
                        f"{kind:<26}{beside or '-':<20}seed {seed:<3} {_sizes(row['effects'])} "
                        f"worst channel {row['residual']} "
                        f"{row['group'] or '-'} {row['first_term'] or '-'} "
                        f"shape {row['lateral']!s} LVDTs {row['lvdt_before']:.3g} -> {row['lvdt_after']:.3g} "
                        f"halved {row['halved']!s} selected again {row['lvdt_again'] or math.nan:.3g} "
                        f"wrong library {','.join(row['wrong_library']) or '-'} "
                        f"tied {','.join(row['tied_library']) or '-'} "
                        f"(other {','.join(row['other_library']) or '-'}) "
                        f"beside found {row['beside_found']!s} silent {row['silent']!s} {row['seconds']:.0f} s"
                        + (
                            f" | second {row['group_2'] or '-'} ({row['candidate_2'] or '-'}) two found "
                            f"{row['two_found']!s} spurious second {row['spurious_second']!s} final worst "
                            f"{row['worst_final']} final LVDTs halved {row['final_halved']!s}"
                            if kind in PAIRS
                            else ""
                        ),
                        flush=True,
                    )
                    if args.out:  # after every recording: a long run leaves what it measured
                        args.out.write_text(json.dumps(rows, indent=1, default=str))
    for kind in dict.fromkeys(r["kind"] for r in rows):
        rs = [r for r in rows if r["kind"] == kind]
        print(
            f"{kind}: shape {sum(r['lateral'] for r in rs)}/{len(rs)}, halved by the candidate's fit "
            f"{sum(r['halved'] for r in rs)}/{len(rs)}, by the model selected again "
            f"{sum(r['halved_again'] for r in rs)}/{len(rs)}, wrong library {sum(bool(r['wrong_library']) for r in rs)}"
            f"/{len(rs)} (tie stated {sum(bool(r['tied_library']) for r in rs)}/{len(rs)}; "
            f"other library effects {sum(bool(r['other_library']) for r in rs)}/{len(rs)}), silent "
            f"{sum(r['silent'] for r in rs)}/{len(rs)}"
            + (f", two found {sum(r['two_found'] for r in rs)}/{len(rs)}" if kind in PAIRS else "")
        )
    n = len(rows)
    with_beside = [r for r in rows if r["beside"] is not None]
    print(
        f"total {n}: lateral candidate with the right shape {sum(r['lateral'] for r in rows)}/{n}, "
        f"LVDT misfit halved by the candidate's fit {sum(r['halved'] for r in rows)}/{n}, "
        f"by the model selected again with it {sum(r['halved_again'] for r in rows)}/{n}, "
        f"wrong library effect named {sum(bool(r['wrong_library']) for r in rows)}/{n} "
        f"(a tie stated {sum(bool(r['tied_library']) for r in rows)}/{n}), "
        f"library effect beside found {sum(bool(r['beside_found']) for r in with_beside)}/{len(with_beside)}"
    )
    if args.out:
        args.out.write_text(json.dumps(rows, indent=1, default=str))
    return rows


if __name__ == "__main__":
    main()
