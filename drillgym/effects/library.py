"""The effect library: ten physical effects a real rig shows and the base model leaves out.

Each is written as a user would write one (:mod:`drillgym.effects.base`); nothing about them
is special to the simulator.  ``drillgym effects`` lists them with their parameters.
"""

from __future__ import annotations

import math

from .base import Delay, Force, Friction, Input, Measurement, Parameter, State

__all__ = [
    "PositionFriction",
    "BrakeAsymmetry",
    "StringDamping",
    "MotorLag",
    "InputDelay",
    "LateralAnisotropy",
    "LvdtOffset",
    "LvdtSkew",
    "LateralCoulomb",
    "FrictionDrift",
    "LIBRARY",
]

#: regularisation speed of the lateral dry-friction direction (m/s)
LATERAL_COULOMB_EPS = 1e-4


class PositionFriction(Friction):
    """Friction level of the lower disc that depends on its angle (spots on the brake surface).

    Library name ``position_friction``; :meth:`describe` gives its physics and the residual it leaves when missing.

    Parameters
    ----------
    **values : float
        Parameter values by name:

        * ``pf_c1``: cos(theta_l) coefficient of the friction level, in [-0.9, 0.9]; default 0.
        * ``pf_s1``: sin(theta_l) coefficient, in [-0.9, 0.9]; default 0.
        * ``pf_c2``: cos(2 theta_l) coefficient, in [-0.9, 0.9]; default 0.
        * ``pf_s2``: sin(2 theta_l) coefficient, in [-0.9, 0.9]; default 0.
    """

    name = "position_friction"
    disc = "lower"
    parameters = (
        Parameter("pf_c1", "-", -0.9, 0.9, 0.0, 0.05, "cos(theta_l) coefficient of the friction level", neutral=0.0),
        Parameter("pf_s1", "-", -0.9, 0.9, 0.0, 0.05, "sin(theta_l) coefficient", neutral=0.0),
        Parameter("pf_c2", "-", -0.9, 0.9, 0.0, 0.05, "cos(2 theta_l) coefficient", neutral=0.0),
        Parameter("pf_s2", "-", -0.9, 0.9, 0.0, 0.05, "sin(2 theta_l) coefficient", neutral=0.0),
    )
    configurations = ("torsional", "lateral", "coupled", "free_vibration")
    needs = ("theta_l",)
    explanation = (
        "The friction level of the lower disc depends on the disc's angle: the brake blocks and the bearing do not "
        "touch a perfectly flat, round, evenly oiled surface, so each revolution passes the same high- and "
        "low-friction spots. The report saw bifurcation points scatter by ±0.1 V with the starting angle. "
        "Modelled as Tfl × (1 + c1 cos θl + s1 sin θl + c2 cos 2θl + s2 sin 2θl), stick set scaled alike."
    )
    signature = (
        "residual torque on the lower disc periodic in θl (once and twice per revolution); angle residuals grow in "
        "the slip phases and their spectrum peaks at the rotation frequency and its second harmonic; sticking "
        "happens at preferred angles"
    )

    def level(theta_l, pf_c1, pf_s1, pf_c2, pf_s2):
        c, s = math.cos(theta_l), math.sin(theta_l)
        c2, s2 = c * c - s * s, 2.0 * s * c  # cos 2θl, sin 2θl
        return 1.0 + pf_c1 * c + pf_s1 * s + pf_c2 * c2 + pf_s2 * s2


