"""The effect library: model extensions the diagnosis tries, one by one.

Every effect is already implemented in the core kernels as extension
parameters of :class:`drillgym.RigParams` (0 = off); this module documents
each one (physics, residual signature, where it applies) and says how to fit
it: which variables, their initial values, bounds and typical magnitudes.
Some effects are fitted in better-conditioned variables than the stored
parameters (the angle-dependent friction as cosine/sine coefficients, which is
linear where amplitude/phase is not) and mapped by ``apply``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..configurations import Configuration
from ..identification.fitting import FitVariable
from ..params import IDX, RigParams

__all__ = ["Effect", "EFFECTS", "get_effect", "effects_for"]

T, L, C, F = Configuration.TORSIONAL, Configuration.LATERAL, Configuration.COUPLED, Configuration.FREE_VIBRATION
U = Configuration.UPPER


@dataclass(frozen=True)
class Effect:
    """A documented model extension.

    ``variables(params)`` gives the fit variables (initial guess, bounds, scale),
    ``apply(vec, z)`` writes fitted variables into a kernel parameter vector,
    ``readout(z)`` gives the RigParams values the fitted variables mean.
    """

    name: str
    parameters: tuple[str, ...]
    explanation: str
    signature: str
    configurations: tuple[Configuration, ...]
    _variables: Callable[[RigParams], list[FitVariable]]
    _apply: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None
    needs: tuple[str, ...] = field(default_factory=tuple)

    def variables(self, params: RigParams) -> list[FitVariable]:
        return self._variables(params)

    def apply(self, vec: np.ndarray, z: np.ndarray) -> np.ndarray:
        if self._apply is not None:
            return self._apply(vec, z)
        v = vec.copy()
        for n, val in zip(self.parameters, z):
            v[getattr(IDX, n)] = val
        return v

    def readout(self, params: RigParams, z: np.ndarray) -> dict[str, float]:
        """RigParams values (extension parameters) for fitted variables z."""
        vec = self.apply(params.to_vector(), np.asarray(z, dtype=float))
        return {n: float(vec[getattr(IDX, n)]) for n in self.parameters}

    def applies_to(self, config: Configuration) -> bool:
        return config in self.configurations


def _vars(*spec: tuple[str, float, float, float, float]) -> Callable[[RigParams], list[FitVariable]]:
    return lambda p: [FitVariable(n, x0, lo, hi, s) for n, x0, lo, hi, s in spec]


def _pf_apply(vec: np.ndarray, z: np.ndarray) -> np.ndarray:
    v = vec.copy()
    c1, s1, c2, s2 = z
    v[IDX.pf_a1] = math.hypot(c1, s1)
    v[IDX.pf_phi1] = math.atan2(s1, c1)
    v[IDX.pf_a2] = math.hypot(c2, s2)
    v[IDX.pf_phi2] = math.atan2(s2, c2)
    return v


def _aniso_vars(p: RigParams) -> list[FitVariable]:
    return [FitVariable("dk", 0.0, -0.5 * p.k, 0.5 * p.k, 0.02 * p.k),
            FitVariable("db", 0.0, -0.8 * p.b, 0.8 * p.b, 0.05 * max(p.b, 1e-3))]


EFFECTS: dict[str, Effect] = {e.name: e for e in [
    Effect(
        "position_friction", ("pf_a1", "pf_phi1", "pf_a2", "pf_phi2"),
        "The friction level of the lower disc depends on the disc's angle: the brake blocks and the "
        "bearing do not touch a perfectly flat, round, evenly oiled surface, so each revolution passes "
        "the same high- and low-friction spots. The report saw bifurcation points scatter by ±0.1 V "
        "with the starting angle. Modelled as Tfl × (1 + a1 cos(θl − φ1) + a2 cos(2θl − φ2)).",
        "residual torque on the lower disc periodic in θl (once and twice per revolution); angle "
        "residuals grow in the slip phases and their spectrum peaks at the rotation frequency and "
        "its second harmonic; sticking happens at preferred angles",
        (T, L, C, F),
        _vars(("pf_c1", 0.0, -0.6, 0.6, 0.05), ("pf_s1", 0.0, -0.6, 0.6, 0.05),
              ("pf_c2", 0.0, -0.6, 0.6, 0.05), ("pf_s2", 0.0, -0.6, 0.6, 0.05)),
        _pf_apply, ("theta_l",)),
    Effect(
        "brake_asymmetry", ("asym_s", "asym_c"),
        "The brake (oil film between blocks and disc) grips differently in the two directions of "
        "rotation: block geometry and the leading/trailing edge make the static and slip friction "
        "levels direction dependent. Modelled as Ts × (1 + asym_s), Tc × (1 + asym_c) for negative "
        "rotation of the lower disc.",
        "residual correlated with sign(ωl): slips in the negative direction start later/earlier and "
        "run slower/faster than the model; invisible if the disc never turns backwards",
        (T, C), _vars(("asym_s", 0.0, -0.6, 2.0, 0.05), ("asym_c", 0.0, -0.6, 2.0, 0.05)), None,
        ("negative_rotation",)),
    Effect(
        "string_damping", ("dtheta",),
        "The steel string dissipates energy when it twists (material hysteresis, air drag on the "
        "string): a torque dθ (ωl − ωu) in parallel with kθ α. The report assumed it negligible.",
        "torsional oscillations (the α mode at √(kθ/Jl) ≈ 1.4 rad/s) decay faster in the data than in "
        "the model; residual α in quadrature with α̇, largest after slips and steps",
        (T, L, C, F), _vars(("dtheta", 0.002, 0.0, 0.5, 0.005))),
    Effect(
        "motor_lag", ("tau_m",),
        "The amplifier and the motor's electrical time constant turn the commanded voltage into "
        "torque with a first-order lag τm instead of instantly.",
        "the upper disc answers input steps later than the model: residual θu/ωu proportional to "
        "the input's derivative, growing with the input's frequency content",
        (U, T, L, C), _vars(("tau_m", 0.005, 0.0, 0.5, 0.02))),
    Effect(
        "input_delay", ("delay",),
        "A pure transport delay between the commanded voltage and the motor (sampling, "
        "communication, amplifier dead time).",
        "the whole response is shifted in time: residual ∝ u(t) − u(t − d), the cross-correlation "
        "between input and residual peaks at a positive lag",
        (U, T, L, C), _vars(("delay", 0.005, 0.0, 0.5, 0.02))),
    Effect(
        "lateral_anisotropy", ("dk", "db"),
        "The leaf-spring constraints of the lower disc are not equally stiff and damped in x and y "
        "(report table 3.5: kx = 2260, ky = 2035 N/m). Modelled as kx = k + dk, ky = k − dk, "
        "bx = b + db, by = b − db in the fixed frame.",
        "ripple in r at twice the whirl frequency; the orbit in the (x, y) plane is an ellipse, not a "
        "circle; x and y residuals of different size",
        (L, C), _aniso_vars),
    Effect(
        "lvdt_offset", ("lvdt_x0", "lvdt_y0"),
        "The LVDTs read a nonzero position with the disc at rest (mounting, electronics offset).",
        "constant offsets in the x, y residuals; ripple in r at the whirl frequency (the circle's "
        "centre is shifted)",
        (L, C), _vars(("lvdt_x0", 0.0, -0.01, 0.01, 1e-4), ("lvdt_y0", 0.0, -0.01, 0.01, 1e-4))),
    Effect(
        "lvdt_skew", ("lvdt_skew",),
        "The two LVDT axes are not perpendicular: the y reading contains a fraction sin(skew) of x.",
        "y residual proportional to x; the measured orbit is a tilted ellipse; ripple in r at twice "
        "the whirl frequency",
        (L, C), _vars(("lvdt_skew", 0.0, -0.3, 0.3, 0.01))),
    Effect(
        "lateral_coulomb", ("Fc_lat",),
        "Dry friction in the lateral guides and the LVDT cores (the report suspected LVDT friction "
        "for its worse fit at large lateral displacement, R² 0.905): a force of size Fc_lat against "
        "the lateral velocity.",
        "measured whirl amplitude r smaller than the model's, most at large r and near the whirl "
        "resonance; small motions die out completely (lateral stick)",
        (L, C), _vars(("Fc_lat", 0.2, 0.0, 50.0, 0.5))),
    Effect(
        "friction_drift", ("drift",),
        "The brake's oil warms up during a run, its viscosity falls and the friction level drifts: "
        "lower friction × (1 + drift t).",
        "residual that grows (or changes sign) along the run: early windows fit, late ones do not; "
        "stick phases lengthen or shorten over time",
        (T, L, C, F), _vars(("drift", 0.0, -0.02, 0.02, 5e-4))),
]}


def get_effect(name: str) -> Effect:
    """The effect named ``name``; a clear error lists the known names."""
    try:
        return EFFECTS[name]
    except KeyError:
        raise ValueError(f"unknown effect {name!r}; known effects: {', '.join(EFFECTS)}") from None


def effects_for(config: Configuration) -> list[Effect]:
    """The effects that can act in a configuration."""
    return [e for e in EFFECTS.values() if e.applies_to(config)]
