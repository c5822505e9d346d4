"""The ``observer``, ``lqg`` and ``lqg-2enc`` laws compiled on a model with effects: the composition's model inside.

What :meth:`controllers.observer.ObserverController.act`, :meth:`controllers.observer.LQGController.act` and
:meth:`controllers.two_encoder.TwoEncoderLQG.act` compute each period on any model :mod:`controllers.model` takes
(motor lag, input delay, dead zone, string damping, user files, discovered candidates ...), for every lane, with
the right-hand side, its Jacobian and the torques taken through the functions
:class:`controllers.dynamics.ModelDynamics` calls (its per-composition numba functions: ``evaluate``,
``slipping``, ``lane_jacobian``, ``settled``), so the law and the controller's ``act`` agree to round-off:

* ``observer``: the extended filter's update (Joseph form), the flatness law with the model's torques (the brake
  law with its effects at the law's speed and ±``step``, the upper disc's at the estimated upper speed:
  :meth:`~controllers.dynamics.ModelDynamics.lower_torque`, :meth:`~controllers.dynamics.ModelDynamics.upper_torque`),
  the inversion of the static input map (a dead zone, an offset: the monotone hull's tables of
  :meth:`~controllers.dynamics.ModelDynamics.input_map_branches`), the clip, then the prediction: the Jacobian at
  the estimate re-linearised every period (central differences with the modes held), the covariance with
  F = Ad + (Gamma_new + Gamma_old)(J - Ac), the mean by the exponential Euler step split at the fractional delay,
  the line of past commands shifted;
* ``lqg``: the stationary filter's correction, the brake law with its effects at the estimated lower speed and the
  upper disc's torque at the reference speed, the LQR feedback, the inversion, the clip, the mean's prediction;
* ``lqg-2enc``: the equilibrium from the composition's torques at the reference speed and the estimated angles,
  the design's correction and LQR voltage (:mod:`controllers.compiled.two_encoder_law`), the inversion, the clip,
  the motor's voltage the command gives (the static input map), the prediction.

The steps live in :mod:`controllers.compiled.composition_law`, a kernel client template each composition gets a
copy of, compiled once and then loaded from numba's cache (:func:`law_step`); this module holds what they share
and builds their state and constants: the dimensions and the model's numbers are the law's constants.  Not
run here (the controller keeps its step-by-step loop, :func:`compiled_law` returns None): a Measurement effect on
the motor angle for the observer, any Measurement effect for lqg-2enc (the readings and the observer's output map
through the composition's measurement every period, which is not among the functions above), the ``descent``
fallback, a filter without the nominal brake law.

State rows (n columns): the estimates (dim), then for the observer the covariance (dim^2) and the flatness law's
rows (:data:`controllers.compiled.observer_law.ROWS`), for the lqg its rows
(:data:`controllers.compiled.lqg_law.ROWS`); then work rows (:func:`observer_rows`, :func:`lqg_rows`).  Constants:
:data:`~controllers.compiled.observer_law.CONSTANTS`, :data:`~controllers.compiled.lqg_law.EXTRA`,
:data:`SCALARS`, then the arrays their offsets name.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

from drillgym.closed_loop.abi import LAW_SIGNATURE
from drillgym.effects import Composition
from drillgym.effects.foreign_client import foreign_client

from ..dynamics import jacobian_steps, lag_arrays
from . import lqg_law as lq
from . import observer_law as ob
from . import two_encoder_law as te
from .two_encoder_law import interp

__all__ = ["compiled_law", "law_step", "SCALARS", "observer_rows", "lqg_rows"]

#: rows of the observer's torques: the brake law at three speeds, the upper disc's, six at a moved lower angle
OBSERVER_TORQUES = 10
SCALARS = ("nc", "e0", "idu", "delay_steps", "n_line", "has_old", "compensates", "g0", "n_pos", "n_neg", "o_p",
           "o_h", "o_hp", "o_up", "o_hn", "o_un", "o_lc", "o_lt", "o_mats", "o_gn", "o_go", "o_kf", "o_hh",
           "o_tail")  # fmt: skip
"""The model's dimensions and the offsets in the constants of its arrays: continuous states, first effect state,
row of ``du`` (-1: none), whole periods of the delay, length of the line of past commands, whether a fractional
delay splits the period, whether the input map is inverted, its value at 0 V and its tables' lengths; the parameter
vector, the Jacobian's steps, the input map's tables (voltages, commands: positive then negative branch), the
filter's matrices (Ad, Gamma_new + Gamma_old, Ac, Qd), Gamma_new, Gamma_old, the lqg's Kf and H, the lqg-2enc's
own constants (:mod:`controllers.compiled.two_encoder_law`)."""
_S0 = len(ob.CONSTANTS) + len(lq.EXTRA)
(NC, E0, IDU, DSTEPS, NLINE, HAS_OLD, COMP, G0, NPOS, NNEG, OP,
 OH, OHP, OUP, OHN, OUN, OLC, OLT, OMATS, OGN, OGO, OKF, OHH, OTAIL) = range(_S0, _S0 + len(SCALARS))  # fmt: skip
_STEPS: dict[tuple[Composition, str], Any] = {}


@njit(cache=True)
def observer_rows(dim, nc):
    """First rows of the observer's covariance, law rows, W (2 dim^2 + dim), f(new), f(old), J (nc^2), torques
    (:data:`OBSERVER_TORQUES`), and the number of rows."""
    p0 = dim
    l0 = p0 + dim * dim
    w0 = l0 + len(ob.ROWS)
    fn = w0 + 2 * dim * dim + dim
    fo = fn + nc
    j0 = fo + nc
    t0 = j0 + nc * nc
    return p0, l0, w0, fn, fo, j0, t0, t0 + OBSERVER_TORQUES


@njit(cache=True)
def lqg_rows(dim, nc):
    """First rows of the lqg's law rows, f(new), f(old), W (nc), torques (2), reference speed, and the number of
    rows."""
    g0 = dim
    fn = g0 + len(lq.ROWS)
    fo = fn + nc
    w0 = fo + nc
    t0 = w0 + nc
    return g0, fn, fo, w0, t0, t0 + 2, t0 + 3


@njit(cache=True)
def invert(U, C, n):
    """The commands (V) whose settled voltage at the motor is U (V), in place: the monotone hull of the static
    input map inverted (:meth:`controllers.dynamics.ModelDynamics.command`)."""
    g0, npos, nneg = C[G0], int(C[NPOS]), int(C[NNEG])
    hp, up, hn, un = int(C[OHP]), int(C[OUP]), int(C[OHN]), int(C[OUN])
    for k in range(n):
        v = U[k]
        if v > g0:
            U[k] = interp(v, C, hp, up, npos, 0.0)
        elif v < g0:
            U[k] = -interp(-v, C, hn, un, nneg, 0.0)
        else:
            U[k] = 0.0


@njit(cache=True)
def command(U, C, n):
    """The commands (V) sent for the motor voltages U (V), in place: the static input map inverted (when the model
    has one), then clipped to the amplifier's range."""
    if C[COMP] > 0:
        invert(U, C, n)
    ob.clip(U, n, C[ob.U_MAX])


