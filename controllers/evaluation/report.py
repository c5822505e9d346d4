"""Outputs of an evaluation: CSV of every run, markdown summary table, SSI-versus-target figure (and,
for a plant population, :mod:`.population_report`'s table and figure)."""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from drillgym.io import create_directory

from .metrics import SSI_THRESHOLD, lowest_free_speed

__all__ = ["write_csv", "summary", "markdown_table", "plot_ssi", "write_report"]


def write_csv(rows: Sequence[dict], path: str | Path) -> Path:
    """All rows (one per controller, configuration, scenario, [plant,] target) as CSV; the columns are
    the union of the rows' keys in first-seen order (a population's rows add one column per parameter)."""
    path = Path(path)
    if not rows:
        raise ValueError("no evaluation rows to write")
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(dict.fromkeys(k for r in rows for k in r)))
        w.writeheader()
        w.writerows(rows)
    return path


def _select(rows, controller, config, scenario):
    sel = sorted(
        (r for r in rows if r["controller"] == controller and r["config"] == config and r["scenario"] == scenario),
        key=lambda r: r["omega_ref"],
    )
    return (
        np.array([r["omega_ref"] for r in sel]),
        np.array([r["ssi"] for r in sel]),
        np.array([r.get("offset", 0.0) for r in sel]),
    )


def summary(rows: Sequence[dict], scenario: str = "rest", speeds: Sequence[float] = (2.0, 4.0)) -> list[dict]:
    """Per controller and configuration: lowest stick-slip-free target and SSI at ``speeds`` (rad/s)."""
    out = []
    for c in dict.fromkeys(r["controller"] for r in rows):
        entry = {"controller": c}
        periods = {r["control_dt"] for r in rows if r["controller"] == c and "control_dt" in r}
        if periods:
            entry["control_dt"] = min(periods)
        for cfg in dict.fromkeys(r["config"] for r in rows):
            t, s, off = _select(rows, c, cfg, scenario)
            if t.size == 0:
                continue
            entry[f"lowest_free_{cfg}"] = lowest_free_speed(t, s, offset=off)
            for v in speeds:
                k = np.flatnonzero(np.isclose(t, v))
                entry[f"ssi_{v:g}_{cfg}"] = float(s[k[0]]) if k.size else float("nan")
        out.append(entry)
    return out


def _fmt(v: float, unit: str = "") -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "none"
    if math.isinf(v):
        return "stuck"
    return f"{v:.2f}{unit}"


