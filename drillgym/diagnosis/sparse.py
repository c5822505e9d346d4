"""The data-driven route: residual generalised torques and a sparse candidate term.

For effects outside the library.  At every sample where the discs slip, the
data give the state (angles, speeds and lateral positions from the recording;
accelerations by a Savitzky–Golay second derivative) and the base model gives
the accelerations it would predict in that state (the right-hand side the
simulator compiled for the model's composition,
``composition.kernels.model.state_derivative``: the base model plus any effects
already in it).  The difference, multiplied by the mass matrix, is the generalised
force the model is missing: ``Q_res = M(q) (q̈_data − q̈_model)``; its θl
component is the residual torque on the lower disc (N m).

That torque is regressed by sequentially thresholded least squares (pysindy's
STLSQ) on a library of candidate functions of θl, α, the speeds and x, y
(harmonics of θl, signs, powers, time); the few surviving terms are shown as a
candidate expression.  The residual torque is also what :mod:`.compare` bins
by speed and angle: it is local in time, so it does not suffer from the phase
drift of stick-slip.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..configurations import N_STATE
from ..dynamics import brake_on, mass_matrix
from ..effects import Input
from ..identification.experiment import Experiment, estimate_rate
from ..identification.fitting import base_vector
from ..identification.segmented import as_composition
from ..params import N_PARAMS, RigParams

MIN_SPARSE_R2 = 0.1  # a candidate expression must explain at least this share of the residual torque

__all__ = ["ResidualTorque", "residual_torques", "SparseTerm", "sparse_residual_model", "candidate_library"]


@dataclass
class ResidualTorque:
    """Residual generalised forces at the recording's samples (NaN where a disc is stuck).

    ``tau_u``, ``tau_l``: on the upper / lower disc (N m); ``states`` (n, N_STATE) the data's
    states; ``t`` times (s); ``slip`` samples where the lower (or, in 'upper', the upper) disc slips;
    ``slip_upper`` samples where the upper disc slips (None: as ``slip``); ``u_motor`` the model's voltage at the
    motor (V; after its Delay and Input effects); ``force_X``, ``force_Y`` the residual lateral force on the lower
    disc's centre in the fixed (LVDT) frame (N; None when the disc does not move laterally), known where the lower
    disc's balance is (the lateral rows of the mass matrix, turned by θu); ``friction_l`` the model's lower-disc
    friction torque where the brake is on (N m, 0 with the brake off, NaN where not evaluated); ``effects`` the
    effects the model holds (set by the caller: a search composition holds every candidate at its neutral
    values).  Each disc's torque balance holds
    while that disc slips, whatever the other one does: the upper disc's is known while the lower disc is
    stuck (its string torque kθ α is measured).
    """

    t: np.ndarray
    tau_u: np.ndarray
    tau_l: np.ndarray
    states: np.ndarray
    slip: np.ndarray
    slip_upper: np.ndarray | None = None
    u_motor: np.ndarray | None = None
    force_X: np.ndarray | None = None
    force_Y: np.ndarray | None = None
    friction_l: np.ndarray | None = None
    effects: tuple[str, ...] = ()

    @property
    def upper_valid(self) -> np.ndarray:
        """Samples where the upper disc's residual torque is known."""
        return (self.slip if self.slip_upper is None else self.slip_upper) & np.isfinite(self.tau_u)

    @property
    def lower_valid(self) -> np.ndarray:
        """Samples where the lower disc's residual torque is known."""
        return self.slip & np.isfinite(self.tau_l)


