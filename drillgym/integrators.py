"""Fixed-step Runge-Kutta integration with exact, event-driven stick-slip.

Two explicit tableaus: classical RK4 and Dormand-Prince 5 (the 5th-order
solution of DOPRI5, MATLAB's ``ode5``: a cost that is smooth in the parameters
for identification).  ``dp45`` takes adaptive Dormand-Prince 5(4) steps (embedded error
estimate, tolerances ``rtol``/``atol``) between the located events, with outputs interpolated
on the same fixed grid: the fastest choice for one long trajectory.  Both run on a fixed grid of step ``dt``; the
default ``DEFAULT_DT = 1 ms`` resolves the fastest mode of the coupled rig (lateral,
15 rad/s, period 0.42 s) with >400 steps per period and keeps RK4's error on
the stick-slip cycle below 1e-6 rad/s (tests compare against dt/4).

Set-valued friction is treated exactly with a hybrid (event-driven) scheme
inside each fixed step, the approach of Leine's switch model made exact:

* every disc is in a discrete mode: slipping +1 / -1 (smooth friction law with
  that sign) or stuck 0 (speed exactly zero, friction = the constraint torque
  lambda that keeps it at rest);
* after a step, event functions are checked: a slipping disc's signed speed
  ``d w`` and a stuck disc's margin to its stick set ``min(hi - lambda, lambda - lo)``;
* when one changes sign, the event time inside the step is located by the
  Illinois method (re-stepping from the step's start), the state is advanced
  to it, the mode switched (a disc reaching w = 0 sticks if the torque needed
  to hold it lies in its stick set, otherwise it reverses), and the rest of
  the step is integrated with the new modes.

So a stuck disc stays at exactly zero speed for as long as the holding torque
stays in the stick set, and releases when (to the located event time) it leaves.
Outputs stay on the fixed grid.

The kernels themselves (:mod:`drillgym.kernels.stepping`, :mod:`drillgym.kernels.lanes`)
are templates compiled per composition of effects; this module holds what does not depend
on the composition: the tableaus, the default step and the base output columns.
"""

from __future__ import annotations

import numpy as np

from .errors import InputError

DEFAULT_DT = 1e-3  # s

# Butcher tableaus ---------------------------------------------------------------
RK4_A = np.array([[0.0, 0, 0, 0], [0.5, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, 1.0, 0]])
RK4_B = np.array([1 / 6, 1 / 3, 1 / 3, 1 / 6])
RK4_C = np.array([0.0, 0.5, 0.5, 1.0])

DP5_A = np.array(
    [
        [0, 0, 0, 0, 0, 0],
        [1 / 5, 0, 0, 0, 0, 0],
        [3 / 40, 9 / 40, 0, 0, 0, 0],
        [44 / 45, -56 / 15, 32 / 9, 0, 0, 0],
        [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0, 0],
        [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656, 0],
    ],
    dtype=np.float64,
)
DP5_B = np.array([35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84])
DP5_C = np.array([0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0])

TABLEAUS = {"rk4": (RK4_A, RK4_B, RK4_C), "dp5": (DP5_A, DP5_B, DP5_C), "dp45": (DP5_A, DP5_B, DP5_C)}
#: adaptive methods: their steps are chosen by an embedded error estimate (outputs stay on the grid)
ADAPTIVE = ("dp45",)
#: default tolerances of the adaptive method (relative, absolute per state)
DEFAULT_RTOL, DEFAULT_ATOL = 1e-11, 1e-12

#: recorded columns of the base model; a composition appends its effects' states
OUTPUT_NAMES = (
    "t",
    "u",
    "theta_u",
    "theta_l",
    "omega_u",
    "omega_l",
    "x_rot",
    "y_rot",
    "vx_rot",
    "vy_rot",
    "alpha",
    "x",
    "y",
    "r",
    "Tfu",
    "Tfl",
    "stick_u",
    "stick_l",
)
N_OUT = len(OUTPUT_NAMES)


def fixed_step_tableau(method: str, where: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`tableau` for a path that steps at a fixed dt (``where`` names it in the error): 'dp45' is
    adaptive and only single runs take it, so it is refused instead of run as fixed-step DP5."""
    if isinstance(method, str) and method.lower() == "dp45":
        raise InputError(f"{where}: method 'dp45' is adaptive (single runs only); use 'rk4' or 'dp5'")
    return tableau(method)


def tableau(method: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A, b, c) of 'rk4', 'dp5' (fixed step) or 'dp45' (adaptive Dormand-Prince 5(4))."""
    try:
        return TABLEAUS[method.lower()]
    except (KeyError, AttributeError):
        raise InputError(f"unknown integration method {method!r}; expected 'rk4', 'dp5' or 'dp45'") from None
