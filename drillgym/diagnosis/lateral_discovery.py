"""Discovery on the lateral side: the residual lateral force regressed on forces shaped by physics.

The residual lateral force on the lower disc's centre (:attr:`.sparse.ResidualTorque.force_X`, ``force_Y``: the
lateral rows of ``M(q) (q̈_data − q̈_model)``, turned into the fixed frame) is known where the lower disc slips.
The LVDTs' positions were low-passed (5 Hz, zero phase) before they were differentiated, so the residual holds
nothing above that band: the residual and every term are filtered alike, by the same zero-phase low-pass
(``LVDT_LOWPASS_HZ``) and a moving average of :data:`.discovery.SMOOTH_S` (a linear operation on both sides keeps
the regression's relation), and regressed with the rows of both components stacked, [FX; FY].

The terms outside the library (:func:`.lateral_terms.outside_terms`) enter by the same greedy forward selection as
the torque groups (:mod:`.greedy`), jointly with the base parameters' own columns (k, b, the unbalance e:
:func:`.lateral_terms.lateral_nuisance`) and the library lateral effects' shapes (anisotropy, dry friction), so
that a term explains only what the base and the library cannot; the group, ``lateral_force``, is ranked against
the torque groups by the same criterion (the share of its residual it explains).  The candidate is written as a
lateral ``Force`` effect (:func:`.effect_file.write_effect_file`).
"""

from __future__ import annotations

import numpy as np

from ..identification.experiment import estimate_rate
from ..measurement import lowpass_zero_phase
from .candidate import Candidate
from .greedy import MAX_CANCEL, greedy_terms
from .lateral_terms import (
    CONSTANT_FORCES,
    LIBRARY_SHAPES,
    LateralTerm,
    lateral_nuisance,
    lateral_terms,
    outside_terms,
)
from .sparse import ResidualTorque

__all__ = ["LATERAL_GROUP", "LVDT_LOWPASS_HZ", "lateral_candidate", "lateral_data"]

#: the group's name among discovery's groups
LATERAL_GROUP = "lateral_force"
#: the LVDTs' low-pass (Hz, zero phase) the residual and the terms are filtered by alike
LVDT_LOWPASS_HZ = 5.0
#: fewest samples with a known lateral balance
MIN_SAMPLES = 50


def lateral_data(rt: ResidualTorque) -> dict[str, np.ndarray]:
    """The data the lateral terms are functions of, at every sample: the centre's position and velocity in the
    fixed frame (``X``, ``Y`` m; ``VX``, ``VY`` m/s), the lower disc's
    angle, speed and acceleration (``thl`` rad, ``wl`` rad/s, ``dwl`` rad/s²) and the model's brake torque on it
    (``Tfl`` N m; 0 where the brake is off or the torque is not known).

    Parameters
    ----------
    rt : ResidualTorque
        The residual forces and the data's states (rotating-frame x, y, vx, vy).

    Returns
    -------
    dict of str to numpy.ndarray
        The data by name.
    """
    S = rt.states
    fs = 1.0 / float(np.median(np.diff(rt.t)))
    c, s = np.cos(S[:, 0]), np.sin(S[:, 0])
    x, y, W = S[:, 4], S[:, 5], S[:, 2]
    vx, vy = S[:, 6] - W * y, S[:, 7] + W * x  # the centre's velocity, rotating-frame components
    d = {
        "X": x * c - y * s,
        "Y": x * s + y * c,
        "VX": vx * c - vy * s,
        "VY": vx * s + vy * c,
        "thl": S[:, 1],
        "wl": S[:, 3],
        "dwl": estimate_rate(S[:, 3], fs, window_s=0.1),
        "Tfl": np.zeros(S.shape[0]) if rt.friction_l is None else np.nan_to_num(rt.friction_l),
    }
    return d


