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

Compiled once per composition and process (the steps are closures over the composition's functions, as
:func:`controllers.dynamics.model_kernels`); the dimensions and the model's numbers are the law's constants.  Not
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
from drillgym.params import IDX

from ..dynamics import jacobian_steps, model_kernels
from ..flatness import ANGLE_STEP
from . import lqg_law as lq
from . import observer_law as ob
from . import two_encoder_law as te
from .two_encoder_law import interp

__all__ = ["compiled_law", "law_step", "SCALARS", "observer_rows", "lqg_rows"]

#: rows of the observer's torques: the brake law at three speeds, the upper disc's, six at a moved lower angle
OBSERVER_TORQUES = 10
SCALARS = ("nc", "e0", "idu", "delay_steps", "n_line", "has_old", "compensates", "g0", "n_pos", "n_neg", "o_p",
           "o_h", "o_hp", "o_up", "o_hn", "o_un", "o_mats", "o_gn", "o_go", "o_kf", "o_hh", "o_tail")  # fmt: skip
"""The model's dimensions and the offsets in the constants of its arrays: continuous states, first effect state,
row of ``du`` (-1: none), whole periods of the delay, length of the line of past commands, whether a fractional
delay splits the period, whether the input map is inverted, its value at 0 V and its tables' lengths; the parameter
vector, the Jacobian's steps, the input map's tables (voltages, commands: positive then negative branch), the
filter's matrices (Ad, Gamma_new + Gamma_old, Ac, Qd), Gamma_new, Gamma_old, the lqg's Kf and H, the lqg-2enc's
own constants (:mod:`controllers.compiled.two_encoder_law`)."""
_S0 = len(ob.CONSTANTS) + len(lq.EXTRA)
(NC, E0, IDU, DSTEPS, NLINE, HAS_OLD, COMP, G0, NPOS, NNEG, OP,
 OH, OHP, OUP, OHN, OUN, OMATS, OGN, OGO, OKF, OHH, OTAIL) = range(_S0, _S0 + len(SCALARS))  # fmt: skip
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


def _functions(comp: Composition) -> tuple:
    """The per-lane functions of the laws on the composition: the model's torques and its linearisation."""
    kern = model_kernels(comp)
    evaluate, slipping, lane_jacobian = kern.evaluate, kern.slipping, kern.lane_jacobian
    ny = comp.n_state
    iKT, iJL, iJU, iKM = IDX.ktheta, IDX.Jl, IDX.Ju, IDX.km

    @njit(cache=False)
    def load(X, k, C, z):  # pragma: no cover
        """The estimate of lane k with d = du = 0 into z (the model's torques at its own brake level)."""
        for i in range(z.size):
            z[i] = X[i, k]
        z[4] = 0.0
        if C[IDU] >= 0:
            z[int(C[IDU])] = 0.0

    @njit(cache=False)
    def torques(X, C, n, TQ, nlow, REF):  # pragma: no cover
        """The model's torques (N m) at the estimates into TQ: for the observer (nlow 3) the brake law at the
        law's speed ww and ww +- step, for the lqg (nlow 1) at the estimated lower speed (at ``slip_eps`` while it
        rests); then the upper disc's at the estimated upper speed (observer) or at REF (lqg, rad/s); for the
        observer then the brake law at the lower angle moved by +- ANGLE_STEP at ww, ww + step, ww - step, ww + step,
        ww - step (signs +, -, +, +, -, -: its derivatives in the angle, :meth:`FlatnessLaw.friction`)."""
        nz, e0, idu = int(C[NC]), int(C[E0]), int(C[IDU])
        p = C[int(C[OP]) : int(C[OH])]
        scale, eps, hf = C[ob.SCALE] > 0, C[ob.EPS], C[ob.HF]
        z, out = np.zeros(nz), np.zeros(nz)
        y, pp, dy, d2 = np.zeros(ny), np.zeros(p.size), np.zeros(ny), np.zeros(ny)
        fric, mode, mode_in = np.zeros(2), np.zeros(2, np.int64), np.zeros(2, np.int64)
        for k in range(n):
            load(X, k, C, z)
            wu, al, wl = z[1], z[2], z[3]
            if nlow == 3:
                ww = max(wl, C[ob.W_REST] + hf)
                speeds = (ww, ww + hf, ww - hf)
            else:
                seps = C[lq.SLIP_EPS]
                speeds = (wl if abs(wl) > seps else seps, 0.0, 0.0)
            for j in range(nlow):
                slipping(z, 0.0, wu, speeds[j], p, e0, idu, scale, eps, out, y, pp, dy, d2, fric, mode, mode_in)
                TQ[j, k] = -p[iKT] * al - p[iJL] * out[3]
            w = (1e-9 if wu == 0 else wu) if nlow == 3 else REF[k]
            vm = slipping(z, 0.0, w, wl, p, e0, idu, scale, eps, out, y, pp, dy, d2, fric, mode, mode_in)
            TQ[nlow, k] = p[iKM] * vm + p[iKT] * al - p[iJU] * out[1]
            if nlow == 3:  # the lower angle moved, the twist kept: the motor angle moved
                th = z[0]
                for j in range(6):
                    z[0] = th + (ANGLE_STEP if j == 0 or j == 2 or j == 3 else -ANGLE_STEP)
                    sp = speeds[0] if j < 2 else (speeds[1] if j == 2 or j == 4 else speeds[2])
                    slipping(z, 0.0, wu, sp, p, e0, idu, scale, eps, out, y, pp, dy, d2, fric, mode, mode_in)
                    TQ[4 + j, k] = -p[iKT] * al - p[iJL] * out[3]
                z[0] = th

    @njit(cache=False)
    def linearise(X, C, n, U, Fn, Fo, J, jac):  # pragma: no cover
        """f at the estimates under the newer command (U or the line's) into Fn (nc, n), under the older one into
        Fo when a fractional delay splits the period, and with ``jac`` the Jacobian df/dz at the newer into J
        (nc^2, n; the modes held)."""
        nz, e0, idu = int(C[NC]), int(C[E0]), int(C[IDU])
        ds, nline = int(C[DSTEPS]), int(C[NLINE])
        p = C[int(C[OP]) : int(C[OH])]
        H = C[int(C[OH]) : int(C[OH]) + nz + 1]
        scale, eps = C[ob.SCALE] > 0, C[ob.EPS]
        z, f0, fp, fm, Jk, Bk = np.zeros(nz), np.zeros(nz), np.zeros(nz), np.zeros(nz), np.zeros((nz, nz)), np.zeros(nz)
        y, pp, dy = np.zeros(ny), np.zeros(p.size), np.zeros(ny)
        fric, mode, mode0 = np.zeros(2), np.zeros(2, np.int64), np.zeros(2, np.int64)
        for k in range(n):
            for i in range(nz):
                z[i] = X[i, k]
            new = U[k] if ds == 0 else X[nz + ds - 1, k]
            if jac:
                lane_jacobian(z, new, p, e0, idu, scale, eps, H, False, Jk, Bk, f0, fp, fm, y, pp, dy, fric, mode,
                              mode0)  # fmt: skip
                for i in range(nz):
                    for c in range(nz):
                        J[i * nz + c, k] = Jk[i, c]
            else:
                evaluate(z, new, p, e0, idu, scale, eps, False, mode0, f0, y, pp, dy, fric, mode)
            for i in range(nz):
                Fn[i, k] = f0[i]
            if C[HAS_OLD] > 0:
                old = X[nz + ds, k] if ds < nline else new
                evaluate(z, old, p, e0, idu, scale, eps, False, mode0, fp, y, pp, dy, fric, mode)
                for i in range(nz):
                    Fo[i, k] = fp[i]

    return torques, linearise


