"""The base of a residual policy built on each rig's own model: training on identified plants.

An identified task scores a residual policy on its base controller (``observer``, ``lqg-2enc``:
:mod:`agents.residual_bases`) built on each held-out plant's identified model (``controllers.make("agent:DIR",
model=...)``).  A residual trained on a base built on one nominal model learns to correct that base on the rigs
it trained on, not the base it will run on.  :class:`PlantwiseResidual` gives the training the situation it will
run in: every rig's episode runs one training plant, and the rig's base is the controller built on that plant's
identified model (:func:`agents.identified_plants.identified_plants`), rebuilt at each of the rig's episodes.

It has the interface of the residual bases (what :class:`agents.residual_base_env.ResidualBaseVecEnv` calls),
with the plants of the rigs given at :meth:`~PlantwiseResidual.reset`; each rig holds its own one-rig base, so
a period costs one controller step per rig (about 1 ms on this machine for the observer): the price of one
model per rig.  :func:`plantwise_base` builds it from a recipe's ``identified: {plants: P, folder: DIR}``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from drillgym.envs.tasks import BenchmarkTask
from drillgym.errors import InputError

from .residual_bases import RESIDUAL_BASES, make_residual_base

__all__ = ["PlantwiseResidual", "PlantwiseObserverResidual", "IdentifiedTraining", "plantwise_base"]


@dataclass(frozen=True)
class IdentifiedTraining:
    """A recipe's ``identified:`` section: which training plants are identified and run.

    Parameters
    ----------
    plants : int
        The first ``plants`` plants of the task's training list (>= 1); every episode runs one of them.
    folder : str, optional
        Where their identifications are kept (read back, the missing ones identified and written there);
        None: identified in memory.
    """

    plants: int
    folder: str | None = None

    @classmethod
    def from_config(cls, raw: Mapping[str, Any]) -> IdentifiedTraining:
        """The section from its mapping; an unknown or missing key is refused in one line."""
        if not isinstance(raw, Mapping):
            raise InputError(f"identified must be a mapping {{plants: P, folder: DIR}}, got {raw!r}")
        unknown = sorted(set(raw) - {"plants", "folder"})
        if unknown:
            raise InputError(f"identified: unknown key {unknown[0]!r}; it takes plants and folder")
        if "plants" not in raw:
            raise InputError("identified needs plants: how many of the task's training plants to identify and run")
        folder = raw.get("folder")
        return cls(raw["plants"], None if folder is None else str(folder))


class PlantwiseResidual:
    """Rig i's base: controller ``base`` built on ``models[plant of rig i's episode]``.

    Parameters
    ----------
    base : str
        The controller (a key of :data:`agents.residual_bases.RESIDUAL_BASES`).
    config : str
        Rig configuration the controllers are designed for.
    scale : float
        Voltage of a full action (V), > 0.
    models : sequence of drillgym.Model
        The model of each listed plant, by the plant list's index.
    dt : float, optional
        Control period (s).
    options : dict, optional
        Keywords of the controller.
    """

    per_plant = True  # :class:`agents.residual_base_env.ResidualBaseVecEnv` gives the rigs' plants at reset

    def __init__(
        self,
        base: str,
        config: str,
        scale: float,
        models: Sequence[Any],
        dt: float = 0.01,
        options: dict[str, Any] | None = None,
    ) -> None:
        if base not in RESIDUAL_BASES:
            raise InputError(f"base must be {' or '.join(map(repr, RESIDUAL_BASES))}, got {base!r}")
        if not models:
            raise InputError(f"a plant-wise {base} base needs the model of at least one plant")
        self.name, self.config, self.models, self.options = base, config, list(models), dict(options or {})
        self.scale, self.dt = scale, dt
        self.uses: tuple[str, ...] = RESIDUAL_BASES[base].uses
        self._dim = self._build(0).dim  # bad settings fail here, not in the first episode
        self._rigs: list[Any] = []
        self.n = 0

    def _build(self, plant: int) -> Any:
        model = self.models[plant]
        return make_residual_base(self.name, self.config, self.scale, dt=self.dt, options=self.options, model=model)

    @property
    def dim(self) -> int:
        """Number of policy inputs (a rig's base's)."""
        return self._dim

    def start(self, n: int) -> None:
        """Allocate n rigs (call :meth:`reset` for all of them before :meth:`correct`)."""
        self.n = int(n)
        self._rigs = [None] * self.n

    def reset(self, index: np.ndarray, omega_ref: np.ndarray, plants: np.ndarray, **readings: np.ndarray) -> None:
        """Rigs ``index`` start at rest at the encoder angles ``readings`` (rad, by name: :attr:`uses`) towards
        targets omega_ref (rad/s), each on the base built on its plant's model (``plants``: list indices, one per
        rig of ``index``)."""
        idx = np.atleast_1d(np.asarray(index, dtype=np.int64))
        ref = np.broadcast_to(np.asarray(omega_ref, dtype=float), idx.shape)
        pl = np.broadcast_to(np.asarray(plants, dtype=np.int64), idx.shape)
        read = {k: np.broadcast_to(np.asarray(v, dtype=float), idx.shape) for k, v in readings.items()}
        for j, i in enumerate(idx):
            if not 0 <= pl[j] < len(self.models):
                raise InputError(f"rig {i} runs plant {pl[j]}, which has no model (plants 0..{len(self.models) - 1})")
            rig = self._build(int(pl[j]))
            rig.start(1)
            first = {k: v[j : j + 1] for k, v in read.items()}
            rig.reset(np.zeros(1, dtype=np.int64), omega_ref=ref[j : j + 1], **first)
            self._rigs[i] = rig

    def correct(self, index: np.ndarray | slice = slice(None), **readings: np.ndarray) -> None:
        """The encoder angles (rad, by name) of rigs ``index`` this period."""
        read = {k: np.atleast_1d(np.asarray(v, dtype=float)) for k, v in readings.items()}
        for j, i in enumerate(np.arange(self.n)[index]):
            self._rigs[i].correct(**{k: v[j : j + 1] for k, v in read.items()})

    def features(self) -> np.ndarray:
        """Policy inputs (n, :attr:`dim`), float32."""
        return np.concatenate([r.features() for r in self._rigs], axis=0)

    def base(self) -> np.ndarray:
        """The rigs' base voltages (V, (n,)); advances their controllers and clocks by one period."""
        return np.concatenate([r.base() for r in self._rigs])

    def voltage(self, action: np.ndarray) -> np.ndarray:
        """Applied voltages (V, (n,)) for policy actions (n,) or (n, 1) in [-1, 1]."""
        a = np.asarray(action, dtype=float).reshape(-1)
        return np.concatenate([r.voltage(a[i : i + 1]) for i, r in enumerate(self._rigs)])

    def predict(self, u: np.ndarray) -> None:
        """Propagate every rig's estimates over one period with its applied voltage u (V, (n,))."""
        u = np.asarray(u, dtype=float).reshape(-1)
        for i, r in enumerate(self._rigs):
            r.predict(u[i : i + 1])