@njit(cache=True)
def shift_line(X, n, nc, dim, U):
    """The line of past commands (rows nc..dim-1) one period on, the command U (V) entering it."""
    for i in range(dim - 1, nc, -1):
        for k in range(n):
            X[i, k] = X[i - 1, k]
    if dim > nc:
        for k in range(n):
            X[nc, k] = U[k]


#: the kernel client template of the laws' steps on a composition
LAW_TEMPLATE = "controllers.compiled.composition_law"
#: the step of each law in it
_STEP_NAMES = {"observer": "observer_step", "lqg": "lqg_step", "lqg-2enc": "two_encoder_step"}


def law_step(comp: Composition, kind: str):
    """The compiled step of the ``kind`` law ("observer", "lqg" or "lqg-2enc") on the composition: the composition's
    copy of :mod:`controllers.compiled.composition_law`, compiled once and then loaded from numba's cache."""
    key = (comp, kind)
    if key not in _STEPS:
        step = getattr(foreign_client(comp.kernels, LAW_TEMPLATE), _STEP_NAMES[kind])
        step.compile(LAW_SIGNATURE.args)
        _STEPS[key] = step
    return _STEPS[key]


def _constants(dyn, compensates: bool, u_max: float, head: np.ndarray, dims: dict, arrays: dict) -> np.ndarray:
    """The law's constants: ``head`` (the base law's), :data:`SCALARS` (``dims`` and the composition's), then the
    arrays: the parameter vector, the Jacobian's steps, the input map's tables, then ``arrays``."""
    none = (np.zeros(1), np.zeros(1))
    g0, (hp, up), (hn, un) = dyn.input_map_branches(u_max) if compensates else (0.0, none, none)
    lc, lt = lag_arrays(dyn.composition)
    blocks = {"p": dyn.vector, "h": jacobian_steps(dyn.nz), "hp": hp, "up": up, "hn": hn, "un": un, "lc": lc, "lt": lt}
    blocks |= arrays
    scalars = dict(
        nc=dyn.nz, e0=dyn.e0, idu=5 if dyn.has_du else -1, compensates=float(compensates), g0=g0, n_pos=len(hp),
        n_neg=len(hn),
    ) | dims  # fmt: skip
    at = _S0 + len(SCALARS)
    for name, a in blocks.items():
        scalars[f"o_{name}"] = at
        at += np.size(a)
    tail = [np.ravel(np.asarray(a, dtype=float)) for a in blocks.values()]
    values = [float(scalars.get(k, 0.0)) for k in SCALARS]
    return np.ascontiguousarray(np.concatenate([head, values] + tail), dtype=np.float64)


