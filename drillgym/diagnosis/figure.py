"""The figure of what the final model leaves unexplained (``drillgym diagnose --plot``).

Three panels from :class:`.unexplained.Unexplained`:

1. each channel's residual RMS in noise units, against the verdict's thresholds (explained below
   :data:`.unexplained.EXPLAINED_RATIO`, not explained from :data:`.unexplained.UNEXPLAINED_RATIO`);
2. the phases of the run: each phase's share of the model's drift from the data beside its share of the time
   (a phase well above the diagonal is where the model fails);
3. the drift (noise units/s, the residual's rate within a multiple-shooting segment) binned against the
   quantity it depends on most, with the bin where it is largest marked, and the next two quantities beside it.

A model at the noise has no phases and no dependence: the figure then holds the first panel alone.
"""

from __future__ import annotations

from pathlib import Path

from .unexplained import EXPLAINED_RATIO, UNEXPLAINED_RATIO, Dependence, Unexplained

__all__ = ["plot_unexplained"]

#: quantities drawn beside the one the drift depends on most
OTHERS_DRAWN = 2


def plot_unexplained(un: Unexplained, path: str | Path, title: str = "") -> Path:
    """Draw the unexplained residual (module docstring) to a PNG file.

    Parameters
    ----------
    un : Unexplained
        The final model's residual against the noise (:attr:`.results.Diagnosis.unexplained`).
    path : str or path
        The figure file (its directory must exist).
    title : str, optional
        A title (the recording).

    Returns
    -------
    Path
        ``path``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    deps = [d for d in (un.depends_on, *un.others[:OTHERS_DRAWN]) if d is not None and d.bins]
    n = 1 + (1 if un.where or deps else 0) + len(deps)
    fig, axes = plt.subplots(1, n, figsize=(4.2 * n, 3.4), squeeze=False)
    axes = list(axes[0])
    _channels(axes.pop(0), un)
    if n > 1:
        _phases(axes.pop(0), un)
    for i, d in enumerate(deps):
        _dependence(axes[i], d, most=i == 0)
    head = f"{un.verdict.replace('_', ' ')}: residual {un.ratio_to_noise:.3g}× the noise"
    fig.suptitle(f"{title}: {head}" if title else head, fontsize=10)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def _channels(ax, un: Unexplained) -> None:
    names = list(un.channels)
    values = [un.channels[c] for c in names]
    colors = [
        "tab:green" if v < EXPLAINED_RATIO else "tab:orange" if v < UNEXPLAINED_RATIO else "tab:red" for v in values
    ]
    ax.bar(names, values, color=colors)
    ax.axhline(EXPLAINED_RATIO, color="tab:green", ls="--", lw=1, label=f"explained below {EXPLAINED_RATIO:g}")
    ax.axhline(UNEXPLAINED_RATIO, color="tab:red", ls="--", lw=1, label=f"not explained from {UNEXPLAINED_RATIO:g}")
    if max(values, default=1.0) > 100 * UNEXPLAINED_RATIO:
        ax.set_yscale("log")
    ax.set_ylabel("residual RMS (noise units)")
    ax.set_title("per channel", fontsize=9)
    ax.legend(fontsize=7, loc="best")


def _phases(ax, un: Unexplained) -> None:
    ax.plot([0, 1], [0, 1], color="gray", ls=":", lw=1)
    for p in un.where:
        ax.scatter(p.time_share, p.drift_share, color="tab:red")
        ax.annotate(p.name.replace("_", " "), (p.time_share, p.drift_share), fontsize=7, xytext=(3, 3),
                    textcoords="offset points")  # fmt: skip
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    ax.set_xlabel("share of the time")
    ax.set_ylabel("share of the drift")
    ax.set_title("where it concentrates" if un.where else "spread over the run (no phase stands out)", fontsize=9)


def _dependence(ax, d: Dependence, most: bool) -> None:
    edges = [b[0] for b in d.bins] + [d.bins[-1][1]]
    means = [b[2] for b in d.bins]
    ax.stairs(means, edges, color="tab:blue" if most else "gray", lw=1.5)
    ax.axvspan(d.worst_lo, d.worst_hi, color="tab:red", alpha=0.15, label="largest drift")
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_xlabel(f"{d.quantity} ({d.unit})")
    ax.set_ylabel("mean drift (noise units/s)")
    what = "depends most on" if most else "also tried:"
    ax.set_title(f"{what} {d.quantity} ({d.explained:.0%} of the drift's variance)", fontsize=9)
    if most:
        ax.legend(fontsize=7, loc="best")
