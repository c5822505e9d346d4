"""Draw the rig schematic of the README (docs/figures/rig.png): side view of the drill-string set-up."""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.patches import FancyArrowPatch, Rectangle


def main(path: str = "docs/figures/rig.png") -> None:
    fig, ax = plt.subplots(figsize=(6.2, 6.2))
    ax.set_xlim(-3.2, 4.6)
    ax.set_ylim(-0.6, 10.4)
    ax.axis("off")
    box = dict(ec="k", lw=1.2)
    ax.add_patch(Rectangle((-0.7, 9.0), 1.4, 1.0, fc="#9fb4c7", **box))
    ax.text(0, 9.5, "DC motor\nu (V)", ha="center", va="center", fontsize=9)
    ax.add_patch(Rectangle((-1.6, 8.3), 3.2, 0.35, fc="#d9d9d9", **box))
    ax.text(1.8, 8.47, r"upper disc $J_u$, encoder $\theta_u$", va="center", fontsize=8.5)
    ax.plot([0, 0], [8.3, 2.35], color="#555", lw=1.4)
    ax.text(
        0.15,
        5.4,
        "steel string, 2 mm x 1.47 m\n" + r"$k_\theta$ (torsion), $\alpha=\theta_l-\theta_u$",
        fontsize=8.5,
        va="center",
    )
    ax.add_patch(Rectangle((-1.6, 2.0), 3.2, 0.35, fc="#f4a460", **box))
    ax.plot([1.0], [2.17], "ko", ms=6)
    ax.text(1.8, 2.95, r"lower disc $J_l$, encoder $\theta_l$" + "\nmass unbalance e (whirl x, y)", fontsize=8.5)
    ax.add_patch(Rectangle((-0.35, 1.0), 0.7, 1.0, fc="#bbb", **box))
    ax.add_patch(Rectangle((-1.2, 1.25), 0.6, 0.5, fc="#7a7a7a", **box))
    ax.add_patch(Rectangle((0.6, 1.25), 0.6, 0.5, fc="#7a7a7a", **box))
    ax.text(0, 0.55, "oil brake (20 N normal force):\nStribeck friction, stick-slip", ha="center", fontsize=8.5)
    for x0 in (-2.6, 2.6):
        ax.add_patch(FancyArrowPatch((x0, 2.17), (x0 * 0.66, 2.17), arrowstyle="<->", mutation_scale=10))
    ax.text(-2.95, 1.7, "LVDT x", fontsize=8)
    ax.text(2.1, 1.7, "LVDT y", fontsize=8)
    ax.set_title("drillgym: the drill-string rig", fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