@njit(cache=True)
def predict(X, C, n, U, Fn, Fo, W):
    """The mean one period on: x[:nc] += Gamma_new f(new) (+ Gamma_old f(old)), the line shifted."""
    nc, dim = int(C[NC]), int(C[ob.DIM])
    ob.predict_mean(X, C, n, nc, int(C[OGN]), Fn, W)
    if C[HAS_OLD] > 0:
        ob.predict_mean(X, C, n, nc, int(C[OGO]), Fo, W)
    shift_line(X, n, nc, dim, U)


def _observer_step(comp: Composition):
    """The observer's step on the composition (module doc)."""
    torques, linearise = _functions(comp)

    @njit(LAW_SIGNATURE, cache=False)
    def step(t, M, X, C, U):  # pragma: no cover - compiled
        """One period of the observer for every lane: update, law, inversion, clip, predict."""
        n, dim, nc = U.size, int(C[ob.DIM]), int(C[NC])
        p0, l0, w0, fn, fo, j0, t0, _ = observer_rows(dim, nc)
        ob.update(M, X, C[ob.R], n, dim, p0, X[w0:fn])
        torques(X, C, n, X[t0 : t0 + OBSERVER_TORQUES], 3, X[t0])
        ob.flatness_law(M, X, X[l0:w0], C, n, U, X[t0 : t0 + OBSERVER_TORQUES])
        command(U, C, n)
        linearise(X, C, n, U, X[fn:fo], X[fo:j0], X[j0:t0], True)
        ob.predict_covariance(X, C, n, dim, nc, p0, int(C[OMATS]), X[j0:t0], X[w0:fn])
        predict(X, C, n, U, X[fn:fo], X[fo:j0], X[w0:fn])

    return step


def _lqg_step(comp: Composition):
    """The lqg's step on the composition (module doc)."""
    torques, linearise = _functions(comp)

    @njit(LAW_SIGNATURE, cache=False)
    def step(t, M, X, C, U):  # pragma: no cover - compiled
        """One period of the lqg for every lane: correct, torques, feedback, inversion, clip, predict."""
        g0, fn, fo, w0, t0, r0, _ = lqg_rows(int(C[ob.DIM]), int(C[NC]))
        lq.correct(M, X, C, U.size, int(C[ob.DIM]), int(C[OKF]), int(C[OHH]))
        lq.clock(M, X[g0:fn], C, U.size, X[r0])
        torques(X, C, U.size, X[t0:r0], 1, X[r0])
        lq.feedback(X, X[g0:fn], C, U.size, U, X[t0:r0], X[r0])
        command(U, C, U.size)
        linearise(X, C, U.size, U, X[fn:fo], X[fo:w0], X[fn:fo], False)
        predict(X, C, U.size, U, X[fn:fo], X[fo:w0], X[w0:t0])

    return step


