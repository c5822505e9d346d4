"""The command schedule a policy is given: the target reached from above along the stable branch.

From rest the rig falls into stick-slip for every voltage up to the second fold (docs/model.md, R7, R9), but
its slip equilibrium is stable from the second Hopf point up.  A policy that sees only the motor angle
cannot damp the lower disc robustly below that point (:mod:`controllers.limits`); what it can do is
reach a low target *from above*, where no stick-slip cycle exists on the way.  The schedule is the
speed command (rad/s) the policy is asked to follow, not a voltage::

    omega_cmd(t) = approach                                    t < hold
                 = approach + (t - hold) / ramp * (target - approach)   hold <= t < hold + ramp
                 = target                                      later
    (targets at or above ``approach``: omega_cmd = target throughout)

passed through ``order`` first-order lags (three by default) of time constant ``lag`` (a gentle start from
rest; the command is 0 at the start).  :class:`SpeedCommand` replaces the target entry of the 'motor' observation by it,
and the motor-angle tracking integral (:mod:`agents.integral`) follows it.  ``settled_integral``: the integral
runs only where the ``observer``'s low-speed branch (:class:`controllers.flatness.FlatnessLaw`) integrates its
speed error, for targets below ``approach`` once the ramp is over (0 elsewhere), and is clipped at ``z_max``, so
that a student of that teacher sees the integral the teacher's voltage depends on.  It is a function of the
clock and the target only (numpy, no model): :class:`agents.envs.MotorIntegralVecEnv` computes it in
training and :class:`agents.controller.AgentController` on the rig, with the same class.  The voltage is
the network's alone: nothing here computes or adds a voltage.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from drillgym.errors import InputError

from .integral import Z_MAX

__all__ = ["CommandSchedule", "SpeedCommand", "schedule_of"]


@dataclass(frozen=True)
class CommandSchedule:
    """Speed command reaching the target from above.

    Parameters
    ----------
    approach : float, optional
        Speed (rad/s) commanded first, above the fold of the bifurcation diagram (nominal torsional rig: fold at
        3.85 V, about 6.7 rad/s; 8.5 rad/s needs 4.87 V).
    hold : float, optional
        Time (s) at the approach speed.
    ramp : float, optional
        Duration (s) of the linear ramp from the approach speed down to the target.
    lag : float, optional
        Time constant (s) of each of the lags the schedule passes through (0: none).
    order : int, optional
        Number of those lags, 1 to 3 (one: the reference of ``lqg-2enc``, :mod:`controllers.two_encoder`).
    settled_integral : bool, optional
        The motor-angle integral runs only for targets below ``approach`` once the ramp is over
        (:meth:`integrating`).
    z_max : float, optional
        Clip of the motor-angle integral (rad).  Default 2 (:data:`agents.integral.Z_MAX`).
    """

    approach: float = 8.5
    hold: float = 8.0
    ramp: float = 20.0
    lag: float = 1.0
    order: int = 3
    settled_integral: bool = False
    z_max: float = Z_MAX

    def __post_init__(self) -> None:
        if isinstance(self.order, bool) or not isinstance(self.order, int) or self.order not in (1, 2, 3):
            raise InputError(f"command schedule: order must be 1, 2 or 3 lags, got {self.order!r}")
        if not isinstance(self.settled_integral, bool):
            raise InputError(f"command schedule: settled_integral must be true or false, got {self.settled_integral!r}")
        if not (isinstance(self.z_max, (int, float)) and np.isfinite(self.z_max) and self.z_max > 0):
            raise InputError(f"command schedule: z_max must be a positive angle (rad), got {self.z_max!r}")
        for name in ("approach", "hold", "ramp", "lag"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and np.isfinite(v) and v >= 0):
                raise InputError(f"command schedule: {name} must be a finite number >= 0, got {v!r}")
        if self.approach <= 0:
            raise InputError(f"command schedule: approach must be a positive speed (rad/s), got {self.approach!r}")

    @classmethod
    def from_config(cls, spec: dict[str, Any] | None) -> CommandSchedule | None:
        """The schedule of a hyperparameter entry (``command_schedule: {approach, hold, ramp, lag, order,
        settled_integral, z_max}``); None: none."""
        if spec is None:
            return None
        keys = ("approach", "hold", "ramp", "lag", "order", "settled_integral", "z_max")
        if not isinstance(spec, dict):
            raise InputError(f"command schedule: expected a mapping {{{', '.join(keys)}}}, got {spec!r}")
        unknown = sorted(set(spec) - set(keys))
        if unknown:
            raise InputError(f"command schedule: unknown keys {unknown}; expected {', '.join(keys)}")
        return cls(**{k: (v if k in ("order", "settled_integral") else float(v)) for k, v in spec.items()})

    def __call__(self, t: float | np.ndarray, target: float | np.ndarray) -> np.ndarray:
        """Commanded speed (rad/s) at time ``t`` (s since the start) towards ``target`` (rad/s)."""
        t = np.asarray(t, dtype=float)
        target = np.asarray(target, dtype=float)
        s = np.clip((t - self.hold) / self.ramp, 0.0, 1.0) if self.ramp > 0 else (t >= self.hold).astype(float)
        return np.where(target < self.approach, self.approach + s * (target - self.approach), target)

    def integrating(self, t: float | np.ndarray, target: float | np.ndarray) -> np.ndarray:
        """Whether the motor-angle integral runs at time ``t`` (s since the start) towards ``target`` (rad/s):
        always, unless ``settled_integral``; then for targets below ``approach`` after ``hold + ramp`` only."""
        t, target = np.asarray(t, dtype=float), np.asarray(target, dtype=float)
        if not self.settled_integral:
            return np.ones(np.broadcast(t, target).shape, dtype=bool)
        return (target < self.approach) & (t > self.hold + self.ramp)


def schedule_of(spec: dict[str, Any] | None, motor_integral: bool) -> CommandSchedule | None:
    """The schedule of a hyperparameter entry's ``command_schedule``, which needs the motor-angle integral
    (the integral follows the command); None: no schedule."""
    if spec is not None and not motor_integral:
        raise InputError("the command schedule needs the motor-angle integral (motor_integral: true)")
    return CommandSchedule.from_config(spec)


class SpeedCommand:
    """The commanded speed of ``n`` rigs over time: the schedule through its lags.

    ``value`` (rad/s, (n,)) is the command at the current time; :meth:`advance` moves every rig one
    control period on; :meth:`reset` starts rigs from rest (time 0, command 0).

    Parameters
    ----------
    schedule : CommandSchedule
        The schedule.
    n : int
        Number of rigs.
    dt : float
        Control period (s), > 0.
    """

    def __init__(self, schedule: CommandSchedule, n: int, dt: float) -> None:
        if not (np.isfinite(dt) and dt > 0):
            raise InputError(f"the control period must be positive (s), got {dt!r}")
        self.schedule, self.dt = schedule, float(dt)
        self.t = np.zeros(n)
        self.y = np.zeros((3, n))

    @property
    def value(self) -> np.ndarray:
        """Commanded speed now (rad/s)."""
        return self.y[self.schedule.order - 1].copy()

    def integrating(self, target: np.ndarray) -> np.ndarray:
        """Whether each rig's motor-angle integral runs now towards its ``target`` (rad/s, (n,)), (n,) bool
        (:meth:`CommandSchedule.integrating`)."""
        return self.schedule.integrating(self.t, target)

    def reset(self, index: np.ndarray | slice = slice(None)) -> None:
        """Rigs ``index`` start from rest: time 0, command 0."""
        self.t[index] = 0.0
        self.y[:, index] = 0.0

    def advance(self, target: np.ndarray) -> None:
        """One control period on, towards each rig's ``target`` (rad/s, (n,))."""
        w = self.schedule(self.t, target)
        tau = self.schedule.lag
        if tau <= 0:
            self.y[:] = w
        else:  # exact discretisation of each lag for a constant input over the period
            a = 1.0 - np.exp(-self.dt / tau)
            self.y[0] += a * (w - self.y[0])
            for k in range(1, self.schedule.order):
                self.y[k] += a * (self.y[k - 1] - self.y[k])
        self.t += self.dt
