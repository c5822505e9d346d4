"""lqg-2enc built on identified models of coarse-encoder plants: told the model's encoders, or not.

    .venv/bin/python benchmarks/bench_identified_encoders.py [--counts 2048] [--noise 0]

Three plants (a lag and a delay, a lag and position friction, the nominal rig; base parameters a few percent
off), each read by ``--counts`` encoders with ``--noise`` rad of white noise after the count.  Each gets the
harness's excitation run and :func:`drillgym.identify` (``evaluate --identify``'s route), and ``lqg-2enc`` runs on
its identified model twice: as ``controllers.make(..., model=m)`` builds it (told ``m.encoders``, what the
recording showed) and with the model's encoders removed (the controller's own design, 4096 counts assumed).
Torsional, from rest, ``--duration`` s judged on the last ``--window`` s; prints each plant's SSI per target.
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
import warnings
from pathlib import Path

from controllers.evaluation import evaluate
from controllers.evaluation.identify import ExcitationOptions
from controllers.evaluation.plants_file import load_plants
from controllers.evaluation.population_jobs import identify_population

PLANTS = """plants:
  - name: lag-delay
    params: {{Ts: 0.29, km: 4.2}}
    effects:
      - {{spec: motor_lag, values: {{tau_m: 0.03}}}}
      - {{spec: input_delay, values: {{delay: 0.008}}}}
    encoder: {enc}
  - name: lag-friction
    params: {{Tc: 0.05, Ju: 0.49}}
    effects:
      - {{spec: motor_lag, values: {{tau_m: 0.015}}}}
      - {{spec: position_friction, values: {{pf_c1: 0.06, pf_s1: -0.03}}}}
    encoder: {enc}
  - name: nominal
    encoder: {enc}
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--counts", type=int, default=2048)
    ap.add_argument("--noise", type=float, default=0.0, help="white angle noise after the count (rad)")
    ap.add_argument("--targets", default="1,1.25,1.5,1.75,2,2.5,3")
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--window", type=float, default=20.0)
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args()
    warnings.simplefilter("ignore")  # the margin checks' words: the SSI is what is compared
    targets = [float(v) for v in a.targets.split(",")]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "plants.yaml"
        path.write_text(PLANTS.format(enc=f"{{counts_per_rev: {a.counts}, angle_noise: {a.noise!r}}}"))
        ps = load_plants(path)
        found = identify_population(
            ps.n, 0, None, None, ExcitationOptions(), "torsional", workers=a.workers, progress=False, plant_set=ps
        )
    print(f"{a.counts} counts, {a.noise:g} rad noise; SSI at {targets} rad/s")
    for k, f in found.items():
        print(f"plant {k} ({ps.plants[k].name}): identified {f.model.label}, encoders {f.model.encoders}")
    for told in (True, False):
        blind = {k: dataclasses.replace(f, model=f.model.replace(encoders=None)) for k, f in found.items()}
        ident = found if told else blind
        rows = evaluate(
            ["lqg-2enc"], ["torsional"], ["plants"], targets, duration=a.duration, window=a.window, plants_file=ps,
            identify=ident, workers=a.workers, progress=False,
        )  # fmt: skip
        for k in range(ps.n):
            ssi = " / ".join(f"{r['ssi']:.3f}" for r in rows if r["plant"] == k)
            print(f"{'told the encoders' if told else 'not told':<18} plant {k}: {ssi}")


if __name__ == "__main__":
    main()
