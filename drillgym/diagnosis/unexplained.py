"""What the final model leaves unexplained: its residual against the measurement noise, where it lives, and
what it depends on.

The diagnosis compares every channel in noise units (:func:`.segments.robust_noise`), so a model that explains
a recording leaves a residual RMS of about 1 on every channel.  :func:`unexplained` measures the final model's
residual there, on the noise scales (not the misfit-weighted ones the selection may have used), and says:

* ``ratio_to_noise``: the residual RMS over all channels, and per channel, in noise units;
* the verdict: *explained* only when every channel is below :data:`EXPLAINED_RATIO` times its noise; *a
  small misfit* up to :data:`UNEXPLAINED_RATIO`; *not explained* from there on;
* ``where``: the phases of the run where the model drifts from the data fastest for their share of the time
  (after input steps, the lower disc sticking or slipping, the upper disc at rest);
* ``depends_on``: the quantity (voltage, speeds, string twist, motor angle) whose bins explain most of the
  drift's variance, and its range where the drift is largest.

The drift is the residual's rate of change within a multiple-shooting segment (noise units per second): the
residual itself grows along a segment from the data's state at its start, so its level mixes the time since the
segment started with the phase the rig is in; its rate is the model's speed error there.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..identification.fitting import Objective

__all__ = ["EXPLAINED_RATIO", "UNEXPLAINED_RATIO", "Phase", "Dependence", "Unexplained", "unexplained"]

#: the final residual is at the noise (the model explains the recording) when every channel's RMS is below this
#: many times its noise.  The noise unit is one encoder count / √12 (:func:`.segments.robust_noise`); the exact
#: model of 8 s synthetic recordings at 250 Hz (nominal base, start speeds refined) leaves 1.55 on both encoders
#: (torsional), 1.51-1.54 on the encoders and 0.2 on the LVDTs (coupled), 2.16 on the upper disc alone, and up to
#: 2.4 on 500 Hz-1 kHz recordings (the speed estimates' smoothing error at stick/slip kinks)
EXPLAINED_RATIO = 3.0
#: from this many times the noise on a channel, the residual is *not explained* (below: a small misfit)
UNEXPLAINED_RATIO = 10.0
#: a phase is named when it holds at least this many times its share of the time of the drift's mean square
CONCENTRATION = 1.5
#: after a step of the input, this long (s) counts as its transient
STEP_WINDOW_S = 0.5
#: an input step: a change between two comparison samples of more than this share of the input's 5-95 % range
STEP_SHARE = 0.05
#: a disc at rest: slower than this (rad/s)
REST_SPEED = 0.1
#: bins of a quantity when its dependence is measured (the motor angle: :data:`ANGLE_BINS` over a turn)
N_BINS = 12
ANGLE_BINS = 36


@dataclass
class Phase:
    """A part of the run where the model drifts from the data.

    Attributes
    ----------
    name : str
        ``steps``, ``lower_stick``, ``lower_slip`` or ``upper_rest``.
    description : str
        The phase in words.
    drift_share : float
        Share of the drift's mean square in the phase.
    time_share : float
        Share of the compared samples in the phase.
    """

    name: str
    description: str
    drift_share: float
    time_share: float

    @property
    def concentration(self) -> float:
        """Drift share over time share (1: the drift is spread evenly)."""
        return self.drift_share / self.time_share if self.time_share > 0 else 0.0

    def to_json(self) -> dict:
        """``{name, description, drift_share, time_share, concentration}``."""
        return {
            "name": self.name,
            "description": self.description,
            "drift_share": round(self.drift_share, 4),
            "time_share": round(self.time_share, 4),
            "concentration": round(self.concentration, 3),
        }


@dataclass
class Dependence:
    """How the drift depends on one quantity.

    Attributes
    ----------
    quantity : str
        ``u``, ``omega_u``, ``omega_l``, ``alpha`` or ``theta_u_mod_2pi``.
    description, unit : str
        The quantity in words, and its unit.
    explained : float
        Share of the drift's variance its bin means explain (correlation ratio, adjusted for the bins' count).
    worst_lo, worst_hi : float
        The bin where the drift's mean square is largest (the quantity's unit).
    bins : list of tuple of (float, float, float)
        Every bin's (lower edge, upper edge, mean drift in noise units/s): the figure's data.
    """

    quantity: str
    description: str
    unit: str
    explained: float
    worst_lo: float
    worst_hi: float
    bins: list[tuple[float, float, float]] = field(default_factory=list)

    def to_json(self) -> dict:
        """``{quantity, description, unit, explained, worst_range, bins}``."""
        return {
            "quantity": self.quantity,
            "description": self.description,
            "unit": self.unit,
            "explained": round(self.explained, 4),
            "worst_range": [self.worst_lo, self.worst_hi],
            "bins": [list(b) for b in self.bins],
        }


@dataclass
class Unexplained:
    """The final model's residual against the measurement noise.

    Attributes
    ----------
    ratio_to_noise : float
        Residual RMS over all compared channels (noise units).
    channels : dict of str to float
        Residual RMS per channel (noise units).
    where : list of Phase
        Phases holding at least :data:`CONCENTRATION` times their share of the time of the drift, most
        concentrated first (empty when the residual is at the noise).
    depends_on : Dependence or None
        The quantity the drift depends on most (None when the residual is at the noise).
    others : list of Dependence
        The other quantities tried, most explaining first.
    """

    ratio_to_noise: float
    channels: dict[str, float]
    where: list[Phase] = field(default_factory=list)
    depends_on: Dependence | None = None
    others: list[Dependence] = field(default_factory=list)

    @property
    def worst(self) -> float:
        """The largest channel ratio (noise units)."""
        return max(self.channels.values(), default=self.ratio_to_noise)

    @property
    def explained(self) -> bool:
        """Whether every channel's residual is at the noise (below :data:`EXPLAINED_RATIO`)."""
        return self.worst < EXPLAINED_RATIO

    @property
    def verdict(self) -> str:
        """``explained``, ``small_misfit`` or ``not_explained``."""
        if self.explained:
            return "explained"
        return "small_misfit" if self.worst < UNEXPLAINED_RATIO else "not_explained"

    def to_json(self) -> dict:
        """The residual's verdict, ratios, phases and dependence as a JSON-ready dict."""
        return {
            "verdict": self.verdict,
            "explained": self.explained,
            "ratio_to_noise": self.ratio_to_noise,
            "worst_channel_ratio": self.worst,
            "thresholds": {"explained_below": EXPLAINED_RATIO, "not_explained_from": UNEXPLAINED_RATIO},
            "channels": self.channels,
            "where": [p.to_json() for p in self.where],
            "depends_on": self.depends_on.to_json() if self.depends_on is not None else None,
            "others": [{"quantity": d.quantity, "explained": round(d.explained, 4)} for d in self.others],
        }

    def lines(self) -> list[str]:
        """The verdict in words, as the diagnosis prints it first."""
        chans = ", ".join(f"{c} {v:.3g}" for c, v in self.channels.items())
        if self.explained:
            return [
                f"explained: the final model's residual is at the measurement noise ({self.ratio_to_noise:.3g} "
                f"noise units RMS; {chans}; below {EXPLAINED_RATIO:g} counts as the noise)"
            ]
        head = "NOT EXPLAINED" if self.verdict == "not_explained" else "a small misfit remains"
        lines = [
            f"{head}: the final model leaves a residual of {self.ratio_to_noise:.3g} times the measurement noise "
            f"(RMS; {chans} noise units; at the noise it would be about 1, below {EXPLAINED_RATIO:g} on every channel)"
        ]
        for p in self.where:
            lines.append(
                f"  it concentrates {p.description}: {p.drift_share:.0%} of the model's drift from the data in "
                f"{p.time_share:.0%} of the time"
            )
        if not self.where:
            lines.append(
                "  it is spread over the run: no phase (input steps, stick, slip, rest) holds much more than its share"
            )
        d = self.depends_on
        if d is not None:
            lines.append(
                f"  it depends most on {d.description}: its bins explain {d.explained:.0%} of the drift's variance; "
                f"largest for {d.quantity} in {d.worst_lo:.3g} to {d.worst_hi:.3g} {d.unit}"
            )
        return lines


