"""What a controller that sees only the motor angle needs of its model, and what its model file offers.

Below omega_2 no linear controller reading only the motor angle tolerates more than a fraction
1/M of multiplicative input error, M the bound of :func:`controllers.limits.motor_angle_limit` at the
target (4.3 % at 2.5 rad/s, 1.1 % at 2.0 rad/s on the nominal rig).  A model file written by
identification (``identify --out``, ``diagnose --model-out``) carries the standard errors of what was
fitted.  What the identification achieved is counted as that input error, :data:`SIGMAS` standard errors
of each part, summed in quadrature:

* the motor constant: its relative error σ_km / km;
* the signal path's timing: a lag's time constant or a delay off by δ changes the input by about ω δ at
  frequency ω (|e^{-jωδ} − 1| ≈ ω δ; a lag's relative change is at most that), counted at the unstable
  lower-disc mode's frequency |p| (the loop must act there: its complementary sensitivity peaks near it).

:func:`model_margins` compares the two per target; a model-based controller reports them (``margins``),
warns when a target needs more than the model has, and may fall back to ``descent`` for those targets
(``fallback=True``).  A lag or delay in the model whose standard error the file does not carry makes the
achieved accuracy unknown.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from drillgym import Model

from .limits import motor_angle_limits

__all__ = ["SIGMAS", "TIMING_PARAMETERS", "ModelMargin", "model_margins", "check_margins"]

#: standard errors counted as the identification's accuracy (about 95 % of the estimates within)
SIGMAS = 2.0
#: the signal path's timing parameters (s) whose error costs margin: a lag's time constant, a delay
TIMING_PARAMETERS = ("tau_m", "delay")


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
        :data:`SIGMAS` x the model's input error (fraction; the module docstring): km's relative standard
        error and the timing parameters' at the unstable mode's frequency, in quadrature; None: the file
        carries no standard error of km or of a lag or delay in the model.
    parts : dict of str to float
        Each counted part of ``achieved`` (fraction) by parameter name.
    """

    omega: float
    needed: float
    achieved: float | None
    parts: dict[str, float] = field(default_factory=dict)

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
            "unknown (the model file has no standard error of km, or of a lag or delay it holds)"
            if self.achieved is None
            else f"{100 * self.achieved:.3g} % ({SIGMAS:g} standard errors: "
            + ", ".join(f"{k} {100 * v:.3g} %" for k, v in self.parts.items())
            + ")"
        )
        verdict = {True: "enough", False: "NOT enough", None: "not known to be enough"}[self.enough]
        return f"{controller} at {self.omega:g} rad/s tolerates {need}; the model is right to {have}: {verdict}"


def model_margins(model: Model, targets: Sequence[float] | np.ndarray) -> list[ModelMargin]:
    """The :class:`ModelMargin` of each distinct target (rad/s), in increasing order.

    Parameters
    ----------
    model : drillgym.Model
        The controller's model, with the standard errors its file carries.
    targets : sequence of float
        Target lower-disc speeds (rad/s).

    Returns
    -------
    list of ModelMargin
        One per distinct target.
    """
    p = model.params
    sd = model.std.get("km")
    km_part = None if sd is None or not math.isfinite(sd) else SIGMAS * sd / abs(p.km)
    timing = {n: model.std.get(n) for n in TIMING_PARAMETERS if n in model.values}
    known = km_part is not None and all(v is not None and math.isfinite(v) for v in timing.values())
    out = []
    omegas = sorted({float(v) for v in np.atleast_1d(targets)})
    for w, lim in zip(omegas, motor_angle_limits(p, omegas) if omegas else []):
        needed = lim.tolerated if lim.rhp_poles else math.inf
        if not known:
            out.append(ModelMargin(w, needed, None))
            continue
        mode = max((abs(z) for z in lim.rhp_poles), default=0.0)  # rad/s
        parts = {"km": km_part} | {n: SIGMAS * mode * float(v) for n, v in timing.items()}
        out.append(ModelMargin(w, needed, math.sqrt(sum(x * x for x in parts.values())), parts))
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
