"""The host's measurements of the rig, as :class:`hw.env.HardwareEnv` reads them.

A SAMPLE reply of the firmware becomes readings in SI units, the state-shaped array the simulated
envs' reward, task and 'full' observation read (one row, :data:`drillgym.configurations.N_STATE`
columns) and the observation of the simulated envs' observation models:

* encoder counts: the firmware's wrapping counters unwrapped (:class:`hw.processing.CounterUnwrap`),
  then rad;
* LVDT: raw values to metres, offset taken at rest, causal low-pass (:class:`hw.processing.LvdtProcessor`);
* speeds: encoder estimates (:class:`drillgym.measurement.EncoderVelocityEstimator`); the lateral
  velocities: differences of the low-passed LVDT; the lower end sticks while its count does not change;
* observation: 'sensors' and 'motor' from the readings (LVDT low-passed), 'full' from the measured
  state (its speeds: the encoder estimates);
* times: from the episode's start, on the firmware's clock (``t``) and on the host's (``t_host``).
"""

from __future__ import annotations

import math

import numpy as np

from drillgym.configurations import N_STATE
from drillgym.envs.observation import ObservationModel
from drillgym.measurement import EncoderVelocityEstimator, counts_to_angle

from .client import Reply
from .processing import CounterUnwrap, LvdtProcessor

__all__ = ["RigMeasurements"]


class RigMeasurements:
    """The rig as measured: SAMPLE replies to readings (SI units) and to the measured state.

    Parameters
    ----------
    counts_per_rev : int
        Encoder resolution (from the firmware's CONFIG).
    lvdt_m_per_lsb : float
        LVDT scale (m per raw count, from the firmware's CONFIG).
    control_dt : float
        Period of the samples (s).
    velocity_filter_tau : float
        Time constant of the encoder speed estimates (s).
    lvdt_cutoff_hz : float
        Causal LVDT low-pass cut-off (Hz).

    Attributes
    ----------
    Y : ndarray
        The state as measured, shape (1, N_STATE) (mechanical states; filled in place).
    MODE : ndarray
        The stick/slip modes, shape (1, 2); ``MODE[0, 1]`` is 0 while the lower encoder count holds.
    lvdt : LvdtProcessor
        The LVDT processing (its ``offset``: the one taken at rest).
    t0_us, t0_host : float
        The episode's start on the firmware's clock (us) and on the host's (s).
    """

    def __init__(
        self,
        counts_per_rev: int,
        lvdt_m_per_lsb: float,
        control_dt: float,
        velocity_filter_tau: float,
        lvdt_cutoff_hz: float,
    ) -> None:
        self.counts_per_rev = counts_per_rev
        self.control_dt = control_dt
        self.speed = EncoderVelocityEstimator(2, control_dt, velocity_filter_tau)
        self.lvdt = LvdtProcessor(lvdt_m_per_lsb, 1.0 / control_dt, lvdt_cutoff_hz)
        self._cu, self._cl = CounterUnwrap(), CounterUnwrap()
        self.Y = np.zeros((1, N_STATE))
        self.MODE = np.zeros((1, 2), dtype=np.int64)
        self._xy_prev = np.zeros(2)
        self._counts_l_prev = 0
        self.t0_us = 0
        self.t0_host = 0.0

    def start(self, rest: list[Reply]) -> dict[str, float]:
        """Start an episode on the replies of the rig at rest: the clocks start at the last one, the LVDT
        offset is their mean, the counters and the speed estimates start from the last; its readings."""
        last = rest[-1]
        self.t0_us, self.t0_host = last.sample.timestamp_us, last.received
        self.lvdt.calibrate_rest(np.array([r.sample.lvdt_x for r in rest]), np.array([r.sample.lvdt_y for r in rest]))
        self._cu.reset()
        self._cl.reset()
        m = self.read(last)
        self._counts_l_prev = m["counts_l"]
        self.speed.reset(np.array([m["theta_u"], m["theta_l"]]))
        self._xy_prev[:] = (m["x_lp"], m["y_lp"])
        return m

    def read(self, reply: Reply) -> dict[str, float]:
        """Processed readings of a SAMPLE (SI units)."""
        s = reply.sample
        cu, cl = self._cu.update(s.counts_u), self._cl.update(s.counts_l)
        tu, tl = (float(a) for a in counts_to_angle(np.array([cu, cl]), self.counts_per_rev))
        xy, xy_lp = self.lvdt.update(s.lvdt_x, s.lvdt_y)
        return {
            "t": (s.timestamp_us - self.t0_us) * 1e-6,
            "u": s.volts,
            "theta_u": tu,
            "theta_l": tl,
            "x": xy[0],
            "y": xy[1],
            "x_lp": xy_lp[0],
            "y_lp": xy_lp[1],
            "counts_u": cu,
            "counts_l": cl,
            "lvdt_x_raw": s.lvdt_x,
            "lvdt_y_raw": s.lvdt_y,
            "status": int(s.status),
            "t_host": reply.received - self.t0_host,
        }

    def update(self, reply: Reply) -> tuple[dict[str, float], np.ndarray]:
        """One control period's SAMPLE: its readings and the speed estimates [omega_u, omega_l] (rad/s);
        the measured state and the lower end's mode updated."""
        m = self.read(reply)
        omega = self.speed.update(np.array([m["theta_u"], m["theta_l"]]))
        xy = np.array([m["x_lp"], m["y_lp"]])
        dxy, self._xy_prev[:] = (xy - self._xy_prev) / self.control_dt, xy
        self.fill_state(m, omega, dxy)
        self.MODE[0, 1] = 0 if m["counts_l"] == self._counts_l_prev else int(np.sign(omega[1]) or 1)
        self._counts_l_prev = m["counts_l"]
        return m, omega

    def fill_state(self, m: dict[str, float], omega: np.ndarray, dxy: np.ndarray, angle_shift: float = 0.0) -> None:
        """Fill the state-shaped array the envs' reward/task/'full' observation read, from measurements."""
        Y = self.Y[0]
        Y[0], Y[1] = m["theta_u"] + angle_shift, m["theta_l"] + angle_shift
        Y[2], Y[3] = omega
        c, s = math.cos(Y[0]), math.sin(Y[0])
        X, Yf = m["x_lp"], m["y_lp"]
        Y[4], Y[5] = X * c + Yf * s, -X * s + Yf * c  # rotating frame
        vbx, vby = dxy[0] * c + dxy[1] * s, -dxy[0] * s + dxy[1] * c
        Y[6], Y[7] = vbx + Y[2] * Y[5], vby - Y[2] * Y[4]

    def observe(
        self,
        obs_model: ObservationModel,
        m: dict[str, float],
        u_prev: np.ndarray,
        omega_ref: np.ndarray,
        out: np.ndarray,
        rngs: list[np.random.Generator],
    ) -> None:
        """Write the observation of readings ``m`` (and the measured state) to ``out``."""
        mode = obs_model.mode
        tu, tl = np.array([m["theta_u"]]), np.array([m["theta_l"]])
        if mode == "sensors":
            obs_model.from_readings(tu, tl, np.array([m["x_lp"]]), np.array([m["y_lp"]]), u_prev, omega_ref, out)
        elif mode == "motor":
            obs_model.from_readings(tu, u_prev, omega_ref, out)
        else:  # 'full' from the measured state (speeds estimated from the encoders)
            obs_model.observe(self.Y, u_prev, omega_ref, out, rngs)
