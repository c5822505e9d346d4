"""A policy of several learned networks, each serving a band of target speeds.

One network trained for every target and every rig of the population has to trade the low targets on the
nominal rig against the population (``docs/agents_eval/learned_robust_ablation.md``).  A *target-switched*
policy keeps several exported networks and gives each rig to the network whose band holds its target::

    member k serves  edges[k-1] <= omega_ref < edges[k]      (edges increasing, rad/s; len(members) - 1 of them)

The choice depends on the target alone, fixed for an episode (the harness and the rig give it at reset), so
every network runs exactly as it was trained: its own observation model, its own command schedule, its own
motor-angle integral, and only its own rigs.  Nothing but the networks computes the voltage: the switch is
a lookup on the command, not a controller.

File format: one ``.npz`` whose ``meta`` holds ``{"format", "switch": {"by": "target", "edges"}, "members":
[meta of each network]}`` and whose arrays are each network's, prefixed ``m0_``, ``m1_``, ...
(:meth:`agents.export.ExportedPolicy.to_arrays`).  ``agent:PATH``, ``drillgym evaluate`` and
``drillgym rig run --policy`` accept it as they accept a single network's ``policy.npz``.

    >>> from agents.switched import combine
    >>> combine(["low/policy.npz", "high/policy.npz"], [3.0], "switched/policy.npz")
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from drillgym.errors import InputError
from drillgym.io import create_directory, dumps_json

from .export import ExportedPolicy, policy_file

__all__ = ["TargetSwitchedPolicy", "combine", "read_policy", "SWITCH_FORMAT"]

SWITCH_FORMAT = 1


class TargetSwitchedPolicy:
    """Exported networks chosen by the target speed.

    Parameters
    ----------
    members : sequence of ExportedPolicy
        At least two single networks, lowest band first, trained on the same environment and control
        period.
    edges : sequence of float
        Band edges (rad/s), positive and increasing, one fewer than ``members``: member k serves
        ``edges[k-1] <= omega_ref < edges[k]``.
    note : str, optional
        Free text stored with the policy.

    Raises
    ------
    InputError
        Fewer than two networks, wrong or unordered edges, nested switches, or networks of different
        environments or control periods.
    """

    def __init__(self, members: Sequence[ExportedPolicy], edges: Sequence[float], note: str = "") -> None:
        members = list(members)
        edges = [float(e) for e in edges]
        if len(members) < 2:
            raise InputError(f"a target-switched policy needs at least two networks, got {len(members)}")
        if len(edges) != len(members) - 1:
            raise InputError(
                f"{len(members)} networks need {len(members) - 1} target edge(s) (rad/s), got {len(edges)}"
            )
        if not all(np.isfinite(edges)) or any(e <= 0 for e in edges) or any(b <= a for a, b in zip(edges, edges[1:])):
            raise InputError(f"target edges must be positive, finite and increasing (rad/s), got {edges}")
        if any("members" in m.meta for m in members):
            raise InputError("a member of a target-switched policy must be a single network, not another switch")
        dts = sorted({m.control_dt for m in members})
        if len(dts) != 1:
            raise InputError(
                f"the networks were trained at different control periods {dts} s; they cannot share one rig loop"
            )
        if len({m.config.get("env_id") for m in members}) != 1:
            raise InputError(
                "the networks were trained on different environments: "
                + ", ".join(str(m.config.get("env_id")) for m in members)
            )
        self.members, self.edges, self.note = members, tuple(edges), note

    @property
    def meta(self) -> dict[str, Any]:
        """The file's metadata: format, switch rule, the members' metadata, the note."""
        return {
            "format": SWITCH_FORMAT,
            "switch": {"by": "target", "edges": list(self.edges)},
            "members": [m.meta for m in self.members],
            "note": self.note,
        }

    def member_of(self, omega_ref: float | np.ndarray) -> np.ndarray:
        """Index of the network serving each target (rad/s)."""
        return np.searchsorted(np.asarray(self.edges), np.asarray(omega_ref, dtype=float), side="right")

    def save(self, path: str | Path) -> Path:
        """Write the policy to ``path`` (.npz)."""
        path = Path(path)
        arrays: dict[str, np.ndarray] = {}
        for k, m in enumerate(self.members):
            arrays |= m.to_arrays(prefix=f"m{k}_")
        np.savez(path, meta=np.array(dumps_json(self.meta, nonfinite="refuse")), **arrays)
        return path

    @classmethod
    def from_arrays(cls, meta: dict[str, Any], arrays: Any) -> TargetSwitchedPolicy:
        """The policy of the file's ``meta`` and arrays (an open ``.npz``)."""
        switch = meta["switch"]
        if switch.get("by") != "target":
            raise InputError(f"unknown switch rule {switch.get('by')!r} (only 'target')")
        members = [ExportedPolicy.from_arrays(m, arrays, prefix=f"m{k}_") for k, m in enumerate(meta["members"])]
        return cls(members, switch["edges"], meta.get("note", ""))

    @classmethod
    def load(cls, path: str | Path) -> TargetSwitchedPolicy:
        """The target-switched policy in a ``.npz`` written by :meth:`save`."""
        with policy_file(path, "target-switched drillgym policy") as (meta, z):
            return cls.from_arrays(meta, z)


def read_policy(path: str | Path) -> ExportedPolicy | TargetSwitchedPolicy:
    """The policy in the ``.npz`` at ``path``, read once: one network, or a target-switched set of them."""
    with policy_file(path, "exported drillgym policy") as (meta, z):
        return TargetSwitchedPolicy.from_arrays(meta, z) if "members" in meta else ExportedPolicy.from_arrays(meta, z)


def combine(paths: Sequence[str | Path], edges: Sequence[float], out: str | Path, note: str = "") -> Path:
    """Combine exported networks into one target-switched policy file.

    Parameters
    ----------
    paths : sequence of str or path
        Exported networks (``policy.npz``), lowest band first; they must share the environment and the
        control period.
    edges : sequence of float
        Band edges (rad/s), one fewer than ``paths``.
    out : str or path
        Output ``.npz`` (its directory is created).
    note : str, optional
        Free text stored with the policy.

    Returns
    -------
    Path
        The path written.
    """
    members = [ExportedPolicy.load(p) for p in paths]
    out = Path(out)
    create_directory(out.parent, out)
    return TargetSwitchedPolicy(members, edges, note).save(out)
