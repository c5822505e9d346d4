"""The lateral terms discovery regresses the residual lateral force on: forces on the lower disc's centre.

Every term is a force (FX, FY) in the fixed (LVDT) frame, shaped by physics:

* springs that depend on the radius r = √(X² + Y²): r (X, Y), r² (X, Y) (a stiffening spring: −k3 r² (X, Y)),
  r⁴ (X, Y), and a stop at radius r0 that pushes back beyond it, (X, Y) max(r − r0, 0) / r, for the radii
  :data:`STOP_RADII`;
* anisotropy: (X, −Y) (kx ≠ ky), (Y, X) (stiffness axes turned against the LVDTs'), (VX, −VY) (bx ≠ by);
* damping shapes: |V| (VX, VY) (quadratic drag), (VX, VY) / |V| (dry friction, its direction regularised
  below :data:`DRY_EPS`), r² (VX, VY) (damping that grows with the radius);
* a constant force (1, 0), (0, 1) (a brake's contact force, a preload);
* a force along a fixed direction that follows the brake's torque T_fl (a brake pad at a fixed point of the rim:
  its friction T_fl / R_pad along the tangent there): T_fl (1, 0), T_fl (0, 1), T_fl by the base's brake law at
  the lower disc's speed;
* a force that turns with the lower disc: (cos θl, sin θl) and (−sin θl, cos θl).

The viscous (VX, VY), the linear spring (X, Y) and the unbalance's force are the base parameters' own columns
(:func:`lateral_nuisance`); the anisotropy (X, −Y), (VX, −VY) and the dry friction are the library's
``lateral_anisotropy`` and ``lateral_coulomb`` (:data:`LIBRARY_SHAPES`): discovery regresses jointly with them and
proposes the others (:func:`outside_terms`), so a candidate explains only what the base and the library cannot.
Each term's code is the Python expression of its (FX, FY) in the arguments ``X, Y, VX, VY, theta_l`` of a lateral
``Force`` effect (:func:`.effect_file.write_effect_file`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = [
    "LateralTerm",
    "lateral_terms",
    "outside_terms",
    "lateral_nuisance",
    "STOP_RADII",
    "DRY_EPS",
    "LIBRARY_SHAPES",
    "CONSTANT_FORCES",
]

#: radii (m) beyond which a stop's force (X, Y) max(r − r0, 0) / r is tried
STOP_RADII = (0.5e-3, 1e-3, 2e-3, 3e-3)
#: speed (m/s) below which the dry friction's direction is regularised (as the library's lateral_coulomb)
DRY_EPS = 1e-4
#: the terms whose shape is a library effect's: term label -> the effect (the library versus the outside)
LIBRARY_SHAPES = {
    "(VX, VY)/|V|": "lateral_coulomb",
    "(X, −Y)": "lateral_anisotropy",
    "(VX, −VY)": "lateral_anisotropy",
}

#: the constant forces' labels (an LVDT offset the model holds reads as one: then they are its columns)
CONSTANT_FORCES = ("(1, 0)", "(0, 1)")
#: the brake's torque on the lower disc (N m) in an effect function's arguments: the base's Stribeck law at the
#: lower disc's speed (:func:`drillgym.friction.brake_law`) while it slips, the string's torque it holds while it
#: sticks (−kθ α), 0 with the brake off
_BRAKE = (
    "brake * ((Tc + (Ts - Tc) * math.exp(-math.exp(delta * math.log(max(abs(omega_l) / ws, 1e-300)))))"
    " * math.copysign(1.0, omega_l) + bb * omega_l if omega_l != 0.0 else -ktheta * alpha)"
)

_R2 = "(X * X + Y * Y)"
_R = f"math.sqrt{_R2}"


@dataclass(frozen=True)
class LateralTerm:
    """A force on the lower disc's centre, fixed frame.

    Attributes
    ----------
    label : str
        The term as shown.
    code : str
        Python expression of the pair (FX, FY) per unit coefficient, in ``X, Y, VX, VY, theta_l`` (m, m/s, rad).
    values : callable
        The data (a dict with ``X``, ``Y``, ``VX``, ``VY``, ``thl``) -> the pair (FX, FY) of arrays.
    """

    label: str
    code: str
    values: Callable[[dict], tuple[np.ndarray, np.ndarray]]


def _radius(d: dict) -> np.ndarray:
    return np.hypot(d["X"], d["Y"])


def _speed(d: dict) -> np.ndarray:
    return np.hypot(d["VX"], d["VY"])


def lateral_terms() -> list[LateralTerm]:
    """The lateral term library (see the module docstring).

    Returns
    -------
    list of LateralTerm
        The terms, in the order they are tried.
    """
    out = [
        LateralTerm("r·(X, Y)", f"({_R} * X, {_R} * Y)", lambda d: (_radius(d) * d["X"], _radius(d) * d["Y"])),
        LateralTerm(
            "r²·(X, Y)", f"({_R2} * X, {_R2} * Y)", lambda d: (_radius(d) ** 2 * d["X"], _radius(d) ** 2 * d["Y"])
        ),
        LateralTerm(
            "r⁴·(X, Y)",
            f"({_R2} ** 2 * X, {_R2} ** 2 * Y)",
            lambda d: (_radius(d) ** 4 * d["X"], _radius(d) ** 4 * d["Y"]),
        ),
    ]
    for r0 in STOP_RADII:
        out.append(
            LateralTerm(
                f"(X, Y)·max(r − {r0 * 1e3:g} mm, 0)/r",
                f"(X * max(1.0 - {r0!r} / max({_R}, 1e-12), 0.0), Y * max(1.0 - {r0!r} / max({_R}, 1e-12), 0.0))",
                lambda d, r0=r0: _stop(d, r0),
            )
        )
    speed = f"math.sqrt(VX * VX + VY * VY + {DRY_EPS * DRY_EPS!r})"
    out += [
        LateralTerm("(X, −Y)", "(X, -Y)", lambda d: (d["X"], -d["Y"])),
        LateralTerm("(Y, X)", "(Y, X)", lambda d: (d["Y"], d["X"])),
        LateralTerm("(VX, −VY)", "(VX, -VY)", lambda d: (d["VX"], -d["VY"])),
        LateralTerm(
            "|V|·(VX, VY)",
            "(math.sqrt(VX * VX + VY * VY) * VX, math.sqrt(VX * VX + VY * VY) * VY)",
            lambda d: (_speed(d) * d["VX"], _speed(d) * d["VY"]),
        ),
        LateralTerm("(VX, VY)/|V|", f"(VX / {speed}, VY / {speed})", lambda d: _dry(d)),
        LateralTerm(
            "r²·(VX, VY)", f"({_R2} * VX, {_R2} * VY)", lambda d: (_radius(d) ** 2 * d["VX"], _radius(d) ** 2 * d["VY"])
        ),
        LateralTerm("(1, 0)", "(1.0, 0.0)", lambda d: (np.ones_like(d["X"]), np.zeros_like(d["X"]))),
        LateralTerm("(0, 1)", "(0.0, 1.0)", lambda d: (np.zeros_like(d["X"]), np.ones_like(d["X"]))),
        LateralTerm("T_fl·(1, 0)", f"({_BRAKE}, 0.0)", lambda d: (d["Tfl"], np.zeros_like(d["Tfl"]))),
        LateralTerm("T_fl·(0, 1)", f"(0.0, {_BRAKE})", lambda d: (np.zeros_like(d["Tfl"]), d["Tfl"])),
        LateralTerm(
            "(cos θl, sin θl)", "(math.cos(theta_l), math.sin(theta_l))", lambda d: (np.cos(d["thl"]), np.sin(d["thl"]))
        ),
        LateralTerm(
            "(−sin θl, cos θl)",
            "(-math.sin(theta_l), math.cos(theta_l))",
            lambda d: (-np.sin(d["thl"]), np.cos(d["thl"])),
        ),
    ]
    return out


def outside_terms() -> list[LateralTerm]:
    """The lateral terms whose shape is no library effect's (not in :data:`LIBRARY_SHAPES`): what a candidate
    outside the library is made of.

    Returns
    -------
    list of LateralTerm
        The terms.
    """
    return [t for t in lateral_terms() if t.label not in LIBRARY_SHAPES]


def _stop(d: dict, r0: float) -> tuple[np.ndarray, np.ndarray]:
    f = np.maximum(1.0 - r0 / np.maximum(_radius(d), 1e-12), 0.0)
    return d["X"] * f, d["Y"] * f


def _dry(d: dict) -> tuple[np.ndarray, np.ndarray]:
    v = np.sqrt(d["VX"] ** 2 + d["VY"] ** 2 + DRY_EPS**2)
    return d["VX"] / v, d["VY"] / v


def lateral_nuisance(d: dict, P: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """The columns a change of the base parameters would add to the residual lateral force (fixed frame, N per
    unit): the spring k (−X, −Y), the damping b (−VX, −VY) and the unbalance P = e mr (its force on the centre,
    ωl² (cos θl, sin θl) − ω̇l (−sin θl, cos θl)).  Not the mass's −(ẌB, ŸB) with the data's acceleration: that is
    the sum of every force on the centre, the missing one too, and would take any candidate's place.

    Parameters
    ----------
    d : dict
        The data: ``X``, ``Y``, ``VX``, ``VY`` (m, m/s), ``thl``, ``wl``, ``dwl`` (rad, rad/s, rad/s²).
    P : float
        The model's unbalance e mr (kg m).

    Returns
    -------
    list of tuple of numpy.ndarray
        The columns as pairs (FX, FY).
    """
    c, s = np.cos(d["thl"]), np.sin(d["thl"])
    w2, dw = d["wl"] ** 2, d["dwl"]
    return [
        (-d["X"], -d["Y"]),
        (-d["VX"], -d["VY"]),
        (P * (w2 * c + dw * s), P * (w2 * s - dw * c)),
    ]
