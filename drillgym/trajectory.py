"""Simulated runs as tables: :class:`Trajectory` (one run) and :class:`BatchTrajectory` (many).

Both hold the recorded samples of the columns ``output_names`` of their composition of effects
and give each column as an attribute (``traj.omega_l``, ``batch.omega_l``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .configurations import Configuration
from .effects.composition import Composition
from .errors import InputError
from .params import RigParams

__all__ = ["Trajectory", "BatchTrajectory", "column_index"]


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
        """Write the run in the interchange format of ``shared/DATA_FORMAT.md``.

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
