"""An independent rig for the diagnosis benchmarks: docs/model.md written again, by hand, for scipy.

Not drillgym's simulator: the equations of motion of docs/model.md (torsional: the report's
(3.19)-(3.20); coupled: the four Lagrange equations with the mass matrix solved at every call),
friction signs smoothed (tanh(ω / eps), eps = 2 mrad/s: creep in the stick phases instead of
drillgym's exact stick), integrated by scipy's ``solve_ivp`` (LSODA, rtol 1e-7), the input
interpolated linearly between its samples; then a measurement chain of its own (Gaussian angle
noise of 0.1 mrad, encoder quantisation 8000 counts/rev, LVDT noise 3 µm and the 5 Hz zero-phase
low-pass).  Every effect is coded here from its physical description (the library's effects and
effects outside the library), not imported from drillgym.

    rig_recording(config, signal, duration, rate_hz, seed, effects={name: {param: value}},
                  scale={base parameter: factor}, offset=..., amplitude=...) -> TimeSeries
"""

from __future__ import annotations

import math
import os

import numpy as np
from scipy.integrate import solve_ivp

from drillgym import RigParams
from drillgym.io import TimeSeries
from drillgym.measurement import lowpass_zero_phase, quantize_angle
from drillgym.signals import quasi_random, sum_of_sines

EPS = 2e-3  # rad/s: friction sign smoothing (DRILLGYM_BENCH_RIG_EPS overrides it, see rig_eps)
LAT_EPS = 1e-4  # m/s: lateral dry-friction direction smoothing


#: the command between samples: held (zero-order, as an amplifier holds a DAC's output) when
#: DRILLGYM_BENCH_RIG_HOLD=1, else interpolated linearly (the default the documented figures were measured with)
HOLD = os.environ.get("DRILLGYM_BENCH_RIG_HOLD", "0") == "1"


def rig_eps() -> float:
    """The friction smoothing in use (rad/s): DRILLGYM_BENCH_RIG_EPS if set, else EPS."""
    return float(os.environ.get("DRILLGYM_BENCH_RIG_EPS") or EPS)


#: effects outside drillgym's library (for the "discovery" rows)
OUTSIDE = ("brake_quadratic", "stribeck_shape", "upper_stribeck", "string_cubic", "string_freeplay")
#: lateral effects outside drillgym's library (coupled only): a stiffening spring −k3 r² (X, Y) (N/m³) and a
#: quadratic damping −c2 |V| V (N s²/m²), both in the fixed frame; ``brake_contact``: a brake pad that touches the
#: lower disc's rim at a fixed point of the fixed (LVDT) frame, at the angle phi: its normal force N (N) pushes the
#: disc's centre away from the pad, −N (cos φ, sin φ), and its friction, the lower disc's friction torque T_fl over
#: the pad's radius R_pad (m), pushes it along the tangent against the rim's motion, (T_fl / R_pad) (sin φ, −cos φ)
#: (a constant force shifts the disc as an LVDT offset would; only its coupling to the rotation and the friction
#: part that follows T_fl tell them apart)
OUTSIDE_LATERAL = ("lateral_cubic", "lateral_quadratic_damping", "brake_contact")
#: sensors that read off the truth, before their noise and quantisation: an LVDT whose gain is off reads (1 + k) X
#: (lvdt_kx) and (1 + k) Y (lvdt_ky); an encoder whose counts per revolution are off by the factor 1 + k reads
#: (1 + k) θ (the motor's: enc_scale, the lower's: enc_scale_l); the lower encoder's zero off the motor's by c
#: reads θl + c (enc_off_l: the string's twist at rest is read as c)
OUTSIDE_READING = ("lvdt_scale", "motor_encoder_scale", "lower_encoder_scale", "lower_encoder_offset")
#: the encoders' reading kinds and their parameters
ENCODER_READINGS = {
    "motor_encoder_scale": "enc_scale",
    "lower_encoder_scale": "enc_scale_l",
    "lower_encoder_offset": "enc_off_l",
}


def encoder_readings(tu: np.ndarray, tl: np.ndarray, effects: dict) -> tuple[np.ndarray, np.ndarray]:
    """What the encoders read of the true angles (rad), before their noise and quantisation
    (:data:`OUTSIDE_READING`)."""
    if "motor_encoder_scale" in effects:
        tu = tu * (1.0 + effects["motor_encoder_scale"]["enc_scale"])
    if "lower_encoder_scale" in effects:
        tl = tl * (1.0 + effects["lower_encoder_scale"]["enc_scale_l"])
    if "lower_encoder_offset" in effects:
        tl = tl + effects["lower_encoder_offset"]["enc_off_l"]
    return tu, tl


