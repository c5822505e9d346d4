"""The average of several learned networks of one recipe, as one wider network.

Networks distilled by the same recipe from different seeds differ where the imitation error decides: on the
plant population's held-out plants each seed of the motor-side recipe misses a different handful of plants at
3.0 rad/s, several by a stick-slip severity just above the threshold (0.11-0.14 for 0.1).  Their mean action
averages those errors out.  The mean is itself one multilayer perceptron, exactly: with K members of layers
``(W_k, b_k)``,

* first layer: the members' ``W_k`` stacked (every member reads the same observation),
* hidden layers: block-diagonal ``diag(W_1, ..., W_K)``, biases concatenated (each block sees only its own
  member's units),
* last layer: ``[W_1, ..., W_K] / K`` and the mean of the biases,

so the last layer's output is the mean of the members' outputs before the output map (``clip`` or ``tanh``),
and the file is a plain ``policy.npz`` that ``agent:PATH``, ``drillgym benchmark`` and the rig run as they run any
network.  Nothing but the networks computes the voltage.

    >>> from agents.ensemble import average
    >>> average([f"runs/a/seed_{s}/policy.npz" for s in (1, 2, 3)], "runs/a_mean/policy.npz")
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from scipy.linalg import block_diag

from drillgym.errors import InputError
from drillgym.io import create_directory

from .export import ExportedPolicy

__all__ = ["average", "average_networks"]

#: the training configuration a member may differ in: its seed and how it was launched
_MAY_DIFFER = ("seed", "command", "wall_time_s")


def average_networks(members: Sequence[ExportedPolicy]) -> ExportedPolicy:
    """One network whose action is the mean of the members' outputs before the output map.

    Parameters
    ----------
    members : sequence of ExportedPolicy
        Networks of one recipe: the same observation (size, normalisation and training configuration but for
        the seed), activations, output map and action bounds.

    Returns
    -------
    ExportedPolicy
        The averaged network; its metadata is the first member's with ``ensemble`` (each member's seed and
        command) added.

    Raises
    ------
    InputError
        Fewer than two members, or members that do not read the same observation the same way.
    """
    if len(members) < 2:
        raise InputError(f"an average needs at least two networks, got {len(members)}")
    first = members[0]
    for i, m in enumerate(members[1:], start=2):
        _check_same_recipe(first, m, i)
    for i, m in enumerate(members[1:], start=2):
        for j, other in enumerate(members[: i - 1], start=1):
            if _same_weights(m, other):
                raise InputError(
                    f"network {i} of the average has the same weights as network {j}: "
                    "the mean of a network with itself is no average (give distinct seeds)"
                )
    k = len(members)
    n = len(first.layers)
    weights = [[Wt.T for Wt, _ in m.layers] for m in members]  # (out, in) each: the layers hold W transposed
    biases = [[b for _, b in m.layers] for m in members]
    layers: list[tuple[np.ndarray, np.ndarray]] = []
    for i in range(n):
        w_i = [w[i] for w in weights]
        b_i = [b[i] for b in biases]
        if i == 0 and n == 1:
            W, b = np.mean(w_i, axis=0), np.mean(b_i, axis=0)
        elif i == 0:
            W, b = np.vstack(w_i), np.concatenate(b_i)
        elif i == n - 1:
            W, b = np.hstack(w_i) / k, np.mean(b_i, axis=0)
        else:
            W, b = block_diag(*w_i), np.concatenate(b_i)
        layers.append((W.astype(np.float32), b.astype(np.float32)))
    meta = dict(first.meta)
    meta["ensemble"] = [{key: m.config.get(key) for key in ("seed", "command") if key in m.config} for m in members]
    acts = list(meta["activations"])
    return ExportedPolicy(layers, acts, first.output, first.low, first.high, meta, first.obs_norm)


def _check_same_recipe(a: ExportedPolicy, b: ExportedPolicy, index: int) -> None:
    """Refuse member ``index`` (1-based) when it does not read the observation as the first one does."""
    what = None
    if b.obs_dim != a.obs_dim:
        what = f"observation size {b.obs_dim}, not {a.obs_dim}"
    elif [len(x) for x, _ in b.layers] != [len(x) for x, _ in a.layers]:
        what = "another layer layout"
    elif b.meta["activations"] != a.meta["activations"] or b.output != a.output:
        what = "other activations or output map"
    elif not (np.array_equal(a.low, b.low) and np.array_equal(a.high, b.high)):
        what = "other action bounds"
    elif (a.obs_norm is None) != (b.obs_norm is None) or (
        a.obs_norm is not None and not all(np.array_equal(x, y) for x, y in zip(a.obs_norm, b.obs_norm, strict=True))
    ):
        what = "another observation normalisation"
    elif _recipe(a.config) != _recipe(b.config):
        what = "another training configuration (only the seed may differ)"
    if what:
        raise InputError(f"network {index} of the average has {what}: average networks of one recipe")


def _same_weights(a: ExportedPolicy, b: ExportedPolicy) -> bool:
    """Whether ``a`` and ``b`` hold identical weights and biases (one network given twice)."""
    return all(
        np.array_equal(wa, wb) and np.array_equal(ba, bb) for (wa, ba), (wb, bb) in zip(a.layers, b.layers, strict=True)
    )


def _recipe(config: dict[str, Any]) -> dict[str, Any]:
    """The configuration without what members of one recipe may differ in."""
    return {k: v for k, v in config.items() if k not in _MAY_DIFFER}


def average(paths: Sequence[str | Path], out: str | Path) -> Path:
    """Average exported networks into one ``policy.npz`` (:func:`average_networks`).

    Parameters
    ----------
    paths : sequence of str or path
        The members' ``policy.npz`` files.
    out : str or path
        Output ``.npz`` (its directory is created).

    Returns
    -------
    Path
        The path written.
    """
    seen: dict[Path, int] = {}
    for i, p in enumerate(paths, start=1):
        key = Path(p).resolve()
        if key in seen:
            raise InputError(f"network {i} of the average is {p}, the same file as network {seen[key]}")
        seen[key] = i
    net = average_networks([ExportedPolicy.load(p) for p in paths])
    out = Path(out)
    create_directory(out.parent, out)
    return net.save(out)
