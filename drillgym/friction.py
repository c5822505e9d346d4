"""Set-valued friction laws of the rig (docs/model.md, "Friction laws").

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

Effects (:mod:`drillgym.effects`) change these laws through the composition's kernels
(level, shape, stick set); the laws here are the base model's.

The ``*_smooth`` functions are the explicit smoothed option (``tanh(w / eps)``
instead of ``sign``), never used unless asked for.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .params import RigParams
from .vmath import FASTMATH, vexp, vlog


# --- the laws on scalars (shared by the scalar kernel and the SIMD lane kernel) -------------
@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def upper_law(aw: float, d: float, Tcu: float, dTcu: float, bu: float, dbu: float) -> float:
    """Upper slip torque (N m) at speed magnitude aw (rad/s) in direction d (+1/-1; 0 gives 0)."""
    t_pos = Tcu + dTcu + (bu + dbu) * aw
    t_neg = -(Tcu - dTcu + (bu - dbu) * aw)
    return t_pos if d > 0 else (t_neg if d < 0 else 0.0)


def _make_brake_law(exp, log):
    """The Stribeck law with a given exp/log: libm for the scalar kernel (fastest on one value),
    the vectorisable :mod:`drillgym.vmath` versions for the SIMD lane kernel.  One formula."""

    @njit(inline="always", fastmath=FASTMATH, error_model="numpy")
    def brake_law(aw: float, d: float, Ts: float, Tc: float, ws: float, delta: float, bb: float) -> float:
        """Stribeck brake torque (N m) at speed magnitude aw in direction d (+1/-1; 0 gives 0)."""
        z = max(aw / ws, 1e-300)
        return d * (Tc + (Ts - Tc) * exp(-exp(delta * log(z))) + bb * aw)

    return brake_law


brake_law = _make_brake_law(math.exp, math.log)
brake_law_simd = _make_brake_law(vexp, vlog)


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def bearing_law(aw: float, d: float, Tcl: float, bl: float) -> float:
    """Bearing torque (N m, brake off) at speed magnitude aw in direction d (+1/-1; 0 gives 0)."""
    return d * (Tcl + bl * aw)


# ----------------------------------------------------------------- numpy helpers
def upper_friction(w: np.ndarray, params: RigParams | None = None) -> np.ndarray:
    """Upper slip friction torque Tfu(w) of the base law, vectorised.

    Parameters
    ----------
    w : ndarray
        Upper disc speed(s) (rad/s).
    params : RigParams, optional
        Base parameters; default the identified set.

    Returns
    -------
    ndarray
        Tfu (N m), shaped as ``w``; 0 at w = 0 (the stick set is not a value).
    """
    p = params or RigParams()
    w = np.asarray(w, dtype=float)
    out = np.empty(w.size)
    _upper_torques(np.ascontiguousarray(w).ravel(), p.Tcu, p.dTcu, p.bu, p.dbu, out)
    return out.reshape(w.shape)


def lower_friction(w: np.ndarray, params: RigParams | None = None, brake: bool = True) -> np.ndarray:
    """Lower slip friction torque Tfl(w) of the base law, vectorised.

    Parameters
    ----------
    w : ndarray
        Lower disc speed(s) (rad/s).
    params : RigParams, optional
        Base parameters; default the identified set.
    brake : bool, optional
        The brake's Stribeck law (True, default) or the bearing law (False).

    Returns
    -------
    ndarray
        Tfl (N m), shaped as ``w``; 0 at w = 0 (the stick set is not a value).
    """
    p = params or RigParams()
    w = np.asarray(w, dtype=float)
    out = np.empty(w.size)
    law = np.array([p.Ts, p.Tc, p.ws, p.delta, p.bb]) if brake else np.array([p.Tcl, p.bl])
    _lower_torques(np.ascontiguousarray(w).ravel(), brake, law, out)
    return out.reshape(w.shape)


@njit(cache=True, error_model="numpy")  # IEEE arithmetic: the same floats in a batch of any size
def _upper_torques(w, Tcu, dTcu, bu, dbu, out):
    """:func:`upper_law` at each speed of w (rad/s) into out (N m), the direction sign(w)."""
    for i in range(w.size):
        out[i] = upper_law(abs(w[i]), np.sign(w[i]), Tcu, dTcu, bu, dbu)


@njit(cache=True, error_model="numpy")
def _lower_torques(w, brake, law, out):
    """:func:`brake_law` (law: Ts, Tc, ws, delta, bb) or :func:`bearing_law` (law: Tcl, bl) at each speed of w
    (rad/s) into out (N m), the direction sign(w)."""
    for i in range(w.size):
        aw, d = abs(w[i]), np.sign(w[i])
        if brake:
            out[i] = brake_law(aw, d, law[0], law[1], law[2], law[3], law[4])
        else:
            out[i] = bearing_law(aw, d, law[0], law[1])


def lower_friction_slope(
    w: np.ndarray, params: RigParams | None = None, brake: bool = True, rel_step: float = 1e-6
) -> np.ndarray:
    """Linearised friction damping dTfl/dw at w != 0 by central differences.

    Parameters
    ----------
    w : ndarray
        Lower disc speed(s) (rad/s), not 0.
    params : RigParams, optional
        Base parameters; default the identified set.
    brake : bool, optional
        The brake's Stribeck law (True, default) or the bearing law (False).
    rel_step : float, optional
        Difference step relative to |w| (at least 1e-3 rad/s times it).

    Returns
    -------
    ndarray
        dTfl/dw (N m s/rad), shaped as ``w``.
    """
    w = np.asarray(w, dtype=float)
    h = rel_step * np.maximum(np.abs(w), 1e-3)
    return (lower_friction(w + h, params, brake) - lower_friction(w - h, params, brake)) / (2 * h)


def smooth_sign(w: np.ndarray, eps: float) -> np.ndarray:
    """tanh(w / eps): the explicit smoothed sign of the ``friction='smooth'`` option."""
    return np.tanh(np.asarray(w, dtype=float) / eps)