class BrakeAsymmetry(Friction):
    """Brake friction levels that differ between the two directions of rotation.

    Library name ``brake_asymmetry``; :meth:`describe` gives its physics and the residual it leaves when missing.

    Parameters
    ----------
    **values : float
        Parameter values by name:

        * ``asym_s``: relative change of the static level for negative rotation, in [-0.9, 5]; default 0.
        * ``asym_c``: relative change of the slip level for negative rotation, in [-0.9, 5]; default 0.
    """

    name = "brake_asymmetry"
    disc = "lower"
    parameters = (
        Parameter(
            "asym_s",
            "-",
            -0.9,
            5.0,
            0.0,
            0.05,
            "relative change of the static level for negative rotation",
            neutral=0.0,
        ),
        Parameter(
            "asym_c", "-", -0.9, 5.0, 0.0, 0.05, "relative change of the slip level for negative rotation", neutral=0.0
        ),
    )
    configurations = ("torsional", "coupled")
    needs = ("negative_rotation",)
    explanation = (
        "The brake (oil film between blocks and disc) grips differently in the two directions of rotation: block "
        "geometry and the leading/trailing edge make the static and slip friction levels direction dependent. "
        "Modelled as Ts × (1 + asym_s), Tc × (1 + asym_c) for negative rotation of the lower disc."
    )
    signature = (
        "residual correlated with sign(ωl): slips in the negative direction start later/earlier and run "
        "slower/faster than the model; invisible if the disc never turns backwards"
    )

    def slip(T, direction, speed, brake, Ts, Tc, ws, delta, asym_s, asym_c):
        if direction > 0.0 or brake == 0.0:
            return T
        stribeck = math.exp(-math.exp(delta * math.log(max(speed / ws, 1e-300))))  # exp(-(speed/ws)^delta)
        return T - (asym_c * Tc + (asym_s * Ts - asym_c * Tc) * stribeck)

    def stick(lo, hi, brake, asym_s):
        return (lo * (1.0 + asym_s), hi) if brake != 0.0 else (lo, hi)


class StringDamping(Force):
    """Torsional damping of the string, in parallel with its stiffness.

    Library name ``string_damping``; :meth:`describe` gives its physics and the residual it leaves when missing.

    Parameters
    ----------
    **values : float
        Parameter values by name:

        * ``dtheta``: torsional damping of the string (N m s/rad), in [0, 10]; default 0.002.
    """

    name = "string_damping"
    acts_on = "string"
    parameters = (
        Parameter("dtheta", "N m s/rad", 0.0, 10.0, 0.002, 0.005, "torsional damping of the string", neutral=0.0),
    )
    configurations = ("torsional", "lateral", "coupled", "free_vibration")
    explanation = (
        "The steel string dissipates energy when it twists (material hysteresis, air drag on the string): a torque "
        "dθ (ωl − ωu) in parallel with kθ α. The report assumed it negligible."
    )
    signature = (
        "torsional oscillations (the α mode at √(kθ/Jl) ≈ 1.4 rad/s) decay faster in the data than in the model; "
        "residual α in quadrature with α̇, largest after slips and steps"
    )

    def torque(alpha_dot, dtheta):
        return dtheta * alpha_dot


class MotorLag(Input):
    """First-order lag of the amplifier and motor: tau_m du_m/dt = u - u_m.

    Library name ``motor_lag``; :meth:`describe` gives its physics and the residual it leaves when missing.

    Parameters
    ----------
    **values : float
        Parameter values by name:

        * ``tau_m``: first-order amplifier/motor time constant (s), in [0.0001, 5]; default 0.005.
    """

    name = "motor_lag"
    parameters = (Parameter("tau_m", "s", 1e-4, 5.0, 0.005, 0.02, "first-order amplifier/motor time constant"),)
    states = (State("u_m", "V", "voltage at the motor after the lag"),)
    lag = {"u_m": "tau_m"}  # integrated exactly over each step: stable for any tau_m (also << dt)
    configurations = ("upper", "torsional", "lateral", "coupled")
    explanation = (
        "The amplifier and the motor's electrical time constant turn the commanded voltage into torque with a "
        "first-order lag τm instead of instantly: τm u̇m = u − um."
    )
    signature = (
        "the upper disc answers input steps later than the model: residual θu/ωu proportional to the input's "
        "derivative, growing with the input's frequency content"
    )

    def derivative(u, u_m, tau_m):
        return (u - u_m) / tau_m

    def voltage(u_m):
        return u_m