def residual_torques(
    ex: Experiment,
    params: RigParams | np.ndarray | None = None,
    min_speed: float = 0.05,
    *,
    effects: Any = None,
    effect_params: dict[str, float] | None = None,
) -> ResidualTorque:
    """Residual generalised torques of a model on a recording (see the module docstring).

    The model: ``params`` (RigParams or a vector in the composition's layout) with ``effects``
    (a Composition or effect specs; default the base model) and their ``effect_params``.
    The command reaches the motor as in the simulator: delayed by the Delay effects, then through the Input
    effects in their order, whose states (a motor lag's ``u_m``) are integrated along the recording
    (:func:`motor_voltage_along`).  Samples within 0.1 s (the second-derivative window) of a stick phase are
    left out.

    Parameters
    ----------
    ex : Experiment
        The recording.
    params : RigParams or numpy.ndarray, optional
        Base parameters, or a vector in the composition's layout (default: the identified set).
    min_speed : float, optional
        Speed (rad/s) above which a disc slips.  Default 0.05.
    effects : any, optional
        A Composition or effect specs (default: the base model).
    effect_params : dict of str to float, optional
        The effects' parameter values.

    Returns
    -------
    ResidualTorque
        The residual torques on both discs and the states they were taken in.
    """
    comp = as_composition(effects)
    p = base_vector(comp, params, effect_params)
    state_derivative = comp.kernels.model.state_derivative
    inertia = RigParams.from_vector(p[:N_PARAMS])
    n = ex.n
    Y = np.zeros((n, comp.n_state))
    Y[:, :N_STATE] = ex.initial_states(np.arange(n), np.repeat(p[None, :], n, axis=0), comp)
    u_motor = motor_voltage_along(ex, comp, p, Y)
    acc = np.zeros((n, 4))
    acc[:, 0] = estimate_rate(ex.meas["theta_u"], ex.fs, window_s=0.1, deriv=2)
    if "theta_l" in ex.meas:
        acc[:, 1] = estimate_rate(ex.meas["theta_l"], ex.fs, window_s=0.1, deriv=2)
    if ex.config.lateral_free:
        acc[:, 2] = estimate_rate(Y[:, 6], ex.fs, window_s=0.1)
        acc[:, 3] = estimate_rate(Y[:, 7], ex.fs, window_s=0.1)
    cfg = int(ex.config)
    dy = np.zeros(comp.n_state)
    fric = np.zeros(2)
    M = np.zeros((4, 4))
    mode = np.zeros(2, dtype=np.int64)
    tau = np.full((n, 4), np.nan)
    friction_l = np.full(n, np.nan)
    brake = brake_on(cfg)
    half = max(1, int(round(0.1 * ex.fs)))

    def slipping(w: np.ndarray) -> np.ndarray:
        """Slipping, and not within the derivative window of a stick phase (accelerations there are smeared)."""
        stuck = (np.abs(w) <= min_speed).astype(float)
        return ~(np.convolve(stuck, np.ones(2 * half + 1), mode="same") > 0)

    has_lower = "theta_l" in ex.meas
    slip = slipping(Y[:, 3] if has_lower else Y[:, 2])
    slip_upper = slipping(Y[:, 2]) if has_lower else slip
    for i in np.flatnonzero(slip | slip_upper):
        y = Y[i].copy()
        mode[0] = 1 if y[2] > 0 else (-1 if y[2] < 0 else 0)
        mode[1] = 1 if y[3] > 0 else (-1 if y[3] < 0 else 0)
        if mode[0] == 0:  # stuck upper disc: its torque balance is unknown (set-valued)
            mode[0] = 1
        state_derivative(ex.t[i] - ex.t[0], y, mode, u_motor.command[i], p, cfg, 0.0, dy, fric)
        friction_l[i] = fric[1] if brake else 0.0
        da = acc[i] - np.array([dy[2], dy[3], dy[6], dy[7]])
        if ex.config.lateral_free:
            mass_matrix(y, p, M)
            tau[i] = M @ da
        else:
            tau[i, 0] = inertia.Ju * da[0]
            tau[i, 1] = inertia.Jl * da[1]
    tau[~slip, 1:] = np.nan  # the lower disc's balance (and the lateral forces, through it) only while it slips
    tau[~slip_upper, 0] = np.nan
    FX = FY = None
    if ex.config.lateral_free:  # the generalised forces on x, y (rotating frame) are the force turned by -θu
        c, s = np.cos(Y[:, 0]), np.sin(Y[:, 0])
        FX, FY = tau[:, 2] * c - tau[:, 3] * s, tau[:, 2] * s + tau[:, 3] * c
    return ResidualTorque(
        ex.t - ex.t[0], tau[:, 0], tau[:, 1], Y, slip, slip_upper, u_motor.at_motor, FX, FY, friction_l
    )


@dataclass
class MotorVoltage:
    """The voltage along a recording: ``command`` the command as it leaves the Delay effects (V), ``at_motor``
    the voltage the motor sees after the Input effects (V)."""

    command: np.ndarray
    at_motor: np.ndarray


def motor_voltage_along(ex: Experiment, comp: Any, p: np.ndarray, Y: np.ndarray) -> MotorVoltage:
    """The command's path to the motor along a recording, as the simulator takes it, with the discs' states
    the data's.

    The recorded input is delayed by the composition's Delay effects (the first value held before the start);
    the effects' states (columns ``N_STATE:`` of ``Y``, filled in place) start as the simulator starts them (a
    lag state at the steady state of the first command, the others at 0) and are advanced sample by sample: a
    declared lag (``Input.lag``) exactly, any other state by its derivative (explicit Euler over the sample
    period).

    Parameters
    ----------
    ex : Experiment
        The recording.
    comp : Composition
        The model's composition.
    p : numpy.ndarray
        The model's parameter vector in the composition's layout.
    Y : numpy.ndarray
        (n, comp.n_state) states: the discs' from the data; the effects' are written here.

    Returns
    -------
    MotorVoltage
        The delayed command and the voltage at the motor at every sample (V).
    """
    n, dt = ex.n, 1.0 / ex.fs
    calls = comp.hook_calls()
    vec = np.ascontiguousarray(p, dtype=np.float64)
    delay = comp.delay(vec)
    command = ex.input_on_grid(dt, n, ex.t[0] - delay)
    at_motor = command.copy()
    if comp.n_state == N_STATE and not comp.has_kind(Input):
        return MotorVoltage(command, at_motor)
    lags = np.asarray(comp.lag_state_columns, dtype=np.int64)
    t = np.ascontiguousarray(ex.t, dtype=np.float64)
    calls.input_path(t, np.ascontiguousarray(command), Y, vec, int(ex.config), dt, lags, at_motor)
    return MotorVoltage(command, at_motor)


