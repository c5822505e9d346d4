"""Set-valued friction laws of the rig (MODEL.md "Friction laws").

Each law is split in two parts, which is what an exact (switch / event-driven)
treatment of stick needs:

* the slip torque ``T(|w|, d)`` for a disc slipping in direction ``d = +1/-1``,
  a smooth function of the speed magnitude, and
* the stick set ``[lo, hi]``: while the disc is stuck (w = 0 exactly) the
  friction torque is whatever keeps it at rest, as long as it stays in this set.

Laws (torques in N m, speeds in rad/s):

* upper disc, asymmetric Coulomb + viscous (3.4), (3.5):
  ``Tfu(w) = (Tcu + dTcu sign w + bu |w| + dbu w) sign w``, stick set
  ``[-Tcu + dTcu, Tcu + dTcu]``
* lower disc, bearing (brake off) (3.10), (3.11):
  ``Tfl(w) = (Tcl + bl |w|) sign w``, stick set ``[-Tcl, Tcl]``
* lower disc, brake on, Stribeck (3.21), (3.22):
  ``Tfl(w) = (Tc + (Ts - Tc) exp(-|w/ws|^delta) + bb |w|) sign w``, stick set ``[-Ts, Ts]``

Lower-disc extensions of the effect library act on the whole lower law as a
level factor ``g = (1 + pf_a1 cos(theta_l - pf_phi1) + pf_a2 cos(2 theta_l - pf_phi2)) (1 + drift t)``
and, for negative rotation of the brake, ``Ts (1 + asym_s)``, ``Tc (1 + asym_c)``.

The ``*_smooth`` functions are the explicit smoothed option (``tanh(w / eps)``
instead of ``sign``), never used unless asked for.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .params import IDX, RigParams
from .vmath import vexp, vlog

_Tcu, _dTcu, _bu, _dbu = IDX.Tcu, IDX.dTcu, IDX.bu, IDX.dbu
_Tcl, _bl = IDX.Tcl, IDX.bl
_Ts, _Tc, _ws, _delta, _bb = IDX.Ts, IDX.Tc, IDX.ws, IDX.delta, IDX.bb
_pf_a1, _pf_phi1, _pf_a2, _pf_phi2 = IDX.pf_a1, IDX.pf_phi1, IDX.pf_a2, IDX.pf_phi2
_asym_s, _asym_c, _drift = IDX.asym_s, IDX.asym_c, IDX.drift


# --- the laws on scalars (shared by the scalar kernel and the SIMD lane kernel) -------------
@njit(inline="always", fastmath=True, error_model="numpy")
def upper_law(aw: float, d: float, Tcu: float, dTcu: float, bu: float, dbu: float) -> float:
    """Upper slip torque (N m) at speed magnitude aw (rad/s) in direction d (+1/-1; 0 gives 0)."""
    t_pos = Tcu + dTcu + (bu + dbu) * aw
    t_neg = -(Tcu - dTcu + (bu - dbu) * aw)
    return t_pos if d > 0 else (t_neg if d < 0 else 0.0)


def _make_brake_law(exp, log):
    """The Stribeck law with a given exp/log: libm for the scalar kernel (fastest on one value),
    the vectorisable :mod:`drillgym.vmath` versions for the SIMD lane kernel.  One formula."""

    @njit(inline="always", fastmath=True, error_model="numpy")
    def brake_law(aw: float, d: float, Ts: float, Tc: float, ws: float, delta: float, bb: float,
                  asym_s: float, asym_c: float) -> float:
        """Stribeck brake torque (N m) at speed magnitude aw in direction d (+1/-1; 0 gives 0);
        for d < 0 the levels are scaled by (1 + asym_s), (1 + asym_c) (brake_asymmetry)."""
        neg = 1.0 if d < 0 else 0.0
        ts = Ts * (1.0 + asym_s * neg)
        tc = Tc * (1.0 + asym_c * neg)
        z = max(aw / ws, 1e-300)
        return d * (tc + (ts - tc) * exp(-exp(delta * log(z))) + bb * aw)

    return brake_law


brake_law = _make_brake_law(math.exp, math.log)
brake_law_simd = _make_brake_law(vexp, vlog)


@njit(inline="always", fastmath=True, error_model="numpy")
def bearing_law(aw: float, d: float, Tcl: float, bl: float) -> float:
    """Bearing torque (N m, brake off) at speed magnitude aw in direction d (+1/-1; 0 gives 0)."""
    return d * (Tcl + bl * aw)


# --- the laws on the kernel's parameter vector ----------------------------------------------
@njit(cache=True, _nrt=False)
def upper_slip_torque(w: float, d: int, p: np.ndarray) -> float:
    """Upper friction torque (N m) while slipping in direction d (sign of the result is d)."""
    return upper_law(abs(w), float(d), p[_Tcu], p[_dTcu], p[_bu], p[_dbu])


@njit(cache=True, _nrt=False)
def upper_stick_bounds(p: np.ndarray) -> tuple:
    """Stick set of the upper disc (N m): (lo, hi)."""
    return -p[_Tcu] + p[_dTcu], p[_Tcu] + p[_dTcu]


@njit(cache=True, fastmath=True, _nrt=False)
def lower_level_factor(theta_l: float, t: float, p: np.ndarray) -> float:
    """Multiplicative level of the lower friction law: position dependence and drift (1 when off)."""
    g = 1.0
    if p[_pf_a1] != 0.0 or p[_pf_a2] != 0.0:
        g += p[_pf_a1] * math.cos(theta_l - p[_pf_phi1]) + p[_pf_a2] * math.cos(2.0 * theta_l - p[_pf_phi2])
    if p[_drift] != 0.0:
        g *= 1.0 + p[_drift] * t
    return g


@njit(cache=True, _nrt=False)
def lower_slip_torque(w: float, d: int, theta_l: float, t: float, p: np.ndarray, brake: bool) -> float:
    """Lower friction torque (N m) while slipping in direction d (brake: Stribeck law, else bearing)."""
    aw = abs(w)
    if brake:
        law = brake_law(aw, float(d), p[_Ts], p[_Tc], p[_ws], p[_delta], p[_bb], p[_asym_s], p[_asym_c])
    else:
        law = bearing_law(aw, float(d), p[_Tcl], p[_bl])
    return lower_level_factor(theta_l, t, p) * law


@njit(cache=True, _nrt=False)
def lower_stick_bounds(theta_l: float, t: float, p: np.ndarray, brake: bool) -> tuple:
    """Stick set of the lower disc (N m): (lo, hi)."""
    g = lower_level_factor(theta_l, t, p)
    if brake:
        return -g * p[_Ts] * (1.0 + p[_asym_s]), g * p[_Ts]
    return -g * p[_Tcl], g * p[_Tcl]


# ----------------------------------------------------------------- numpy helpers
def upper_friction(w: np.ndarray, params: RigParams | None = None) -> np.ndarray:
    """Upper slip friction torque Tfu(w) for w != 0 (0 returned at w = 0), vectorised."""
    p = (params or RigParams()).to_vector()
    w = np.asarray(w, dtype=float)
    return np.vectorize(lambda v: upper_slip_torque(v, int(np.sign(v)), p) if v != 0 else 0.0)(w)


def lower_friction(w: np.ndarray, params: RigParams | None = None, brake: bool = True,
                   theta_l: float = 0.0, t: float = 0.0) -> np.ndarray:
    """Lower slip friction torque Tfl(w) for w != 0 (0 returned at w = 0), vectorised."""
    p = (params or RigParams()).to_vector()
    w = np.asarray(w, dtype=float)
    return np.vectorize(
        lambda v: lower_slip_torque(v, int(np.sign(v)), theta_l, t, p, brake) if v != 0 else 0.0
    )(w)


def lower_friction_slope(w: np.ndarray, params: RigParams | None = None, brake: bool = True,
                         rel_step: float = 1e-6) -> np.ndarray:
    """Linearised friction damping dTfl/dw (N m s/rad) at w != 0 by central differences."""
    w = np.asarray(w, dtype=float)
    h = rel_step * np.maximum(np.abs(w), 1e-3)
    return (lower_friction(w + h, params, brake) - lower_friction(w - h, params, brake)) / (2 * h)


def smooth_sign(w: np.ndarray, eps: float) -> np.ndarray:
    """tanh(w / eps): the explicit smoothed sign of the ``friction='smooth'`` option."""
    return np.tanh(np.asarray(w, dtype=float) / eps)
