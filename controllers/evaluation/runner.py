"""Closed-loop simulation of a batch of scenarios: the core's BatchSimulator + a controller + the encoders.

One call steps n trajectories together (one compiled ``advance`` per control
period for the whole batch, one vectorised controller call), which is what
makes the harness fast.  The plant may run hidden effects (a composition of
:mod:`drillgym.effects`; the controller does not know them).  The measurement
chain is the rig's: the composition's Measurement effects, then encoder angles
quantized to ``counts_per_rev`` (:func:`drillgym.measurement.quantize_angle`),
optional white angle noise, LVDT x, y in the fixed frame.

A controller that offers a compiled law (:meth:`controllers.Controller.compiled_law`) runs instead in the
compiled closed loop (:func:`drillgym.closed_loop.run_compiled_loop`): plant and law advance together for
the whole run with no Python call per control period, the same measurement chain and noise stream; the
step-by-step loop stays the reference (``compiled=False``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from drillgym import BatchSimulator, Configuration, Model, parse_configuration
from drillgym.closed_loop import LoopSignals, run_compiled_loop
from drillgym.errors import InputError, InputTypeError
from drillgym.measurement import DEFAULT_COUNTS_PER_REV
from drillgym.run_setup import real_number, real_numbers, whole_number

from ..base import Controller

__all__ = ["ClosedLoopRun", "run_closed_loop"]

SIM_DT = 1e-3  # s, integrator step (the core's default)
TWO_PI = 2.0 * np.pi
_SIGNALS = tuple(f.name for f in fields(LoopSignals))


@dataclass
class ClosedLoopRun(LoopSignals):
    """Signals of n closed-loop runs sampled at the control period (:class:`drillgym.closed_loop.LoopSignals`: arrays
    (n, m)), with the configuration, the times t (s, (m,)) and the targets omega_ref (rad/s, (n,))."""

    config: Configuration
    t: np.ndarray
    omega_ref: np.ndarray

    @property
    def dt(self) -> float:
        return float(self.t[1] - self.t[0])


def _per_run(name: str, value: Any, n: int, unit: str) -> np.ndarray:
    """``value`` (one number, or one per run) as an array of ``n`` numbers."""
    array = real_numbers(name, value, unit)
    if array.ndim > 1 or array.size not in (1, n):
        raise InputError(f"{name} must be one number or one per run ({n}), got shape {array.shape}")
    return np.broadcast_to(array.reshape(-1), (n,)).copy()


def run_closed_loop(
    controller: Controller,
    config: str | Configuration,
    omega_ref: np.ndarray,
    duration: float,
    *,
    params=None,
    x0: np.ndarray | None = None,
    alpha0: float | np.ndarray = 0.0,
    counts_per_rev: int | np.ndarray = DEFAULT_COUNTS_PER_REV,
    angle_noise: float | np.ndarray = 0.0,
    seed: int = 0,
    sim_dt: float = SIM_DT,
    effects: Any = None,
    effect_params: Mapping[str, float] | None = None,
    compiled: bool | None = None,
) -> ClosedLoopRun:
    """Run ``controller`` on n simulated rigs for ``duration`` seconds.

    Parameters
    ----------
    controller : Controller
        Any :class:`controllers.Controller` (vectorised over the batch).
    config : str or Configuration
        Plant configuration ('torsional', 'coupled', ...).
    omega_ref : ndarray
        Target speeds (rad/s), (n,).
    duration : float
        Simulated time (s).
    params : RigParams or list of RigParams or ndarray, optional
        Plant base parameters: RigParams, a list (one per run) or an (n, n_params) matrix (base parameters, or
        base then effect parameters in the composition's layout).
    x0 : ndarray, optional
        Initial states (n, 8) or (n, n_state) (default: rest with winding ``alpha0``).
    alpha0 : float or ndarray, optional
        Initial winding of the string (rad) of a run from rest, or one per run (n,). Default 0.
    counts_per_rev : int or ndarray, optional
        Encoder resolution of the measurement (0: exact angles), or one per run (n,).
    angle_noise : float or ndarray, optional
        White noise added to the measured angles (rad, std), or one per run (n,).
    seed : int, optional
        Seed of the measurement noise.
    sim_dt : float, optional
        Integrator step of the plant (s), a divisor of the controller's period. Default 1 ms.
    effects, effect_params : object, optional
        Hidden effects of the plant and their values (as :func:`drillgym.simulate`); the controller is built
        without them.
    compiled : bool, optional
        Run the controller's compiled law in the compiled closed loop: None (default) when the controller
        offers one (:meth:`controllers.Controller.compiled_law`), else step by step; False: always step by
        step (the reference); True: the compiled loop or an error.

    Returns
    -------
    ClosedLoopRun
        The signals of the n runs at the control period: arrays (n, m), times ``t`` (m,) in s.

    Raises
    ------
    InputError
        Bad settings, or ``compiled=True`` for a controller without a compiled law.
    """
    if not isinstance(controller, Controller):
        raise InputTypeError(
            f"controller must be a controllers.Controller (controllers.make(name)), got {type(controller).__name__}"
        )
    cfg = parse_configuration(config)
    ref = np.atleast_1d(real_numbers("omega_ref", omega_ref, "rad/s"))
    n = ref.size
    duration = real_number("duration", duration, "s")
    if not (np.isfinite(duration) and duration > 0):
        raise InputError(f"duration must be a positive number of seconds, got {duration!r}")
    if round(duration / controller.dt) < 1:
        raise InputError(f"duration {duration:g} s is shorter than one control period ({controller.dt:g} s)")
    sim_dt = real_number("sim_dt", sim_dt, "s")
    if not (np.isfinite(sim_dt) and sim_dt > 0):
        raise InputError(f"sim_dt must be a positive number of seconds, got {sim_dt!r}")
    seed = whole_number("seed", seed, 0)
    if compiled is not None and not isinstance(compiled, (bool, np.bool_)):
        raise InputTypeError(f"compiled must be True, False or None, got {compiled!r}")
    cpr, noise = (
        _per_run(k, v, n, u)
        for k, v, u in (("counts_per_rev", counts_per_rev, "counts/rev"), ("angle_noise", angle_noise, "rad"))
    )
    if np.any(cpr < 0) or np.any(cpr != np.round(cpr)):
        raise InputError(f"counts_per_rev must be whole numbers >= 0 (0: exact angles), got {counts_per_rev!r}")
    if isinstance(params, Model):
        raise InputTypeError(
            "params is a drillgym.Model: give params=model.params, effects=model.composition, "
            "effect_params=dict(model.values)"
        )
    sub = int(round(controller.dt / sim_dt))
    if sub < 1 or abs(sub * sim_dt - controller.dt) > 1e-9:
        raise InputError(f"control period {controller.dt} s must be a multiple of the integrator step {sim_dt} s")
    m = int(round(duration / controller.dt))
    sim = BatchSimulator(cfg, n, params=params, dt=sim_dt, effects=effects, effect_params=effect_params)
    sim.reset(alpha0=alpha0, x0=x0)
    rng = np.random.default_rng(seed)
    if np.any(noise < 0) or not np.all(np.isfinite(noise)):
        raise InputError("angle_noise must be non-negative (rad)")
    t = np.arange(m) * controller.dt
    meas = _measure(sim, t[0], ref, cpr, noise, rng)
    controller.reset(meas)
    law = controller.compiled_law() if compiled is not False else None
    if compiled and law is None:
        raise InputError(f"controller {controller.name!r} offers no compiled law; run it with compiled=False or None")
    if law is not None:
        try:
            sig = run_compiled_loop(
                sim, law.step, law.state, law.constants, periods=m, control_dt=controller.dt, first=meas,
                counts_per_rev=cpr, angle_noise=noise, rng=rng, u_max=controller.u_max,
            )  # fmt: skip
        except FloatingPointError:
            raise FloatingPointError(f"controller {controller.name!r} produced a non-finite voltage") from None
        return ClosedLoopRun(**{k: getattr(sig, k) for k in _SIGNALS}, config=cfg, t=t, omega_ref=ref)
    out = {k: np.empty((n, m)) for k in _SIGNALS}
    for k in range(m):
        if k > 0:
            meas = _measure(sim, t[k], ref, cpr, noise, rng)
        u = np.broadcast_to(np.asarray(controller.act(meas), dtype=float), (n,))
        out["u"][:, k] = u
        out["omega_u"][:, k] = sim.omega_u
        out["omega_l"][:, k] = sim.omega_l
        out["alpha"][:, k] = sim.alpha
        out["stuck_l"][:, k] = sim.stuck_l
        out["friction_l"][:, k] = sim.friction[:, 1]
        out["r"][:, k] = np.hypot(sim.x, sim.y)
        sim.advance(u, sub)
    return ClosedLoopRun(**out, config=cfg, t=t, omega_ref=ref)


def _measure(
    sim: BatchSimulator, t: float, ref: np.ndarray, cpr: np.ndarray, noise: np.ndarray, rng: np.random.Generator
) -> dict[str, np.ndarray]:
    """What the rig's sensors report (batched; cpr counts/rev and noise rad std per run)."""

    def enc(theta: np.ndarray) -> np.ndarray:
        c = np.where(cpr > 0, cpr, 1.0)
        q = np.where(cpr > 0, np.floor(theta * (c / TWO_PI)) * (TWO_PI / c) + 0.0, theta)  # quantize_angle, per run
        return q + rng.normal(0.0, 1.0, q.shape) * noise if np.any(noise > 0) else q

    if sim.composition.has_measurement:  # the plant's Measurement effects (per rig: its parameter row)
        tu, tl, X, Y = sim.composition.kernels.client("drillgym.envs.sensor_kernel").measured_channels_batch(
            sim.Y, sim.P
        )
    else:
        tu, tl = sim.theta_u, sim.theta_l
        X, Y = sim.lateral_fixed
    return {
        "t": np.full(sim.n, t),
        "theta_u": enc(tu),
        "theta_l": enc(tl),
        "x": X.copy(),
        "y": Y.copy(),
        "omega_ref": ref,
    }