def unexplained(obj: Objective, vector: np.ndarray, noise_scales: dict[str, float]) -> Unexplained:
    """The residual a model leaves on the objective's recordings, on the noise scales.

    Parameters
    ----------
    obj : Objective
        The objective (its model's segments and speed corrections as they are).
    vector : numpy.ndarray
        The model's parameter vector.
    noise_scales : dict of str to float
        Each channel's noise (its unit): the scales the objective was built with, before any weighting.

    Returns
    -------
    Unexplained
        The ratios to the noise, and (when above it) where the residual lives and what it depends on.
    """
    r = obj.residual_matrix(np.asarray(vector, dtype=float)[None, :])[0]
    ids = obj.channel_ids
    factor = np.array([obj.scales[c] / (obj.weights[c] * noise_scales[c]) for c in obj.channels])
    r = r * factor[ids]
    channels = {c: float(np.sqrt(np.mean(r[ids == i] ** 2))) for i, c in enumerate(obj.channels) if np.any(ids == i)}
    out = Unexplained(float(np.sqrt(np.mean(r**2))) if len(r) else 0.0, channels)
    if out.explained or len(r) < 4:
        return out
    drift, samples = _drift(obj, r)
    if len(drift) < 4 * N_BINS:
        return out
    quantities = _quantities(obj, samples)
    out.where = _phases(drift, quantities)
    deps = sorted(_dependences(drift, quantities), key=lambda d: -d.explained)
    if deps:
        out.depends_on, out.others = deps[0], deps[1:]
    return out


