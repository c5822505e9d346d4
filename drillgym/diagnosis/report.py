"""Markdown report of one model-improvement round: base model -> diagnosis -> effect added -> refit."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..identification.experiment import Experiment
from ..params import RigParams
from .compare import compare, write_compare
from .refit import RefitResult
from .results import Diagnosis

__all__ = ["write_report"]


def _metrics_table(before: dict[str, float], after: dict[str, float], rms_b: dict, rms_a: dict) -> list[str]:
    rows = ["| channel | R² base | R² refit | RMS base | RMS refit | RMS cut |", "|---|---|---|---|---|---|"]
    for c in before:
        cut = 1 - rms_a[c] / rms_b[c] if rms_b[c] else 0.0
        rows.append(
            f"| {c} | {before[c]:.4f} | {after.get(c, float('nan')):.4f} | {rms_b[c]:.4g} | "
            f"{rms_a.get(c, float('nan')):.4g} | {cut:.0%} |"
        )
    return rows


def write_report(
    out_dir: str | Path,
    ex: Experiment,
    base: RigParams,
    diagnosis: Diagnosis | None,
    result: RefitResult,
    segment_s: float | None,
    base_effects: Any = None,
    base_values: Mapping[str, float] | None = None,
) -> Path:
    """Write ``report.md`` with figures of the model before and after a refit.

    Parameters
    ----------
    out_dir : str or path
        The directory (made if missing).
    ex : Experiment
        The recording.
    base : RigParams
        The model's base parameters before.
    diagnosis : Diagnosis or None
        The diagnosis of the model before.
    result : RefitResult
        The refit.
    segment_s : float or None
        Multiple-shooting segment length (s).
    base_effects : any, optional
        The model's effects before.
    base_values : mapping of str to float, optional
        Their values.

    Returns
    -------
    pathlib.Path
        The report file.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    cb = compare(ex, base, segment_s=segment_s, effects=base_effects, effect_params=base_values)
    write_compare(cb, out / "1_base")
    ca = compare(ex, result.params, segment_s=segment_s, effects=result.composition, effect_params=result.effect_values)
    write_compare(ca, out / "3_refit")
    lines = [
        f"# Model improvement report: {ex.name}",
        "",
        f"Configuration `{ex.config.label}`, {ex.duration:.1f} s at {ex.fs:g} Hz (comparison grid); "
        + (
            "free run from the recording's initial state."
            if not segment_s
            else f"multiple shooting: segments of {segment_s:g} s re-started from the recording."
        ),
        "",
        "## 1. Base model",
        "",
        "```",
        cb.text(),
        "```",
        "",
        "![time](1_base/time.png)",
        "",
    ]
    if (out / "1_base" / "bins.png").exists():
        lines += ["![bins](1_base/bins.png)", ""]
    if (out / "1_base" / "spectrum.png").exists():
        lines += ["![spectrum](1_base/spectrum.png)", ""]
    lines += ["## 2. Diagnosis", ""]
    if diagnosis is not None:
        lines += [
            "| rank | effect | score | RMS before | RMS after | cut | significant |",
            "|---|---|---|---|---|---|---|",
        ]
        for i, s in enumerate(diagnosis.ranking, 1):
            lines.append(
                f"| {i} | {s.effect} | {s.score:.1f} | {s.rmse_before:.3g} | {s.rmse_after:.3g} | "
                f"{s.reduction:.0%} | {'yes' if s.significant else 'no'} |"
            )
        lines += ["", "```", diagnosis.text(), "```", ""]
    else:
        lines += ["(not run)", ""]
    added = ", ".join(f"`{e}`" for e in result.effects) or "none (base parameters refitted)"
    lines += [
        "## 3. Effect added and refit",
        "",
        f"Effects added: {added}.",
        "",
        "Fitted values: " + ", ".join(f"{k} = {v:.5g}" for k, v in result.values.items()),
        "",
    ]
    if result.warnings:
        lines += ["Warnings: " + "; ".join(result.warnings), ""]
    lines += ["```", ca.text(), "```", "", "![time](3_refit/time.png)", "", "## 4. The error falling", ""]
    lines += _metrics_table(result.r2_before, result.r2_after, result.rms_before, result.rms_after)
    path = out / "report.md"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path
