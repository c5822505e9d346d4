"""The motor-angle tracking integral: an observation entry the rig's motor side gives.

``z = clip(z + control_dt * (omega_u_inc_0 - omega_ref), -z_max, z_max)`` (rad): the measured motor angle
minus the target's angle since the episode began (the newest encoder increment of the 'motor'
observation, entry 0, and the target, the last entry), clipped against wind-up.  In steady rotation the
mean motor speed is the mean lower-disc speed, so a policy that keeps ``z`` bounded tracks the target on
average: an integral-like tracking observation.  It is a measurement (encoder and clock),
not a controller: :class:`agents.envs.MotorIntegralVecEnv` appends it in training,
:class:`agents.controller.AgentController` on the rig, with the same :func:`advance` (numpy only: no SB3 or
torch on the rig).
"""

from __future__ import annotations

import numpy as np

__all__ = ["advance", "Z_MAX"]

#: clip of the integral (rad)
Z_MAX = 2.0


def advance(z: np.ndarray, obs: np.ndarray, control_dt: float, z_max: float = Z_MAX) -> np.ndarray:
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

    Returns
    -------
    ndarray
        The new integral (rad), (n,).
    """
    return np.clip(z + control_dt * (obs[:, 0].astype(float) - obs[:, -1].astype(float)), -z_max, z_max)
