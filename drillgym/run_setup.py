"""The arrays a run of the compiled kernels starts from, checked and laid out.

The commands (:func:`input_matrix`), the initial states (:func:`initial_states`), the delay lines
of Delay effects (:func:`delay_lines`), the recorded columns (:func:`record_columns`) and the
friction model's regularisation (:func:`friction_eps`), shared by :func:`drillgym.simulate_batch`
and :class:`drillgym.BatchSimulator`.
"""

from __future__ import annotations

import numbers
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from .configurations import N_STATE
from .effects.composition import Composition
from .errors import InputError, InputTypeError
from .io import U_LIMIT_FILE
from .params import RigParams
from .trajectory import column_index

__all__ = [
    "InputLike",
    "ParamsLike",
    "DEFAULT_SMOOTH_EPS",
    "U_LIMIT",
    "real_number",
    "whole_number",
    "as_voltages",
    "real_numbers",
    "initial_state",
    "input_matrix",
    "delay_lines",
    "initial_states",
    "friction_eps",
    "record_columns",
    "optional_args",
]

#: a motor command: a scalar, one value per run, per-step values, a ``(t, u)`` table or a function of time
InputLike = float | Sequence[float] | np.ndarray | tuple | Callable[[np.ndarray], np.ndarray]
#: parameters: one RigParams, one per run, or a parameter matrix
ParamsLike = RigParams | Sequence[RigParams] | np.ndarray | None
DEFAULT_SMOOTH_EPS = 1e-3  # rad/s, for friction="smooth"
#: V: the largest motor command a run accepts, as the command line and recordings (the amplifier gives +-5 V)
U_LIMIT = U_LIMIT_FILE


def _shown(value: Any) -> str:
    """``value`` for a message: numbers as plain numbers (never ``np.float64(2.1)``), the rest by repr."""
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        return f"{float(value):g}"
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def real_number(name: str, value: Any, unit: str) -> float:
    """``value`` as a float, refused unless it is one real number.

    Parameters
    ----------
    name : str
        The argument's name, for the message.
    value : Any
        What the caller gave.
    unit : str
        Its unit, for the message (e.g. ``"s"``).

    Returns
    -------
    float
        The value (finiteness and range are the caller's to check).

    Raises
    ------
    InputTypeError
        ``value`` is a string, a bool, None, an array of several values or anything not a real number.
    """
    if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iuf":
        value = value.item()
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InputTypeError(f"{name} must be a number ({unit}), got {_shown(value)} of type {type(value).__name__}")
    return float(value)


def whole_number(name: str, value: Any, minimum: int) -> int:
    """``value`` as an int >= ``minimum``; refused if it is not a whole number (2.5, "3", True) or smaller.

    Raises
    ------
    InputTypeError
        ``value`` is not an integer.
    InputError
        ``value`` is smaller than ``minimum``.
    """
    if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iu":
        value = value.item()
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise InputTypeError(f"{name} must be a whole number, got {_shown(value)} of type {type(value).__name__}")
    if value < minimum:
        raise InputError(f"{name} must be >= {minimum}, got {value}")
    return int(value)


def real_numbers(name: str, value: Any, unit: str) -> np.ndarray:
    """``value`` (a number or an array of numbers) as a float array; refused if it holds anything else or NaN/inf.

    Raises
    ------
    InputTypeError
        ``value`` is None, a string, a bool or holds something other than numbers.
    InputError
        A value is NaN or infinite.
    """
    if value is None or isinstance(value, (str, bytes, bool)):
        raise InputTypeError(f"{name} must be a number or an array of numbers ({unit}), got {_shown(value)}")
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputTypeError(f"{name} must hold numbers ({unit}), got {_shown(value)}") from None
    if not np.all(np.isfinite(array)):
        raise InputError(f"{name} must be finite ({unit}), got {_shown(value)}")
    return array


#: the most steps one run may take (1e9 steps of the rig's states alone fill 80 GB)
MAX_STEPS = 1e9


def step_grid(duration: Any, dt: Any) -> tuple[float, float]:
    """A run's ``duration`` (s) and step ``dt`` (s), refused unless they are numbers in range.

    Raises
    ------
    InputTypeError
        Either is not a number.
    InputError
        ``duration`` not positive and finite, or ``dt`` outside (0, 0.1] s.
    """
    duration, dt = real_number("duration", duration, "s"), real_number("dt", dt, "s")
    if not (np.isfinite(duration) and duration > 0):
        raise InputError(f"duration must be a positive number of seconds, got {duration:g}")
    if not (np.isfinite(dt) and 0 < dt <= 0.1):
        raise InputError(f"dt must be in (0, 0.1] s, got {dt:g}")
    if not duration / dt <= MAX_STEPS:
        raise InputError(
            f"duration {duration:g} s at dt {dt:g} s is {duration / dt:.3g} steps, more than a run can hold "
            f"({MAX_STEPS:.0e}): shorten the duration or raise dt"
        )
    return duration, dt