class InputDelay(Delay):
    """Pure transport delay between the commanded voltage and the motor.

    Library name ``input_delay``; :meth:`describe` gives its physics and the residual it leaves when missing.

    Parameters
    ----------
    **values : float
        Parameter values by name:

        * ``delay``: pure transport delay of the command (s), in [0, 0.5]; default 0.005.
    """

    name = "input_delay"
    parameters = (Parameter("delay", "s", 0.0, 0.5, 0.005, 0.02, "pure transport delay of the command", neutral=0.0),)
    configurations = ("upper", "torsional", "lateral", "coupled")
    explanation = (
        "A pure transport delay between the commanded voltage and the motor (sampling, communication, amplifier "
        "dead time): the motor sees u(t − d)."
    )
    signature = (
        "the whole response is shifted in time: residual ∝ u(t) − u(t − d), the cross-correlation between input and "
        "residual peaks at a positive lag"
    )

    def delay(delay):
        return delay


class LateralAnisotropy(Force):
    """Lateral stiffness and damping that differ in x and y (fixed frame).

    Library name ``lateral_anisotropy``; :meth:`describe` gives its physics and the residual it leaves when missing.

    Parameters
    ----------
    **values : float
        Parameter values by name:

        * ``dk``: kx = k + dk, ky = k - dk (fixed frame) (N/m), in [-1500, 1500]; default 0.
        * ``db``: bx = b + db, by = b - db (fixed frame) (N s/m), in [-20, 20]; default 0.
    """

    name = "lateral_anisotropy"
    acts_on = "lateral"
    parameters = (
        Parameter("dk", "N/m", -1500.0, 1500.0, 0.0, 60.0, "kx = k + dk, ky = k - dk (fixed frame)", neutral=0.0),
        Parameter("db", "N s/m", -20.0, 20.0, 0.0, 1.25, "bx = b + db, by = b - db (fixed frame)", neutral=0.0),
    )
    configurations = ("lateral", "coupled")
    explanation = (
        "The leaf-spring constraints of the lower disc are not equally stiff and damped in x and y (report table "
        "3.5: kx = 2260, ky = 2035 N/m). Modelled as kx = k + dk, ky = k − dk, bx = b + db, by = b − db in the "
        "fixed frame: the extra force is (−dk X − db Ẋ, dk Y + db Ẏ)."
    )
    signature = (
        "ripple in r at twice the whirl frequency; the orbit in the (x, y) plane is an ellipse, not a circle; x and "
        "y residuals of different size"
    )

    def force(X, Y, VX, VY, dk, db):
        return -dk * X - db * VX, dk * Y + db * VY


class LateralCoulomb(Force):
    """Dry friction in the lateral guides and LVDT cores, against the lateral velocity.

    Library name ``lateral_coulomb``; :meth:`describe` gives its physics and the residual it leaves when missing.

    Parameters
    ----------
    **values : float
        Parameter values by name:

        * ``Fc_lat``: dry friction in the lateral guides (N), in [0, 50]; default 0.2.
    """

    name = "lateral_coulomb"
    acts_on = "lateral"
    parameters = (Parameter("Fc_lat", "N", 0.0, 50.0, 0.2, 0.5, "dry friction in the lateral guides", neutral=0.0),)
    configurations = ("lateral", "coupled")
    explanation = (
        "Dry friction in the lateral guides and the LVDT cores (the report suspected LVDT friction for its worse fit "
        "at large lateral displacement, R² 0.905): a force of size Fc_lat against the lateral velocity, its "
        "direction regularised below 0.1 mm/s."
    )
    signature = (
        "measured whirl amplitude r smaller than the model's, most at large r and near the whirl resonance; small "
        "motions die out completely (lateral stick)"
    )

    def force(VX, VY, Fc_lat):
        v = math.sqrt(VX * VX + VY * VY + LATERAL_COULOMB_EPS * LATERAL_COULOMB_EPS)
        return -Fc_lat * VX / v, -Fc_lat * VY / v


