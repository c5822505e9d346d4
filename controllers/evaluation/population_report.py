"""Summary and figure of a plant population (``--scenarios plants``).

Per controller and configuration: each plant's lowest held target (:func:`.metrics.lowest_free_speed`
over that plant's targets; inf when not even the highest target is held), then over the plants the
median and the 90th percentile (``numpy.quantile(method='higher')``: a value some plant reached,
rounded towards the worse plant), the number of plants holding no target, and the number of plants on
which some run passed the over-speed stop (``runaway``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from drillgym.params import PARAM_NAMES

from .metrics import lowest_free_speed

__all__ = ["plant_lowest", "population_summary", "population_table", "named_plants_table", "plot_population"]


def plant_lowest(
    rows: Sequence[dict], controller: str, config: str, scenario: str = "plants", whirl_threshold: float | None = None
) -> dict[int, float]:
    """Plant index -> lowest held target (rad/s; inf: none held) of one controller and configuration; with
    ``whirl_threshold`` a target is held only when its whirl (``run_metrics``) is also below it."""
    out: dict[int, float] = {}
    sel = [r for r in rows if r["controller"] == controller and r["config"] == config and r["scenario"] == scenario]
    for k in sorted({int(r["plant"]) for r in sel}):
        pr = sorted((r for r in sel if int(r["plant"]) == k), key=lambda r: float(r["omega_ref"]))
        low = lowest_free_speed(
            np.array([float(r["omega_ref"]) for r in pr]),
            np.array([float(r["ssi"]) for r in pr]),
            offset=np.array([float(r["offset"]) for r in pr]),
            whirl=None if whirl_threshold is None else np.array([float(r["whirl"]) for r in pr]),
            whirl_threshold=whirl_threshold,
        )
        out[k] = math.inf if math.isnan(low) else low
    return out


def _truthy(v) -> bool:
    return v is True or str(v).lower() in ("true", "1")


def population_summary(rows: Sequence[dict], scenario: str = "plants") -> list[dict]:
    """One entry per (controller, configuration): plants, median, p90, worst lowest held target (rad/s),
    plants holding nothing, plants with a runaway run."""
    out = []
    sel = [r for r in rows if r["scenario"] == scenario]
    for c in dict.fromkeys(r["controller"] for r in sel):
        for cfg in dict.fromkeys(r["config"] for r in sel):
            low = plant_lowest(sel, c, cfg, scenario)
            if not low:
                continue
            v = np.array(list(low.values()))
            run = {
                int(r["plant"]) for r in sel if r["controller"] == c and r["config"] == cfg and _truthy(r["runaway"])
            }
            periods = {float(r["control_dt"]) for r in sel if r["controller"] == c}
            out.append(
                {
                    "controller": c,
                    "config": cfg,
                    "plants": int(v.size),
                    "control_dt": min(periods),
                    "median": float(np.quantile(v, 0.5, method="higher")),
                    "p90": float(np.quantile(v, 0.9, method="higher")),
                    "worst": float(v.max()),
                    "none_held": int(np.isinf(v).sum()),
                    "runaway": len(run),
                }
            )
    return out


def _fmt(v: float) -> str:
    return "none" if math.isinf(v) else f"{v:.2f}"


def population_table(rows: Sequence[dict], scenario: str = "plants") -> str:
    """Markdown table of :func:`population_summary`."""
    head = [
        "controller",
        "period (ms)",
        "config",
        "plants",
        "median lowest held (rad/s)",
        "90th pct (rad/s)",
        "worst (rad/s)",
        "plants holding none",
        "plants with a run past 40 rad/s",
    ]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for e in population_summary(rows, scenario):
        lines.append(
            "| "
            + " | ".join(
                [
                    e["controller"],
                    f"{1e3 * e['control_dt']:g}",
                    e["config"],
                    str(e["plants"]),
                    _fmt(e["median"]),
                    _fmt(e["p90"]),
                    _fmt(e["worst"]),
                    str(e["none_held"]),
                    str(e["runaway"]),
                ]
            )
            + " |"
        )
    return "\n".join(lines) + "\n"


def named_plants_table(rows: Sequence[dict], scenario: str = "plants") -> str:
    """Markdown: per plant of a plants file (its name and effects) each controller's lowest held target (rad/s;
    'none': not even the highest held) per configuration; empty for drawn plants (no ``plant_name``)."""
    sel = [r for r in rows if r["scenario"] == scenario and "plant_name" in r]
    if not sel:
        return ""
    pairs = list(dict.fromkeys((r["controller"], r["config"]) for r in sel))
    low = {pair: plant_lowest(sel, *pair, scenario) for pair in pairs}
    plants = {int(r["plant"]): (str(r["plant_name"]), str(r.get("effects", ""))) for r in sel}
    head = ["plant", "effects"] + [f"{c}, {cfg}: lowest held (rad/s)" for c, cfg in pairs]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for k in sorted(plants):
        cells = [_fmt(low[pair][k]) if k in low[pair] else "-" for pair in pairs]
        lines.append("| " + " | ".join([*plants[k], *cells]) + " |")
    return "\n".join(lines) + "\n"


def plot_population(rows: Sequence[dict], path: str | Path, scenario: str = "plants") -> Path:
    """Fraction of plants on which each controller holds every target from x up (one panel per configuration)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sel = [r for r in rows if r["scenario"] == scenario]
    cfgs = list(dict.fromkeys(r["config"] for r in sel))
    targets = sorted({float(r["omega_ref"]) for r in sel})
    fig, axes = plt.subplots(1, len(cfgs), figsize=(6.5 * len(cfgs), 4.2), squeeze=False)
    for ax, cfg in zip(axes[0], cfgs):
        for c in dict.fromkeys(r["controller"] for r in sel):
            low = np.array(list(plant_lowest(sel, c, cfg, scenario).values()))
            if low.size:
                x = np.array(targets)
                ax.step(x, [(low <= w).mean() for w in x], where="post", label=c)
        ax.axhline(0.5, color="k", lw=0.6, ls=":")
        ax.axhline(0.9, color="k", lw=0.6, ls="--")
        ax.set(
            xlabel="target speed (rad/s)",
            ylabel="fraction of plants holding every target from here up",
            title=f"{cfg}, {len({int(r['plant']) for r in sel})} plants, from rest",
            ylim=(-0.02, 1.02),
        )
        ax.legend(fontsize=8)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def identification_rows(rows: Sequence[dict], scenario: str = "plants") -> list[dict]:
    """One entry per identified plant: its name (a plants file's) or index, the effects selected, the
    identification time (s), and per parameter the true and identified values (``id_<name>`` columns of
    :mod:`.identify`)."""
    seen: dict[int, dict] = {}
    for r in rows:
        if r["scenario"] == scenario and "identify_s" in r and int(r["plant"]) not in seen:
            names = [k[3:] for k in r if k.startswith("id_")]
            seen[int(r["plant"])] = {
                "plant": r.get("plant_name", int(r["plant"])),
                "selected": r["selected"],
                "identify_s": float(r["identify_s"]),
                "true": {n: float(r[n]) for n in names if _given(r.get(n))},
                "identified": {
                    n: float(r["id_" + n]) if _given(r["id_" + n]) else math.nan for n in names if _given(r.get(n))
                },
            }
    return [seen[k] for k in sorted(seen)]


