"""Environments built with effects: they run the composition's compiled model.

Each env with an effect behaves differently from the base env and matches the single-run
simulator with the same effect (``drillgym.simulate(..., dt=env dt)``) driven by the same voltages
to 1e-9 rad/s on omega_l, for the single and the vector env.  The sensor observations apply the
composition's Measurement effects (library and user effects); domain randomisation may name
effect parameters.
"""

from __future__ import annotations

import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import drillgym
from drillgym.effects import Measurement, Parameter
from drillgym.envs import make_vec

ROOT = Path(__file__).resolve().parents[1]
CUBIC = f"{ROOT / 'examples' / 'effects' / 'string_cubic.py'}:string_cubic"
STEPS = 500  # 5 s of 10 ms periods: the lower disc sticks and slips
TOL = 1e-9  # rad/s

CASES = {
    "input_delay": (["input_delay"], {"delay": 0.03}),
    "motor_lag": (["motor_lag"], {"tau_m": 0.05}),
    "string_cubic": ([CUBIC], {"c3": 0.01}),
}


def _voltages(seed: int, n: int = STEPS) -> np.ndarray:
    """Steps between 1 and 4.5 V every 0.2 s with some noise: stick-slip and its transients."""
    r = np.random.default_rng(seed)
    return np.clip(np.repeat(r.uniform(1.0, 4.5, n // 20 + 1), 20)[:n] + r.normal(0.0, 0.2, n), -5.0, 5.0)


def _env_run(effects, values, u: np.ndarray, seed: int = 0) -> tuple[np.ndarray, float, float]:
    """omega_l after each period, the initial winding alpha0 (rad) and the env's dt (s)."""
    env = gym.make("drillgym/Torsional-v0", normalize_action=False, effects=effects, effect_params=values)
    env.reset(seed=seed)
    system = env.unwrapped.batch.system
    alpha0 = float(system.alpha[0])
    w = np.array([env.step(np.array([v], dtype=np.float32))[4]["omega_l"] for v in u])
    return w, alpha0, env.unwrapped.options.dt


def _reference(effects, values, u: np.ndarray, alpha0: float, dt: float) -> np.ndarray:
    traj = drillgym.simulate(
        "torsional", u=u, duration=len(u) * dt, dt=dt, alpha0=alpha0, effects=effects, effect_params=values
    )
    return traj.omega_l[1:]


@pytest.mark.parametrize("name", list(CASES))
def test_single_env_matches_the_simulator_and_differs_from_the_base(name: str) -> None:
    effects, values = CASES[name]
    u = _voltages(1)
    u32 = u.astype(np.float32).astype(np.float64)  # the env's action dtype
    w, alpha0, dt = _env_run(effects, values, u32)
    ref = _reference(effects, values, u32, alpha0, dt)
    assert np.abs(w - ref).max() <= TOL, f"{name}: env vs simulate differ by {np.abs(w - ref).max():.3g} rad/s"
    base, alpha0_b, _ = _env_run(None, None, u32)
    assert alpha0_b == alpha0  # same seed, same episode draws
    assert np.abs(w - base).max() > 0.02, f"{name}: the effect changed nothing"  # >> TOL
    assert np.ptp(w) > 1.0  # the disc turned and stopped: stick-slip transients were compared


@pytest.mark.parametrize("name", list(CASES))
def test_vector_env_rows_match_the_simulator(name: str) -> None:
    effects, values = CASES[name]
    n = 3
    venv = make_vec("drillgym/Torsional-v0", n, normalize_action=False, effects=effects, effect_params=values)
    venv.reset(seed=7)
    system = venv.batch.system
    alpha0 = system.alpha.copy()
    U = np.stack([_voltages(10 + i) for i in range(n)], axis=1).astype(np.float32)
    W = np.array([venv.step(U[k])[4]["omega_l"] for k in range(STEPS)])
    dt = venv.options.dt
    for i in range(n):
        ref = _reference(effects, values, U[:, i].astype(np.float64), float(alpha0[i]), dt)
        assert np.abs(W[:, i] - ref).max() <= TOL, f"{name}, rig {i}: {np.abs(W[:, i] - ref).max():.3g} rad/s"


def test_env_options_reject_unknown_effects_and_parameters() -> None:
    with pytest.raises(Exception, match="no_such_effect"):
        gym.make("drillgym/Torsional-v0", effects=["no_such_effect"])
    with pytest.raises(ValueError, match="tau_m"):
        gym.make(
            "drillgym/Torsional-v0", normalize_action=False, effects=["input_delay"], effect_params={"tau_m": 0.02}
        )
    with pytest.raises(ValueError, match="delay"):
        gym.make(
            "drillgym/Torsional-v0", normalize_action=False, effects=["input_delay"], effect_params={"delay": 2.0}
        )  # above 0.5 s


def test_randomisation_may_name_effect_parameters() -> None:
    n = 4
    venv = make_vec(
        "drillgym/Torsional-v0",
        n,
        normalize_action=False,
        effects=["input_delay"],
        effect_params={"delay": 0.05},
        randomize=0.5,
        randomize_names=("delay", "Ts"),
    )
    venv.reset(seed=3)
    comp = venv.batch.system.composition
    P = venv.batch.system.params_matrix.copy()
    d = P[:, comp.param_index("delay")]
    assert np.all((d >= 0.025) & (d <= 0.075)) and np.ptp(d) > 1e-3  # drawn per rig within +/- 50 %
    assert d.max() > 0.05  # a delay longer than the nominal one: the delay lines had to grow
    assert np.ptp(P[:, comp.param_index("Ts")]) > 0
    # every rig runs its own drawn parameters: each against the simulator with its parameter row
    u = _voltages(4, 120).astype(np.float32)
    alpha0 = venv.batch.system.alpha.copy()
    W = np.array([venv.step(np.full(n, v, dtype=np.float32))[4]["omega_l"] for v in u])
    for i in range(n):
        traj = drillgym.simulate(
            "torsional",
            u=u.astype(np.float64),
            duration=len(u) * venv.options.dt,
            dt=venv.options.dt,
            alpha0=float(alpha0[i]),
            params=P[i],
            effects=comp,
        )
        assert np.abs(W[:, i] - traj.omega_l[1:]).max() <= TOL, f"rig {i} (delay {d[i]:.4f} s)"
    with pytest.raises(ValueError, match="tau_m"):
        make_vec(
            "drillgym/Torsional-v0",
            2,
            normalize_action=False,
            effects=["input_delay"],
            randomize=0.1,
            randomize_names=("tau_m",),
        )


def test_randomised_effect_parameters_stay_within_their_bounds() -> None:
    venv = make_vec(
        "drillgym/Torsional-v0",
        16,
        normalize_action=False,
        effects=["input_delay"],
        effect_params={"delay": 0.4},
        randomize=0.9,
        randomize_names=("delay",),
    )
    venv.reset(seed=0)
    comp = venv.batch.system.composition
    d = venv.batch.system.params_matrix[:, comp.param_index("delay")]
    assert d.max() == 0.5 and d.min() >= 0.04  # clipped at the parameter's 0.5 s bound


# --------------------------------------------------------------------- measurement effects
class EncoderGain(Measurement):
    """A user measurement effect: both encoders read ``enc_gain`` times the true angle."""

    name = "encoder_gain_test"
    channels = ("theta_u", "theta_l")
    parameters = (Parameter("enc_gain", "-", 0.5, 2.0, 1.0, 0.01, "encoder scale factor"),)
    explanation = "A mis-set encoder resolution scales the measured angles."
    signature = "angle residuals proportional to the angles."

    def measure(theta_u, theta_l, enc_gain):
        return enc_gain * theta_u, enc_gain * theta_l


def _sensors_episode(env_id: str, mode: str, steps: int = 120, **kw):
    env = gym.make(env_id, normalize_action=False, observation=mode, **kw)
    obs, _ = env.reset(seed=2)
    system = env.unwrapped.batch.system
    Y, observations = [system.Y[0].copy()], [obs]
    for k in range(steps):
        obs, *_ = env.step(np.array([3.5 if k < 60 else 4.8], dtype=np.float32))
        Y.append(system.Y[0].copy())
        observations.append(obs)
    return env, np.array(Y), np.array(observations)


def test_sensors_observation_applies_library_measurement_effects() -> None:
    x0, y0, skew = 1e-3, -5e-4, 0.1
    kw = dict(
        lvdt_noise_std=0.0,
        effects=["lvdt_offset", "lvdt_skew"],
        effect_params={"lvdt_x0": x0, "lvdt_y0": y0, "lvdt_skew": skew},
    )
    env, Y, obs = _sensors_episode("drillgym/Coupled-v0", "sensors", **kw)
    _, Yb, obs_b = _sensors_episode("drillgym/Coupled-v0", "sensors", lvdt_noise_std=0.0)
    np.testing.assert_allclose(Y, Yb, rtol=0, atol=1e-12)  # measurement effects never touch the dynamics
    c, s = np.cos(Y[:, 0]), np.sin(Y[:, 0])
    X, Yf = Y[:, 4] * c - Y[:, 5] * s, Y[:, 4] * s + Y[:, 5] * c
    assert np.abs(X).max() > 1e-5  # the disc moved laterally: skew has something to act on
    xm, ym = X + x0, (Yf + y0) * math.cos(skew) + (X + x0) * math.sin(skew)  # offset, then skew (their order)
    names = env.unwrapped.observation_names
    ix, iy = names.index("X_meas"), names.index("Y_meas")
    np.testing.assert_allclose(obs[:, ix], np.float32(1e3 * xm), rtol=0, atol=1e-6)  # mm
    np.testing.assert_allclose(obs[:, iy], np.float32(1e3 * ym), rtol=0, atol=1e-6)
    np.testing.assert_allclose(obs_b[:, ix], np.float32(1e3 * X), rtol=0, atol=1e-6)
    assert np.abs(ym - (Yf + y0)).max() > 1e-6  # the skew's share (m) is well above the tolerance
    np.testing.assert_array_equal(obs[:, :ix], obs_b[:, :ix])  # encoders untouched by LVDT effects


@pytest.mark.parametrize("mode", ["sensors", "motor"])
def test_observations_apply_a_user_measurement_effect(mode: str) -> None:
    gain = 1.25
    env, Y, obs = _sensors_episode(
        "drillgym/Torsional-v0", mode, effects=[EncoderGain], effect_params={"enc_gain": gain}
    )
    _, Yb, obs_b = _sensors_episode("drillgym/Torsional-v0", mode)
    np.testing.assert_allclose(Y, Yb, rtol=0, atol=1e-12)
    o = env.unwrapped.options
    q = drillgym.measurement.quantize_angle(gain * Y[:, 0], o.counts_per_rev)
    if mode == "sensors":
        np.testing.assert_allclose(obs[:, 0], np.float32(np.mod(q + np.pi, 2 * np.pi) - np.pi), atol=1e-6)
        ql = drillgym.measurement.quantize_angle(gain * Y[:, 1], o.counts_per_rev)
        np.testing.assert_allclose(obs[:, 2], np.float32(ql - q), atol=1e-5)
    else:
        inc = np.diff(q) / o.control_dt
        np.testing.assert_allclose(obs[1:, 0], np.float32(inc), rtol=1e-6, atol=1e-4)
    assert np.abs(obs - obs_b).max() > 0.1  # the effect is visible


@pytest.mark.parametrize("make", ["single", "vector"])
def test_an_effect_that_does_not_act_in_the_configuration_is_refused(make: str) -> None:
    from drillgym.errors import InputError

    with pytest.raises(InputError, match="lateral_anisotropy: the effect does not act in the torsional configuration"):
        if make == "single":
            gym.make("drillgym/Torsional-v0", effects=["lateral_anisotropy"])
        else:
            make_vec("drillgym/Torsional-v0", 2, effects=["lateral_anisotropy"])
    env = gym.make("drillgym/Coupled-v0", effects=["lateral_anisotropy"])  # it acts there
    assert "lateral_anisotropy" in env.unwrapped.options.effects.names


def test_a_models_effect_that_does_not_act_is_left_out_with_a_warning():
    """The env's model= is the whole rig's: an effect of it that does not act in the env's configuration is left
    out, with a warning naming it (an effect named by hand is refused, above)."""
    model = drillgym.Model(effects=("motor_lag", "lateral_anisotropy"), values={"tau_m": 0.03})
    with pytest.warns(UserWarning, match="effect lateral_anisotropy does not act in the torsional configuration"):
        env = gym.make("drillgym/Torsional-v0", model=model)
    assert env.unwrapped.options.effects.names == ("motor_lag",)


def test_a_models_encoders_set_the_envs_resolution(tmp_path):
    """An env on a model that carries its encoders reads through them (the counts the recording showed), from the
    model or its file; counts_per_rev given beside it wins, and a model without a count keeps the default."""
    coarse = drillgym.Model(encoders=drillgym.Encoders(counts_per_rev=2048, angle_noise=0.0))
    path = coarse.save(tmp_path / "model.json")
    for given in (coarse, path):
        env = gym.make("drillgym/Torsional-v0", model=given, observation="sensors")
        assert env.unwrapped.options.counts_per_rev == 2048
        env.reset(seed=0)
        sensors = env.unwrapped.batch.obs_model.sensors
        state = np.zeros((1, 8))  # the base state (no effect states)
        state[0, :2] = 0.1234, -0.4321
        theta_u, theta_l = (float(a[0]) for a in sensors.encoders(state))
        step = 2 * math.pi / 2048
        assert theta_u == math.floor(0.1234 / step) * step and theta_l == math.floor(-0.4321 / step) * step
    assert gym.make("drillgym/Torsional-v0", model=coarse, counts_per_rev=0).unwrapped.options.counts_per_rev == 0
    plain = drillgym.Model(encoders=drillgym.Encoders(counts_per_rev=None, angle_noise=2e-4))
    default = gym.make("drillgym/Torsional-v0").unwrapped.options.counts_per_rev
    assert gym.make("drillgym/Torsional-v0", model=plain).unwrapped.options.counts_per_rev == default == 8000