def markdown_table(rows: Sequence[dict], scenario: str = "rest", speeds: Sequence[float] = (2.0, 4.0)) -> str:
    """Markdown comparison table (the README's): lowest stick-slip-free target and SSI at ``speeds``."""
    summ = summary(rows, scenario, speeds)
    cfgs = list(dict.fromkeys(r["config"] for r in rows))
    head = ["controller", "period (ms)"] + [f"lowest free target, {c} (rad/s)" for c in cfgs]
    head += [f"SSI at {v:g} rad/s, {c}" for c in cfgs for v in speeds]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for e in summ:
        period = f"{1e3 * e['control_dt']:g}" if "control_dt" in e else "?"
        cells = [e["controller"], period] + [_fmt(e.get(f"lowest_free_{c}", float("nan"))) for c in cfgs]
        cells += [_fmt(e.get(f"ssi_{v:g}_{c}", float("nan"))) for c in cfgs for v in speeds]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def plot_ssi(rows: Sequence[dict], path: str | Path, scenario: str = "rest", params=None) -> Path:
    """SSI versus target speed, one curve per controller and configuration, with the open-loop diagram
    (equilibrium branch omega_l(u), stable/unstable, and the baseline's steady omega_l range) beside it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from drillgym.bifurcation import equilibrium_branch

    cfgs = list(dict.fromkeys(r["config"] for r in rows))
    fig, axes = plt.subplots(len(cfgs), 2, figsize=(12, 4.2 * len(cfgs)), squeeze=False)
    for i, cfg in enumerate(cfgs):
        ax = axes[i, 0]
        for c in dict.fromkeys(r["controller"] for r in rows):
            t, s, _ = _select(rows, c, cfg, scenario)
            if t.size:
                ax.semilogy(t, np.clip(np.where(np.isfinite(s), s, 10.0), 1e-4, 10.0), "o-", label=c)
        ax.axhline(SSI_THRESHOLD, color="k", lw=0.8, ls="--")
        ax.set(
            xlabel="target speed omega_ref (rad/s)",
            ylabel="SSI (steady state)",
            title=f"closed loop, {cfg}, from {scenario}",
        )
        ax.legend(fontsize=8)
        ax = axes[i, 1]
        br = equilibrium_branch(cfg, params, umax=5.0)
        st = br.stable
        ax.plot(br.u, np.where(st, br.omega, np.nan), "b-", label="stable equilibria")
        ax.plot(br.u, np.where(~st, br.omega, np.nan), "b--", label="unstable equilibria")
        base = [r for r in rows if r["controller"] == "baseline" and r["config"] == cfg and r["scenario"] == scenario]
        if base:
            u = [r["u_mean"] for r in base]
            ax.plot(u, [r["omega_l_max"] for r in base], "r^", label="baseline from rest: max omega_l")
            ax.plot(u, [r["omega_l_min"] for r in base], "rv", label="baseline from rest: min omega_l")
        for h in br.hopf:
            ax.plot(h.u, h.omega, "ks")
        ax.set(xlabel="voltage u (V)", ylabel="omega_l (rad/s)", title=f"open loop, {cfg}", xlim=(0, 5))
        ax.legend(fontsize=8)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def write_report(rows: Sequence[dict], out_dir: str | Path, params=None, plant: str | None = None) -> dict[str, Path]:
    """Write the evaluation's report: results.csv, summary.md (a table per scenario), ssi_vs_target.png.

    Parameters
    ----------
    rows : sequence of dict
        The rows of :func:`controllers.evaluation.evaluate`.
    out_dir : str or path
        Output directory (created).
    params : RigParams, optional
        Nominal parameters of the open-loop diagram in the figure; default the identified set.
    plant : str, optional
        One line on the plant's hidden effects; default from the rows' ``plant`` labels.

    Returns
    -------
    dict of str to Path
        The files written by kind: ``csv``, ``markdown``, ``figure``, and ``population_figure`` for a
        population scenario.
    """
    out = create_directory(out_dir)
    files = {"csv": write_csv(rows, out / "results.csv")}
    parts = [
        "# Controller evaluation\n",
        f"Stick-slip: SSI >= {SSI_THRESHOLD} in steady state. 'lowest free target': "
        "lowest target of the grid from which every higher target is held: no stick-slip and the mean "
        "lower-disc speed within 10 % of the target.\n",
    ]
    population = [r for r in rows if r["scenario"] == "plants"]
    rows = [r for r in rows if r["scenario"] != "plants"]
    labels = sorted({str(r.get("plant", "base")) for r in rows})
    if plant is None and rows and labels != ["base"]:
        plant = "hidden effects: " + ", ".join(labels)
    models = {str(r["controller"]): str(r.get("model", "base")) for r in rows + population}
    own = {c: m for c, m in models.items() if m != "base"}
    if plant:
        told = "the controllers are built from the nominal parameters and do not know them"
        if own:
            told = "the controllers are built from their model: " + ", ".join(f"{c} on {m}" for c, m in own.items())
            told += ", the others on its base parameters" if len(own) < len(models) else ""
        parts.append(f"\nPlant: {plant} ({told}).\n")
    elif own:
        parts.append("\nControllers' model: " + ", ".join(f"{c} on {m}" for c, m in own.items()) + ".\n")
    for sc in dict.fromkeys(r["scenario"] for r in rows):
        parts.append(f"\n## scenario: {sc}\n\n" + markdown_table(rows, sc))
    if population:
        from .population_report import identification_table, named_plants_table, plot_population, population_table

        n = len({int(r["plant"]) for r in population})
        named = named_plants_table(population)
        origin = "listed in the plants file" if named else "drawn from the uncertainty set"
        parts.append(
            f"\n## scenario: plants ({n} plants {origin}, from rest)\n\n"
            "Each plant's lowest held target; median and 90th percentile over the plants (the higher "
            "plant's value); 'none': not even the highest target held.\n\n" + population_table(population)
        )
        if named:
            parts.append("\nEach plant of the file by its name, with its effects:\n\n" + named)
        ident = identification_table(population)
        if ident:
            parts.append(
                "\nEach controller built on its plant's identified model (excitation run, diagnose, identify). "
                "Per plant: the effects selected, the identification time, and each parameter identified: base "
                "parameters as their error, effect parameters as identified (true); '-': effect not selected.\n\n"
                + ident
            )
        files["population_figure"] = plot_population(population, out / "plants_lowest_held.png")
    md = out / "summary.md"
    md.write_text("".join(parts))
    files["markdown"] = md
    if rows:
        scen = "rest" if any(r["scenario"] == "rest" for r in rows) else rows[0]["scenario"]
        files["figure"] = plot_ssi(rows, out / "ssi_vs_target.png", scen, params)
    return files