def _filter_constants(c, head: np.ndarray, arrays: dict) -> np.ndarray:
    """The constants of the observer's or the lqg's law (:func:`_constants`) with its model's delay."""
    mdl = c.model
    dims = dict(delay_steps=mdl.delay_steps, n_line=mdl.Ad.shape[0] - mdl.nc, has_old=float(np.any(mdl.gamma_old)))
    return _constants(mdl.dynamics, mdl.compensates, c.u_max, head, dims, arrays)


def _observer_state(c) -> tuple[np.ndarray, np.ndarray]:
    """(state, constants) of the observer's law on the model with effects of the reset controller c."""
    mdl = c.model
    n, nc, dim = c.n, mdl.nc, mdl.Ad.shape[0]
    p0, l0, *_, rows = observer_rows(dim, nc)
    X = np.zeros((rows, n))
    X[:dim] = c.observer.x
    X[p0:l0] = c.observer.P.reshape(n, dim * dim).T
    ob.law_rows(c, X[l0 : l0 + len(ob.ROWS)])
    head = np.concatenate([ob.observer_constants(c, dim), np.zeros(len(lq.EXTRA))])
    mats = np.concatenate([np.ravel(a) for a in (mdl.Ad, mdl.gamma_new + mdl.gamma_old, mdl.Ac, mdl.Qd)])
    return X, _filter_constants(c, head, {"mats": mats, "gn": mdl.gamma_new, "go": mdl.gamma_old})


def _lqg_state(c) -> tuple[np.ndarray, np.ndarray]:
    """(state, constants) of the lqg's law on the model with effects of the reset controller c."""
    mdl = c.model
    n, nc, dim = c.n, mdl.nc, mdl.Ad.shape[0]
    g0, fn, *_, rows = lqg_rows(dim, nc)
    X = np.zeros((rows, n))
    X[:dim] = c._x
    lq.law_rows(c, X[g0:fn])
    arrays = {"gn": mdl.gamma_new, "go": mdl.gamma_old, "kf": c.Kf, "hh": mdl.H}
    return X, _filter_constants(c, lq.lqg_constants(c, dim), arrays)


def _two_encoder_law(c):
    """The lqg-2enc's law: :func:`controllers.compiled.two_encoder_law.two_encoder_law` without effects, else this
    module's; None with a Measurement effect (the readings through the composition each period)."""
    from . import CompiledLaw

    if c.dyn is None:
        return te.two_encoder_law(c)
    state = None if c.dyn.composition.has_measurement else te.law_state(c)
    if state is None:
        return None
    X, T = state
    values = dict.fromkeys(ob.CONSTANTS, 0.0) | dict(eps=c.dyn.eps, km=c.params.km, kth=c.params.ktheta, u_max=c.u_max)
    head = np.array([values[k] for k in ob.CONSTANTS] + [0.0] * len(lq.EXTRA))
    C = _constants(c.dyn, c.compensates, c.u_max, head, {}, {"tail": T})
    return CompiledLaw(law_step(c.dyn.composition, "lqg-2enc"), X, C)


def compiled_law(c, kind: str):
    """The compiled law of a reset ``observer``, ``lqg`` or ``lqg-2enc`` controller (``kind``), or None.

    On the base model of its parameters the laws of :mod:`controllers.compiled.observer_law`,
    :mod:`controllers.compiled.lqg_law` and :mod:`controllers.compiled.two_encoder_law`; on a model with effects
    this module's.

    Parameters
    ----------
    c : ObserverController, LQGController or TwoEncoderLQG
        The controller, reset.
    kind : str
        "observer", "lqg" or "lqg-2enc".

    Returns
    -------
    controllers.compiled.CompiledLaw or None
        The law with its state (the estimates, the observer's covariances, the law's rows) and constants; None
        for what it does not run (module doc).
    """
    from . import CompiledLaw

    if kind == "lqg-2enc":
        return _two_encoder_law(c)
    if ob.plain_model(c):
        return ob.observer_law(c) if kind == "observer" else lq.lqg_law(c)
    mdl = c.model
    if not ob.filter_settled(c, mdl.Ad.shape[0], np.inf) or (kind == "observer" and mdl.reads_effects):
        return None
    X, C = _observer_state(c) if kind == "observer" else _lqg_state(c)
    return CompiledLaw(law_step(c.effects.composition, kind), np.ascontiguousarray(X), C)
