"""Discovery beyond the library: a candidate effect from the residual torques, written as an effect file.

After the selection (:mod:`.forward`), what the model still misses is read from the residual
generalised torques on BOTH discs (:func:`.sparse.residual_torques`: the data's accelerations
against the model's in the data's state, times the inertia or mass matrix; lateral forces enter
through the mass matrix in the coupled configuration), each disc's where that disc slips, whatever the
other one does (an upper-disc friction shows while the lower disc is stuck).  The residual is regressed, in
acceleration units (each disc's torque divided by its inertia, so that both discs weigh alike),
on a library of terms shaped by physics, grouped by where they would act:

* ``lower_friction`` / ``upper_friction``: a change of a disc's slip torque, odd in its speed ω:
  sign(ω), ω, ω|ω|, ω³, sign(ω) exp(−|ω|/v) and sign(ω) exp(−(ω/v)²) for speeds v of the
  Stribeck range, sign(ω) cos/sin of the disc angle (once and twice per revolution), sign(ω) t;
* ``string``: a torque added to kθ α: α|α|, α³, α⁵, saturation sat(α, g) (free play / dead zone:
  kθ (dz(α) − α) = −kθ sat(α, g)), α̇, sign(α̇);
* ``lower_force`` / ``upper_force``: constant, cos/sin of the disc angle, time; on the upper disc the
  harmonics cos/sin kθu of the motor angle (cogging, :data:`.discovery_terms.COGGING_HARMONICS`);
* ``motor_voltage``: a change of the voltage the motor sees, as a function of the voltage: 1 (an offset),
  sign(u), |u|,
  u|u|, u³ (a motor constant that depends on the voltage), sat(u, u0) for scanned widths u0 (a dead zone
  is −sat(u, u0)); regressed as the torque km × (the change) on the upper disc, written as an Input effect.
* ``lateral_force`` (lateral and coupled configurations): a force on the lower disc's centre, regressed on the
  residual lateral force (:mod:`.lateral_discovery`, terms :mod:`.lateral_terms`: springs and damping shaped by
  the radius and the speed, anisotropy, a constant force, a force turning with the disc), written as a lateral
  Force effect.

Each group's terms enter by greedy forward selection (at most ``MAX_TERMS``, each one must
explain ``MIN_GAIN`` more of the residual's variance); the group that explains most wins.  The
candidate is written as a Python effect file of the open-effect mechanism (:func:`write_effect_file`:
a ``Friction`` with ``slip`` and ``stick`` for friction groups, an ``Input`` for the voltage, a ``Force``
otherwise), with the
regressed coefficients as guesses and bounds of ±4 times their size, so that
``drillgym identify --add-effect FILE.py:NAME`` fits it.  What a sensor reads (a scale error, an offset, free
play between an encoder's shaft and its disc) is no torque and cannot be regressed here: :mod:`.sensor_reading`
tries each sensor's reading by its own fit.
When nothing explains the residual,
:func:`advice` says which experiment would show more.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..effects import Composition
from ..identification.experiment import Experiment
from ..params import N_PARAMS, RigParams
from .discovery_terms import _SENSE, _groups, _Term, odd_form
from .effect_file import write_effect_file
from .effects import get_effect, label_effects
from .greedy import MAX_CANCEL, greedy_terms, with_quadratures
from .lateral_discovery import LATERAL_GROUP, lateral_candidate
from .library_columns import LIBRARY_PREFIX, library_columns, library_view
from .results import Candidate
from .sparse import ResidualTorque
from .state import transfer
from .timing import LAG_DELAY
from .unexplained import EXPLAINED_RATIO

__all__ = ["Candidate", "find_candidate", "write_effect_file", "advice", "discover", "MIN_EXPLAINED_SHARE"]

SMOOTH_S = 0.3  # s: moving average of the residual torques and the terms before the regression
MIN_EXPLAINED_SHARE = 0.3  # a candidate must explain at least this share of the residual torque
#: the groups on the motor side: the best of them is kept beside a better-regressed candidate elsewhere, and the
#: candidates' own fits decide (each group is regressed on its own disc's rows, so shares of different discs
#: compare residuals of different sizes)
MOTOR_GROUPS = ("motor_voltage", "upper_force")


def _data(rt: ResidualTorque, u: np.ndarray) -> dict[str, np.ndarray]:
    S = rt.states
    return {
        "thu": S[:, 0],
        "thl": S[:, 1],
        "wu": S[:, 2],
        "wl": S[:, 3],
        "a": S[:, 1] - S[:, 0],
        "ad": S[:, 3] - S[:, 2],
        "t": rt.t,
        "u": u,
    }


def _nuisance(d: dict, n: int, Ju: float, Jl: float, ws: float, delta: float) -> np.ndarray:
    """Columns a change of the base parameters would add to the residual (stacked [upper; lower],
    acceleration units): per-disc offsets, Coulomb sign(ω), viscous ω, the Stribeck shape (Ts), the
    motor constant (u), the inertias (the model's accelerations) and the string stiffness (α)."""
    z = np.zeros(n)
    up = lambda g: np.concatenate([g / Ju, z])  # noqa: E731
    lo = lambda g: np.concatenate([z, g / Jl])  # noqa: E731
    one = np.ones(n)
    strib = np.sign(d["wl"]) * np.exp(-(np.abs(d["wl"] / ws) ** delta))
    cols = [
        up(one),
        lo(one),
        up(np.sign(d["wu"])),
        up(d["wu"]),
        up(d["u"]),
        up(d["accu"]),
        lo(np.sign(d["wl"])),
        lo(d["wl"]),
        lo(strib),
        lo(d["accl"]),
        np.concatenate([d["a"] / Ju, -d["a"] / Jl]),
    ]
    return np.column_stack(cols)


def find_candidate(
    rt: ResidualTorque,
    u: np.ndarray,
    Ju: float,
    Jl: float,
    lateral: bool = False,
    ws: float = 1.4302,
    delta: float = 2.0575,
    km: float = 4.3228,
    base_columns: bool = True,
    only: tuple[str, ...] | None = None,
    library: dict[str, np.ndarray] | None = None,
    weights: dict[str, float] | None = None,
) -> Candidate | None:
    """The best candidate group and terms for some residual torques.

    Terms are regressed jointly with the columns a change of the base parameters would give, so a
    candidate explains only what the base parameters cannot; ``explained`` is its share of the residual
    left by those.

    Parameters
    ----------
    rt : ResidualTorque
        The residual torques on both discs.
    u : numpy.ndarray
        The input at their samples (V).
    Ju, Jl : float
        The discs' inertias (kg m²).
    lateral : bool, optional
        Whether the lower disc moves laterally (coupled configuration).  Default False.
    ws : float, optional
        The Stribeck law's speed (rad/s).
    delta : float, optional
        The Stribeck law's exponent.
    km : float, optional
        The motor constant (N m/V): a voltage change Δv is the torque km Δv on the upper disc.
    base_columns : bool, optional
        Regress jointly with the columns of a change of the base parameters (default).  Without them (only the
        lower disc's offset), a term may take what the base parameters could take unbounded but cannot within
        their ±12 % (a dead zone on one-signed voltages is a constant torque, Tcu's Coulomb term there too).
    only : tuple of str, optional
        Only these groups (default all).
    library : dict of str to numpy.ndarray, optional
        Library effects' columns (:func:`.library_columns.library_columns`), each effect regressed as a whole on
        the same rows; their shares are recorded in the candidate's :attr:`~.candidate.Candidate.rest` under
        :data:`.library_columns.LIBRARY_PREFIX`.
    weights : dict of str to float, optional
        A group's weight in the choice of the best (default 1): the squared misfit of the channels it acts on
        against the angles' (:func:`group_weights`), so that the shares of residuals of different sizes compare.

    Returns
    -------
    Candidate or None
        The candidate, or None if too few samples slip; a ``motor_voltage`` candidate's coefficients are in
        volts at the motor per unit of its terms.
    """
    prepared = _weighted_rows(rt, u, Ju, Jl)
    if prepared is None:
        return None
    d, ok, n, y, W, smooth = prepared
    y = smooth(W * y)
    # no constant torque on the upper disc among them: no base parameter re-identified where discovery runs
    # gives one (ΔTcu, the upper disc's Coulomb asymmetry, is held but in the upper configuration), and as a
    # nuisance it hid what a constant torque there stands for (a voltage offset, a dead zone on one-signed
    # voltages: km u0 = 1.7 N m for u0 = 0.4 V, where Tcu's ±12 % cover 0.05 N m)
    Nm = np.column_stack([smooth(c) for c in (W[:, None] * _nuisance(d, n, Ju, Jl, ws, delta)).T])[:, 1:]
    if not base_columns:
        Nm = Nm[:, :1]
    cands: dict[str, Candidate] = {}
    shares: dict[str, float] = {}
    groups = _groups(lateral, ws, delta)
    # each group is judged on the rows of the discs it acts on, and a both-disc group (the string) also on
    # each disc alone: a disc whose residual is noise (e.g. the upper disc's under voltage steps, which the
    # second derivative smears) must not hide a term the other disc shows clearly
    rowsets = {
        "upper": np.r_[np.ones(n, bool), np.zeros(n, bool)],
        "lower": np.r_[np.zeros(n, bool), np.ones(n, bool)],
        "both": np.ones(2 * n, bool),
    }
    for where, rows in rowsets.items():
        Wr = W * rows
        if not np.any(Wr > 0):
            continue
        Q, _ = np.linalg.qr(Nm * rows[:, None])

        def project(v: np.ndarray, Q: np.ndarray = Q) -> np.ndarray:
            return v - Q @ (Q.T @ v)

        yr = project(y * rows)
        tss = float(yr @ yr) or 1.0
        for effect, block in (library or {}).items():
            cols = [project(rows * smooth(W * _accelerations(c, ok, Ju, Jl))) for c in block.T]
            key = LIBRARY_PREFIX + effect
            shares[key] = max(shares.get(key, 0.0), _share(np.column_stack(cols), yr, tss))
        for group, terms in groups.items():
            if only is not None and group not in only:
                continue
            su, sl = _SENSE[group]
            acts = {"upper": su != 0, "lower": sl != 0, "both": su != 0 and sl != 0}[where]
            if not acts:
                continue
            cols = [
                project(rows * smooth(W * np.concatenate([su * g / Ju, sl * g / Jl])))
                for g in (np.asarray(tm.values(d), dtype=float) for tm in terms)
            ]
            chosen, share = greedy_terms(cols, yr, tss)
            chosen = with_quadratures(chosen, [t.label for t in terms])
            shares[group] = max(shares.get(group, 0.0), share)
            if chosen and (group not in cands or share > cands[group].explained):
                # the file's coefficients: the terms alone (with per-disc offsets), as the effect will act on the
                # model as it is; the joint regression above only decides which terms and how much they explain
                raw = [
                    rows
                    * smooth(
                        W
                        * np.concatenate(
                            [
                                su * np.asarray(terms[j].values(d), float) / Ju,
                                sl * np.asarray(terms[j].values(d), float) / Jl,
                            ]
                        )
                    )
                    for j in chosen
                ]
                coef = _alone_coefficients(raw, Nm, rows, y)
                if coef is None:
                    continue  # the terms alone cancel each other: not a usable candidate
                cands[group] = Candidate(
                    group,
                    {terms[j].label: float(coef[i]) for i, j in enumerate(chosen)},
                    {terms[j].label: terms[j].code for j in chosen},
                    {terms[j].label: terms[j].at_rest for j in chosen},
                    share,
                    n,
                    widths={terms[j].label: terms[j].width for j in chosen if terms[j].width is not None},
                )
    for c in cands.values():  # a library effect on the other disc is no answer to it, but may be missing beside it
        c.rest, c.beside = library_view(shares, library or {}, n, _SENSE[c.group])
        _set_reach(c, rt, d, ok, W, n, groups[c.group])
        if c.group == "motor_voltage":  # the torque km Δv on the upper disc -> the voltage change Δv (V)
            c.terms = {k: v / km for k, v in c.terms.items()}
            c.reach = {k: v / km for k, v in c.reach.items()}
            odd_form(c, u)
    lat = lateral_candidate(rt) if lateral and (only is None or LATERAL_GROUP in only) else None
    if lat is not None:  # the residual lateral force, regressed on its own terms (.lateral_discovery)
        shares[LATERAL_GROUP] = lat.explained
        cands[LATERAL_GROUP], lat.rest = lat, shares
    if not cands:
        return None
    weight = weights or {}
    best = max(cands.values(), key=lambda c: c.explained * weight.get(c.group, 1.0))
    motor = [c for g, c in cands.items() if g in MOTOR_GROUPS and c.explained >= MIN_EXPLAINED_SHARE]
    if best.group not in MOTOR_GROUPS and motor:  # the motor side's best, fitted beside it (.candidate_fit)
        best.alternative = max(motor, key=lambda c: c.explained)
    return best


def group_weights(unexplained) -> dict[str, float]:
    """The lateral group's weight in the choice of the best group: (the LVDTs' misfit / the angles'), squared.

    Each group's share is of its own residual (the lateral force's, a disc's torque); where the LVDTs are left at
    30-100 noise units and the encoders at 2, a torque group explaining half of its residual removes far less of
    the misfit than a lateral one explaining a third of its own (an independent rig's brake pad: a lower-friction
    term at 35-58 % of the torque residual was proposed while the LVDTs stayed at 30-100 noise units).

    Parameters
    ----------
    unexplained : Unexplained or None
        The diagnosis' final residual in noise units per channel.

    Returns
    -------
    dict of str to float
        ``{LATERAL_GROUP: weight}``, or empty (no residual, or no LVDT or angle channel).
    """
    if unexplained is None:
        return {}
    ch = unexplained.channels
    lvdt = max((ch[c] for c in ("x", "y") if c in ch), default=None)
    angles = max((ch[c] for c in ("theta_u", "theta_l", "alpha") if c in ch), default=None)
    if lvdt is None or not angles:
        return {}
    return {LATERAL_GROUP: (lvdt / angles) ** 2}


def _weighted_rows(rt: ResidualTorque, u: np.ndarray, Ju: float, Jl: float):
    """The regression's rows: (state data of the rows used, their mask, their count, the residual in
    acceleration units [upper; lower], each row's weight, the moving average over each disc's rows), or None
    when too few samples slip."""
    from ..identification.experiment import estimate_rate

    fs = 1.0 / float(np.median(np.diff(rt.t)))
    full = _data(rt, u)
    # each disc's rows where its own torque balance is known (the upper disc's also while the lower one is
    # stuck: an upper-disc effect on a recording whose lower disc hardly turns); unknown torques enter as 0
    # with weight 0
    ok_u, ok_l = rt.upper_valid, rt.lower_valid
    tau_u, tau_l = np.where(ok_u, rt.tau_u, 0.0), np.where(ok_l, rt.tau_l, 0.0)
    # the model's accelerations (an inertia change scales them): the data's minus the residual
    full["accu"] = estimate_rate(rt.states[:, 0], fs, window_s=0.1, deriv=2) - tau_u / Ju
    full["accl"] = estimate_rate(rt.states[:, 1], fs, window_s=0.1, deriv=2) - tau_l / Jl
    ok = ok_u | ok_l
    if ok.sum() < 50:
        return None
    d = {k: v[ok] for k, v in full.items()}
    n = int(ok.sum())
    # the upper disc's torque balance is unknown near its own speed reversals (the Coulomb torque jumps within
    # the second-derivative window): those rows are left out; each disc's rows are scaled by the robust size
    # of its residual (so that neither disc drowns the other) and outliers (> 8 robust SDs) are left out
    half = max(1, int(round(0.1 * fs)))
    slow_u = np.convolve((np.abs(full["wu"]) <= 0.05).astype(float), np.ones(2 * half + 1), mode="same") > 0
    y = np.concatenate([tau_u[ok] / Ju, tau_l[ok] / Jl])
    W = np.concatenate([(ok_u[ok] & ~slow_u[ok]).astype(float), ok_l[ok].astype(float)])
    for blk in (slice(0, n), slice(n, 2 * n)):
        v = y[blk][W[blk] > 0]
        sc = 1.4826 * float(np.median(np.abs(v - np.median(v)))) if v.size > 20 else 0.0
        if sc > 0:
            W[blk] = W[blk] * (np.abs(y[blk] - np.median(v)) < 8 * sc) / sc
        else:
            W[blk] = 0.0
    if not np.any(W > 0):
        return None
    # a moving average (``SMOOTH_S``) over each disc's rows, applied alike to the residual and to every column
    # (a linear operation on both sides keeps the regression's relation): the second derivative's noise is
    # high-frequency, the effects are smooth functions of the state
    m = max(1, int(round(SMOOTH_S * fs)))

    def smooth(v: np.ndarray) -> np.ndarray:
        if m <= 1:
            return v
        k = np.ones(m) / m
        return np.concatenate([np.convolve(v[:n], k, mode="same"), np.convolve(v[n:], k, mode="same")])

    return d, ok, n, y, W, smooth


def _accelerations(column: np.ndarray, ok: np.ndarray, Ju: float, Jl: float) -> np.ndarray:
    """A torque column on the full grid (upper disc's samples, then the lower's) on the regression's rows, in
    acceleration units."""
    n = ok.size
    return np.concatenate([column[:n][ok] / Ju, column[n:][ok] / Jl])


def _share(X: np.ndarray, yr: np.ndarray, tss: float) -> float:
    """The share of ``yr``'s variance the columns ``X`` explain together."""
    if not np.any(X):
        return 0.0
    c, *_ = np.linalg.lstsq(X, yr, rcond=None)
    return 1.0 - float(np.sum((yr - X @ c) ** 2)) / tss


def _alone_coefficients(raw: list[np.ndarray], Nm: np.ndarray, rows: np.ndarray, y: np.ndarray) -> np.ndarray | None:
    """The terms' coefficients regressed alone (with the lower disc's offset), or None when they cancel each
    other."""
    X = np.column_stack(raw + [Nm[:, 0] * rows])  # the lower disc's offset
    coef, *_ = np.linalg.lstsq(X, y * rows, rcond=None)
    k = len(raw)
    if np.any(np.abs(coef[:k]) * np.linalg.norm(X[:, :k], axis=0) > MAX_CANCEL * np.linalg.norm(y * rows)):
        return None
    return coef


def _set_reach(
    best: Candidate, rt: ResidualTorque, d: dict, ok: np.ndarray, W: np.ndarray, n: int, terms: list[_Term]
) -> None:
    """Each term's coefficient that would make it alone as large as the residual torque (``best.reach``)."""
    su, sl = _SENSE[best.group]
    res_rms = float(
        np.sqrt(
            np.mean(
                np.concatenate(
                    ([(rt.tau_l[ok][W[n:] > 0]) ** 2] if sl else []) + ([(rt.tau_u[ok][W[:n] > 0]) ** 2] if su else [])
                )
            )
        )
    )
    for tm in terms:
        if tm.label in best.terms:
            g = np.asarray(tm.values(d), dtype=float)
            best.reach[tm.label] = res_rms / max(float(np.sqrt(np.mean(g**2))), 1e-12)


def advice(ex: Experiment, rt: ResidualTorque | None) -> list[str]:
    """Which experiments would show more, from what the recording does not cover.

    Parameters
    ----------
    ex : Experiment
        The recording.
    rt : ResidualTorque or None
        Its residual torques.

    Returns
    -------
    list of str
        The advice.
    """
    out = []
    wl = ex.rates.get("omega_l", np.zeros(ex.n))
    if np.mean(wl < -0.1) < 0.05:
        out.append(
            "the lower disc hardly turns backwards: an input around 0 V (offset 0, amplitude >= 3 V) shows "
            "direction-dependent friction"
        )
    if rt is not None and np.mean(np.sign(rt.states[:, 1] - rt.states[:, 0]) < 0) < 0.05:
        out.append(
            "the string's twist α hardly changes sign: an input around 0 V (offset 0) that winds the string "
            "both ways shows free play or a non-linear string near zero twist"
        )
    if np.percentile(np.abs(wl), 95) < 3.0:
        out.append(
            "the lower disc stays below 3 rad/s: slow ramps up to 4-5 V cover the Stribeck range and viscous terms"
        )
    if "theta_l" in ex.meas and abs(ex.meas["theta_l"][-1] - ex.meas["theta_l"][0]) < 4 * math.pi:
        out.append(
            "the lower disc turns less than two revolutions: a longer run (several revolutions) shows "
            "angle-dependent effects"
        )
    if ex.duration < 40.0:
        out.append("a longer recording (60 s or more) separates slow drifts from noise")
    if not out:
        out.append(
            "the residual is not explained by any term of the candidate library: repeat the run to see "
            "whether it is reproducible (a disturbance, not a model error), or record at a higher rate"
        )
    return out


#: noise units: a model closer than this to the data on every channel leaves nothing to discover (the verdict's
#: *explained*: discovery looks wherever the diagnosis says a misfit remains)
MIN_RESIDUAL_UNITS = EXPLAINED_RATIO


def discover(
    ex: Experiment, diagnosis, candidate_out: str | Path | None = None, name: str | None = None
) -> tuple[Candidate | None, list[str]]:
    """The candidate effect for what the diagnosed model still misses.

    The model is the diagnosis' (selected effects, base parameters as decided); when the base parameters
    moved, the nominal base is looked at too (the base refit may have absorbed part of an effect outside the
    library).

    Parameters
    ----------
    ex : Experiment
        The recording, on a grid fine enough for its accelerations (the command line uses its own
        samples up to 250 Hz).
    diagnosis : Diagnosis
        The diagnosis of the recording.
    candidate_out : str or path, optional
        Where to write the candidate's effect file.
    name : str, optional
        The effect's name in it.

    Returns
    -------
    tuple of (Candidate or None, list of str)
        The candidate (None when the model fits to within a few noise units, or nothing explains enough of
        the residual torque) and, when none is found, the experiments that would show more.
    """
    from .sparse import residual_torques

    if diagnosis.vector is None or ex.config.label == "upper":
        return None, []
    residual = diagnosis.rmse_after if diagnosis.rmse_after is not None else diagnosis.rmse_before
    if diagnosis.unexplained is not None:
        # the worst channel in noise units, as the verdict judges (pooled, the encoders' smaller misfit hid the
        # LVDTs' residual of a lateral force that k and b took to their bounds; misfit-weighted units are ~1)
        residual = diagnosis.unexplained.worst
    if residual < MIN_RESIDUAL_UNITS:
        return None, []
    vectors = [diagnosis.vector]
    if (diagnosis.base_parameters or diagnosis.base_off) and diagnosis.nominal_vector is not None:
        # the base refit may have absorbed part of an effect outside the library: look at the nominal base too
        vectors.append(diagnosis.nominal_vector)
    cand, rt, lib = None, None, None
    held = (*label_effects(diagnosis.model), *diagnosis.selected)  # what the model holds
    weights = group_weights(diagnosis.unexplained)
    for vec in vectors:
        rt_v = residual_torques(ex, vec, effects=diagnosis.composition)
        rt_v.effects = held
        p = RigParams.from_vector(vec[:N_PARAMS])  # the inertias and brake law of the model that left it
        # the library's torque effects the model lacks, regressed beside the terms (.library_columns): their
        # torques per unit of their parameters hardly depend on the base parameters, taken once at the diagnosis'
        if lib is None and diagnosis.composition is not None:
            lib = library_columns(ex, diagnosis.composition, vec, list(held), rt_v)  # in the model: not offered
        # the voltage terms are functions of the voltage the model's motor sees (after its delay and lag)
        c = find_candidate(
            rt_v, rt_v.u_motor, p.Ju, p.Jl, ex.config.lateral_free, p.ws, p.delta, p.km, library=lib, weights=weights
        )
        if c is not None and (cand is None or c.explained > cand.explained):
            cand, rt = c, rt_v
        rt = rt if rt is not None else rt_v
    if diagnosis.unexplained is not None and not diagnosis.unexplained.explained:
        cand = _with_motor_side(cand, ex, diagnosis)
    if cand is None or cand.explained < MIN_EXPLAINED_SHARE or residual < MIN_RESIDUAL_UNITS:
        if residual < MIN_RESIDUAL_UNITS:
            return None, []
        return None, advice(ex, rt)
    if candidate_out is not None:
        write_effect_file(cand, candidate_out, name)
    return cand, []


def _with_motor_side(cand: Candidate | None, ex: Experiment, diagnosis) -> Candidate | None:
    """The candidate, with the motor side's best regressed without the base parameters' columns beside it (its
    :attr:`~.results.Candidate.alternative`, in place of the joint regression's motor-side one when it was found
    through a lag or explains more; the candidates' own fits decide), or that one when there is none."""
    motor = _motor_side_candidate(ex, diagnosis)
    if motor is None or motor.explained < MIN_EXPLAINED_SHARE:
        return cand
    if cand is None or cand.explained < MIN_EXPLAINED_SHARE:
        return motor
    if motor.terms == cand.terms and motor.through_lag is None:
        return cand
    alt = cand.alternative
    if alt is None or motor.through_lag is not None or motor.explained > alt.explained:
        cand.alternative = motor
    return cand


#: first-order lags (s) the motor side's terms are also regressed through when the model has no lag or delay
LAGS_TRIED = (0.005, 0.01, 0.02, 0.04, 0.08, 0.16)


def _motor_side_candidate(ex: Experiment, diagnosis) -> Candidate | None:
    """The motor side's best candidate on the diagnosed model's residual torques and, when that model has neither
    a motor lag nor an input delay, on those of the model with a lag of each of :data:`LAGS_TRIED` ahead of the
    terms (the candidate's :attr:`~.results.Candidate.through_lag`): a voltage transformation seen through an
    unselected lag is not a function of the commanded voltage (a dead zone after a 20 ms lag on steps looks like
    upper-disc friction there).  The lag is kept when its candidate leaves less than :data:`LAG_KEPT_SHARE` of the
    residual power the one without leaves.  When the diagnosis left a base parameter at a bound of its range, the
    model with the nominal base parameters is looked at too (the bound may have absorbed the motor side: a
    voltage offset on ramps takes the motor constant 12 % off, to its bound)."""
    from .sparse import residual_torques

    comp, vec = diagnosis.composition or Composition(()), diagnosis.vector
    models = [(None, comp, vec)]
    if not set(diagnosis.selected) & set(LAG_DELAY):
        # the search model holds the lag switched off (at its neutral values); a selection's model gets it added
        with_lag = (
            comp
            if "motor_lag" in {e.name for e in comp.effects}
            else Composition((*comp.effects, get_effect("motor_lag")))
        )
        for tau in LAGS_TRIED:
            v = transfer(vec, comp, with_lag)
            v[with_lag.param_index("tau_m")] = tau
            models.append((tau, with_lag, v))
    if diagnosis.at_bounds and diagnosis.nominal_vector is not None:
        models.append((None, comp, diagnosis.nominal_vector))
    best, best_left = None, math.inf
    for tau, c, v in models:
        p = RigParams.from_vector(v[:N_PARAMS])
        rt = residual_torques(ex, v, effects=c)
        motor = find_candidate(
            rt, rt.u_motor, p.Ju, p.Jl, ex.config.lateral_free, p.ws, p.delta, p.km, False, MOTOR_GROUPS
        )
        if motor is None:
            continue
        left = (1.0 - motor.explained) * _upper_power(rt)
        if tau is not None and best is not None and best.through_lag is None and left > LAG_KEPT_SHARE * best_left:
            continue
        if left < best_left:
            motor.through_lag = tau
            best, best_left = motor, left
    return best


#: a lag ahead of the motor side's terms is kept when its candidate leaves less than this share of the residual
#: power the candidate without a lag leaves (a lag is another parameter: it must explain clearly more)
LAG_KEPT_SHARE = 0.5


def _upper_power(rt) -> float:
    """The residual torque's mean square on the upper disc where it is known (N² m²)."""
    tau = rt.tau_u[rt.upper_valid]
    return float(np.mean(tau**2)) if tau.size else math.inf
