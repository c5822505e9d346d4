"""An independent plant for closed-loop benchmarks: the torsional rig with the effects a diagnosis finds.

Written from the model page's torsional equations (docs/model.md; the same as :mod:`scipy_switch_model`, no
drillgym code)

    Ju θ̈u + Tfu(θ̇u) − kθ α − c α̇ = km v,      Jl θ̈l + g(θl) Tfl(θ̇l) + kθ α + c α̇ = 0,

vectorised over a batch of plants with a fixed step (``H`` = 0.25 ms, semi-implicit Euler) and Karnopp's stick
logic: a disc whose speed changes sign in a step stops there, and stays at rest while the torque on it lies in
its stick set (upper ±Tcu + ΔTcu, lower ±g(θl) Ts).  ``solve_ivp`` with events (:mod:`scipy_switch_model`)
restarts at every control period, too slow for a closed loop at 500 Hz over 60 s; the equations, parameters
and stick sets are the same.

The effects (each one per plant, any combination), in the order a command passes them:

* ``delay`` (s): the command reaches the drive that much later (a buffer of the steps' commands);
* ``u0`` (V): a dead zone of the drive, v = sign(u) max(|u| − u0, 0); ``u_off`` (V): an offset, v = u + u_off;
* ``tau_m`` (s): a first-order lag of the motor, τm v̇m = v − vm (exact over a step);
* ``c`` (N m s/rad): viscous damping in the string (c α̇ above);
* ``tcu_f``, ``bu_f``: the upper disc's Coulomb level and viscous friction times these factors;
* ``pf_c1``, ``pf_s1``: the brake's level times g(θl) = 1 + c1 cos θl + s1 sin θl;
* ``enc_scale``: the motor encoder reads (1 + enc_scale) θu;

then the encoders are quantised to ``counts`` per revolution with white angle noise ``noise`` (rad).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy_switch_model import PARAMS

H = 2.5e-4  # s, the integration step
EFFECTS = ("delay", "u0", "u_off", "tau_m", "c", "tcu_f", "bu_f", "pf_c1", "pf_s1", "enc_scale")
NEUTRAL = {"delay": 0.0, "u0": 0.0, "u_off": 0.0, "tau_m": 0.0, "c": 0.0, "tcu_f": 1.0, "bu_f": 1.0}
NEUTRAL.update({"pf_c1": 0.0, "pf_s1": 0.0, "enc_scale": 0.0})


@dataclass
class Plant:
    """One plant: base parameters (MODEL.md's names, SI units), its effects and its encoders."""

    params: dict = field(default_factory=lambda: dict(PARAMS))
    effects: dict = field(default_factory=dict)
    counts: int = 8000
    noise: float = 0.0

    def value(self, name: str) -> float:
        return float(self.effects.get(name, NEUTRAL.get(name, self.params.get(name, 0.0))))


class IndependentRig:
    """A batch of plants stepped together (module doc).

    Parameters
    ----------
    plants : list of Plant
        One per lane.
    seed : int, optional
        Seed of the encoder noise.
    """

    def __init__(self, plants: list[Plant], seed: int = 0) -> None:
        self.n = len(plants)
        col = lambda k: np.array([p.params[k] for p in plants], dtype=float)  # noqa: E731
        eff = lambda k: np.array([p.value(k) for p in plants], dtype=float)  # noqa: E731
        self.Ju, self.km, self.Jl, self.kth = col("Ju"), col("km"), col("Jl"), col("ktheta")
        self.Tcu, self.dTcu = col("Tcu") * eff("tcu_f"), col("dTcu") * eff("tcu_f")
        self.bu, self.dbu = col("bu") * eff("bu_f"), col("dbu") * eff("bu_f")
        self.Ts, self.Tc, self.ws, self.delta, self.bb = col("Ts"), col("Tc"), col("ws"), col("delta"), col("bb")
        self.delay, self.u0, self.u_off, self.tau = eff("delay"), eff("u0"), eff("u_off"), eff("tau_m")
        self.c, self.c1, self.s1, self.scale = eff("c"), eff("pf_c1"), eff("pf_s1"), eff("enc_scale")
        self.q = np.array([2 * math.pi / p.counts if p.counts else 0.0 for p in plants])
        self.noise = np.array([p.noise for p in plants])
        self.rng = np.random.default_rng(seed)
        self.lag_steps = np.rint(self.delay / H).astype(int)
        self.buf = np.zeros((int(self.lag_steps.max()) + 1, self.n))
        self.k = 0
        self.x = np.zeros((4, self.n))  # theta_u, theta_l, omega_u, omega_l
        self.vm = np.zeros(self.n)
        self.t = 0.0

    def _drive(self, u: np.ndarray) -> np.ndarray:
        v = np.sign(u) * np.maximum(np.abs(u) - self.u0, 0.0) + self.u_off
        return v

    def _friction(self, w: np.ndarray, d: np.ndarray, lower: bool, level: np.ndarray) -> np.ndarray:
        aw = np.abs(w)
        if lower:
            return level * d * (self.Tc + (self.Ts - self.Tc) * np.exp(-((aw / self.ws) ** self.delta)) + self.bb * aw)
        return d * (self.Tcu + self.dTcu * d + self.bu * d * w + self.dbu * w)

    def step(self, u: np.ndarray, duration: float) -> None:
        """Hold the commands u (V, (n,)) for ``duration`` s."""
        u = np.broadcast_to(np.asarray(u, dtype=float), (self.n,))
        m = self.buf.shape[0]
        idx = np.arange(self.n)
        a_lag = np.where(self.tau > 0, np.exp(-H / np.maximum(self.tau, 1e-12)), 0.0)
        for _ in range(int(round(duration / H))):
            self.buf[self.k % m] = u
            ud = np.where(self.k >= self.lag_steps, self.buf[(self.k - self.lag_steps) % m, idx], 0.0)
            self.k += 1
            v = self._drive(ud)
            self.vm = v + (self.vm - v) * a_lag
            tu, tl, wu, wl = self.x
            alpha, adot = tl - tu, wl - wu
            string = self.kth * alpha + self.c * adot
            level = 1.0 + self.c1 * np.cos(tl) + self.s1 * np.sin(tl)
            # upper disc
            ext_u = self.km * self.vm + string
            lo_u, hi_u = -self.Tcu + self.dTcu, self.Tcu + self.dTcu
            rest_u = wu == 0.0
            du = np.where(ext_u >= 0, 1.0, -1.0)
            stays_u = rest_u & (ext_u >= lo_u) & (ext_u <= hi_u)
            dir_u = np.where(rest_u, du, np.sign(wu))
            acc_u = np.where(stays_u, 0.0, (ext_u - self._friction(wu, dir_u, False, 1.0)) / self.Ju)
            # lower disc
            ext_l = -string
            lim = level * self.Ts
            rest_l = wl == 0.0
            dl = np.where(ext_l >= 0, 1.0, -1.0)
            stays_l = rest_l & (np.abs(ext_l) <= lim)
            dir_l = np.where(rest_l, dl, np.sign(wl))
            acc_l = np.where(stays_l, 0.0, (ext_l - self._friction(wl, dir_l, True, level)) / self.Jl)
            wu_new, wl_new = wu + H * acc_u, wl + H * acc_l
            # a slipping disc whose speed changes sign stops (Karnopp); at rest it leaves in its torque's direction
            wu_new = np.where(~rest_u & (wu_new * wu < 0), 0.0, wu_new)
            wl_new = np.where(~rest_l & (wl_new * wl < 0), 0.0, wl_new)
            self.x = np.stack([tu + H * wu_new, tl + H * wl_new, wu_new, wl_new])
            self.t += H

    def measure(self) -> dict[str, np.ndarray]:
        """What the encoders read (rad): the motor encoder's scale error, quantisation and noise."""
        out = {}
        for name, th in (("theta_u", self.x[0] * (1.0 + self.scale)), ("theta_l", self.x[1])):
            th = th + self.noise * self.rng.standard_normal(self.n)
            out[name] = np.where(self.q > 0, np.round(th / np.where(self.q > 0, self.q, 1.0)) * self.q, th)
        return out

    @property
    def omega_l(self) -> np.ndarray:
        return self.x[3]

    @property
    def omega_u(self) -> np.ndarray:
        return self.x[2]
