"""How robust can a controller that sees only the motor angle be?  The bound of controllers.limits.

For each target speed: the brake's slope, the right-half-plane poles and zeros of the motor-angle
loop theta_u/u, and the lower bound on ||S||_inf and ||T||_inf of EVERY stabilising linear
controller (Skogestad-Postlethwaite theorem 5.3), with the relative input error (km, a lag's phase
at the crossover) it tolerates (1/bound).  Then the same bound over the plants of the default
uncertainty set (their base parameters): median and 90th percentile.

    .venv/bin/python benchmarks/bench_motor_angle_limit.py [--plants 20 --seed 0]
"""

from __future__ import annotations

import argparse

import numpy as np

from controllers.evaluation.population import sample_plants
from controllers.limits import motor_angle_limit
from drillgym import RigParams

TARGETS = (0.5, 1.0, 1.5, 2.0, 2.5, 2.75, 3.0, 3.5)


def _fmt(zs) -> str:
    """The first two of ``zs`` as complex numbers to 3 decimals, or ``-`` when there are none."""
    return ", ".join(f"{z.real:.3f}{z.imag:+.3f}j" if abs(z.imag) > 1e-9 else f"{z.real:.3f}" for z in zs[:2]) or "-"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--plants", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    p = RigParams()
    print("nominal rig (docs/model.md)")
    print(
        f"{'omega (rad/s)':>13} {'slope (N m s)':>14} {'RHP poles (1/s)':>22} {'RHP zeros (1/s)':>22} "
        f"{'bound ||T||':>12} {'tolerated':>10}"
    )
    for w in TARGETS:
        lim = motor_angle_limit(p, w)
        print(
            f"{w:13.2f} {lim.slope:14.4f} {_fmt(lim.rhp_poles):>22} {_fmt(lim.rhp_zeros):>22} {lim.bound:12.1f} "
            f"{100 * lim.tolerated:9.2f}%"
        )
    pop = sample_plants(a.plants, a.seed)
    nb = len(p.to_vector())
    print(f"\n{a.plants} plants of the default uncertainty set (seed {a.seed}), their base parameters")
    print(
        f"{'omega (rad/s)':>13} {'median bound':>13} {'p90 bound':>10} {'max bound':>10} "
        f"{'plants with bound <= 20':>24}"
    )
    for w in TARGETS:
        b = np.array([motor_angle_limit(RigParams.from_vector(pop.matrix[k, :nb]), w).bound for k in range(pop.n)])
        print(
            f"{w:13.2f} {np.median(b):13.1f} {np.quantile(b, 0.9, method='higher'):10.1f} {b.max():10.1f} "
            f"{int(np.sum(b <= 20)):>17d} of {pop.n}"
        )
    print(
        "\nbound <= 20 is what km +-5 % alone needs (a 5 % input gain error destabilises a loop with ||T|| >= 20);"
        "\nlags of 1-50 ms and delays of 0-20 ms add several % more at the lower disc's 1-5 rad/s."
    )


if __name__ == "__main__":
    main()
