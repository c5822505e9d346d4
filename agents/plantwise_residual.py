"""The observer base of a residual policy built on each rig's own model: training on identified plants.

An identified task scores a residual policy on the ``observer`` controller built on each held-out plant's
identified model (:mod:`agents.observer_residual`, ``controllers.make("agent:DIR", model=...)``).  A residual
trained on a base built on one nominal model learns to correct that base on the rigs it trained on, not the base
it will run on.  :class:`PlantwiseObserverResidual` gives the training the situation it will run in: every rig's
episode runs one training plant, and the rig's base is the observer built on that plant's identified model
(:func:`agents.identified_plants.identified_plants`), rebuilt at each of the rig's episodes.

It has the interface of :class:`agents.observer_residual.ObserverResidual` (what
:class:`agents.envs.ObserverResidualVecEnv` calls), with the plants of the rigs given at :meth:`reset`; each rig
holds its own one-rig :class:`~agents.observer_residual.ObserverResidual`, so a period costs one controller step
per rig (about 1 ms on this machine): the price of one model per rig.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from drillgym.errors import InputError

from .observer_residual import ObserverResidual

__all__ = ["PlantwiseObserverResidual"]


class PlantwiseObserverResidual:
    """Rig i's base: the ``observer`` controller built on ``models[plant of rig i's episode]``.

    Parameters
    ----------
    config : str
        Rig configuration the observers are designed for.
    scale : float
        Voltage of a full action (V), > 0.
    models : sequence of drillgym.Model
        The model of each listed plant, by the plant list's index.
    dt : float, optional
        Control period (s).
    observer : dict, optional
        Keywords of :class:`controllers.observer.ObserverController`.
    """

    per_plant = True  # :class:`agents.envs.ObserverResidualVecEnv` gives the rigs' plants at reset

    def __init__(
        self,
        config: str,
        scale: float,
        models: Sequence[Any],
        dt: float = 0.01,
        observer: dict[str, Any] | None = None,
    ) -> None:
        if not models:
            raise InputError("a plant-wise observer base needs the model of at least one plant")
        self.config, self.models, self.observer = config, list(models), dict(observer or {})
        self.scale, self.dt = scale, dt
        self._dim = self._build(0).dim  # bad settings fail here, not in the first episode
        self._rigs: list[ObserverResidual] = []
        self.n = 0

    def _build(self, plant: int) -> ObserverResidual:
        model = self.models[plant]
        return ObserverResidual(self.config, self.scale, dt=self.dt, observer=self.observer, model=model)

    @property
    def dim(self) -> int:
        """Number of policy inputs (a rig's base's)."""
        return self._dim

    def start(self, n: int) -> None:
        """Allocate n rigs (call :meth:`reset` for all of them before :meth:`correct`)."""
        self.n = int(n)
        self._rigs = [None] * self.n  # type: ignore[list-item]

    def reset(self, index: np.ndarray, theta_u: np.ndarray, omega_ref: np.ndarray, plants: np.ndarray) -> None:
        """Rigs ``index`` start at rest at motor angles theta_u (rad) towards targets omega_ref (rad/s), each on the
        base built on its plant's model (``plants``: list indices, one per rig of ``index``)."""
        idx = np.atleast_1d(np.asarray(index, dtype=np.int64))
        th = np.broadcast_to(np.asarray(theta_u, dtype=float), idx.shape)
        ref = np.broadcast_to(np.asarray(omega_ref, dtype=float), idx.shape)
        pl = np.broadcast_to(np.asarray(plants, dtype=np.int64), idx.shape)
        for j, i in enumerate(idx):
            if not 0 <= pl[j] < len(self.models):
                raise InputError(f"rig {i} runs plant {pl[j]}, which has no model (plants 0..{len(self.models) - 1})")
            rig = self._build(int(pl[j]))
            rig.start(1)
            rig.reset(np.zeros(1, dtype=np.int64), th[j : j + 1], ref[j : j + 1])
            self._rigs[i] = rig

    def _each(self, index: np.ndarray | slice) -> np.ndarray:
        return np.arange(self.n)[index]

    def correct(self, theta_u: np.ndarray, index: np.ndarray | slice = slice(None)) -> None:
        """Kalman measurement update of rigs ``index`` with their motor angles (rad)."""
        th = np.atleast_1d(np.asarray(theta_u, dtype=float))
        for j, i in enumerate(self._each(index)):
            self._rigs[i].correct(th[j : j + 1])

    def features(self) -> np.ndarray:
        """Policy inputs (n, :attr:`dim`), float32."""
        return np.concatenate([r.features() for r in self._rigs], axis=0)

    def base(self) -> np.ndarray:
        """The rigs' observer voltages (V, (n,)); advances their laws and clocks by one period."""
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
