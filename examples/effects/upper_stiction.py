"""Stiction of the motor bearing: the upper disc needs more torque to break away than to keep turning.

A user file for drillgym (docs/EFFECTS.md, "Friction"):
``--add-effect examples/effects/upper_stiction.py:upper_stiction``.  A Friction effect: it changes the
upper disc's slip torque and, consistently, its stick set; the set-valued stick logic stays exact.
"""

import math

from drillgym.effects import Friction, Parameter


class UpperStiction(Friction):
    """A Stribeck bump on the upper disc: slip torque T + ds_u exp(-speed / vs_u) in the slip direction,
    stick set widened by ds_u on both sides."""

    name = "upper_stiction"
    disc = "upper"
    parameters = (
        Parameter("ds_u", "N m", 0.0, 0.5, 0.05, 0.02, "extra breakaway torque of the upper disc", neutral=0.0),
        # with ds_u = 0 the effect adds nothing whatever vs_u is: any value in the bounds is neutral
        Parameter("vs_u", "rad/s", 0.01, 5.0, 0.5, 0.1, "speed over which the extra torque fades", neutral=0.5),
    )
    explanation = (
        "The motor's bearing and brushes stick: breaking the upper disc away takes ds_u more than the Coulomb "
        "level, and the extra torque fades over a speed vs_u once it turns (a Stribeck bump)."
    )
    signature = (
        "the upper disc starts later after each stop and runs slightly slow just after; residual torque on the "
        "upper disc in the slip direction, largest at low speed"
    )

    def slip(T, direction, speed, ds_u, vs_u):
        """Slip torque of the upper disc (N m, signed like its speed) from the law's T."""
        return T + direction * ds_u * math.exp(-speed / vs_u)

    def stick(lo, hi, ds_u):
        """Stick set (N m): the slip torque's limits at zero speed, so stick and slip agree."""
        return lo - ds_u, hi + ds_u