class FrictionDrift(Friction):
    """Lower friction level drifting along the run (the brake's oil warming up).

    Library name ``friction_drift``; :meth:`describe` gives its physics and the residual it leaves when missing.

    Parameters
    ----------
    **values : float
        Parameter values by name:

        * ``drift``: relative drift rate of the friction level (1/s), in [-0.02, 0.02]; default 0.
    """

    name = "friction_drift"
    disc = "lower"
    parameters = (
        Parameter("drift", "1/s", -0.02, 0.02, 0.0, 5e-4, "relative drift rate of the friction level", neutral=0.0),
    )
    configurations = ("torsional", "lateral", "coupled", "free_vibration")
    explanation = (
        "The brake's oil warms up during a run, its viscosity falls and the friction level drifts: lower friction "
        "× (1 + drift t)."
    )
    signature = (
        "residual that grows (or changes sign) along the run: early windows fit, late ones do not; stick phases "
        "lengthen or shorten over time"
    )

    def level(t, drift):
        return 1.0 + drift * t


class LvdtOffset(Measurement):
    """Offsets of the LVDT readings with the disc at rest.

    Library name ``lvdt_offset``; :meth:`describe` gives its physics and the residual it leaves when missing.

    Parameters
    ----------
    **values : float
        Parameter values by name:

        * ``lvdt_x0``: lVDT x reading with the disc at rest (m), in [-0.01, 0.01]; default 0.
        * ``lvdt_y0``: lVDT y reading with the disc at rest (m), in [-0.01, 0.01]; default 0.
    """

    name = "lvdt_offset"
    channels = ("X", "Y")
    parameters = (
        Parameter("lvdt_x0", "m", -0.01, 0.01, 0.0, 1e-4, "LVDT x reading with the disc at rest", neutral=0.0),
        Parameter("lvdt_y0", "m", -0.01, 0.01, 0.0, 1e-4, "LVDT y reading with the disc at rest", neutral=0.0),
    )
    configurations = ("lateral", "coupled")
    explanation = "The LVDTs read a nonzero position with the disc at rest (mounting, electronics offset)."
    signature = (
        "constant offsets in the x, y residuals; ripple in r at the whirl frequency (the circle's centre is shifted)"
    )

    def measure(X, Y, lvdt_x0, lvdt_y0):
        return X + lvdt_x0, Y + lvdt_y0


class LvdtSkew(Measurement):
    """Non-perpendicular LVDT axes: the y reading contains a fraction of x.

    Library name ``lvdt_skew``; :meth:`describe` gives its physics and the residual it leaves when missing.

    Parameters
    ----------
    **values : float
        Parameter values by name:

        * ``lvdt_skew``: angle by which the y LVDT axis deviates from perpendicular (rad), in [-0.3, 0.3]; default 0.
    """

    name = "lvdt_skew"
    channels = ("Y",)
    parameters = (
        Parameter(
            "lvdt_skew",
            "rad",
            -0.3,
            0.3,
            0.0,
            0.01,
            "angle by which the y LVDT axis deviates from perpendicular",
            neutral=0.0,
        ),
    )
    configurations = ("lateral", "coupled")
    explanation = "The two LVDT axes are not perpendicular: the y reading contains a fraction sin(skew) of x."
    signature = (
        "y residual proportional to x; the measured orbit is a tilted ellipse; ripple in r at twice the whirl frequency"
    )

    def measure(X, Y, lvdt_skew):
        return Y * math.cos(lvdt_skew) + X * math.sin(lvdt_skew)


LIBRARY = {
    e.name: e
    for e in (
        PositionFriction,
        BrakeAsymmetry,
        StringDamping,
        MotorLag,
        InputDelay,
        LateralAnisotropy,
        LvdtOffset,
        LvdtSkew,
        LateralCoulomb,
        FrictionDrift,
    )
}