def _two_encoder_step(comp: Composition):
    """The lqg-2enc's step on the composition: its equilibrium from the composition's torques at the reference speed
    and the estimated angles, its correction and prediction (:mod:`controllers.compiled.two_encoder_law`) with the
    static input map inverted in the command and the motor's voltage the command gives."""
    kern = model_kernels(comp)
    slipping, settled = kern.slipping, kern.settled
    ny = comp.n_state
    iKT, iJL, iJU, iKM = IDX.ktheta, IDX.Jl, IDX.Ju, IDX.km

    @njit(cache=False)
    def equilibrium(X, C, T, n, EQ):  # pragma: no cover
        """The winding (rad) and the voltage at the motor (V) of the model's slip equilibrium at each lane's
        reference speed near its estimated angles into EQ (TwoEncoderLQG._model_equilibrium); T the law's own."""
        nz, e0, eps = int(C[NC]), int(C[E0]), C[ob.EPS]
        p = C[int(C[OP]) : int(C[OH])]
        z, out = np.zeros(nz), np.zeros(nz)
        y, pp, dy, d2 = np.zeros(ny), np.zeros(p.size), np.zeros(ny), np.zeros(ny)
        fric, mode, mode_in = np.zeros(2), np.zeros(2, np.int64), np.zeros(2, np.int64)
        for k in range(n):
            r = max(X[te.REF, k], T[te.GSTEP])
            z[:] = 0.0
            z[0], z[2] = X[0, k], X[2, k]
            slipping(z, 0.0, r, r, p, e0, -1, False, eps, out, y, pp, dy, d2, fric, mode, mode_in)
            a = -(-p[iKT] * z[2] - p[iJL] * out[3]) / C[ob.KTH]
            z[2] = a
            vm = slipping(z, 0.0, r, r, p, e0, -1, False, eps, out, y, pp, dy, d2, fric, mode, mode_in)
            EQ[0, k] = a
            EQ[1, k] = (p[iKM] * vm + p[iKT] * a - p[iJU] * out[1] - C[ob.KTH] * a) / C[ob.KM]

    @njit(cache=False)
    def motor(C, n, U, V, XD, EV):  # pragma: no cover
        """The voltage at the motor (V) the commands U (V) give once the lags settled, at the corrected estimates."""
        nz, e0 = int(C[NC]), int(C[E0])
        p = C[int(C[OP]) : int(C[OH])]
        z, y, dy = np.zeros(nz), np.zeros(ny), np.zeros(ny)
        for k in range(n):
            if C[COMP] == 0:
                V[k] = U[k]
                continue
            z[:] = 0.0
            for i in range(4):
                z[i] = XD[i, k] + EV[i, k]
            V[k] = settled(z, U[k], p, e0, y, dy)

    @njit(LAW_SIGNATURE, cache=False)
    def step(t, M, X, C, U):  # pragma: no cover - compiled
        """One period of the lqg-2enc for every lane: equilibrium, correction, inversion, clip, prediction."""
        n, T = U.size, C[int(C[OTAIL]) :]
        EQ, XD, EV = (
            X[te.EQ_ROW : te.EQ_ROW + 2],
            X[te.XD_ROW : te.XD_ROW + te.MAX_NX],
            X[te.EV_ROW : te.EV_ROW + te.MAX_NX],
        )
        equilibrium(X, C, T, n, EQ)
        te.correct(M, X, T, n, U, EQ, XD, EV)
        command(U, C, n)
        motor(C, n, U, X[te.V_ROW], XD, EV)
        te.predict(X, T, n, X[te.V_ROW], EQ, XD, EV)

    return step


_BUILDERS = {"observer": _observer_step, "lqg": _lqg_step, "lqg-2enc": _two_encoder_step}


def law_step(comp: Composition, kind: str):
    """The compiled step of the ``kind`` law ("observer" or "lqg") on the composition, once per composition and
    process."""
    key = (comp, kind)
    if key not in _STEPS:
        _STEPS[key] = _BUILDERS[kind](comp)
    return _STEPS[key]


def _constants(dyn, compensates: bool, u_max: float, head: np.ndarray, dims: dict, arrays: dict) -> np.ndarray:
    """The law's constants: ``head`` (the base law's), :data:`SCALARS` (``dims`` and the composition's), then the
    arrays: the parameter vector, the Jacobian's steps, the input map's tables, then ``arrays``."""
    none = (np.zeros(1), np.zeros(1))
    g0, (hp, up), (hn, un) = dyn.input_map_branches(u_max) if compensates else (0.0, none, none)
    blocks = {"p": dyn.vector, "h": jacobian_steps(dyn.nz), "hp": hp, "up": up, "hn": hn, "un": un} | arrays
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
