"""A nonlinear string: the steel string stiffens (or softens) when twisted far.

A user file for drillgym (docs/EFFECTS.md walks through it): add it to any command with
``--add-effect examples/effects/string_cubic.py:string_cubic``.
"""

from drillgym.effects import Force, Parameter


class StringCubic(Force):
    """Torque of the string k_theta (alpha + c3 alpha^3) instead of k_theta alpha."""

    name = "string_cubic"
    acts_on = "string"  # a torque in the string: +torque on the upper disc, -torque on the lower
    parameters = (
        Parameter(
            "c3",
            unit="1/rad^2",
            lo=-0.05,
            hi=0.2,
            guess=0.0,
            scale=0.005,
            doc="relative cubic stiffness of the string",
            neutral=0.0,
        ),
    )
    explanation = (
        "A long thin steel string under large twist does not stay linear: its torsional stiffness grows "
        "with the twist (geometric stiffening of the helically deformed string) or falls (slack in its "
        "clamps). To third order the string torque is kθ (α + c3 α³)."
    )
    signature = (
        "residual torque proportional to α³: small at small twist, growing fast in the stick phases where the "
        "string winds up most; the stick-slip period and the peak twist differ from the model in the same sense"
    )

    def torque(alpha, ktheta, c3):
        """Extra string torque (N m), in the sense of ktheta * alpha."""
        return ktheta * c3 * alpha**3