def as_voltages(u: Any, what: str = "u") -> np.ndarray:
    """``u`` as a float array, refused in the caller's words if it holds anything but numbers."""
    if u is None or isinstance(u, (str, bytes, bool)):
        raise InputTypeError(
            f"{what} must be a voltage (V): a number, per-step values, a (t, u) table or a function of time; "
            f"got {_shown(u)}"
        )
    try:
        return np.asarray(u, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputTypeError(f"{what} must hold numbers (V), got {_shown(u)}") from None


def initial_state(
    alpha0: float = 0.0,
    theta_u0: float = 0.0,
    omega_u0: float = 0.0,
    omega_l0: float = 0.0,
    x0: float = 0.0,
    y0: float = 0.0,
    vx0: float = 0.0,
    vy0: float = 0.0,
) -> np.ndarray:
    """A mechanical state vector (see :mod:`drillgym.configurations`).

    Effect states, when a composition has any, start at 0.

    Parameters
    ----------
    alpha0 : float, optional
        Initial winding ``theta_l - theta_u`` (rad).
    theta_u0 : float, optional
        Upper disc angle (rad).
    omega_u0, omega_l0 : float, optional
        Upper and lower disc speeds (rad/s).
    x0, y0 : float, optional
        Lateral position of the lower disc in the rotating frame (m).
    vx0, vy0 : float, optional
        Lateral velocity in the rotating frame (m/s).

    Returns
    -------
    numpy.ndarray
        ``(theta_u, theta_l, omega_u, omega_l, x, y, vx, vy)``.

    Raises
    ------
    InputTypeError
        A value that is not a number.
    InputError
        A value that is not finite.
    """
    given = dict(alpha0=alpha0, theta_u0=theta_u0, omega_u0=omega_u0, omega_l0=omega_l0, x0=x0, y0=y0, vx0=vx0, vy0=vy0)
    units = dict(alpha0="rad", theta_u0="rad", omega_u0="rad/s", omega_l0="rad/s", x0="m", y0="m", vx0="m/s", vy0="m/s")
    v = {k: real_number(k, x, units[k]) for k, x in given.items()}
    bad = next((k for k, x in v.items() if not np.isfinite(x)), None)
    if bad is not None:
        raise InputError(f"{bad} must be finite, got {v[bad]}")
    return np.array(
        [
            v["theta_u0"],
            v["theta_u0"] + v["alpha0"],
            v["omega_u0"],
            v["omega_l0"],
            v["x0"],
            v["y0"],
            v["vx0"],
            v["vy0"],
        ],
        dtype=np.float64,
    )


def table_steps(ts: np.ndarray, n_steps: int, dt: float) -> np.ndarray:
    """First grid step of each entry of a ``(t, u)`` table.

    Step ``i`` (time ``t_i = i dt``) uses the last entry with ``ts[j] <= t_i`` (to 1e-12 dt); the
    first entry also applies before its time.

    Parameters
    ----------
    ts : numpy.ndarray
        The table's times (s), non-decreasing.
    n_steps : int
        Steps of the run.
    dt : float
        Integration step (s).

    Returns
    -------
    numpy.ndarray of int64
        The step from which each entry applies.
    """
    first = np.maximum(np.ceil(ts / dt - 1e-12), 0).astype(np.int64)
    for j, tj in enumerate(ts):  # the grid's own rounding decides, as a comparison against t_i would
        while first[j] > 0 and (first[j] - 1) * dt + 1e-12 * dt >= tj:
            first[j] -= 1
        while first[j] * dt + 1e-12 * dt < tj:
            first[j] += 1
    first[0] = 0
    return first


def input_matrix(u: InputLike, n_batch: int, n_steps: int, dt: float) -> tuple[np.ndarray, np.ndarray | None]:
    """The kernels' commands of a run, held from step to step (zero-order hold).

    Step ``i`` uses ``u(t_i)``. A constant command (a scalar or one per run) stays one column
    ``(B, 1)``, never expanded over the steps; a ``(t, u)`` table stays its ``m`` entries ``(B, m)``
    with the step from which each applies (evaluated in the kernels).

    Parameters
    ----------
    u : InputLike
        Motor voltage (V): see :func:`drillgym.simulate_batch`.
    n_batch : int
        Number of runs B.
    n_steps : int
        Steps of each run.
    dt : float
        Integration step (s).

    Returns
    -------
    U : numpy.ndarray
        Commands (V), ``(B, 1)``, ``(B, n_steps)`` or ``(B, m)``.
    USTEP : numpy.ndarray or None
        For a table, the first step of each entry ``(m,)``; else None.

    Raises
    ------
    InputError
        The table is malformed, the signal is too short, the rows do not match the batch, or a
        command is NaN or infinite.
    """
    steps = None
    if callable(u):
        U = as_voltages(u(np.arange(n_steps) * dt), "the value of the input function u(t)")
        if U.ndim == 0:
            U = np.full(n_steps, float(U))
    elif isinstance(u, tuple) and len(u) == 2:
        ts = as_voltages(u[0], "the times t of a (t, u) input")
        us = as_voltages(u[1], "the voltages u of a (t, u) input")
        if ts.ndim != 1 or ts.size == 0 or us.shape[-1] != ts.size or us.ndim > 2:
            raise InputError(f"a (t, u) input needs t (m,) and u (m,) or (B, m); got {ts.shape} and {us.shape}")
        if not (np.all(np.isfinite(ts)) and np.all(np.diff(ts) >= 0)):
            raise InputError("the times of a (t, u) input must be finite and non-decreasing")
        steps = table_steps(ts, n_steps, dt)
        U = us
    else:
        U = as_voltages(u, "u")
        if U.ndim == 0:
            U = np.full((n_batch, 1), float(U))
        elif U.ndim == 1 and U.shape[0] == n_batch and n_steps != n_batch:
            U = U[:, None].copy()
    if U.ndim == 1:
        U = np.broadcast_to(U, (n_batch, U.shape[0]))
    if steps is None and U.shape[-1] != 1 and U.shape[-1] < n_steps:
        raise InputError(f"input signal has {U.shape[-1]} samples, the run needs {n_steps} (one per step)")
    if steps is None and U.shape[-1] != 1:
        U = U[..., :n_steps]
    U = np.ascontiguousarray(U, dtype=np.float64)
    if U.shape[0] != n_batch:
        raise InputError(f"input has {U.shape[0]} rows for a batch of {n_batch}")
    if not np.all(np.isfinite(U)):
        bad = np.argwhere(~np.isfinite(U))[0]
        raise InputError(
            f"input voltage is NaN/inf (trajectory {bad[0]}, {'entry' if steps is not None else 'step'} {bad[1]})"
        )
    if U.size and not np.max(np.abs(U)) <= U_LIMIT:
        bad = np.unravel_index(np.argmax(np.abs(U)), U.shape)
        raise InputError(
            f"input voltage {U[bad]:g} V (trajectory {bad[0]}, {'entry' if steps is not None else 'step'} {bad[1]}) "
            f"is beyond the model's range |u| <= {U_LIMIT:g} V (the rig's amplifier gives +-5 V)"
        )
    return U, steps


def delay_lines(
    comp: Composition, P: np.ndarray, dt: float, u_before: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Delay lines and their heads for the composition's Delay effects.

    Without ``u_before`` the lines are empty (head -1: the first command is taken as held before
    the start); with it they hold the commands of the steps before the start (steps older than
    given: the oldest value held).

    Parameters
    ----------
    comp : Composition
        The composition of effects.
    P : numpy.ndarray
        Parameter matrix ``(B, n_params)``.
    dt : float
        Integration step (s).
    u_before : numpy.ndarray, optional
        Commands (V) of the steps before the start, ``(m,)`` or ``(B, m)``, oldest first.

    Returns
    -------
    H : numpy.ndarray
        Delay lines ``(B, L)``.
    head : numpy.ndarray of int64
        Index of each line's newest entry ``(B,)``, -1 when empty.

    Raises
    ------
    InputError
        ``u_before`` contains NaN or inf.
    """
    L = comp.delay_line_length(P, dt)
    B = P.shape[0]
    H, head = np.zeros((B, L)), np.full(B, -1, dtype=np.int64)
    if u_before is not None and comp.has_delay:
        ub = np.asarray(u_before, dtype=np.float64)
        ub = np.broadcast_to(ub if ub.ndim == 2 else ub[None, :], (B, ub.shape[-1]))
        if ub.shape[1] > 0:
            if not np.all(np.isfinite(ub)):
                raise InputError("u_before contains NaN or inf")
            m = min(ub.shape[1], L)
            H[:, L - m :] = ub[:, ub.shape[1] - m :]
            H[:, : L - m] = ub[:, ub.shape[1] - m : ub.shape[1] - m + 1]
            head[:] = L - 1
    return H, head


def initial_states(comp: Composition, B: int, x0: Any, alpha0: Any) -> np.ndarray:
    """Initial states of B runs: at rest with winding ``alpha0``, or ``x0``.

    Effect states not given start at 0, except lag states: NaN, which the kernels replace at the
    first step by the first command held before the start (as the delay lines assume; the
    identification starts its lag filter the same way).

    Parameters
    ----------
    comp : Composition
        The composition of effects.
    B : int
        Number of runs.
    x0 : array_like or None
        All states ``(n_state,)`` or ``(B, n_state)``, or the 8 mechanical ones; None: at rest.
    alpha0 : float or array_like
        Initial winding (rad), scalar or per run, used when ``x0`` is None.

    Returns
    -------
    numpy.ndarray
        States ``(B, n_state)``.

    Raises
    ------
    InputError
        ``x0`` has the wrong length or contains NaN or inf.
    """
    n = comp.n_state
    if x0 is None:
        Y = np.zeros((B, n))
        Y[:, 1] = np.broadcast_to(real_numbers("alpha0", alpha0, "rad"), (B,))
        Y[:, list(comp.lag_state_columns)] = np.nan
        return Y
    X = real_numbers("the initial state x0", x0, "the states' units")
    given = X.shape[-1]
    if given == N_STATE and n > N_STATE:  # mechanical states only: effect states start at 0
        X = np.concatenate([X, np.zeros(X.shape[:-1] + (n - N_STATE,))], axis=-1)
    if X.shape[-1] != n:
        raise InputError(f"initial state must have {n} entries ({', '.join(comp.full_state_names)}), got {X.shape[-1]}")
    Y = np.array(np.broadcast_to(X, (B, n)))
    if not np.all(np.isfinite(Y)):
        raise InputError("initial state contains NaN or inf")
    if given == N_STATE:
        Y[:, list(comp.lag_state_columns)] = np.nan
    return Y


def friction_eps(friction: str, smooth_eps: float) -> float:
    """The kernels' friction regularisation: 0 for the exact set-valued law.

    Parameters
    ----------
    friction : str
        ``"exact"`` (set-valued, event-driven) or ``"smooth"`` (``tanh(w / smooth_eps)``).
    smooth_eps : float
        Speed scale of the smooth law (rad/s).

    Returns
    -------
    float
        0.0 for ``"exact"``, else ``smooth_eps``.

    Raises
    ------
    InputError
        Unknown ``friction``, or ``smooth_eps <= 0`` with ``"smooth"``.
    """
    if friction == "exact":
        return 0.0
    if friction == "smooth":
        if not smooth_eps > 0:
            raise InputError("smooth_eps must be > 0 for friction='smooth'")
        return float(smooth_eps)
    raise InputError(f"friction must be 'exact' (set-valued, default) or 'smooth', got {friction!r}")


def record_columns(comp: Composition, record: Sequence[str] | None) -> tuple[tuple, np.ndarray | None]:
    """The recorded outputs of a run.

    Parameters
    ----------
    comp : Composition
        The composition of effects.
    record : sequence of str or str or None
        Names among the composition's ``output_names``; None records all.

    Returns
    -------
    names : tuple of str
        The recorded columns.
    cols : numpy.ndarray of int64 or None
        Their indices for the kernels; None means all columns.

    Raises
    ------
    InputError
        A name is unknown or repeated, or none is given.
    """
    if record is None:
        return comp.output_names, None
    if isinstance(record, str):
        record = (record,)
    names = tuple(record)
    unknown = [n for n in names if n not in comp.output_names]
    if unknown or len(set(names)) != len(names) or not names:
        what = f"unknown column {unknown[0]!r}" if unknown else "empty or repeated columns"
        raise InputError(f"record: {what}; choose among {', '.join(comp.output_names)}")
    idx = column_index(comp.output_names)
    return names, np.array([idx[n] for n in names], dtype=np.int64)


def optional_args(COLS: np.ndarray | None, USTEP: np.ndarray | None, n_out: int) -> tuple:
    """The kernels' optional trailing arguments ``(COLS, USTEP)``.

    They are omitted, not None, when not used: numba compiles one version per combination actually
    used. A table without chosen columns records all of them.

    Parameters
    ----------
    COLS : numpy.ndarray or None
        Indices of the recorded columns, or None for all.
    USTEP : numpy.ndarray or None
        First step of each entry of a ``(t, u)`` table, or None.
    n_out : int
        Number of output columns of the composition.

    Returns
    -------
    tuple
        ``()``, ``(COLS,)`` or ``(COLS, USTEP)``.
    """
    if USTEP is None:
        return () if COLS is None else (COLS,)
    return (np.arange(n_out, dtype=np.int64) if COLS is None else COLS, USTEP)
