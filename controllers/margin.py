"""What a controller that sees only the motor angle needs of its model, and what its model file offers.

Below omega_2 no linear controller reading only the motor angle tolerates more than a fraction
1/M of multiplicative input error, M the bound of :func:`controllers.limits.motor_angle_limit` at the
target (4.3 % at 2.5 rad/s, 1.1 % at 2.0 rad/s on the nominal rig).  A model file written by
identification (``identify --out``, ``diagnose --model-out``) carries the standard errors of what was
fitted; the motor constant's, times :data:`SIGMAS`, is what the identification achieved for that
input error.  :func:`model_margins` compares the two per target; a model-based controller reports
them (``margins``), warns when a target needs more than the model has, and may fall back to
``descent`` for those targets (``fallback=True``).  Only km's error is counted: a lag or delay
identified with an error also costs margin (omega tau ~ 1/M at the crossover), which this check
does not include.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .limits import motor_angle_limit
from .model import ControllerModel

__all__ = ["SIGMAS", "ModelMargin", "model_margins", "check_margins"]

#: standard errors counted as the identification's accuracy (about 95 % of the estimates within)
SIGMAS = 2.0


@dataclass(frozen=True)
class ModelMargin:
    """The model accuracy a target needs and what the model offers.

    Attributes
    ----------
    omega : float
        Target lower-disc speed (rad/s).
    needed : float
        Largest relative input (km) error the best motor-angle-only loop tolerates there (fraction; inf
        where the brake is stable).
    achieved : float or None
        :data:`SIGMAS` x the relative standard error of km in the model file (fraction); None: the file
        carries none.
    """

    omega: float
    needed: float
    achieved: float | None

    @property
    def enough(self) -> bool | None:
        """True: the model is accurate enough for the target; False: it needs more; None: unknown."""
        if math.isinf(self.needed):
            return True
        return None if self.achieved is None else self.achieved <= self.needed

    def line(self, controller: str) -> str:
        """One line for the user."""
        need = (
            "any model error (the brake is stable there)" if math.isinf(self.needed) else f"{100 * self.needed:.3g} %"
        )
        have = (
            "unknown (the model file has no standard error of km)"
            if self.achieved is None
            else f"{100 * self.achieved:.3g} % ({SIGMAS:g} standard errors of km)"
        )
        verdict = {True: "enough", False: "NOT enough", None: "not known to be enough"}[self.enough]
        return f"{controller} at {self.omega:g} rad/s tolerates {need}; the model is right to {have}: {verdict}"


def model_margins(model: ControllerModel, targets: Sequence[float] | np.ndarray) -> list[ModelMargin]:
    """The :class:`ModelMargin` of each distinct target (rad/s), in increasing order."""
    p = model.params
    sd = model.std.get("km")
    achieved = None if sd is None or not math.isfinite(sd) else SIGMAS * sd / abs(p.km)
    out = []
    for w in sorted({float(v) for v in np.atleast_1d(targets)}):
        lim = motor_angle_limit(p, w)
        out.append(ModelMargin(w, lim.tolerated if lim.rhp_poles else math.inf, achieved))
    return out


def check_margins(controller, m: dict[str, np.ndarray], fallback: bool) -> tuple[list[ModelMargin], Any, Any]:
    """At a model-based controller's reset: its margins, one warning per target that needs more than the
    model has, and, with ``fallback``, a reset ``descent`` controller and the mask (n,) of the trajectories
    it drives instead (None, None without).

    Parameters
    ----------
    controller : Controller
        The controller (its ``effects``, ``omega_ref``, ``name``, ``config``, ``params``, ``dt``, ``u_max``).
    m : dict of str to ndarray
        The measurements its reset got.
    fallback : bool
        Drive the targets the model is not accurate enough for with ``descent``.
    """
    from .descent import DescentController

    margins = model_margins(controller.effects, controller.omega_ref)
    short = [g.omega for g in margins if g.enough is False]
    for g in margins:
        if g.enough is False:
            warnings.warn(g.line(controller.name) + ("; descent drives it" if fallback else ""), stacklevel=3)
    if not (fallback and short):
        return margins, None, None
    mask = np.isin(controller.omega_ref, short)
    descent = DescentController(
        controller.omega_ref,
        config=controller.config,
        params=controller.params,
        dt=controller.dt,
        u_max=controller.u_max,
    )
    descent.reset(m)
    return margins, mask, descent
