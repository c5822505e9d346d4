"""Simulated runs as tables: :class:`Trajectory` (one run) and :class:`BatchTrajectory` (many).

Both hold the recorded samples of the columns ``output_names`` of their composition of effects
and give each column as an attribute (``traj.omega_l``, ``batch.omega_l``).

:func:`check_run` is the test every produced run passes before it is returned (the simulator's
single runs and batches, the stepping :class:`~drillgym.batch_simulator.BatchSimulator`): a run
whose state is not finite, or whose disc speed exceeds :func:`speed_limit`, is a
:class:`~drillgym.errors.SimulationError` naming the run, the time and the state.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from .configurations import Configuration
from .effects.composition import Composition
from .errors import InputError, SimulationError
from .params import IDX, RigParams

__all__ = ["Trajectory", "BatchTrajectory", "column_index", "check_run", "speed_limit", "SPEED_FACTOR", "U_REACH"]

#: V: the largest voltage any input of drillgym may hold (the files' and the command line's limit;
#: the rig's amplifier gives +-5 V)
U_REACH = 50.0
#: a disc speed beyond this many times the motor's no-load speed at :data:`U_REACH` is a diverged run
SPEED_FACTOR = 100.0
_SPEEDS = ("omega_u", "omega_l")


def column_index(names: Sequence[str]) -> dict[str, int]:
    """Map column names to their positions.

    Parameters
    ----------
    names : sequence of str
        Column names in recording order.

    Returns
    -------
    dict of str to int
        The position of each name.
    """
    return {n: i for i, n in enumerate(names)}


def speed_limit(p: np.ndarray) -> np.ndarray:
    """The disc speed no run of the rig can reach (rad/s), per parameter vector.

    In steady rotation at a voltage ``u`` the motor torque ``km u`` balances the viscous friction
    of the upper disc, the bearing and the brake, so no disc turns faster than the motor's no-load
    speed ``km u / (bu + bl + bb)`` (89 rad/s at 50 V with the nominal parameters; the rig's 5 V
    give 9 rad/s). The limit is :data:`SPEED_FACTOR` times that speed at :data:`U_REACH` (8900 rad/s,
    85,000 rpm, nominally): far above any transient (a released wound-up string, an effect's
    torque), far below a numerical divergence. Without viscous friction there is no such speed
    and the limit is infinite (only non-finite states count).

    Parameters
    ----------
    p : numpy.ndarray
        Parameter vectors ``(n_params,)`` or ``(B, n_params)`` (base parameters first).

    Returns
    -------
    numpy.ndarray
        The limit of each vector (rad/s), ``inf`` without viscous friction.
    """
    p = np.atleast_2d(np.asarray(p, dtype=np.float64))
    viscous = p[:, IDX.bu] + p[:, IDX.bl] + p[:, IDX.bb]
    with np.errstate(divide="ignore"):
        return np.where(viscous > 0, SPEED_FACTOR * p[:, IDX.km] * U_REACH / viscous, np.inf)


@njit(cache=True)
def _first_bad_sample(D, speed_cols, limits):
    """``(sample, run)`` of the earliest sample of ``D`` (n_samples, n_columns, B) with a non-finite value or a
    speed column beyond its run's limit; ``(-1, -1)`` when none. One read of the data, stopping at the first."""
    n, m, B = D.shape
    for k in range(n):
        for j in range(m):
            for b in range(B):
                if not np.isfinite(D[k, j, b]):
                    return k, b
        for j in speed_cols:
            for b in range(B):
                if abs(D[k, j, b]) > limits[b]:
                    return k, b
    return -1, -1


def _first_bad(data: np.ndarray, names: Sequence[str], limits: np.ndarray) -> tuple[int, int, list[int]] | None:
    """``(run, sample, columns)`` of the earliest sample with a non-finite value or an over-fast speed
    (the earliest over the runs), or None."""
    speeds = np.array([names.index(n) for n in _SPEEDS if n in names], dtype=np.int64)
    if data.size == 0:
        return None
    k, b = _first_bad_sample(data.transpose(1, 2, 0), speeds, np.ascontiguousarray(limits, dtype=np.float64))
    if k < 0:
        return None
    row = data[b, k]
    bad = ~np.isfinite(row)
    for j in speeds:
        bad[j] |= abs(row[j]) > limits[b]
    return int(b), int(k), [int(j) for j in np.flatnonzero(bad)]