class PlantwiseObserverResidual(PlantwiseResidual):
    """:class:`PlantwiseResidual` on the ``observer`` (``observer``: its keywords)."""

    def __init__(
        self,
        config: str,
        scale: float,
        models: Sequence[Any],
        dt: float = 0.01,
        observer: dict[str, Any] | None = None,
    ) -> None:
        super().__init__("observer", config, scale, models, dt, observer)


def plantwise_base(
    task: BenchmarkTask | None,
    identified: Mapping[str, Any],
    base: str,
    config: str,
    scale: float,
    dt: float,
    options: dict[str, Any] | None = None,
) -> PlantwiseResidual:
    """The per-plant base of an identified task's training plants (``make_training_env(identified=)``).

    Parameters
    ----------
    task : BenchmarkTask or None
        The task trained on: an identified one.
    identified : mapping
        The recipe's ``identified`` section (:class:`IdentifiedTraining`).
    base : str
        The controller (:data:`agents.residual_bases.RESIDUAL_BASES`).
    config : str
        Rig configuration.
    scale : float
        Voltage of a full action (V).
    dt : float
        Control period (s).
    options : dict, optional
        Keywords of the controller.

    Returns
    -------
    PlantwiseResidual

    Raises
    ------
    InputError
        Not an identified task, a malformed section, or an identification that fails.
    """
    from .identified_plants import identified_plants

    section = IdentifiedTraining.from_config(identified)
    if task is None or not task.identified:
        raise InputError("identified applies to an identified task (drillgym/...-Identified-v0)")
    found = identified_plants(task, "train", section.plants, section.folder)
    models = [p.model for p in found.values()]
    if base == "observer":  # the observer's own class (its recipes and the API pages name it)
        return PlantwiseObserverResidual(config, scale, models, dt, options)
    return PlantwiseResidual(base, config, scale, models, dt, options)