def lateral_candidate(
    rt: ResidualTorque, smooth_s: float = 0.3, terms: list[LateralTerm] | None = None, library: bool = True
) -> Candidate | None:
    """The lateral group's candidate for some residual forces (see the module docstring).

    Parameters
    ----------
    rt : ResidualTorque
        The residual torques and lateral forces (coupled or lateral configuration).
    smooth_s : float, optional
        The moving average's length (s) after the LVDTs' low-pass.  Default 0.3 (:data:`.discovery.SMOOTH_S`).
    terms : list of LateralTerm, optional
        The terms tried (default: :func:`.lateral_terms.outside_terms`, those outside the library).
    library : bool, optional
        Regress jointly with the library lateral effects' shapes too (:data:`.lateral_terms.LIBRARY_SHAPES`:
        the library has effects for them; default), not only with the base parameters' columns.

    Returns
    -------
    Candidate or None
        The ``lateral_force`` candidate (its coefficients in N per unit of each term, the share of the residual
        force beyond the base parameters' columns it explains), or None when the disc does not move laterally,
        too few samples have a known balance or no term explains enough.
    """
    if rt.force_X is None or rt.force_Y is None:
        return None
    ok = rt.lower_valid & np.isfinite(rt.force_X) & np.isfinite(rt.force_Y)
    if ok.sum() < MIN_SAMPLES:
        return None
    FX, FY = np.where(ok, rt.force_X, 0.0), np.where(ok, rt.force_Y, 0.0)
    # outliers (> 8 SDs of either component) are left out: not robust SDs, the force of a stiffening spring or of
    # a stop is large in the few samples of large orbits and near zero in most
    sc = float(np.std(np.concatenate([FX[ok], FY[ok]])))
    if sc > 0:
        ok = ok & (np.abs(FX - np.median(FX[ok])) < 8 * sc) & (np.abs(FY - np.median(FY[ok])) < 8 * sc)
    w = ok.astype(float)
    fs = 1.0 / float(np.median(np.diff(rt.t)))
    m = max(1, int(round(smooth_s * fs)))
    low = LVDT_LOWPASS_HZ < 0.5 * fs and rt.t.size > 30

    def filt(v: np.ndarray) -> np.ndarray:
        """The LVDTs' low-pass and the moving average, on the full grid (weight-0 samples enter as 0), then the
        rows used."""
        v = lowpass_zero_phase(w * v, fs, LVDT_LOWPASS_HZ) if low else w * v
        if m > 1:
            v = np.convolve(v, np.ones(m) / m, mode="same")
        return v[ok]

    def pair(fx: np.ndarray, fy: np.ndarray) -> np.ndarray:
        return np.concatenate([filt(np.asarray(fx, float)), filt(np.asarray(fy, float))])

    d = lateral_data(rt)
    y = pair(FX, FY)
    joint = [pair(*col) for col in lateral_nuisance(d, 1.0)]
    if library:
        joint += [pair(*t.values(d)) for t in lateral_terms() if t.label in LIBRARY_SHAPES]
    offset = "lvdt_offset" in rt.effects
    if offset:  # the model's LVDT offset reads as a constant force (F / k): its columns
        joint += [pair(*t.values(d)) for t in lateral_terms() if t.label in CONSTANT_FORCES]
    Q, _ = np.linalg.qr(np.column_stack(joint))

    def project(v: np.ndarray) -> np.ndarray:
        return v - Q @ (Q.T @ v)

    yr = project(y)
    tss = float(yr @ yr) or 1.0
    terms = outside_terms() if terms is None else list(terms)
    if offset:
        terms = [t for t in terms if t.label not in CONSTANT_FORCES]
    raw = [pair(*tm.values(d)) for tm in terms]
    chosen, share = greedy_terms([project(c) for c in raw], yr, tss)
    if not chosen:
        return None
    X = np.column_stack([raw[j] for j in chosen])
    # the file's coefficients: the joint ones, beside the base's columns (a stiffening spring's linear part is k's:
    # where the diagnosis took k to its bound for it, the terms alone would take the opposite sign); the
    # candidate's fit holds the base at nominal too when the diagnosis left it at a bound
    coef, *_ = np.linalg.lstsq(np.column_stack([X, Q]), y, rcond=None)
    coef = coef[: len(chosen)]
    constant = None
    if offset:  # the constant force beside the terms, in N: the model's offset takes it (Candidate.constant_force)
        raw_nuisance = np.column_stack([X, *joint])  # the constant forces' columns last
        full, *_ = np.linalg.lstsq(raw_nuisance, y, rcond=None)
        constant = (float(full[-2]), float(full[-1]))
    # the terms cancel each other (their parts beside the base's and the model's columns): not a usable candidate
    # (the raw columns would count a part the nuisance takes: a brake torque's mean beside an LVDT offset)
    if np.any(np.abs(coef) * np.linalg.norm(project(X), axis=0) > MAX_CANCEL * np.linalg.norm(y)):
        return None
    res_rms = float(np.sqrt(np.mean(np.concatenate([FX[ok], FY[ok]]) ** 2)))
    reach = {}
    for j in chosen:
        gx, gy = terms[j].values(d)
        size = float(np.sqrt(np.mean(np.concatenate([gx[ok], gy[ok]]) ** 2)))
        reach[terms[j].label] = res_rms / max(size, 1e-300)
    return Candidate(
        LATERAL_GROUP,
        {terms[j].label: float(coef[i]) for i, j in enumerate(chosen)},
        {terms[j].label: terms[j].code for j in chosen},
        {terms[j].label: 0.0 for j in chosen},
        share,
        int(ok.sum()),
        reach=reach,
        constant_force=constant,
    )
