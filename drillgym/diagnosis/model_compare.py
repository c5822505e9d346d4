"""The error falls where the user looks: a recording compared with the nominal model and with a model beside it.

``drillgym compare REC --model model.json`` after ``diagnose --model-out`` / ``identify``: per channel, the
RMS error of each model against the recording and in units of the recording's noise (1: at the noise),
as text, JSON (``compare_models.json``) and a figure of both residuals in time (``nominal_vs_model.png``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..identification.experiment import Experiment
from ..io.jsonfile import write_json
from ..model import Model
from ..params import RigParams
from .compare import Comparison, compare

__all__ = ["ModelComparison", "compare_models", "write_model_comparison"]


@dataclass(frozen=True)
class ModelComparison:
    """A recording against the nominal model and a model.

    Attributes
    ----------
    nominal, model : Comparison
        The two comparisons, on one grid and with one segmentation.
    label : str
        The model's name in the text (its effects, or ``base``).
    """

    nominal: Comparison
    model: Comparison
    label: str

    def ratios(self, which: Comparison) -> dict[str, float]:
        """Per channel, the RMS error over the recording's noise level (NaN where the noise is unknown)."""
        return {
            c: (m["rms"] / which.noise[c] if which.noise.get(c) else float("nan")) for c, m in which.metrics.items()
        }

    def text(self) -> str:
        """One line per channel: the nominal model's error, the model's, in noise units."""
        a, b = self.ratios(self.nominal), self.ratios(self.model)
        lines = [f"the recording against the nominal model and against {self.label}:"]
        lines.append(f"  {'channel':<8} {'nominal RMS':>12} {'x noise':>9}   {'model RMS':>12} {'x noise':>9}")
        for c, m in self.model.metrics.items():
            n = self.nominal.metrics[c]["rms"]
            lines.append(f"  {c:<8} {n:>12.4g} {a[c]:>9.3g}   {m['rms']:>12.4g} {b[c]:>9.3g}")
        worst = max((v for v in b.values() if np.isfinite(v)), default=float("nan"))
        if np.isfinite(worst):
            verdict = "within 3x the noise" if worst <= 3.0 else f"{worst:.3g}x the noise on its worst channel"
            lines.append(f"  the model leaves a residual {verdict}")
        return "\n".join(lines)

    def to_json(self) -> dict:
        """``{model, channels: {c: {nominal_rms, nominal_to_noise, model_rms, model_to_noise}}, noise}``."""
        a, b = self.ratios(self.nominal), self.ratios(self.model)
        chans = {
            c: {
                "nominal_rms": self.nominal.metrics[c]["rms"],
                "nominal_to_noise": a[c],
                "model_rms": m["rms"],
                "model_to_noise": b[c],
            }
            for c, m in self.model.metrics.items()
        }
        return {"model": self.label, "channels": chans, "noise": dict(self.model.noise)}


def compare_models(
    ex: Experiment, model: Model, nominal: RigParams | None = None, segment_s: float | None = None
) -> ModelComparison:
    """Compare a recording with the nominal base model and with ``model``.

    Parameters
    ----------
    ex : Experiment
        The prepared recording.
    model : Model
        The model (e.g. identified on this recording).
    nominal : RigParams, optional
        The nominal base parameters (default: the model page's identified set), run without effects.
    segment_s : float or None, optional
        Multiple-shooting segment length (s); None: one free run.

    Returns
    -------
    ModelComparison
    """
    base = compare(ex, nominal or RigParams(), segment_s=segment_s)
    with_model = compare(
        ex, model.params, segment_s=segment_s, effects=model.composition, effect_params=dict(model.values)
    )
    return ModelComparison(base, with_model, model.label)


def write_model_comparison(mc: ModelComparison, out_dir: str | Path) -> list[Path]:
    """Write ``compare_models.json`` and ``nominal_vs_model.png`` (both residuals in time) into ``out_dir``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    ex = mc.model.experiment
    t = ex.t - ex.t[0]
    chans = list(mc.model.predicted)
    fig, axes = plt.subplots(len(chans), 1, figsize=(10, 2.2 * len(chans)), squeeze=False, sharex=True)
    for i, c in enumerate(chans):
        meas = ex.channel(c)
        axes[i, 0].plot(t, mc.nominal.predicted[c] - meas, color="0.6", lw=0.8, label="nominal model")
        axes[i, 0].plot(t, mc.model.predicted[c] - meas, "b", lw=0.8, label=mc.label)
        axes[i, 0].set_ylabel(f"model − data {c}")
    axes[0, 0].legend(loc="best", fontsize=8)
    axes[-1, 0].set_xlabel("t (s)")
    fig.tight_layout()
    fig_path = out / "nominal_vs_model.png"
    fig.savefig(fig_path, dpi=90)
    plt.close(fig)
    json_path = out / "compare_models.json"
    write_json(json_path, mc.to_json())
    return [fig_path, json_path]
