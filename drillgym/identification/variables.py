"""The variables of a fit: a model's parameters (:class:`FitVariable`) and the segments' start speeds
(:class:`SpeedVariables`), each with its bounds and scale."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..effects import Composition
from ..errors import InputError
from ..params import N_PARAMS, PARAM_INFO, RigParams

if TYPE_CHECKING:
    from .fitting import Objective

__all__ = ["FitVariable", "SpeedVariables"]


@dataclass(frozen=True)
class FitVariable:
    """One fitted variable, in the parameter's SI unit.

    Attributes
    ----------
    name : str
        A parameter of the model's composition (a RigParams name or an effect's parameter), or a variable an
        ``apply`` function maps.
    x0 : float
        The initial value.
    lo, hi : float
        The bounds.
    scale : float
        The typical magnitude (for scaling and the finite-difference step).
    """

    name: str
    x0: float
    lo: float
    hi: float
    scale: float

    @classmethod
    def of_effect(cls, composition: Composition, name: str, x0: float | None = None) -> FitVariable:
        """An effect's parameter with the effect's own bounds, guess and scale.

        Parameters
        ----------
        composition : Composition
            The composition.
        name : str
            The parameter.
        x0 : float, optional
            Overrides the guess (clipped into the bounds).

        Returns
        -------
        FitVariable
            The variable.

        Raises
        ------
        InputError
            ``name`` is a base parameter.
        """
        prm = composition.parameter(name)
        if composition.owner(name) is None:
            raise InputError(f"{name!r} is a base parameter, not an effect's: use FitVariable.relative")
        v = prm.guess if x0 is None else min(max(float(x0), prm.lo), prm.hi)
        return cls(name, float(v), float(prm.lo), float(prm.hi), float(prm.scale))

    @classmethod
    def named(cls, composition: Composition, name: str, vector: np.ndarray | None = None) -> FitVariable:
        """Any parameter of a composition as a fit variable.

        An effect's (its Parameter's bounds and scale, starting from ``vector``'s value when given, else the
        guess), or a base one (:meth:`relative` around ``vector``'s value, within ×0.5–×2).

        Parameters
        ----------
        composition : Composition
            The composition.
        name : str
            The parameter.
        vector : numpy.ndarray, optional
            A vector of the composition to start from.

        Returns
        -------
        FitVariable
            The variable.
        """
        i = composition.param_index(name)
        if composition.owner(name) is not None:
            return cls.of_effect(composition, name, None if vector is None else float(vector[i]))
        base = RigParams() if vector is None else RigParams.from_vector(np.asarray(vector)[:N_PARAMS])
        if getattr(base, name) == 0:
            info = PARAM_INFO[name]
            return cls(name, 0.0, max(info["lo"], -0.5), min(info["hi"], 0.5), 0.01)
        return cls.relative(base, name, 0.5, 2.0)

    @classmethod
    def relative(cls, params: RigParams, name: str, lo: float = 0.3, hi: float = 3.0) -> FitVariable:
        """A base parameter fitted around its current value.

        Parameters
        ----------
        params : RigParams
            The current values.
        name : str
            The parameter.
        lo, hi : float, optional
            Bounds as factors of the value (also within PARAM_INFO's).

        Returns
        -------
        FitVariable
            The variable.
        """
        v = getattr(params, name)
        info = PARAM_INFO[name]
        a, b = sorted((v * lo, v * hi))
        a, b = max(a, info["lo"]), min(b, info["hi"])
        return cls(name, v, a, b, max(abs(v), 1e-9))


class SpeedVariables:
    """The segment-start speed corrections of ``objective``'s model as fit variables (``fit_speeds`` of
    :func:`fit_parameters`): z = (correction − start) / limit, within ±limit."""

    def __init__(self, objective: Objective) -> None:
        model = self.model = objective.model
        found = model.speed_variables()
        self.count = len(found)
        self.exp = np.array([v[0] for v in found], dtype=int)
        self.seg = np.array([v[1] for v in found], dtype=int)
        self.comp = np.array([v[2] for v in found], dtype=int)
        self.scale = np.array([v[3] for v in found], dtype=float)
        start = np.array([model.speed_offsets[k][j, c] for k, j, c, _ in found], dtype=float)
        self.start = np.clip(start, -self.scale * (1 - 1e-9), self.scale * (1 - 1e-9))
        self.zlo, self.zhi = (-self.scale - self.start) / self.scale, (self.scale - self.start) / self.scale
        # residual entries of each variable's segment
        gid = objective.segment_offsets[self.exp] + self.seg if self.count else np.zeros(0, dtype=int)
        order = np.argsort(objective.segment_ids, kind="stable")
        bounds = np.searchsorted(objective.segment_ids[order], np.arange(objective.segment_ids.max(initial=-1) + 2))
        self.entries = [order[bounds[g] : bounds[g + 1]] for g in gid]

    def set(self, z: np.ndarray) -> None:
        """Set the model's speed corrections from the scaled variables ``z``."""
        values = self.start + self.scale * z
        for i in range(self.count):
            self.model.speed_offsets[self.exp[i]][self.seg[i], self.comp[i]] = values[i]

    def columns(self, D: np.ndarray) -> np.ndarray:
        """The variables' Jacobian columns from the two sensitivity rows.

        Parameters
        ----------
        D : numpy.ndarray
            (2, M): every segment's ω_u, then ω_l, raised together (per unit of speed).

        Returns
        -------
        numpy.ndarray
            (M, count) columns.
        """
        J = np.zeros((D.shape[1], self.count))
        for i in range(self.count):
            idx = self.entries[i]
            J[idx, i] = D[self.comp[i], idx] * self.scale[i]
        return J
