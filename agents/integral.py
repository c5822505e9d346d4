"""The motor-angle tracking integral: an observation entry the rig's motor side gives.

``z = clip(z + control_dt * (omega_u_inc_0 - omega_ref), -z_max, z_max)`` (rad): the measured motor angle
minus the target's angle since the episode began (the newest encoder increment of the 'motor'
observation, entry 0, and the target, the last entry), clipped against wind-up.  On the 'sensors'
observation the motor speed over the period is the change of the wrapped motor angle (entry 0,
:func:`wrapped_speed`).  In steady rotation the
mean motor speed is the mean lower-disc speed, so a policy that keeps ``z`` bounded tracks the target on
average: an integral-like tracking observation.  It is a measurement (encoder and clock),
not a controller: :class:`agents.envs.MotorIntegralVecEnv` appends it in training,
:class:`agents.controller.AgentController` on the rig, with the same :func:`advance` (numpy only: no SB3 or
torch on the rig).
"""

from __future__ import annotations

import numpy as np

__all__ = ["advance", "wrapped_speed", "Z_MAX"]

#: clip of the integral (rad)
Z_MAX = 2.0


def advance(
    z: np.ndarray,
    obs: np.ndarray,
    control_dt: float,
    z_max: float = Z_MAX,
    speed: np.ndarray | None = None,
    active: np.ndarray | None = None,
) -> np.ndarray:
    """The integral after one control period.

    Parameters
    ----------
    z : ndarray
        The integral of each rig (rad), (n,).
    obs : ndarray
        The period's 'motor' observations (n, dim): entry 0 the newest motor speed increment (rad/s),
        the last entry the target (rad/s).
    control_dt : float
        Control period (s).
    z_max : float, optional
        Clip of the integral (rad).  Default 2.
    speed : ndarray, optional
        The motor speed over the period (rad/s, (n,)) instead of entry 0 (the 'sensors' observation:
        :func:`wrapped_speed`).
    active : ndarray of bool, optional
        The rigs whose integral runs this period (n,) (:meth:`agents.command.SpeedCommand.integrating`); the
        others keep theirs.  Default: all.

    Returns
    -------
    ndarray
        The new integral (rad), (n,).
    """
    w = obs[:, 0].astype(float) if speed is None else np.asarray(speed, dtype=float)
    new = np.clip(z + control_dt * (w - obs[:, -1].astype(float)), -z_max, z_max)
    return new if active is None else np.where(active, new, z)


def wrapped_speed(angle: np.ndarray, prev: np.ndarray, control_dt: float) -> np.ndarray:
    """The motor speed over a control period (rad/s) from the wrapped motor angle at its end and start.

    Parameters
    ----------
    angle, prev : ndarray
        The 'sensors' observation's ``theta_u_wrapped`` (rad, in [-pi, pi)) now and a period ago, (n,).
    control_dt : float
        Control period (s); the motor turns by less than pi per period.

    Returns
    -------
    ndarray
        The speed (rad/s), (n,).
    """
    d = np.asarray(angle, dtype=float) - np.asarray(prev, dtype=float)
    return ((d + np.pi) % (2.0 * np.pi) - np.pi) / control_dt
