"""An independent reference: the torsional rig as an event-driven switch model on scipy's ``solve_ivp``.

Written from docs/model.md alone (no drillgym code): the report's (3.19), (3.20)

    Ju θ̈u + Tfu(θ̇u) − kθ α = km u,      Jl θ̈l + Tfl(θ̇l) + kθ α = 0,      α = θl − θu,

with set-valued friction handled as Leine's switch model: each disc slips (+1 / −1, smooth law of
that sign) or sticks (speed exactly 0, the holding torque inside its stick set).  ``solve_ivp``
integrates each smooth phase with terminal events (a slipping disc's speed reaching zero, a stuck
disc's holding torque leaving its stick set); at an event the mode is switched and the integration
restarted.  A non-terminal event at ω̇l = 0 gives the lower disc's speed maxima exactly.

This is what a user writes in an afternoon; ``bench_single_vs_scipy.py`` times drillgym's single
trajectory against it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp

#: the parameter table of docs/model.md (torsional, brake on)
PARAMS = dict(
    Ju=0.4765,
    km=4.3228,
    Tcu=0.37975,
    dTcu=-0.00575,
    bu=2.4245,
    dbu=-0.0084,
    Jl=0.0414,
    ktheta=0.0775,
    Ts=0.2781,
    Tc=0.0473,
    ws=1.4302,
    delta=2.0575,
    bb=0.0105,
)


@dataclass
class SwitchRun:
    """Result of :func:`simulate_switch_model`: times and values of the local maxima of ωl (rad/s),
    the mode switches and the number of right-hand-side evaluations."""

    t_max: list = field(default_factory=list)
    omega_l_max: list = field(default_factory=list)
    n_switches: int = 0
    n_rhs: int = 0
    y_end: np.ndarray | None = None


def simulate_switch_model(
    u: float,
    duration: float,
    alpha0: float = 0.0,
    rtol: float = 1e-8,
    atol: float = 1e-10,
    method: str = "DOP853",
    prm: dict | None = None,
) -> SwitchRun:
    """Torsional rig from rest (twist alpha0, rad) under the constant command u (V) for duration s."""
    P = dict(PARAMS, **(prm or {}))
    Ju, km, Tcu, dTcu, bu, dbu = P["Ju"], P["km"], P["Tcu"], P["dTcu"], P["bu"], P["dbu"]
    Jl, kth, Ts, Tc, ws, delta, bb = P["Jl"], P["ktheta"], P["Ts"], P["Tc"], P["ws"], P["delta"], P["bb"]
    lo_u, hi_u = -Tcu + dTcu, Tcu + dTcu  # upper stick set (N m)
    lo_l, hi_l = -Ts, Ts  # lower stick set, brake on
    # a stuck disc is released just beyond its stick set (the root solver's answer may sit a rounding
    # error inside, where the slip law would at once stop the disc again)
    margin = 1e-10 * (Tcu + Ts)
    drive = km * u

    def tf_upper(w: float, d: int) -> float:  # (Tcu + ΔTcu d + bu|ω| + Δbu ω) d, continued with the mode's sign
        return d * (Tcu + dTcu * d + bu * d * w + dbu * w)

    def tf_lower(w: float, d: int) -> float:
        aw = abs(w)
        return d * (Tc + (Ts - Tc) * math.exp(-((aw / ws) ** delta)) + bb * aw)

    modes = [0, 0]

    def holding(y: np.ndarray) -> tuple[float, float]:
        """Torques (N m) friction must supply to keep each disc at rest."""
        a = y[1] - y[0]
        return drive + kth * a, -kth * a

    def rhs(t: float, y: np.ndarray) -> list:
        run.n_rhs += 1
        a = y[1] - y[0]
        mu, ml = modes
        du = (drive + kth * a - tf_upper(y[2], mu)) / Ju if mu else 0.0
        dl = (-kth * a - tf_lower(y[3], ml)) / Jl if ml else 0.0
        return [y[2], y[3], du, dl]

    def ev_upper(t: float, y: np.ndarray) -> float:
        if modes[0]:
            return modes[0] * y[2]  # slipping: signed speed reaches 0
        lam = holding(y)[0]
        return min(hi_u - lam, lam - lo_u) + margin  # stuck: holding torque leaves the stick set

    def ev_lower(t: float, y: np.ndarray) -> float:
        if modes[1]:
            return modes[1] * y[3]
        lam = holding(y)[1]
        return min(hi_l - lam, lam - lo_l) + margin

    def ev_peak(t: float, y: np.ndarray) -> float:  # ω̇l = 0 from above: a maximum of ωl
        return rhs(t, y)[3] if modes[1] else 1.0

    for ev in (ev_upper, ev_lower):
        ev.terminal = True
        ev.direction = -1
    ev_peak.terminal = False
    ev_peak.direction = -1

    def new_mode(lam: float, lo: float, hi: float) -> int:
        if lo <= lam <= hi:
            return 0
        return 1 if lam > hi else -1

    run = SwitchRun()
    y = np.array([0.0, alpha0, 0.0, 0.0])
    lam_u, lam_l = holding(y)
    modes[0] = new_mode(lam_u, lo_u, hi_u)
    modes[1] = new_mode(lam_l, lo_l, hi_l)
    t = 0.0
    while t < duration:
        sol = solve_ivp(
            rhs, (t, duration), y, method=method, rtol=rtol, atol=atol, events=(ev_upper, ev_lower, ev_peak)
        )
        if modes[1]:
            for tp, yp in zip(sol.t_events[2], sol.y_events[2]):
                run.t_max.append(float(tp))
                run.omega_l_max.append(float(yp[3]))
        t = float(sol.t[-1])
        y = sol.y[:, -1].copy()
        if sol.status != 1:  # reached the end
            break
        hit = [j for j in (0, 1) if len(sol.t_events[j])]
        for j in hit:
            y = sol.y_events[j][0].copy()
            t = float(sol.t_events[j][0])
            lam = holding(y)[j]
            lo, hi = (lo_u, hi_u) if j == 0 else (lo_l, hi_l)
            if modes[j]:  # slipping disc reached zero speed: sticks, or reverses
                y[2 + j] = 0.0
                modes[j] = new_mode(lam, lo, hi)
            else:  # stuck disc released in the direction of the excess torque
                modes[j] = 1 if lam > hi else -1
            run.n_switches += 1
    run.y_end = y
    return run