def _entry_samples(obj: Objective) -> np.ndarray:
    """(M, 2): the experiment and the sample index on its comparison grid of every residual entry."""
    out = np.zeros((len(obj.channel_ids), 2), dtype=np.int64)
    pos = 0
    while pos < len(out):  # the entries come in runs of one (experiment, channel)
        k = int(np.searchsorted(obj.segment_offsets, obj.segment_ids[pos], side="right") - 1)
        c = obj.channels[obj.channel_ids[pos]]
        starts, L = obj.model.segments(k)
        m = obj.model.measured_segments(k, c)
        idx = np.flatnonzero(~np.isnan(m[:, 1:]).ravel())
        if not len(idx):
            raise ValueError(f"residual layout: no compared sample of {c} in experiment {k}")
        j, col = np.divmod(idx, m.shape[1] - 1)
        out[pos : pos + len(idx), 0] = k
        out[pos : pos + len(idx), 1] = np.asarray(starts)[j] + 1 + col
        pos += len(idx)
    return out


def _drift(obj: Objective, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The residual's rate (noise units/s) between consecutive samples of one segment and channel, and the
    (experiment, sample) of each rate's later sample."""
    samples = _entry_samples(obj)
    fs = np.array([ex.fs for ex in obj.model.experiments])[samples[:, 0]]
    same = (obj.block_ids[1:] == obj.block_ids[:-1]) & (samples[1:, 1] - samples[:-1, 1] == 1)
    rate = np.diff(r) * fs[1:]
    return rate[same], samples[1:][same]


def _quantities(obj: Objective, samples: np.ndarray) -> dict[str, np.ndarray]:
    """The rig's state and input at every drift sample, by name: ``u``, ``omega_u``, ``omega_l``, ``alpha``,
    ``theta_u``, and ``step`` (within :data:`STEP_WINDOW_S` after an input step, as 0/1)."""
    names = ("u", "omega_u", "omega_l", "alpha", "theta_u", "step")
    per: dict[str, list[np.ndarray]] = {n: [] for n in names}
    for k, ex in enumerate(obj.model.experiments):
        u = ex.input_on_grid(1.0 / ex.fs, ex.n, ex.t[0])
        have = {"u": u, "omega_u": ex.rates["omega_u"], "theta_u": ex.meas["theta_u"], "step": _after_steps(u, ex.fs)}
        if "theta_l" in ex.meas:
            have.update(omega_l=ex.rates["omega_l"], alpha=ex.meas["theta_u"] - ex.meas["theta_l"])
        sel = samples[samples[:, 0] == k, 1]
        for n in names:
            per[n].append(have[n][sel] if n in have else np.full(len(sel), np.nan))
    order = np.argsort(samples[:, 0], kind="stable")
    back = np.empty_like(order)
    back[order] = np.arange(len(order))
    return {n: np.concatenate(v)[back] for n, v in per.items()}


def _after_steps(u: np.ndarray, fs: float) -> np.ndarray:
    """1.0 within :data:`STEP_WINDOW_S` after a step of the input, else 0.0."""
    lo, hi = np.percentile(u, [5, 95])
    jumps = np.flatnonzero(np.abs(np.diff(u)) > STEP_SHARE * max(hi - lo, 1e-9)) + 1
    out = np.zeros(len(u))
    w = max(1, int(round(STEP_WINDOW_S * fs)))
    for j in jumps:
        out[j : j + w] = 1.0
    return out


def _phases(drift: np.ndarray, q: dict[str, np.ndarray]) -> list[Phase]:
    """The phases holding at least :data:`CONCENTRATION` times their time share of the drift's mean square."""
    masks = {"steps": (f"in the first {STEP_WINDOW_S:g} s after input steps", q["step"] > 0.5)}
    if not np.all(np.isnan(q["omega_l"])):
        masks["lower_stick"] = ("where the lower disc sticks", np.abs(q["omega_l"]) < REST_SPEED)
        masks["lower_slip"] = ("where the lower disc slips", np.abs(q["omega_l"]) >= REST_SPEED)
    masks["upper_rest"] = ("where the upper disc is at rest", np.abs(q["omega_u"]) < REST_SPEED)
    total = float(np.sum(drift**2))
    out = []
    for name, (words, m) in masks.items():
        if total <= 0 or not 0 < m.mean() < 1:
            continue
        p = Phase(name, words, float(np.sum(drift[m] ** 2)) / total, float(m.mean()))
        if p.concentration >= CONCENTRATION:
            out.append(p)
    return sorted(out, key=lambda p: -p.concentration)


_DESCRIPTIONS = {
    "u": ("the voltage u", "V"),
    "omega_u": ("the upper disc's speed ωu", "rad/s"),
    "omega_l": ("the lower disc's speed ωl", "rad/s"),
    "alpha": ("the string's twist α = θu − θl", "rad"),
    "theta_u_mod_2pi": ("the motor angle θu mod 2π", "rad"),
}


def _dependences(drift: np.ndarray, q: dict[str, np.ndarray]) -> list[Dependence]:
    """The drift's dependence on each quantity the recordings have (:class:`Dependence`)."""
    values = {n: q[n] for n in ("u", "omega_u", "omega_l", "alpha")}
    values["theta_u_mod_2pi"] = np.mod(q["theta_u"], 2 * np.pi)
    out = []
    for name, x in values.items():
        ok = np.isfinite(x)
        if ok.sum() < 4 * N_BINS:
            continue
        if name == "theta_u_mod_2pi":
            edges = np.linspace(0.0, 2 * np.pi, ANGLE_BINS + 1)
        else:
            edges = np.unique(np.quantile(x[ok], np.linspace(0, 1, N_BINS + 1)))
        if len(edges) < 3:
            continue
        dep = _binned(drift[ok], x[ok], edges)
        if dep is not None:
            words, unit = _DESCRIPTIONS[name]
            out.append(Dependence(name, words, unit, *dep))
    return out


def _binned(d: np.ndarray, x: np.ndarray, edges: np.ndarray) -> tuple | None:
    """(explained, worst_lo, worst_hi, bins) of the drift ``d`` in bins of ``x`` (None: too few samples)."""
    b = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, len(edges) - 2)
    counts = np.bincount(b, minlength=len(edges) - 1).astype(float)
    sums = np.bincount(b, weights=d, minlength=len(edges) - 1)
    squares = np.bincount(b, weights=d**2, minlength=len(edges) - 1)
    used = counts > 0
    n, k = float(len(d)), int(used.sum())
    if k < 2 or n <= k:
        return None
    means = np.divide(sums, counts, out=np.zeros_like(sums), where=used)
    within = float(np.sum(squares - counts * means**2))
    total = float(np.sum((d - d.mean()) ** 2))
    explained = 1.0 - (within / (n - k)) / (total / (n - 1)) if total > 0 else 0.0
    ms = np.divide(squares, counts, out=np.zeros_like(squares), where=used)
    w = int(np.argmax(ms))
    bins = [(float(edges[i]), float(edges[i + 1]), float(means[i])) for i in range(len(edges) - 1) if used[i]]
    return max(0.0, explained), float(edges[w]), float(edges[w + 1]), bins
