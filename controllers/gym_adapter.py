"""Drive the Gymnasium environments (``drillgym/*-v0``, the hardware env) with a :class:`controllers.Controller`.

The envs' ``sensors`` and ``motor`` observations (:mod:`drillgym.envs.observation`) carry what
the rig measures; :class:`ControllerPolicy` turns each observation into the controller's
measurement dict and the controller's voltage into the env's action::

    env = gymnasium.make("drillgym/Torsional-v0", observation="sensors", omega_ref=2.0)
    policy = ControllerPolicy(controllers.make("observer", omega_ref=2.0), env)
    obs, info = env.reset(seed=0)
    policy.reset(obs)
    obs, reward, terminated, truncated, info = env.step(policy(obs))

Angles: ``sensors`` reports the quantized encoder angles wrapped to [-pi, pi); the policy unwraps
them (the angle advances by less than pi per control period below 314 rad/s).  ``motor``
reports quantized increments of theta_u per control period divided by the period; the policy sums
them (exactly the quantized angle, relative to the start).  LVDT readings (mm) become x, y (m).
The ``full`` observation (true state, no encoder angles) is refused.
"""

from __future__ import annotations

import numpy as np

from drillgym.errors import InputError

from .base import U_MAX, Controller

__all__ = ["ControllerPolicy", "run_episode"]

MM = 1e-3  # mm -> m


class ControllerPolicy:
    """Observation of a drillgym env -> measurement dict -> controller -> action (array of one voltage).

    Parameters
    ----------
    controller : Controller
        Any controller; its control period must equal the env's ``control_dt``.
    env
        The env (wrapped or not) whose observations it reads.
    """

    def __init__(self, controller: Controller, env) -> None:
        base = env.unwrapped
        opts = base.options
        self.controller = controller
        self.names = tuple(base.observation_names)
        self.mode = opts.observation
        if self.mode not in ("sensors", "motor"):
            raise InputError(
                f"ControllerPolicy needs observation='sensors' or 'motor' (measurements), got observation={self.mode!r}"
            )
        if abs(opts.control_dt - controller.dt) > 1e-12:
            raise InputError(
                f"controller period {controller.dt} s differs from the env's control_dt {opts.control_dt} s"
            )
        self.dt = float(opts.control_dt)
        self.scale = 1.0 / U_MAX if opts.normalize_action else 1.0
        self._i = {n: k for k, n in enumerate(self.names)}
        provided = {"t", "omega_ref", "theta_u"} | ({"theta_l"} if self.mode == "sensors" else set())
        if "X_meas" in self._i:
            provided |= {"x", "y"}
        missing = [m for m in controller.uses if m not in provided]
        if missing:
            raise InputError(
                f"controller {controller.name!r} needs {missing}, which observation={self.mode!r} "
                f"of this env does not carry"
            )
        self._theta = np.zeros(2)
        self._t = 0.0
        self._pending: dict | None = None

    def measurement(self, obs: np.ndarray) -> dict[str, float]:
        """The controller's measurements from one observation (advances the unwrapped angles and time)."""
        o = np.asarray(obs, dtype=float)
        i = self._i
        if self.mode == "sensors":
            for k, name in enumerate(("theta_u_wrapped", "theta_l_wrapped")):
                self._theta[k] += _wrap(o[i[name]] - _wrap(self._theta[k]))
        else:
            self._theta[0] += o[i["omega_u_inc_0"]] * self.dt
        m = {"t": self._t, "theta_u": float(self._theta[0]), "omega_ref": float(o[i["omega_ref"]])}
        if self.mode == "sensors":
            m["theta_l"] = float(self._theta[1])
        if "X_meas" in i:
            m["x"], m["y"] = float(o[i["X_meas"]] * MM), float(o[i["Y_meas"]] * MM)
        return m

    def reset(self, obs: np.ndarray) -> None:
        """Start an episode from the reset observation."""
        o = np.asarray(obs, dtype=float)
        self._t = 0.0
        if self.mode == "sensors":
            self._theta = np.array([o[self._i["theta_u_wrapped"]], o[self._i["theta_l_wrapped"]]], dtype=float)
        else:
            self._theta = np.zeros(2)
        self._pending = self.measurement(o)  # the reset observation: the first action is computed from it
        self.controller.reset(self._pending)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """Action (float32 array of one element) for the observation."""
        if self._pending is not None:
            m, self._pending = self._pending, None
        else:
            self._t += self.dt
            m = self.measurement(obs)
        return np.array([float(self.controller.act(m)) * self.scale], dtype=np.float32)


def _wrap(a: float) -> float:
    """Angle wrapped to [-pi, pi) (rad)."""
    return (a + np.pi) % (2 * np.pi) - np.pi


def run_episode(controller: Controller, env, *, seed: int | None = None, max_steps: int | None = None) -> dict:
    """Run one episode of ``controller`` in ``env``; returns arrays of time (s), omega_l (rad/s), voltage (V),
    the rewards and the last info."""
    policy = ControllerPolicy(controller, env)
    obs, info = env.reset(seed=seed)
    policy.reset(obs)
    out = {"t": [], "omega_l": [], "u": [], "reward": []}
    k = 0
    while max_steps is None or k < max_steps:
        obs, rew, term, trunc, info = env.step(policy(obs))
        for key, v in (("t", info["time"]), ("omega_l", info["omega_l"]), ("u", info["voltage"]), ("reward", rew)):
            out[key].append(float(v))
        k += 1
        if term or trunc:
            break
    res = {k: np.asarray(v) for k, v in out.items()}
    res["info"] = info
    return res
