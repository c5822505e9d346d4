"""Compare: where the model fails against a recording.

The recording's input is simulated from the recording's initial state (speeds
estimated by differentiation, then refined for the model; a
free run, or — for stick-slip, whose phase drifts over long horizons —
segments re-started from the data, ``segment_s``).  Reported: R² and RMS per
channel; and where the error lives:

* over time: RMS per window, worst windows named;
* against ωl: residual torque on the lower disc (:mod:`.sparse`) per speed bin;
* against θl mod 2π: the same residual torque per angle bin (angle-dependent effects);
* against r: lateral residual per amplitude bin;
* spectrum of the residual, rotation harmonics and the lateral eigenfrequency marked.

:func:`write_compare` saves figures and a short text report naming the worst regions.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.signal import welch

from ..configurations import Configuration
from ..effects import BASE, Composition, compose
from ..identification.experiment import Experiment, prepare_experiment
from ..identification.fitting import base_vector
from ..identification.metrics import channel_metrics
from ..identification.segment_length import segment_length
from ..identification.segmented import SegmentedModel
from ..io import TimeSeries
from ..io.jsonfile import write_json
from ..params import N_PARAMS, RigParams
from .information import recording_information
from .segments import robust_noise
from .sparse import residual_torques

__all__ = ["Comparison", "compare", "write_compare"]


@dataclass
class Comparison:
    """Outcome of :func:`compare` (all arrays on the comparison grid)."""

    experiment: Experiment
    params: RigParams
    segment_s: float | None
    predicted: dict[str, np.ndarray]
    metrics: dict[str, dict[str, float]]
    windows: list[dict]
    by_speed: list[dict] = field(default_factory=list)
    by_angle: list[dict] = field(default_factory=list)
    by_r: list[dict] = field(default_factory=list)
    by_alpha: list[dict] = field(default_factory=list)
    noise: dict[str, float] = field(default_factory=dict)
    spectrum: dict = field(default_factory=dict)
    findings: list[str] = field(default_factory=list)
    composition: Composition = BASE
    vector: np.ndarray | None = None

    @property
    def effect_values(self) -> dict[str, float]:
        return self.composition.split(self.vector)[1] if self.vector is not None else {}

    def text(self) -> str:
        ex = self.experiment
        how = (
            "free run from the recording's initial state"
            if not self.segment_s
            else f"segments of {self.segment_s:g} s, each re-started from the recording (stick-slip phase drift)"
        )
        lines = [f"compare: {ex.name} ({ex.config.label}, {ex.duration:.1f} s, {how})"]
        if self.composition.effects:
            lines.append(
                "  model: base + "
                + ", ".join(self.composition.names)
                + " ("
                + ", ".join(f"{k} = {v:.4g}" for k, v in self.effect_values.items())
                + ")"
            )
        for c, m in self.metrics.items():
            lines.append(f"  {c:<8} R² = {m['r2']:.4f}   RMS = {m['rms']:.4g} {'m' if c in ('x', 'y', 'r') else 'rad'}")
        lines += ["where the model fails:"] + [f"  - {f}" for f in self.findings]
        return "\n".join(lines)

    def undefined(self) -> list[str]:
        """Why each statistic that could not be computed is missing (``"metrics.x.r2: not computed because ..."``).

        Returns
        -------
        list of str
            One line per non-finite statistic (``to_json`` writes those as null with these lines).
        """
        out = []
        for c, m in self.metrics.items():
            meas = np.asarray(self.experiment.channel(c), dtype=float)
            ok = np.isfinite(meas) & np.isfinite(self.predicted[c])
            for k, v in m.items():
                if np.isfinite(v):
                    continue
                if not ok.any():
                    why = f"no sample of {c} is both measured and predicted"
                elif k == "r2":
                    why = f"the measured {c} is constant (R² divides by its variance)"
                else:
                    why = f"{c} has no finite compared sample"
                out.append(f"metrics.{c}.{k}: not computed because {why}")
        for i, w in enumerate(self.windows):
            for c, v in w.items():
                if not np.isfinite(v):
                    out.append(
                        f"windows[{i}].{c}: not computed because no sample of {c} is compared in "
                        f"{w['t0']:.3g}-{w['t1']:.3g} s (segment starts and ends are not compared)"
                    )
        return out

    def to_json(self) -> dict:
        """The comparison as strict JSON types: a statistic that could not be computed is null, and
        ``warnings`` says why (:meth:`undefined`)."""
        return {
            "model": self.composition.label,
            "effect_values": self.effect_values,
            "metrics": {c: _finite_or_none(m) for c, m in self.metrics.items()},
            "windows": [_finite_or_none(w) for w in self.windows],
            "by_speed": self.by_speed,
            "by_angle": self.by_angle,
            "by_alpha": self.by_alpha,
            "by_r": self.by_r,
            "findings": self.findings,
            "noise": self.noise,
            "segment_s": self.segment_s,
            "spectrum_peaks": self.spectrum.get("peaks", []),
            "signal_path": self.composition.signal_path(),
            "warnings": self.undefined(),
        }


def _finite_or_none(d: Mapping[str, float]) -> dict[str, float | None]:
    """The mapping with its non-finite numbers as None (the caller says why in its warnings)."""
    return {k: (float(v) if np.isfinite(v) else None) for k, v in d.items()}


NOISE_FACTOR = 3.0  # a channel fails only where its RMS error exceeds this many times its noise level


def _noise_levels(ex: Experiment, chans: list[str]) -> dict[str, float]:
    """Measurement noise per channel (rad or m): one encoder count / √12 (the count read from the
    data, :func:`drillgym.identification.reading_noise.angle_noise`), 10 µm for the LVDT channels."""
    _, scales = robust_noise(ex)
    return {c: float(scales.get(c, 1e-5)) for c in chans}


def _main_channel(ex: Experiment) -> str:
    return "theta_u" if ex.config is Configuration.UPPER else "theta_l"


def compare(
    data: TimeSeries | Experiment,
    params: RigParams | np.ndarray | None = None,
    config=None,
    *,
    segment_s: float | None = None,
    compare_rate_hz: float = 100.0,
    n_windows: int = 10,
    refine_speeds: bool = True,
    effects: Any = None,
    effect_params: Mapping[str, float] | None = None,
) -> Comparison:
    """Simulate the recording's input from its initial state and locate the error (see module docstring).

    Parameters
    ----------
    data : TimeSeries or Experiment
        The recording.
    params : RigParams or numpy.ndarray, optional
        Base parameters (default: the identified set), or a vector in the composition's layout.
    config : str or Configuration, optional
        The configuration when the recording's metadata has none.
    segment_s : float or None, optional
        Multiple-shooting segment length (s); negative: the configuration's default
        (:func:`~drillgym.identification.segment_length.default_segment`); None: one free run from the initial
        state.  Default None.
    compare_rate_hz : float, optional
        Comparison grid rate (Hz).  Default 100.
    n_windows : int, optional
        Time windows the error is located in.  Default 10.
    refine_speeds : bool, optional
        Refine the segments' initial speeds for the model.  Default True.
    effects : any, optional
        The model's effects (names, file specs, classes or a Composition).
    effect_params : mapping of str to float, optional
        Their values.

    Returns
    -------
    Comparison
        Where the model fails: per channel, in time, over speed, angle and lateral amplitude, in frequency.
    """
    comp, values = compose(effects, effect_params)
    vec = base_vector(comp, params, values)
    p = RigParams.from_vector(vec[:N_PARAMS])
    ex = data if isinstance(data, Experiment) else prepare_experiment(data, config, compare_rate_hz=compare_rate_hz)
    segment_s = segment_length(segment_s, ex)
    chans = ["theta_u"] if ex.config is Configuration.UPPER else ["theta_u", "theta_l", "alpha"]
    if ex.config.lateral_free:
        chans += ["x", "y", "r"]
    ex, scales = robust_noise(ex)  # the speed limits and scales the diagnosis compares with
    model = SegmentedModel([ex], segment_s, composition=comp)
    if refine_speeds:  # speeds at (segment) starts: derivative estimates corrected for this model
        w = {c: 1.0 for c in chans if c in ("theta_u", "theta_l", "x", "y")}
        model.refine_initial_speeds(vec, w, scales)
    pred = model.predict(vec[None, :], tuple(chans))[0]
    model.check_finite("compare", vec)
    predicted = {c: pred.stitched(0, c) for c in chans}
    meas = {c: ex.channel(c) for c in chans}
    metrics = channel_metrics(meas, predicted)
    res = {c: predicted[c] - meas[c] for c in chans}
    findings: list[str] = []
    # --- over time
    main = _main_channel(ex)
    edges = np.linspace(0, ex.n, n_windows + 1).astype(int)
    windows = []
    for a, b in zip(edges[:-1], edges[1:]):
        w = {"t0": float(ex.t[a] - ex.t[0]), "t1": float(ex.t[b - 1] - ex.t[0])}
        for c in chans:
            e = res[c][a:b]
            w[c] = float(np.sqrt(np.nanmean(e**2)))
        windows.append(w)
    overall = metrics[main]["rms"]
    worst = sorted(windows, key=lambda w: -w[main])[:2]
    for w in worst:
        if overall > 0 and w[main] > 1.5 * overall:
            findings.append(
                f"{main} error is largest in {w['t0']:.1f}–{w['t1']:.1f} s "
                f"(RMS {w[main]:.3g}, {w[main] / overall:.1f}× the record's)"
            )
    if len(windows) >= 4 and overall > 0:
        first, last = (
            np.mean([w[main] for w in windows[: len(windows) // 3]]),
            np.mean([w[main] for w in windows[-(len(windows) // 3) :]]),
        )
        if last > 2 * first:
            findings.append(
                f"the error grows along the run ({first:.3g} early, {last:.3g} late): "
                "a slow change (friction drift?) or accumulated phase"
            )
    comp = Comparison(
        ex, p, segment_s, predicted, metrics, windows, findings=findings, composition=model.composition, vector=vec
    )
    comp.noise = _noise_levels(ex, chans)
    above = {c for c in chans if metrics[c]["rms"] > NOISE_FACTOR * comp.noise[c]}
    why_not = recording_information(ex.recording).why_not if ex.recording is not None else None
    if not above and why_not is not None:  # a match that says nothing about the model
        comp.findings[:] = [f"cannot tell from this recording: {why_not}"]
        return comp
    if not above:  # the model fits to the noise: there is no failure to locate
        comp.findings[:] = [
            f"the model matches the recording within the measurement noise ({main} RMS "
            f"{metrics[main]['rms']:.3g} vs noise {comp.noise[main]:.3g}): no failure to report"
        ]
        return comp
    if main not in above:
        comp.findings[:] = [f for f in comp.findings if not f.startswith(main)]
    if ex.config is not Configuration.UPPER:
        _torque_bins(comp)
    if ex.config.lateral_free:
        _r_bins(comp, res)
    _spectrum(comp, res[main] if not ex.config.lateral_free else res["r"])
    if not comp.findings:
        comp.findings.append("no region stands out: the error is spread evenly")
    return comp


def _torque_bins(comp: Comparison) -> None:
    ex = comp.experiment
    rt = residual_torques(ex, comp.vector, effects=comp.composition)
    ok = rt.lower_valid
    if ok.sum() < 30:
        return
    wl = rt.states[ok, 3]
    th = np.mod(rt.states[ok, 1], 2 * np.pi)
    tau = rt.tau_l[ok]
    total = float(np.sqrt(np.mean(tau**2)))
    qs = np.unique(np.quantile(wl, np.linspace(0, 1, 9)))
    for a, b in zip(qs[:-1], qs[1:]):
        s = (wl >= a) & (wl <= b)
        if s.sum() > 5:
            comp.by_speed.append(
                {
                    "omega_lo": float(a),
                    "omega_hi": float(b),
                    "mean": float(tau[s].mean()),
                    "rms": float(np.sqrt(np.mean(tau[s] ** 2))),
                    "n": int(s.sum()),
                }
            )
    if comp.by_speed:
        w = max(comp.by_speed, key=lambda d: d["rms"])
        if w["rms"] > 1.3 * total:
            comp.findings.append(
                f"residual torque on the lower disc is largest for ωl in "
                f"[{w['omega_lo']:.2f}, {w['omega_hi']:.2f}] rad/s (RMS {w['rms']:.3g} N m, "
                f"record {total:.3g} N m): the friction law there"
            )
    eb = np.linspace(0, 2 * np.pi, 13)
    sg = np.sign(wl)
    for a, b in zip(eb[:-1], eb[1:]):
        s = (th >= a) & (th < b)
        if s.sum() > 5:
            comp.by_angle.append(
                {"theta_lo": float(a), "theta_hi": float(b), "mean": float(np.mean(tau[s] * sg[s])), "n": int(s.sum())}
            )
    a_ = rt.states[ok, 1] - rt.states[ok, 0]
    qa = np.unique(np.quantile(a_, np.linspace(0, 1, 9)))
    for a, b in zip(qa[:-1], qa[1:]):
        s = (a_ >= a) & (a_ <= b)
        if s.sum() > 5:
            comp.by_alpha.append(
                {"alpha_lo": float(a), "alpha_hi": float(b), "mean": float(tau[s].mean()), "n": int(s.sum())}
            )
    if len(comp.by_alpha) >= 4:
        m = np.array([d["mean"] for d in comp.by_alpha])
        n = np.array([d["n"] for d in comp.by_alpha])
        eta2 = float(np.sum(n * (m - tau.mean()) ** 2) / max(np.sum((tau - tau.mean()) ** 2), 1e-300))
        if eta2 > 0.3 and 0.5 * (m.max() - m.min()) > 0.3 * total:
            comp.findings.append(
                f"residual torque on the lower disc varies with the twist α (explains {eta2:.0%} "
                f"of it, from {m.min():.3g} to {m.max():.3g} N m): the string's torque law"
            )
    revolutions = float(np.ptp(rt.states[ok, 1])) / (2 * np.pi)
    if len(comp.by_angle) >= 6 and revolutions >= 3:
        m = np.array([d["mean"] for d in comp.by_angle])
        n = np.array([d["n"] for d in comp.by_angle])
        amp = 0.5 * (m.max() - m.min())
        x = tau * sg
        eta2 = float(np.sum(n * (m - x.mean()) ** 2) / max(np.sum((x - x.mean()) ** 2), 1e-300))
        if amp > 0.3 * total and eta2 > 0.2:  # the angle explains a real share of the residual
            k = int(np.argmax(np.abs(m - m.mean())))
            comp.findings.append(
                f"residual friction torque depends on the lower disc's angle: ±{amp:.3g} N m "
                f"over a revolution, extreme near θl = {np.degrees(comp.by_angle[k]['theta_lo']):.0f}–"
                f"{np.degrees(comp.by_angle[k]['theta_hi']):.0f}°, explaining {eta2:.0%} of its "
                f"variance (angle-dependent friction?)"
            )
    neg, pos = tau[wl < 0] * -1, tau[wl > 0]
    if neg.size > 20 and pos.size > 20 and abs(neg.mean() - pos.mean()) > 0.3 * total:
        comp.findings.append(
            f"residual friction differs between directions: {pos.mean():.3g} N m (ωl > 0) vs "
            f"{neg.mean():.3g} N m (ωl < 0)"
        )


def _r_bins(comp: Comparison, res: dict) -> None:
    ex = comp.experiment
    r = ex.channel("r")
    e = np.hypot(res["x"], res["y"])
    ok = np.isfinite(e)
    qs = np.unique(np.quantile(r[ok], np.linspace(0, 1, 6)))
    for a, b in zip(qs[:-1], qs[1:]):
        s = ok & (r >= a) & (r <= b)
        if s.sum() > 5:
            comp.by_r.append(
                {"r_lo": float(a), "r_hi": float(b), "rms": float(np.sqrt(np.mean(e[s] ** 2))), "n": int(s.sum())}
            )
    if len(comp.by_r) >= 2:
        w = max(comp.by_r, key=lambda d: d["rms"])
        tot = float(np.sqrt(np.mean(e[ok] ** 2)))
        if w["rms"] > 1.3 * tot:
            comp.findings.append(
                f"lateral error is largest for r in [{w['r_lo'] * 1e3:.2f}, {w['r_hi'] * 1e3:.2f}] mm "
                f"(RMS {w['rms'] * 1e3:.3g} mm vs {tot * 1e3:.3g} mm)"
            )


def _spectrum(comp: Comparison, e: np.ndarray) -> None:
    ex = comp.experiment
    e = np.nan_to_num(e - np.nanmean(e))
    if len(e) < 64:
        return
    f, P = welch(e, fs=ex.fs, nperseg=min(len(e), int(ex.fs * 20)))
    wl = ex.rates.get("omega_l", ex.rates["omega_u"])
    f_rot = float(np.mean(np.abs(wl))) / (2 * np.pi)
    f_lat = comp.params.lateral_eigenfrequency / (2 * np.pi)
    marks = {"rotation": f_rot, "2× rotation": 2 * f_rot, "lateral eigenfrequency": f_lat}
    peaks = []
    band = (f > 0.02) & (f < min(10.0, ex.fs / 2))
    if band.any():
        for i in np.argsort(-P * band)[:3]:
            near = [n for n, v in marks.items() if v > 0 and abs(f[i] - v) < 0.1 * v + f[1]]
            peaks.append({"f_hz": float(f[i]), "near": near})
        top = peaks[0]
        if top["near"]:
            comp.findings.append(f"residual spectrum peaks at {top['f_hz']:.2f} Hz, at the {', '.join(top['near'])}")
    comp.spectrum = {"f": f, "P": P, "marks": marks, "peaks": peaks}


def write_compare(comp: Comparison, out_dir: str | Path) -> list[Path]:
    """Write a comparison's figures (time, binned residuals, spectrum), ``report.txt`` and ``compare.json``.

    Parameters
    ----------
    comp : Comparison
        The comparison.
    out_dir : str or path
        The directory (made if missing).

    Returns
    -------
    list of pathlib.Path
        The files written.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = [_time_figure(plt, comp, out)]
    paths += _bins_figure(plt, comp, out)
    paths += _spectrum_figure(plt, comp, out)
    (out / "report.txt").write_text(comp.text() + "\n", encoding="utf-8")
    write_json(out / "compare.json", comp.to_json())
    return paths + [out / "report.txt", out / "compare.json"]