def _given(value: object) -> bool:
    """A value the plant has (a row of a plants file's population leaves the other plants' parameters empty)."""
    return value is not None and value != "" and not (isinstance(value, float) and math.isnan(value))


def identification_table(rows: Sequence[dict], scenario: str = "plants") -> str:
    """Markdown: per plant the effects selected, the identification time and each parameter's identified value
    against the true one (base parameters: error in %; effect parameters: both values; '-' not selected)."""
    ident = identification_rows(rows, scenario)
    if not ident:
        return ""
    names = list(dict.fromkeys(n for e in ident for n in e["true"]))  # a plants file's plants differ in effects
    lines = [
        "| plant | effects selected | identification (s) | " + " | ".join(names) + " |",
        "|" + "---|" * (3 + len(names)),
    ]
    for e in ident:
        cells = []
        for n in names:
            if n not in e["true"]:  # a parameter of another plant's effects
                cells.append("")
                continue
            t, i = e["true"][n], e["identified"][n]
            if math.isnan(i):
                cells.append(f"- ({t:.3g})")
            elif n in _EFFECT_PARAMETERS or n not in PARAM_NAMES:  # a user's effect parameter too
                cells.append(f"{i:.3g} ({t:.3g})")
            else:
                cells.append(f"{100 * (i - t) / t:+.1f} %")
        lines.append(f"| {e['plant']} | {e['selected']} | {e['identify_s']:.0f} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


#: parameters of the population's effects (shown as identified (true) values, not as a relative error)
_EFFECT_PARAMETERS = ("tau_m", "delay", "pf_c1", "pf_s1", "pf_c2", "pf_s2", "counts_per_rev", "angle_noise")
