"""Free play in the string: the coupling turns freely over a small angle before it carries torque.

A user file for drillgym: ``--add-effect examples/effects/string_backlash.py:string_backlash``.
A non-smooth effect: the torque has kinks at alpha = +/- gap (the fixed-step RK4 resolves
them to its step; the stick/slip events stay exact).
"""

from drillgym.effects import Force, Parameter


class StringBacklash(Force):
    """String torque k_theta * dz(alpha) with a dead zone dz of half-width gap."""

    name = "string_backlash"
    acts_on = "string"
    parameters = (
        Parameter(
            "gap",
            unit="rad",
            lo=0.0,
            hi=1.0,
            guess=0.02,
            scale=0.01,
            doc="half-width of the free play in the string's coupling",
        ),
    )
    explanation = (
        "The string is clamped to the discs through couplings with a little play: over |α| < gap the string "
        "carries no torque, beyond it the elastic twist is α − gap sign(α). The base model's kθ α is replaced "
        "by kθ dz(α), so the extra torque is kθ (dz(α) − α)."
    )
    signature = (
        "after every reversal of the twist the lower disc lags by up to 2·gap; the torque residual is a "
        "saturated ramp in α (−kθ α inside the gap, ∓kθ gap outside), largest in the slip phases"
    )

    def torque(alpha, ktheta, gap):
        """Extra string torque (N m): ktheta * (dead_zone(alpha) - alpha)."""
        if alpha > gap:
            dead_zone = alpha - gap
        elif alpha < -gap:
            dead_zone = alpha + gap
        else:
            dead_zone = 0.0
        return ktheta * (dead_zone - alpha)