def input_signal(
    kind: str, duration: float, rate_hz: float, seed: int, offset: float, amplitude: float
) -> tuple[np.ndarray, np.ndarray]:
    """(t, u): 'quasi_random', 'sum_of_sines', 'steps' (levels held 1.5-5 s), 'ramps' (up/down
    ramps between random levels, 3-8 s each) within offset ± amplitude, clipped to ±5 V."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(round(duration * rate_hz)) + 1) / rate_hz
    if kind in ("quasi_random", "sum_of_sines"):  # the generator's shape in ±1 V, moved and scaled here
        gen = quasi_random if kind == "quasi_random" else sum_of_sines
        t, u = gen(duration, rate_hz=rate_hz, seed=seed, amplitude=1.0, offset=0.0)
        u = offset + amplitude * u
    elif kind == "steps":
        u = np.empty_like(t)
        i = 0
        while i < t.size:
            k = max(1, int(rng.uniform(1.5, 5.0) * rate_hz))
            u[i : i + k] = offset + amplitude * rng.uniform(-1.0, 1.0)
            i += k
    elif kind == "ramps":
        knots_t, knots_u, tt = [0.0], [offset], 0.0
        while tt < duration:
            tt += rng.uniform(3.0, 8.0)
            knots_t.append(tt)
            knots_u.append(offset + amplitude * rng.uniform(-1.0, 1.0))
        u = np.interp(t, knots_t, knots_u)
    else:
        raise ValueError(f"unknown signal {kind!r}")
    return t, np.clip(u, -5.0, 5.0)


class _Rig:
    def __init__(
        self, config: str, p: RigParams, effects: dict[str, dict[str, float]], t: np.ndarray, u: np.ndarray
    ) -> None:
        self.config, self.p, self.fx, self.t, self.u = config, p, effects, t, u
        self.eps = rig_eps()

    def drive(self, tt: float, um: float | None) -> float:
        fx = self.fx
        if "input_delay" in fx:
            tt = tt - fx["input_delay"]["delay"]
        if HOLD and tt >= 0:  # the amplifier holds each sample until the next (DRILLGYM_BENCH_RIG_HOLD=1)
            v = float(self.u[min(int(np.searchsorted(self.t, tt, side="right")) - 1, self.u.size - 1)])
        else:
            v = float(np.interp(tt, self.t, self.u)) if tt >= 0 else float(self.u[0])
        return um if um is not None else v

    def motor_voltage(self, v: float) -> float:
        """The voltage the motor turns into torque, from the voltage v reaching it (V): v itself here."""
        return v

    def cogging(self, tu: float) -> float:
        """An extra torque on the upper disc at its angle tu (N m): none here."""
        return 0.0

    def upper_friction(self, w: float) -> float:
        p, s = self.p, math.tanh(w / self.eps)
        T = (p.Tcu * s + p.dTcu * abs(s)) + p.bu * w + p.dbu * abs(w)
        if "upper_stribeck" in self.fx:  # a static bump at low speed (outside the library)
            f = self.fx["upper_stribeck"]
            T += f["Tsu"] * math.exp(-((w / f["wsu"]) ** 2)) * s
        return T

    def lower_friction(self, tt: float, w: float, th: float) -> float:
        p, fx, s = self.p, self.fx, math.tanh(w / self.eps)
        Ts, Tc = p.Ts, p.Tc
        if "brake_asymmetry" in fx and w < 0:
            Ts, Tc = Ts * (1 + fx["brake_asymmetry"]["asym_s"]), Tc * (1 + fx["brake_asymmetry"]["asym_c"])
        x = abs(w / p.ws)
        shape = 1.0 / (1.0 + x * x) if "stribeck_shape" in fx else math.exp(-(x**p.delta))
        T = (Tc + (Ts - Tc) * shape) * s + p.bb * w
        if "brake_quadratic" in fx:  # an oil-drag term ω|ω| (outside the library)
            T += fx["brake_quadratic"]["cq"] * w * abs(w)
        level = 1.0
        if "position_friction" in fx:
            f = fx["position_friction"]
            level += (
                f.get("pf_c1", 0) * math.cos(th)
                + f.get("pf_s1", 0) * math.sin(th)
                + f.get("pf_c2", 0) * math.cos(2 * th)
                + f.get("pf_s2", 0) * math.sin(2 * th)
            )
        if "friction_drift" in fx:
            level *= 1.0 + fx["friction_drift"]["drift"] * tt
        return level * T

    def string_torque(self, a: float, ad: float) -> float:
        p, fx = self.p, self.fx
        el = a
        if "string_freeplay" in fx:
            g = fx["string_freeplay"]["gap"]
            el = a - g if a > g else (a + g if a < -g else 0.0)
        T = p.ktheta * el
        if "string_cubic" in fx:
            T += p.ktheta * fx["string_cubic"]["c3"] * a**3
        if "string_damping" in fx:
            T += fx["string_damping"]["dtheta"] * ad
        return T

    def rhs_torsional(self, tt: float, s: np.ndarray) -> list[float]:
        p = self.p
        tu, tl, wu, wl = s[:4]
        um = s[4] if "motor_lag" in self.fx else None
        v = self.drive(tt, um)
        S = self.string_torque(tl - tu, wl - wu)
        out = [wu, wl, (p.km * v - self.upper_friction(wu) + S) / p.Ju, (-self.lower_friction(tt, wl, tl) - S) / p.Jl]
        if um is not None:
            out.append((self.drive(tt, None) - um) / self.fx["motor_lag"]["tau_m"])
        return out

    def rhs_coupled(self, tt: float, s: np.ndarray) -> list[float]:
        p, fx = self.p, self.fx
        x, y, a, tu, xd, yd, ad, W = s[:8]
        um = s[8] if "motor_lag" in fx else None
        v = self.motor_voltage(self.drive(tt, um))
        m, mr, e = p.mr + p.mt, p.mr, p.e
        c, sn = math.cos(a), math.sin(a)
        wl = W + ad
        tl = a + tu
        Tfl = self.lower_friction(tt, wl, tl)
        Tfu = self.upper_friction(W) - self.cogging(tu)
        S = self.string_torque(a, ad)
        cu, su = math.cos(tu), math.sin(tu)
        # extra lateral forces, fixed frame -> rotating frame and the θu generalised force
        X, Y = x * cu - y * su, x * su + y * cu
        VX = (xd - W * y) * cu - (yd + W * x) * su
        VY = (xd - W * y) * su + (yd + W * x) * cu
        FX = FY = 0.0
        if "lateral_anisotropy" in fx:
            f = fx["lateral_anisotropy"]
            FX += -f["dk"] * X - f["db"] * VX
            FY += f["dk"] * Y + f["db"] * VY
        if "lateral_coulomb" in fx:
            vv = math.sqrt(VX * VX + VY * VY + LAT_EPS * LAT_EPS)
            FX += -fx["lateral_coulomb"]["Fc_lat"] * VX / vv
            FY += -fx["lateral_coulomb"]["Fc_lat"] * VY / vv
        if "lateral_cubic" in fx:  # a spring that stiffens with the radius (outside the library)
            k3 = fx["lateral_cubic"]["k3"] * (X * X + Y * Y)
            FX, FY = FX - k3 * X, FY - k3 * Y
        if "lateral_quadratic_damping" in fx:  # a drag that grows with the speed squared (outside the library)
            c2 = fx["lateral_quadratic_damping"]["c2"] * math.sqrt(VX * VX + VY * VY)
            FX, FY = FX - c2 * VX, FY - c2 * VY
        if "brake_contact" in fx:  # the brake pad's normal force and friction on the rim, fixed frame (outside)
            f = fx["brake_contact"]
            cp, sp, tang = math.cos(f["phi"]), math.sin(f["phi"]), Tfl / f["R_pad"]
            FX, FY = FX - f["N"] * cp + tang * sp, FY - f["N"] * sp - tang * cp
        Fx, Fy = FX * cu + FY * su, -FX * su + FY * cu
        M = np.array(
            [
                [m, 0.0, -e * mr * sn, -(e * mr * sn + m * y)],
                [0.0, m, e * mr * c, e * mr * c + m * x],
                [-e * mr * sn, e * mr * c, p.Jl, p.Jl + e * mr * (x * c + y * sn)],
                [
                    -(e * mr * sn + m * y),
                    e * mr * c + m * x,
                    p.Jl + e * mr * (x * c + y * sn),
                    p.Ju + p.Jl + 2 * e * mr * (x * c + y * sn) + m * (x * x + y * y),
                ],
            ]
        )
        f = np.array(
            [
                -(p.b * (xd - y * W) + p.k * x - m * x * W * W - 2 * m * W * yd - e * mr * c * (ad + W) ** 2) + Fx,
                -(p.b * (yd + x * W) + p.k * y - m * y * W * W + 2 * m * W * xd - e * mr * sn * (ad + W) ** 2) + Fy,
                -(2 * e * mr * W * (c * xd + sn * yd) + e * mr * W * W * (x * sn - y * c) + S + Tfl),
                -(
                    p.b * ((x * x + y * y) * W + x * yd - y * xd)
                    - e * mr * (x * sn - y * c) * (ad * ad + 2 * ad * W)
                    + 2 * e * mr * W * (c * xd + sn * yd)
                    + 2 * m * W * (x * xd + y * yd)
                    + Tfu
                    + Tfl
                )
                + p.km * v
                - y * Fx
                + x * Fy,
            ]
        )
        acc = np.linalg.solve(M, f)
        out = [xd, yd, ad, W, acc[0], acc[1], acc[2], acc[3]]
        if um is not None:
            out.append((self.drive(tt, None) - um) / fx["motor_lag"]["tau_m"])
        return out


def rig_recording(
    config: str,
    signal: str = "quasi_random",
    duration: float = 30.0,
    rate_hz: float = 500.0,
    seed: int = 0,
    effects: dict[str, dict[str, float]] | None = None,
    scale: dict[str, float] | None = None,
    offset: float = 1.0,
    amplitude: float = 3.0,
    alpha0: float = 0.0,
    rig_class: type[_Rig] = _Rig,
) -> TimeSeries:
    """A recording of the independent rig (see the module docstring).  ``config``: 'torsional' or
    'coupled'; ``effects``: {effect name: its parameters} (library names, :data:`OUTSIDE`, :data:`OUTSIDE_LATERAL` and
    :data:`OUTSIDE_READING`);
    ``scale``: factors on base parameters (the rig's base parameters differ from the identified set);
    ``rig_class``: the rig's equations (a subclass adds effects of its own)."""
    effects = dict(effects or {})
    p = RigParams().scaled(**scale) if scale else RigParams()
    t, u = input_signal(signal, duration, rate_hz, seed, offset, amplitude)
    rig = rig_class(config, p, effects, t, u)
    lag = "motor_lag" in effects
    if config == "torsional":
        y0 = [0.0, alpha0, 0.0, 0.0] + ([u[0]] if lag else [])
        fun = rig.rhs_torsional
    elif config == "coupled":
        y0 = [0.0, 0.0, alpha0, 0.0, 0.0, 0.0, 0.0, 0.0] + ([u[0]] if lag else [])
        fun = rig.rhs_coupled
    else:
        raise ValueError(f"the independent rig simulates 'torsional' and 'coupled', not {config!r}")
    sol = solve_ivp(fun, (0.0, duration), y0, method="LSODA", t_eval=t, rtol=1e-7, atol=1e-9, max_step=0.01)
    if not sol.success:
        raise RuntimeError(f"independent rig: {sol.message}")
    rng = np.random.default_rng(seed + 7)
    if config == "torsional":
        tu, tl = sol.y[0], sol.y[1]
    else:
        tu, tl = sol.y[3], sol.y[2] + sol.y[3]
    read_u, read_l = encoder_readings(tu, tl, effects)
    cols = {
        "t": t,
        "u": u,
        "theta_u": quantize_angle(read_u + rng.normal(0, 1e-4, t.size)),
        "theta_l": quantize_angle(read_l + rng.normal(0, 1e-4, t.size)),
    }
    if config == "coupled":
        x, y = sol.y[0], sol.y[1]
        X, Y = x * np.cos(tu) - y * np.sin(tu), x * np.sin(tu) + y * np.cos(tu)
        if "lvdt_offset" in effects:
            X, Y = X + effects["lvdt_offset"]["lvdt_x0"], Y + effects["lvdt_offset"]["lvdt_y0"]
        if "lvdt_skew" in effects:
            sk = effects["lvdt_skew"]["lvdt_skew"]
            Y = Y * math.cos(sk) + X * math.sin(sk)
        if "lvdt_scale" in effects:  # an LVDT whose gain is off (outside the library's readings)
            X = X * (1.0 + effects["lvdt_scale"].get("lvdt_kx", 0.0))
            Y = Y * (1.0 + effects["lvdt_scale"].get("lvdt_ky", 0.0))
        cols["x"] = lowpass_zero_phase(X + rng.normal(0, 3e-6, t.size), rate_hz, 5.0)
        cols["y"] = lowpass_zero_phase(Y + rng.normal(0, 3e-6, t.size), rate_hz, 5.0)
    meta = {
        "configuration": config,
        "source": "emulator",
        "sample_rate_hz": rate_hz,
        "description": f"independent scipy rig, {signal}, effects {sorted(effects)}",
    }
    return TimeSeries(cols, meta, "<independent rig>")
