"""Controllers for the drill-string rig and the harness that compares them (and RL agents).

* :mod:`.base` - the interface (:class:`Controller`: reset, one voltage per control period)
* :mod:`.baseline` - bifurcation-based open-loop baseline, stick-slip region
* :mod:`.pi` - PI speed control of the motor
* :mod:`.descent` - approach from above the fold and down the stable branch (needs no exact model)
* :mod:`.softtorque` - soft-torque active damping
* :mod:`.kalman` - Kalman filters (linear, extended) on the motor angle with a friction-torque state
* :mod:`.flatness` - feedback-linearising tracking law for the lower speed (LQR on its error chain)
* :mod:`.observer` - observer-based active damping (EKF + feedback linearisation) and LQG
* :mod:`.robust_observer` - the observer with a disturbance state, smoothing, integral and fallback
* :mod:`.limits` - what any motor-angle-only controller can achieve (RHP poles/zeros, sensitivity bound)
* :mod:`.two_encoder` - gain-scheduled LQG on the motor and lower encoders (``lqg-2enc``)
* :mod:`.gym_adapter` - ``ControllerPolicy``: a controller drives the Gymnasium envs
* :mod:`.registry` - ``make(name, ...)``, the ``agent:PATH`` hook
* :mod:`.evaluation` - scenarios, metrics, closed-loop runs, report
"""

from typing import TYPE_CHECKING

from drillgym._lazy import lazy_names

if TYPE_CHECKING:  # pragma: no cover - loaded on first use (__getattr__)
    from .base import MEASUREMENTS, U_MAX, Controller
    from .registry import CONTROLLERS, available, make, register_agent_loader

__all__ = ["Controller", "MEASUREMENTS", "U_MAX", "CONTROLLERS", "available", "make", "register_agent_loader"]

#: name -> its module, imported on first use (PEP 562): the registry imports every controller and their
#: design stack (python-control, scipy), which ``drillgym evaluate --help`` (this package's commands) does
#: not need
_LAZY = {
    **dict.fromkeys(("Controller", "MEASUREMENTS", "U_MAX"), "base"),
    **dict.fromkeys(("CONTROLLERS", "available", "make", "register_agent_loader"), "registry"),
}


__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