def _time_figure(plt, comp: Comparison, out: Path) -> Path:
    """Measured and modelled channels and their residual in time: ``time.png``."""
    ex = comp.experiment
    t = ex.t - ex.t[0]
    chans = list(comp.predicted)
    unit = {c: ("mm" if c in ("x", "y", "r") else "rad") for c in chans}
    k = {c: (1e3 if c in ("x", "y", "r") else 1.0) for c in chans}
    fig, axes = plt.subplots(len(chans), 2, figsize=(12, 2.2 * len(chans)), squeeze=False, sharex=True)
    for i, c in enumerate(chans):
        axes[i, 0].plot(t, k[c] * ex.channel(c), "k", lw=1, label="measured")
        axes[i, 0].plot(t, k[c] * comp.predicted[c], "r--", lw=1, label="model")
        axes[i, 0].set_ylabel(f"{c} ({unit[c]})")
        axes[i, 1].plot(t, k[c] * (comp.predicted[c] - ex.channel(c)), "b", lw=0.8)
        if comp.noise.get(c):
            for sgn in (-1, 1):
                axes[i, 1].axhline(sgn * NOISE_FACTOR * k[c] * comp.noise[c], color="gray", ls=":", lw=0.8)
        axes[i, 1].set_ylabel(f"model − data {c} ({unit[c]})")
    axes[0, 0].legend(loc="best")
    axes[0, 1].set_title(f"residual (dotted: ±{NOISE_FACTOR:g}× noise level)", fontsize=9)
    axes[-1, 0].set_xlabel("t (s)")
    axes[-1, 1].set_xlabel("t (s)")
    fig.tight_layout()
    path = out / "time.png"
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def _bins_figure(plt, comp: Comparison, out: Path) -> list[Path]:
    """The residual binned by speed, angle, twist and lateral amplitude: ``bins.png`` (when any has data)."""
    panels = []
    if comp.by_speed:
        panels.append("speed")
    if comp.by_angle:
        panels.append("angle")
    if comp.by_alpha:
        panels.append("alpha")
    if comp.by_r:
        panels.append("r")
    if panels:  # only panels with data
        fig, axes = plt.subplots(1, len(panels), figsize=(4.7 * len(panels), 3.5), squeeze=False)
        for ax, kind in zip(axes[0], panels):
            if kind == "speed":
                x = [(d["omega_lo"] + d["omega_hi"]) / 2 for d in comp.by_speed]
                ax.bar(
                    x,
                    [d["rms"] for d in comp.by_speed],
                    width=[0.9 * (d["omega_hi"] - d["omega_lo"]) for d in comp.by_speed],
                )
                ax.set(xlabel="ωl (rad/s)", ylabel="residual torque RMS (N m)", title="vs lower disc speed")
            elif kind == "angle":
                ax.bar(
                    np.degrees([d["theta_lo"] for d in comp.by_angle]),
                    [d["mean"] for d in comp.by_angle],
                    width=27,
                    align="edge",
                )
                ax.set(xlabel="θl mod 2π (deg)", ylabel="mean residual friction (N m)", title="vs lower disc angle")
            elif kind == "alpha":
                ax.bar(
                    [(d["alpha_lo"] + d["alpha_hi"]) / 2 for d in comp.by_alpha],
                    [d["mean"] for d in comp.by_alpha],
                    width=[0.9 * (d["alpha_hi"] - d["alpha_lo"]) for d in comp.by_alpha],
                )
                ax.set(xlabel="twist α (rad)", ylabel="mean residual torque (N m)", title="vs string twist")
            else:
                ax.bar(
                    [1e3 * (d["r_lo"] + d["r_hi"]) / 2 for d in comp.by_r],
                    [1e3 * d["rms"] for d in comp.by_r],
                    width=[1e3 * (d["r_hi"] - d["r_lo"]) * 0.9 for d in comp.by_r],
                )
                ax.set(xlabel="r (mm)", ylabel="lateral residual RMS (mm)", title="vs lateral amplitude")
        fig.tight_layout()
        fig.savefig(out / "bins.png", dpi=90)
        plt.close(fig)
        return [out / "bins.png"]
    return []


def _spectrum_figure(plt, comp: Comparison, out: Path) -> list[Path]:
    """The residual's spectrum with the model's natural frequencies marked: ``spectrum.png``."""
    ex = comp.experiment
    if comp.spectrum:
        fig, ax = plt.subplots(figsize=(8, 3.5))
        ax.semilogy(comp.spectrum["f"], comp.spectrum["P"])
        for name, v in comp.spectrum["marks"].items():
            if v > 0:
                ax.axvline(v, ls="--", color="gray")
                ax.text(v, ax.get_ylim()[1], name, rotation=90, va="top", fontsize=8)
        u_ = "m" if ex.config.lateral_free else "rad"
        ax.set(
            xlim=(0, min(10, ex.fs / 2)),
            xlabel="f (Hz)",
            ylabel=f"PSD of residual ({u_}²/Hz)",
            title="residual spectrum",
        )
        fig.tight_layout()
        fig.savefig(out / "spectrum.png", dpi=90)
        plt.close(fig)
        return [out / "spectrum.png"]
    return []
