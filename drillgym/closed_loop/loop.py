"""Drive the compiled closed loop: a :class:`drillgym.BatchSimulator` and a compiled law over a whole run."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..batch_simulator import BatchSimulator
from ..errors import InputError, SimulationError
from ..lane_runner import block_width
from ..trajectory import speed_limit
from .abi import M_REF, N_MEASUREMENTS

__all__ = ["LoopSignals", "run_compiled_loop", "CHUNK_PERIODS", "KERNEL_MODULE"]

KERNEL_MODULE = "drillgym.closed_loop.kernel"
#: control periods per compiled call: the angle noise of one chunk is drawn at once (2 x lanes x periods floats)
CHUNK_PERIODS = 500


@dataclass
class LoopSignals:
    """Signals of n lanes at the control period, arrays (n, m) (from the compiled loop: transposed views of one
    period-major block, Fortran-ordered).

    Attributes
    ----------
    u : ndarray
        Command held over each period (V), clipped to the amplifier's range.
    omega_u, omega_l : ndarray
        Disc speeds at the period's start (rad/s).
    alpha : ndarray
        Winding theta_l - theta_u (rad).
    stuck_l : ndarray
        1.0 where the lower disc sticks, else 0.0.
    friction_l : ndarray
        Lower friction torque (N m).
    r : ndarray
        Lateral displacement of the lower disc's centre (m).
    """

    u: np.ndarray
    omega_u: np.ndarray
    omega_l: np.ndarray
    alpha: np.ndarray
    stuck_l: np.ndarray
    friction_l: np.ndarray
    r: np.ndarray


def run_compiled_loop(
    sim: BatchSimulator,
    law,
    X: np.ndarray,
    C: np.ndarray,
    *,
    periods: int,
    control_dt: float,
    first: dict[str, np.ndarray],
    counts_per_rev: np.ndarray,
    angle_noise: np.ndarray,
    rng: np.random.Generator,
    u_max: float,
) -> LoopSignals:
    """Advance the runs of ``sim`` and a compiled law together for ``periods`` control periods.

    Parameters
    ----------
    sim : BatchSimulator
        The plants (n runs, reset), stepped in place with exact friction on a fixed step that divides
        ``control_dt``.
    law : numba function
        The law, compiled with :data:`drillgym.closed_loop.abi.LAW_SIGNATURE`.
    X : ndarray
        The law's state (rows, n), float64, C order; updated in place.
    C : ndarray
        The law's shared constants (k,), float64.
    periods : int
        Control periods to run.
    control_dt : float
        Control period (s).
    first : dict of str to ndarray
        The first period's measurements (``theta_u``, ``theta_l``, ``x``, ``y`` and ``omega_ref``, (n,)),
        already taken (the law was started from them); later periods are measured by the loop.
    counts_per_rev, angle_noise : ndarray
        Encoder resolution (counts/rev, 0: exact angles) and white angle noise (rad, standard deviation)
        of each run, (n,).
    rng : numpy.random.Generator
        The noise's stream: standard normal draws, per period theta_u's n then theta_l's n (as a
        measurement per period would draw them), drawn a chunk of periods at a time.
    u_max : float
        The amplifier's range (V): commands are clipped to [-u_max, u_max].

    Returns
    -------
    LoopSignals
        The signals of the n runs at the control period.

    Raises
    ------
    FloatingPointError
        The law gave a command that is not finite.
    SimulationError
        A run diverged (as :meth:`BatchSimulator.advance`).
    """
    n = sim.n
    sub = int(round(control_dt / sim.dt))
    if sub < 1 or abs(sub * sim.dt - control_dt) > 1e-9:
        raise InputError(f"control period {control_dt} s must be a multiple of the integrator step {sim.dt} s")
    if sim._eps != 0.0:
        raise InputError("the compiled loop steps exact friction only")
    kernel = sim.composition.kernels.client(KERNEL_MODULE)
    lanes = bool(sim._lanes)
    width = block_width(n) if lanes else n
    arrays = [sim.Y, sim.MODE, sim.P, sim.T, sim.FRIC, sim.HIST, sim.HEAD]
    padded = lanes and width != n
    Y, MODE, P, T, FRIC, HIST, HEAD = [np.ascontiguousarray(_pad(a, width) if padded else a) for a in arrays]
    own = [a is b for a, b in zip(arrays, (Y, MODE, P, T, FRIC, HIST, HEAD))]
    M = np.zeros((N_MEASUREMENTS, n))
    for row, key in enumerate(("theta_u", "theta_l", "x", "y", "omega_ref")):
        M[row] = np.broadcast_to(np.asarray(first[key], dtype=float), (n,))
    M[M_REF] = np.broadcast_to(np.asarray(first["omega_ref"], dtype=float), (n,))
    U, UL = np.zeros(n), np.zeros((width, 1))
    OUT = np.empty((7, periods, n))  # period-major: the kernel stores a period's signals contiguously
    norec = np.zeros((0, len(sim.composition.output_names), width))
    cpr = np.ascontiguousarray(counts_per_rev, dtype=float)
    noise = np.ascontiguousarray(angle_noise, dtype=float)
    noisy = bool(np.any(noise > 0))
    limit = float(speed_limit(sim.P).min())
    A, b, c = (np.ascontiguousarray(x, dtype=float) for x in sim._tab)
    has_meas = bool(sim.composition.has_measurement)
    Xc, Cc = _checked(X, n, "X"), np.ascontiguousarray(C, dtype=np.float64)
    k0 = 0
    while k0 < periods:
        m = min(CHUNK_PERIODS, periods - k0)
        draws = m - (k0 == 0)
        Z = np.zeros((m, 2, n))
        if noisy and draws:
            Z[m - draws :] = rng.normal(0.0, 1.0, (draws, 2, n))
        done, status = kernel.run_periods(
            law, Xc, Cc, U, M, UL, Y, MODE, P, int(sim.config), sim.dt, sub, T, 0.0, A, b, c, FRIC, HIST, HEAD,
            norec, n, lanes, has_meas, k0, m, float(control_dt), cpr, noise, Z, noisy, k0 == 0, float(u_max),
            limit, OUT,
        )  # fmt: skip
        if status != kernel.OK or done < m:
            _copy_back(arrays, (Y, MODE, P, T, FRIC, HIST, HEAD), own, n)
            if status == kernel.NON_FINITE_COMMAND:
                t = (k0 + done) * control_dt
                raise FloatingPointError(f"the compiled law produced a non-finite voltage at t = {t:g} s")
            sim._check()
            raise SimulationError(f"a run diverged before t = {(k0 + done) * control_dt:g} s")
        k0 += m
    _copy_back(arrays, (Y, MODE, P, T, FRIC, HIST, HEAD), own, n)
    if X is not Xc:
        X[...] = Xc
    return LoopSignals(*(a.T for a in OUT))  # (n, m) views


def _pad(a: np.ndarray, width: int) -> np.ndarray:
    out = np.empty((width,) + a.shape[1:], dtype=a.dtype)
    out[: a.shape[0]] = a
    out[a.shape[0] :] = a[a.shape[0] - 1]
    return out


def _copy_back(arrays, working, own, n) -> None:
    for a, w, same in zip(arrays, working, own):
        if not same:
            a[...] = w[:n]


def _checked(X: np.ndarray, n: int, name: str) -> np.ndarray:
    X = np.ascontiguousarray(X, dtype=np.float64)
    if X.ndim != 2 or X.shape[1] != n:
        raise InputError(f"the law's state {name} must be (rows, {n}), got {X.shape}")
    return X
