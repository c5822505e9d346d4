"""Safety limits of the rig, used on both sides of the link (host environment and firmware).

* :class:`SafetyLimits`: voltage range, slew rate, over-speed and lateral over-displacement.
* :class:`VoltageLimiter`: clamps a commanded voltage to the range and limits its rate of change.
* :func:`check_limits`: the stop reason (or None) for measured speeds and displacement.

The host applies them before a command leaves (the firmware cannot be trusted to be the only
guard) and the firmware applies them again (the host cannot be trusted either).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from drillgym.errors import InputError

from .protocol import StopReason

__all__ = ["SafetyLimits", "VoltageLimiter", "check_limits"]


@dataclass(frozen=True)
class SafetyLimits:
    """Limits of the rig (SI units), each a finite number > 0.

    Parameters
    ----------
    v_max : float, optional
        Amplifier range (V): |u| <= v_max.  Default 5.
    slew_v_per_s : float, optional
        Largest voltage rate (V/s).  Default 1000.
    max_speed : float, optional
        Over-speed threshold on |omega_u| and |omega_l| (rad/s).  Default 40.
    max_displacement : float, optional
        Lateral over-displacement threshold on |X|, |Y| of the LVDTs (m).  Default 0.02.
    """

    v_max: float = 5.0
    slew_v_per_s: float = 1000.0
    max_speed: float = 40.0
    max_displacement: float = 0.02

    def __post_init__(self) -> None:
        for name in ("v_max", "slew_v_per_s", "max_speed", "max_displacement"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise InputError(f"safety limit {name!r} must be a finite number > 0, got {v!r}")


class VoltageLimiter:
    """Clamp to [-v_max, v_max] and limit the change per call to slew_v_per_s * dt (V).

    Non-finite commands (NaN, inf) give 0 V.

    Parameters
    ----------
    limits : SafetyLimits
        The amplifier range and slew rate.
    """

    def __init__(self, limits: SafetyLimits) -> None:
        self.limits = limits
        self.last = 0.0

    def reset(self, voltage: float = 0.0) -> None:
        """Forget the history: the motor is at ``voltage`` (V) now."""
        self.last = float(voltage)

    def limit(self, command: float, dt: float) -> tuple[float, bool]:
        """The voltage to apply for a command.

        Parameters
        ----------
        command : float
            Commanded voltage (V).
        dt : float
            Time since the last call (s).

        Returns
        -------
        voltage : float
            The clamped, slew-limited voltage (V).
        limited : bool
            Whether the command was changed.
        """
        lim = self.limits
        u = float(command)
        if not math.isfinite(u):
            u = 0.0
        u = min(max(u, -lim.v_max), lim.v_max)
        step = lim.slew_v_per_s * dt
        u = min(max(u, self.last - step), self.last + step)
        limited = u != command
        self.last = u
        return u, limited


def check_limits(
    limits: SafetyLimits, omega_u: float, omega_l: float, x: float = 0.0, y: float = 0.0
) -> StopReason | None:
    """The reason to stop for measured speeds and LVDT displacement, or None.

    Parameters
    ----------
    limits : SafetyLimits
        The thresholds.
    omega_u, omega_l : float
        Measured disc speeds (rad/s).
    x, y : float, optional
        LVDT displacement (m).

    Returns
    -------
    StopReason or None
        ``OVERSPEED`` or ``OVER_DISPLACEMENT``, or None within the limits.
    """
    if not (abs(omega_u) <= limits.max_speed and abs(omega_l) <= limits.max_speed):
        return StopReason.OVERSPEED
    if not (abs(x) <= limits.max_displacement and abs(y) <= limits.max_displacement):
        return StopReason.OVER_DISPLACEMENT
    return None
