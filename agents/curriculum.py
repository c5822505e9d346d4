"""A training-only target curriculum: more episodes with low targets than the task's uniform draw.

On a task the targets of the episodes are uniform in the task's range (0.5-8 rad/s); a student of the
``observer`` then sees few low-speed steady states, where its errors matter most (a voltage a few mV off moves
the slow equilibrium by tenths of rad/s).  :class:`LowTargets` redraws a fraction of the episodes' targets
uniformly below a speed.  It changes only which targets the training episodes get, never the plants, the
observation or anything the deployed policy runs: a curriculum, as the benchmark's rules allow in training.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from drillgym.errors import InputError

__all__ = ["LowTargets"]


@dataclass(frozen=True)
class LowTargets:
    """A fraction of the episodes' targets drawn uniformly between the range's low end and ``below``.

    Parameters
    ----------
    fraction : float
        Probability (in [0, 1]) that an episode's target is redrawn.
    below : float
        Upper end (rad/s) of the redrawn targets; the lower end is the env's ``omega_ref_range[0]``.
    """

    fraction: float
    below: float

    def __post_init__(self) -> None:
        if not (0.0 <= self.fraction <= 1.0):
            raise InputError(f"low_targets: fraction must be in [0, 1], got {self.fraction!r}")
        if not (np.isfinite(self.below) and self.below > 0):
            raise InputError(f"low_targets: below must be a positive speed (rad/s), got {self.below!r}")

    @classmethod
    def from_config(cls, spec: dict[str, Any] | None) -> LowTargets | None:
        """The curriculum of a ``distill.low_targets: {fraction, below}`` entry; None: none."""
        if spec is None:
            return None
        if not isinstance(spec, dict) or set(spec) != {"fraction", "below"}:
            raise InputError(f"low_targets: expected a mapping {{fraction, below}}, got {spec!r}")
        return cls(float(spec["fraction"]), float(spec["below"]))

    def install(self, batch) -> None:
        """Draw the targets of ``batch``'s (a drillgym episode batch's) next episodes through this curriculum."""
        batch.task = _CurriculumTask(batch.task, self)


class _CurriculumTask:
    """The env's task with :meth:`sample` redrawing a fraction of the targets (its other methods the task's)."""

    def __init__(self, task, curriculum: LowTargets) -> None:
        self.task, self.curriculum = task, curriculum
        lo, hi = (float(v) for v in task.o.omega_ref_range)
        if task.o.omega_ref is not None or not lo < curriculum.below <= hi:
            raise InputError(f"low_targets: needs drawn targets with {curriculum.below} in ({lo}, {hi}] rad/s")
        self.low = lo

    def __getattr__(self, name: str):
        return getattr(self.task, name)

    def sample(self, rng: np.random.Generator) -> tuple[float, float]:
        """(omega_ref, alpha0) of a new episode (rad/s, rad): the task's, the target redrawn with probability
        ``fraction`` uniformly in [low end, ``below``)."""
        w, a = self.task.sample(rng)
        if rng.random() < self.curriculum.fraction:
            w = float(rng.uniform(self.low, self.curriculum.below))
        return w, a
