"""The library versus the outside on the lateral side: a library lateral effect that stands in for another force.

A lateral force outside the library (a spring that stiffens with the radius, a quadratic drag) leaves a residual
on the LVDTs that the library's lateral effects partly take: a stiffening spring damps the large orbits, and
``lateral_coulomb`` does too, at several times its usual size.  When the selection took ``lateral_coulomb`` or
``lateral_anisotropy`` and discovery's candidate is a lateral force of another shape, the residual lateral force
of the model *without* the library effect (its parameters at their neutral values) is regressed twice
(:func:`.lateral_discovery.lateral_candidate`): on the library effect's own shapes
(:data:`.lateral_terms.LIBRARY_SHAPES`) and on the terms outside the library.  When the outside terms leave less
than :data:`OUTSIDE_BETTER` of what the library's shapes leave, the diagnosis says so, in words: "a lateral
force that grows with r² (a stiffening spring), not Coulomb friction in the guides (lateral_coulomb)"; where
the candidate's own fit earns it a place in the model, the library effect is left out of it (not selected again
beside the candidate, :func:`.reselection.reselection_inputs`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .candidate import Candidate
from .lateral_discovery import LATERAL_GROUP, lateral_candidate
from .lateral_terms import LIBRARY_SHAPES, lateral_terms, outside_terms

__all__ = ["OUTSIDE_BETTER", "LateralVerdict", "library_versus_outside"]

#: the outside terms must leave less than this share of the residual the library effect's shapes leave
OUTSIDE_BETTER = 0.5

#: each term's shape in words
_WORDS = {
    "r·(X, Y)": "a lateral force that grows with r (a spring that stiffens with the radius)",
    "r²·(X, Y)": "a lateral force that grows with r² (a spring that stiffens with the radius)",
    "r⁴·(X, Y)": "a lateral force that grows with r⁴ (a spring that stiffens steeply with the radius)",
    "(Y, X)": "a stiffness whose axes are turned against the LVDTs'",
    "|V|·(VX, VY)": "a drag that grows with the lateral speed squared",
    "r²·(VX, VY)": "a damping that grows with the radius",
    "(1, 0)": "a constant lateral force (a contact force, a preload)",
    "(0, 1)": "a constant lateral force (a contact force, a preload)",
    "(cos θl, sin θl)": "a lateral force that turns with the lower disc",
    "(−sin θl, cos θl)": "a lateral force that turns with the lower disc",
}
_LIBRARY_WORDS = {
    "lateral_coulomb": "Coulomb friction in the guides (lateral_coulomb)",
    "lateral_anisotropy": "a stiffness that differs in x and y (lateral_anisotropy)",
}


@dataclass(frozen=True)
class LateralVerdict:
    """A library lateral effect that the residual says is another force.

    Attributes
    ----------
    library : str
        The library effect the selection took.
    outside : Candidate
        The outside terms' candidate on the residual of the model without it.
    outside_share, library_share : float
        The share of that residual lateral force the outside terms and the library effect's shapes explain.
    values : dict of str to float
        The library effect's fitted parameters.
    """

    library: str
    outside: Candidate
    outside_share: float
    library_share: float
    values: dict[str, float]

    def line(self, left_out: bool = False) -> str:
        """The verdict in words, one line.

        Parameters
        ----------
        left_out : bool, optional
            The library effect was left out of the model a kept candidate entered (else it stays: no candidate
            took its place).
        """
        first = next(iter(self.outside.terms))
        what = _WORDS.get(first, f"a lateral force {first}")
        vals = ", ".join(f"{k} = {v:.3g}" for k, v in self.values.items())
        fate = (
            f"{self.library} is left out of the model the candidate enters"
            if left_out
            else f"{self.library} stays in the model: no candidate earned its place"
        )
        return (
            f"{what}, not {_LIBRARY_WORDS[self.library]}: without {self.library} ({vals}) in the model, "
            f"{self.outside.expression()} explains {self.outside_share:.0%} of the residual lateral force, "
            f"{self.library}'s own shape {self.library_share:.0%}; {fate}"
        )


def library_versus_outside(ex, diagnosis, candidate: Candidate | None) -> LateralVerdict | None:
    """Whether a selected library lateral effect stands in for a lateral force outside the library.

    Parameters
    ----------
    ex : Experiment
        The recording, on discovery's grid.
    diagnosis : Diagnosis
        The diagnosis (its selection and final model).
    candidate : Candidate or None
        Discovery's candidate (a verdict only for a lateral force whose first term is not a library shape).

    Returns
    -------
    LateralVerdict or None
        The verdict, or None when no library lateral effect was selected, the candidate is not such a lateral
        force, or the outside terms do not explain clearly more.
    """
    from .sparse import residual_torques

    if candidate is None or candidate.group != LATERAL_GROUP or diagnosis.composition is None:
        return None
    if LIBRARY_SHAPES.get(next(iter(candidate.terms), "")) is not None:
        return None
    comp, vec = diagnosis.composition, np.array(diagnosis.vector, dtype=float)
    selected = [e for e in comp.effects if e.name in diagnosis.selected and e.name in _LIBRARY_WORDS]
    best = None
    for eff in selected:
        neutral = eff.neutral_values() or {}
        values = {p.name: float(vec[comp.param_index(p.name)]) for p in eff.parameters}
        v = vec.copy()
        for name, val in neutral.items():
            v[comp.param_index(name)] = val
        rt = residual_torques(ex, v, effects=comp)
        own = [t for t in lateral_terms() if LIBRARY_SHAPES.get(t.label) == eff.name]
        rest = outside_terms()
        lib = lateral_candidate(rt, terms=own, library=False)
        out = lateral_candidate(rt, terms=rest, library=False)
        if out is None:
            continue
        lib_share = lib.explained if lib is not None else 0.0
        if 1.0 - out.explained < OUTSIDE_BETTER * (1.0 - lib_share) and (best is None or out.explained > best[1]):
            best = (LateralVerdict(eff.name, out, out.explained, lib_share, values), out.explained)
    return best[0] if best is not None else None