def candidate_library(rt: ResidualTorque) -> tuple[np.ndarray, list[str]]:
    """Candidate functions (columns) at the samples, and their names.

    Parameters
    ----------
    rt : ResidualTorque
        The residual torques and their states.

    Returns
    -------
    tuple of (numpy.ndarray, list of str)
        The columns and their names.
    """
    S = rt.states
    th, wl, wu = S[:, 1], S[:, 3], S[:, 2]
    a = S[:, 1] - S[:, 0]
    sg = np.sign(wl)
    X, Yf = S[:, 4], S[:, 5]
    r = np.hypot(X, Yf)
    cols = {
        "1": np.ones_like(th),
        "sign(ωl)": sg,
        "ωl": wl,
        "ωl|ωl|": wl * np.abs(wl),
        "cos θl": np.cos(th),
        "sin θl": np.sin(th),
        "cos 2θl": np.cos(2 * th),
        "sin 2θl": np.sin(2 * th),
        "sign(ωl) cos θl": sg * np.cos(th),
        "sign(ωl) sin θl": sg * np.sin(th),
        "sign(ωl) cos 2θl": sg * np.cos(2 * th),
        "sign(ωl) sin 2θl": sg * np.sin(2 * th),
        "α": a,
        "α³": a**3,
        "α̇": wl - wu,
        "sign(α̇)": np.sign(wl - wu),
        "t sign(ωl)": rt.t * sg,
        "[ωl<0]": (wl < 0) * sg,
    }
    if np.any(r > 0):
        cols.update({"x": X, "y": Yf, "r": r, "r² sign(ωl)": r**2 * sg})
    return np.column_stack(list(cols.values())), list(cols)


@dataclass
class SparseTerm:
    """A candidate expression for the residual torque on the lower disc."""

    terms: dict[str, float]
    r2: float
    n_samples: int

    def expression(self) -> str:
        if not self.terms:
            return "τ_res ≈ 0 (no candidate term survives)"
        if self.r2 < MIN_SPARSE_R2:
            return (
                f"no candidate term explains the residual torque (best sparse fit explains {self.r2:.0%}): "
                "it looks like noise"
            )
        parts = [f"{c:+.4g}·{n}" if n != "1" else f"{c:+.4g}" for n, c in self.terms.items()]
        return "τ_res(θl, ω, α, x, y) ≈ " + " ".join(parts) + f"  [N m; explains {self.r2:.0%} of it]"


def sparse_residual_model(rt: ResidualTorque, threshold: float = 0.05, max_terms: int = 4) -> SparseTerm:
    """STLSQ (pysindy) of the lower residual torque on :func:`candidate_library`.

    Columns are standardised; ``threshold`` is relative to the torque's standard deviation.
    At most ``max_terms`` terms are kept (the largest contributions).

    Parameters
    ----------
    rt : ResidualTorque
        The residual torques.
    threshold : float, optional
        The STLSQ threshold, relative to the torque's standard deviation.  Default 0.05.
    max_terms : int, optional
        Terms kept.  Default 4.

    Returns
    -------
    SparseTerm
        The terms and their coefficients.
    """
    import pysindy as ps

    ok = rt.lower_valid
    if ok.sum() < 20:
        return SparseTerm({}, 0.0, int(ok.sum()))
    Th, names = candidate_library(rt)
    Th, y = Th[ok], rt.tau_l[ok]
    sd = Th.std(axis=0)
    sd[0] = 1.0
    keep = sd > 1e-12
    keep[0] = True
    Th, sd = Th[:, keep], sd[keep]
    names = [n for n, k in zip(names, keep) if k]
    ys = y.std() or 1.0
    Z = Th / sd
    opt = ps.STLSQ(threshold=threshold, alpha=1e-6, max_iter=30)
    opt.fit(Z, y / ys)
    coef = np.ravel(opt.coef_)
    if np.count_nonzero(coef) > max_terms:
        order = np.argsort(-np.abs(coef))
        sel = np.zeros_like(coef, dtype=bool)
        sel[order[:max_terms]] = True
        coef = np.zeros_like(coef)
        sol, *_ = np.linalg.lstsq(Z[:, sel], y / ys, rcond=None)
        coef[sel] = sol
    pred = Z @ coef * ys
    den = float(np.sum((y - y.mean()) ** 2)) or 1.0
    r2 = 1.0 - float(np.sum((y - pred) ** 2)) / den
    terms = {names[i]: float(coef[i] * ys / sd[i]) for i in np.flatnonzero(coef)}
    return SparseTerm(terms, r2, int(ok.sum()))
