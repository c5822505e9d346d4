"""Figures of a bifurcation diagram, laid out like the report's 4.4-4.6, 4.10-4.16 and 4.20."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ..io import create_directory  # noqa: E402
from .diagram import BifurcationDiagram  # noqa: E402
from .measured import REPORT_POINTS  # noqa: E402


def _segments(x: np.ndarray, y: np.ndarray, mask: np.ndarray):
    """Consecutive runs where mask is True, as (x, y) pieces."""
    idx = np.flatnonzero(mask)
    if idx.size == 0:
        return []
    cuts = np.flatnonzero(np.diff(idx) > 1) + 1
    return [(x[g], y[g]) for g in np.split(idx, cuts)]


def _equilibria(ax, d: BifurcationDiagram, quantity: str) -> None:
    e = d.equilibria
    y = e.omega if quantity == "omega_l" else e.r * 1e3
    for st, style in ((True, "-"), (False, "--")):
        for xs, ys in _segments(e.u, y, e.stable == st):
            ax.plot(
                xs,
                ys,
                "k" + style,
                lw=1.3,
                label=("stable equilibrium" if st else "unstable equilibrium")
                if not ax.get_legend_handles_labels()[1].count("stable equilibrium" if st else "unstable equilibrium")
                else None,
            )
    ax.plot([0, e.u_stick], [0, 0], "k-", lw=3, label="stick set")


def _cycles(ax, d: BifurcationDiagram, quantity: str) -> None:
    labels = set()
    for br in d.periodic:
        u = br.array("u")
        stable = np.array([s.stable for s in br.solutions])
        if quantity == "omega_l":
            ymax, ymin = br.array("omega_l_max"), br.array("omega_l_min")
        else:
            ymax, ymin = br.array("r_max") * 1e3, br.array("r_min") * 1e3
        for st, color in ((True, "tab:blue"), (False, "tab:red")):
            lab = "stable cycle (max/min)" if st else "unstable cycle (max/min)"
            for xs, ys in _segments(u, ymax, stable == st):
                ax.plot(xs, ys, "-" if st else "--", color=color, lw=1.2, label=None if lab in labels else lab)
                labels.add(lab)
            for xs, ys in _segments(u, ymin, stable == st):
                ax.plot(xs, ys, "-" if st else "--", color=color, lw=1.2)


def _points(ax, d: BifurcationDiagram, quantity: str) -> None:
    for h in d.hopf:
        ax.plot(h.u, h.omega if quantity == "omega_l" else 0, "o", mfc="none", color="tab:green", ms=7)
    for f in d.folds:
        ax.axvline(f.u, color="tab:purple", lw=0.7, ls=":")
    if d.hopf:
        ax.plot([], [], "o", mfc="none", color="tab:green", label="Hopf")
    if d.folds:
        ax.plot([], [], ":", color="tab:purple", label="fold")


def _sweeps(ax, d: BifurcationDiagram, quantity: str) -> None:
    marks = {
        "rest": ("x", "tab:gray", "sweep from rest"),
        "up": ("^", "tab:orange", "sweep up"),
        "down": ("v", "tab:cyan", "sweep down"),
        "equilibrium": ("s", "tab:olive", "from equilibrium"),
    }
    for s in d.sweeps:
        m, c, lab = marks.get(s.kind, ("x", "k", s.kind))
        hi = s.omega_l_max if quantity == "omega_l" else s.r_max * 1e3
        lo = s.omega_l_min if quantity == "omega_l" else s.r_min * 1e3
        ax.plot(s.u, hi, m, color=c, ms=3.5, label=lab, alpha=0.8)
        ax.plot(s.u, lo, m, color=c, ms=3.5, alpha=0.8)


def _measured(ax, d: BifurcationDiagram, quantity: str, report: bool) -> None:
    if d.measured:
        u = [m["u"] for m in d.measured]
        key = "omega_l" if quantity == "omega_l" else "r"
        sc = 1.0 if key == "omega_l" else 1e3
        ax.plot(u, [m[f"{key}_max"] * sc for m in d.measured], "D", mfc="none", color="k", ms=5, label="measured")
        ax.plot(u, [m[f"{key}_min"] * sc for m in d.measured], "D", mfc="none", color="k", ms=5)
    pts = REPORT_POINTS.get(d.config.label, {})
    if report and quantity == "omega_l" and pts:
        for u in pts["hopf"]:
            ax.axvline(u, color="tab:green", lw=0.8, ls="-.")
        for u in pts["fold"]:
            ax.axvline(u, color="tab:purple", lw=0.8, ls="-.")
        for c in pts["coexistence"]:
            if c["omega_eq"] is not None:
                ax.plot(c["u"], c["omega_eq"], "*", color="k", ms=9, label="report: measured equilibrium")
        if pts["hopf"] or pts["fold"]:
            ax.plot([], [], "-.", color="gray", label="report: measured Hopf/fold")


def plot_diagram(d: BifurcationDiagram, quantity: str = "omega_l", ax=None, xlim=None, ylim=None, report: bool = True):
    """omega_l (rad/s) or r (mm) versus u (V): equilibria, cycles, Hopf/fold points, sweeps, measurements."""
    if ax is None:
        _, ax = plt.subplots(figsize=(7, 4.5))
    _equilibria(ax, d, quantity)
    _cycles(ax, d, quantity)
    _sweeps(ax, d, quantity)
    _points(ax, d, quantity)
    _measured(ax, d, quantity, report)
    ax.set_xlabel("u (V)")
    ax.set_ylabel(r"$\omega_l$ (rad/s)" if quantity == "omega_l" else "r (mm)")
    if xlim:
        ax.set_xlim(*xlim)
    if ylim:
        ax.set_ylim(*ylim)
    ax.grid(alpha=0.3)
    h, lab = ax.get_legend_handles_labels()
    uniq = dict(zip(lab, h))
    ax.legend(uniq.values(), uniq.keys(), fontsize=7, loc="upper left")
    return ax


def plot_periods(d: BifurcationDiagram, ax=None):
    """Period (s) of the cycles versus u (report figure 4.10b)."""
    if ax is None:
        _, ax = plt.subplots(figsize=(7, 4))
    for br in d.periodic:
        u, T = br.array("u"), br.array("period")
        st = np.array([s.stable for s in br.solutions])
        for xs, ys in _segments(u, T, st):
            ax.plot(xs, ys, "-", color="tab:blue", label="stable cycle")
        for xs, ys in _segments(u, T, ~st):
            ax.plot(xs, ys, "--", color="tab:red", label="unstable cycle")
    for s in d.sweeps:
        if s.kind == "rest":
            ax.plot(s.u, s.period, "x", color="tab:gray", ms=4, label="sweep from rest")
    if d.measured:
        ax.plot(
            [m["u"] for m in d.measured],
            [m["period"] for m in d.measured],
            "D",
            mfc="none",
            color="k",
            label="measured",
        )
    ax.set_xlabel("u (V)")
    ax.set_ylabel("period (s)")
    ax.grid(alpha=0.3)
    h, lab = ax.get_legend_handles_labels()
    uniq = dict(zip(lab, h))
    ax.legend(uniq.values(), uniq.keys(), fontsize=7)
    return ax


def save_figures(
    d: BifurcationDiagram, out_dir: str | Path, prefix: str = "bifurcation", report: bool = True
) -> list[Path]:
    """Write the configuration's figures as PNG into out_dir; returns the paths."""
    out = create_directory(out_dir)
    name = d.config.label
    paths = []

    def save(fig, tag):
        p = out / f"{prefix}_{name}_{tag}.png"
        fig.tight_layout()
        fig.savefig(p, dpi=110)
        plt.close(fig)
        paths.append(p)

    if name == "lateral":
        fig, axs = plt.subplots(1, 2, figsize=(12, 4.5))
        plot_diagram(d, "r", ax=axs[0], report=report)
        axs[0].set_title("lateral r_eq (report fig. 4.11)")
        plot_diagram(d, "r", ax=axs[1], xlim=(0, 5), ylim=(0, None), report=report)
        axs[1].set_title("0-5 V with sweeps / measurements (report fig. 4.12)")
        save(fig, "r")
        fig, ax = plt.subplots(figsize=(7, 4.5))
        plot_diagram(d, "omega_l", ax=ax, report=report)
        save(fig, "omega_l")
        return paths
    fig, axs = plt.subplots(1, 2, figsize=(12, 4.5))
    plot_diagram(d, "omega_l", ax=axs[0], report=report)
    axs[0].set_title(f"{name}: bifurcation diagram (report fig. {'4.5' if name == 'torsional' else '4.14'})")
    plot_diagram(d, "omega_l", ax=axs[1], xlim=(0.1, 0.35), ylim=(-0.02, 0.5), report=report)
    axs[1].set_title(f"zoom near the first Hopf/fold (fig. {'4.6' if name == 'torsional' else '4.15-4.16'})")
    save(fig, "omega_l")
    fig, ax = plt.subplots(figsize=(7, 4))
    plot_periods(d, ax)
    ax.set_title(f"{name}: period times (report fig. {'4.10b' if name == 'torsional' else '4.20b'})")
    save(fig, "period")
    if d.config.lateral_free:
        fig, ax = plt.subplots(figsize=(7, 4.5))
        plot_diagram(d, "r", ax=ax, report=report)
        ax.set_title(f"{name}: lateral amplitude r (report fig. 4.13, 4.20)")
        save(fig, "r")
    return paths
