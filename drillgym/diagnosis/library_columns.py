"""The library's own torques beside discovery's terms: a candidate a library effect explains is that effect.

Discovery (:mod:`.discovery`) regresses the residual torques on terms shaped by physics.  Some of them are, to first
order, a library effect the selection left out: sign(ωl) cos θl is a position friction, sign(ωl) t a friction drift.
Beside a larger misfit (a lag and a delay taken for one delay) the selection can miss a small library effect, and the
candidate then carries it under another name, beside a share of the base parameters: the user is handed a file of
outside physics where the library held the answer.

Here every library torque effect the model lacks (a :class:`~drillgym.effects.Friction` or a torsional
:class:`~drillgym.effects.Force`, switched off in the search model) gets its own columns: the change of the residual
torques per unit of each of its parameters, through the search model's compiled right-hand side (any library effect,
no term written for it).  :func:`.discovery.find_candidate` regresses them on the same rows as its groups, each effect
as a whole; an effect that explains at least :data:`LIBRARY_SHARE` of what the best outside candidate explains is the
answer (:class:`LibraryAnswer`): held in the model, and the library selected again beside it
(:mod:`.reselection`), no candidate file written.  Only an effect that acts on a disc the candidate acts on can be
its answer (:func:`library_view`); one that explains the other disc's residual is fitted beside it instead (two
effects at once: a cogging torque on the motor's disc beside a position friction on the brake's).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..effects import LIBRARY, Composition, Force, Friction
from ..identification.experiment import Experiment
from .sparse import ResidualTorque

__all__ = ["LIBRARY_SHARE", "LIBRARY_PREFIX", "LibraryAnswer", "library_columns", "library_answer", "library_view"]

#: a library effect is the answer when its columns explain at least this share of what the best outside candidate's
#: terms explain (it names known physics with the parameters the user can look up)
LIBRARY_SHARE = 0.8
#: a library effect is named beside a candidate on another disc when it explains at least this share of that disc's
#: residual (as much as a candidate itself must, :data:`.discovery.MIN_EXPLAINED_SHARE`): its fit beside the
#: candidate decides (a selection that took a friction drift in its place leaves it 44 % of the brake's residual)
BESIDE_SHARE = 0.3
#: the key a library effect's share has among the groups' shares (:attr:`~.candidate.Candidate.rest`)
LIBRARY_PREFIX = "library:"


@dataclass(frozen=True)
class LibraryAnswer:
    """A library effect that explains the residual torques as well as the best outside candidate.

    Attributes
    ----------
    effect : str
        The library effect's name.
    explained : float
        The share of the residual torque its columns explain.
    candidate : str
        The outside candidate's expression it stands against.
    candidate_explained : float
        The share that candidate's terms explain.
    """

    effect: str
    explained: float
    candidate: str
    candidate_explained: float

    def line(self) -> str:
        """The answer in one line."""
        return (
            f"the residual torques are {self.effect}'s (it explains {100 * self.explained:.0f} % of them, the best "
            f"outside candidate {self.candidate} {100 * self.candidate_explained:.0f} %): {self.effect} is held in "
            f"the model and the library selected again beside it"
        )


def library_columns(
    ex: Experiment, comp: Composition, vec: np.ndarray, selected: list[str], base: ResidualTorque
) -> dict[str, np.ndarray]:
    """Each library torque effect's columns: the residual torques' change per unit of each of its parameters.

    Parameters
    ----------
    ex : Experiment
        The recording (the grid discovery regresses on).
    comp : Composition
        The diagnosed model's composition (the search model: the library's effects in it, switched off).
    vec : numpy.ndarray
        Its vector as diagnosed.
    selected : list of str
        The effects the model holds (not offered again).
    base : ResidualTorque
        The residual torques of ``comp`` at ``vec`` on ``ex`` (:func:`.sparse.residual_torques`: discovery's own).

    Returns
    -------
    dict of str to numpy.ndarray
        Per effect, an array (2 N, k): the torque its k parameters add per unit, upper disc's N samples then the
        lower disc's (N m per unit; 0 where a disc's balance is unknown).
    """
    from .sparse import residual_torques

    offered = [
        e
        for e in comp.effects
        if e.name not in selected
        and LIBRARY.get(e.name) is e  # a library effect, not a user's or a candidate's file
        and (issubclass(e, Friction) or (issubclass(e, Force) and e.acts_on != "lateral"))
    ]
    if not offered:
        return {}
    out = {}
    for effect in offered:
        cols = []
        for p in effect.parameters:
            step = 1e-3 * max(abs(p.lo), abs(p.hi), 1e-3)  # the torques are linear in these effects' parameters
            v = np.array(vec, dtype=float)
            v[comp.param_index(p.name)] += step
            moved = residual_torques(ex, v, effects=comp)
            cols.append(np.concatenate([(base.tau_u - moved.tau_u) / step, (base.tau_l - moved.tau_l) / step]))
        out[effect.name] = np.nan_to_num(np.column_stack(cols))
    return out


def library_answer(candidate) -> LibraryAnswer | None:
    """The library effect whose columns explain at least :data:`LIBRARY_SHARE` of what ``candidate`` explains (the
    one that explains most), from the shares :func:`.discovery.find_candidate` recorded; None when there is none.

    Parameters
    ----------
    candidate : Candidate or None
        Discovery's best candidate.

    Returns
    -------
    LibraryAnswer or None
        The answer.
    """
    if candidate is None:
        return None
    shares = {k[len(LIBRARY_PREFIX) :]: v for k, v in candidate.rest.items() if k.startswith(LIBRARY_PREFIX)}
    if not shares:
        return None
    effect, share = max(shares.items(), key=lambda kv: kv[1])
    if share < LIBRARY_SHARE * candidate.explained:
        return None
    return LibraryAnswer(effect, share, candidate.expression(), candidate.explained)


def library_view(
    shares: dict[str, float], library: dict[str, np.ndarray], n: int, sense: tuple[float, float]
) -> tuple[dict[str, float], tuple[str, ...]]:
    """A candidate's view of the library's shares: those of the effects that act on a disc it acts on (its
    :attr:`~.candidate.Candidate.rest`, where :func:`library_answer` looks), and the effect acting on the other disc
    alone that explains most of that disc's residual, at least :data:`BESIDE_SHARE`, if any (its
    :attr:`~.candidate.Candidate.beside`).

    Parameters
    ----------
    shares : dict of str to float
        Every group's and library effect's share (library effects under :data:`LIBRARY_PREFIX`).
    library : dict of str to numpy.ndarray
        The library effects' columns (:func:`library_columns`: the upper disc's ``n`` rows, then the lower's).
    n : int
        Samples per disc.
    sense : tuple of float
        The candidate's sense on the upper and the lower disc (0: it does not act there).

    Returns
    -------
    tuple of (dict of str to float, tuple of str)
        Its shares, and the effect named beside it (empty or one name).
    """
    own, others = dict(shares), {}
    for effect, block in library.items():
        acts = (bool(np.any(block[:n] != 0.0)), bool(np.any(block[n:] != 0.0)))
        if not any(a and s != 0.0 for a, s in zip(acts, sense)):
            others[effect] = own.pop(LIBRARY_PREFIX + effect, 0.0)
    best = max(others.items(), key=lambda kv: kv[1], default=None)
    return own, (best[0],) if best is not None and best[1] >= BESIDE_SHARE else ()