def check_run(
    data: np.ndarray,
    names: Sequence[str],
    final: np.ndarray,
    state_names: Sequence[str],
    P: np.ndarray,
    t0: np.ndarray,
    dt: float,
    record_every: int,
    label: str = "base",
    t_end: np.ndarray | None = None,
) -> None:
    """Refuse a run that diverged: a non-finite value, or a disc faster than :func:`speed_limit`.

    Checks every recorded sample (the first bad one is named: its time, column and value) and the
    final states (for what was not recorded). A run whose samples are all finite and physical
    costs two passes over the recorded data: no check in the compiled loops.

    Parameters
    ----------
    data : numpy.ndarray
        Recorded samples ``(B, n_samples, n_columns)``.
    names : sequence of str
        The recorded columns.
    final : numpy.ndarray
        Final states ``(B, n_state)``.
    state_names : sequence of str
        Names of the states (the composition's ``full_state_names``).
    P : numpy.ndarray
        Parameter matrix ``(B, n_params)``.
    t0 : numpy.ndarray
        Start time of each run (s), ``(B,)``.
    dt : float
        Integration step (s).
    record_every : int
        Steps between recorded samples.
    label : str, optional
        The model (composition's label), named in the message.
    t_end : numpy.ndarray, optional
        Time of the final states (s), ``(B,)``; named when only they are bad (default: "by its end").

    Raises
    ------
    SimulationError
        The run diverged: names the run (in a batch), the time, the state, its value and the limit.
    """
    names = list(names)
    limits = speed_limit(P) if len(P) else np.zeros(0)
    limits = np.broadcast_to(limits, (data.shape[0],))
    where = _first_bad(data, names, limits)
    if where is not None:
        b, k, cols = where
        t = float(data[b, k, names.index("t")]) if "t" in names else float(t0[b]) + k * record_every * dt
        _raise(data.shape[0], b, t, [(names[j], float(data[b, k, j])) for j in cols], float(limits[b]), label)
    final = np.asarray(final)
    state_names = list(state_names)
    bad = ~np.isfinite(final)
    for n in _SPEEDS:
        if n in state_names:
            bad[:, state_names.index(n)] |= np.abs(final[:, state_names.index(n)]) > limits
    if bad.any():
        b = int(np.flatnonzero(bad.any(axis=1))[0])
        values = [(state_names[j], float(final[b, j])) for j in np.flatnonzero(bad[b])]
        _raise(final.shape[0], b, None if t_end is None else float(t_end[b]), values, float(limits[b]), label)


def _raise(n_runs: int, b: int, t: float | None, values: list[tuple[str, float]], limit: float, label: str) -> None:
    """Raise the :class:`SimulationError` of run ``b``: the time, the states that left the range (speeds first)."""
    values = sorted(values, key=lambda nv: nv[0] not in _SPEEDS)
    run = f"run {b} of the batch " if n_runs > 1 else "the run "
    when = f"at t = {t:.6g} s" if t is not None else "by its end (the state was not recorded)"
    model = "" if label in ("", "base") else f" with the effects {label}"
    shown = ", ".join(f"{n} = {v:.3g}" for n, v in values[:3])
    shown += f" and {len(values) - 3} more" if len(values) > 3 else ""
    if not all(np.isfinite(v) for _, v in values):
        why = f"{shown} (not finite){model}: check the effects' formulas, parameter values and x0"
    else:
        verb = "exceed" if len(values) > 1 else "exceeds"
        why = (
            f"{shown} rad/s {verb} {limit:.3g} rad/s, {SPEED_FACTOR:g} times the motor's no-load speed "
            f"at {U_REACH:g} V (a physical run cannot reach it){model}: check the parameters, x0 and alpha0"
        )
    raise SimulationError(f"{run}diverged {when}: {why}")


@dataclass
class Trajectory:
    """One simulated run: samples (rows) of the columns ``output_names``.

    Attributes named like the columns give 1-D arrays: ``t`` (s), ``u`` (V, the command),
    ``theta_u``, ``theta_l``, ``alpha`` (rad), ``omega_u``, ``omega_l`` (rad/s), ``x``, ``y``
    (fixed frame, m), ``r`` (m), ``x_rot``, ``y_rot`` (rotating frame, m), ``Tfu``, ``Tfl`` (N m),
    ``stick_u``, ``stick_l`` (1 = stuck), then the effects' states (e.g. ``u_m``, V, with
    ``motor_lag``).

    Attributes
    ----------
    config : Configuration
        The rig configuration simulated.
    params : RigParams
        The base parameters of the run.
    dt : float
        Integration step (s).
    method : str
        Integration method (``"rk4"``, ``"dp5"`` or ``"dp45"``).
    data : numpy.ndarray
        The samples, shape ``(n_samples, n_columns)``.
    composition : Composition
        The effects added to the base model (empty for the base model).
    effect_values : dict
        The effects' parameter values by name.
    names : tuple of str or None
        The recorded columns; None means all of the composition's ``output_names``.
    """

    config: Configuration
    params: RigParams
    dt: float
    method: str
    data: np.ndarray
    composition: Composition = field(default_factory=lambda: Composition(()))
    effect_values: dict = field(default_factory=dict)
    names: tuple | None = None

    def __getattr__(self, name: str) -> np.ndarray:
        if "data" in self.__dict__ and "composition" in self.__dict__:
            idx = column_index(self.output_names)
            if name in idx:
                return self.data[:, idx[name]]
            if name in self.composition.output_names:
                raise AttributeError(f"column {name!r} was not recorded (record={self.output_names})")
        raise AttributeError(name)

    @property
    def output_names(self) -> tuple[str, ...]:
        """The names of the recorded columns, in the order of ``data``'s columns."""
        return self.names if self.names is not None else self.composition.output_names

    @property
    def final_state(self) -> np.ndarray:
        """State vector at the last sample, to continue a run.

        Returns
        -------
        numpy.ndarray
            The mechanical states, then the effects' states.

        Raises
        ------
        InputError
            A state column was not recorded.
        """
        names = self.composition.full_state_names
        state_cols = [n + "_rot" if n in ("x", "y", "vx", "vy") else n for n in names]  # rotating-frame columns
        idx = column_index(self.output_names)
        missing = [c for c in state_cols if c not in idx]
        if missing:
            raise InputError(f"final_state needs the state columns; {', '.join(missing)} were not recorded")
        row = self.data[-1]
        return np.array([row[idx[c]] for c in state_cols])

    @property
    def parameter_vector(self) -> np.ndarray:
        """The kernels' parameter vector of this run (base, then the effects' parameters)."""
        return self.composition.vector(self.params, self.effect_values)

    def columns(self) -> dict[str, np.ndarray]:
        """The recorded columns by name.

        Returns
        -------
        dict of str to numpy.ndarray
            One 1-D array per recorded column.
        """
        return {n: self.data[:, i] for i, n in enumerate(self.output_names)}

    def to_csv(self, path, description: str = "") -> None:
        """Write the run in the interchange format of docs/data_format.md.

        Parameters
        ----------
        path : str or path-like
            The CSV file to write.
        description : str, optional
            Free text stored in the file's header.
        """
        from .io import write_trajectory_csv

        write_trajectory_csv(self, path, description=description)


@dataclass
class BatchTrajectory:
    """Many runs of one configuration; ``batch[k]`` is the :class:`Trajectory` of run ``k``.

    Attributes named like the columns give 2-D arrays ``(B, n_samples)``.

    Attributes
    ----------
    config : Configuration
        The rig configuration simulated.
    params : list of RigParams
        The base parameters of each run.
    dt : float
        Integration step (s).
    method : str
        Integration method.
    data : numpy.ndarray
        The samples, shape ``(B, n_samples, n_columns)``.
    composition : Composition
        The effects added to the base model.
    effect_values : list of dict
        The effects' parameter values of each run.
    names : tuple of str or None
        The recorded columns; None means all of the composition's ``output_names``.
    """

    config: Configuration
    params: list[RigParams]
    dt: float
    method: str
    data: np.ndarray
    composition: Composition = field(default_factory=lambda: Composition(()))
    effect_values: list = field(default_factory=list)
    names: tuple | None = None

    @property
    def output_names(self) -> tuple[str, ...]:
        """The names of the recorded columns, in the order of ``data``'s last axis."""
        return self.names if self.names is not None else self.composition.output_names

    def __len__(self) -> int:
        return self.data.shape[0]

    def __getitem__(self, k: int) -> Trajectory:
        vals = self.effect_values[k] if self.effect_values else {}
        return Trajectory(
            self.config, self.params[k], self.dt, self.method, self.data[k], self.composition, vals, self.names
        )

    def __getattr__(self, name: str) -> np.ndarray:
        if "data" in self.__dict__ and "composition" in self.__dict__:
            idx = column_index(self.output_names)
            if name in idx:
                return self.data[:, :, idx[name]]
            if name in self.composition.output_names:
                raise AttributeError(f"column {name!r} was not recorded (record={self.output_names})")
        raise AttributeError(name)
