"""Controllers on any model the diagnosis gives: the composition's right-hand side, linearised, in the controllers."""

import numpy as np
import pytest

import controllers
from drillgym import Model, RigParams, simulate
from drillgym.errors import InputError

DT = 0.002
SCALE_FILE = '''
from drillgym.effects import Measurement, Parameter


class EncoderScale(Measurement):
    """The motor encoder reads (1 + scale) theta_u."""

    name = "encoder_scale"
    channels = ("theta_u",)
    parameters = (Parameter("enc_scale", "-", -0.05, 0.05, 0.0, 1e-3, "relative scale error", neutral=0.0),)

    def measure(theta_u, enc_scale):
        return theta_u * (1.0 + enc_scale)
'''

#: one model per kind: (effects, values); library effects and user files
KINDS = {
    "force (library)": (("string_damping",), {"dtheta": 0.02}),
    "force (user file)": (("examples/effects/string_cubic.py:string_cubic",), {"c3": 0.1}),
    "upper friction (user file)": (("examples/effects/upper_stiction.py:upper_stiction",), {"ds_u": 0.2, "vs_u": 3}),
    "lower friction (library)": (("position_friction",), {"pf_c1": 0.15, "pf_s1": 0.1}),
    "input without a state (user file)": (("examples/effects/motor_dead_zone.py:dead_zone",), {"u0": 0.6}),
    "input with a state (library)": (("motor_lag",), {"tau_m": 0.04}),
    "delay (library)": (("input_delay",), {"delay": 0.015}),
    "delay (user file)": (
        ("examples/effects/sampled_command.py:sampled_command",),
        {"t_comp": 0.003, "t_sample": 0.01},
    ),
}


def _prediction_error(model: Model, built_on: Model, horizon: float = 0.1) -> float:
    """Largest speed error (rad/s) of the observer's own prediction (built on ``built_on``) against the
    composition's simulation of ``model``, open loop over ``horizon`` s from a slipping state, the command
    stepping from 3 to 4.5 V there."""
    kw = dict(duration=2.0 + horizon, dt=1e-3, effects=model.composition, effect_params=dict(model.values))
    tr = simulate("torsional", u=3.0, **kw)
    alpha = tr.theta_l - tr.theta_u
    window = np.arange(1000, 2000)
    slip = window[(np.abs(tr.omega_l[window]) > 0.5) & (np.abs(tr.omega_u[window]) > 0.5)]
    k0 = int(slip[np.argmax(np.abs(alpha[slip]))])  # the largest twist while both discs slip
    u = np.where(np.arange(int(round(kw["duration"] / 1e-3))) < k0, 3.0, 4.5)
    tr = simulate("torsional", u=u, **kw)
    dm = controllers.make("observer", omega_ref=3.0, model=built_on).model
    x = np.zeros((dm.Ad.shape[0], 1))
    x[0], x[1], x[2], x[3] = tr.theta_u[k0], tr.omega_u[k0], tr.theta_l[k0] - tr.theta_u[k0], tr.omega_l[k0]
    for j, name in enumerate(built_on.composition.state_names):
        x[dm.dynamics.e0 + j] = getattr(tr, name)[k0]
    if dm.line_index >= 0:
        x[dm.line_index :] = 3.0  # the commands before
    err = 0.0
    for i in range(int(round(horizon / DT))):
        x = dm.predict_mean(x, np.array([4.5]))
        k = k0 + (i + 1) * int(round(DT / 1e-3))
        err = max(err, abs(x[3, 0] - tr.omega_l[k]), abs(x[1, 0] - tr.omega_u[k]))
    return err


@pytest.mark.parametrize("kind", list(KINDS))
def test_the_observers_prediction_is_the_compositions_simulation(kind):
    """Built on a model with the effect, the observer predicts the composition's run to a few mrad/s over 0.1 s
    (50 periods, open loop, from a slipping state); built on the base model it does not."""
    specs, values = KINDS[kind]
    model = Model(RigParams(), specs, values)
    own = _prediction_error(model, model)
    base = _prediction_error(model, Model(RigParams()))
    assert own < 0.01, (kind, own, base)
    assert base > 3 * own, (kind, own, base)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["observer", "lqg", "lqg-2enc"])
def test_every_kind_runs_in_every_model_based_controller(name, tmp_path):
    from controllers.evaluation.runner import run_closed_loop

    (tmp_path / "scale.py").write_text(SCALE_FILE)
    specs = sum((list(s) for s, _ in KINDS.values()), []) + [f"{tmp_path / 'scale.py'}:encoder_scale"]
    values = {k: v for _, vals in KINDS.values() for k, v in vals.items()} | {"enc_scale": 0.01}
    model = Model(RigParams(), tuple(specs), values)
    ctrl = controllers.make(name, omega_ref=np.array([3.0, 4.0]), model=model)
    run = run_closed_loop(
        ctrl, "torsional", np.array([3.0, 4.0]), 1.0, effects=model.composition, effect_params=dict(model.values)
    )
    assert np.all(np.isfinite(run.u)) and np.all(np.abs(run.u) <= 5.0)


def test_a_measurement_on_a_read_channel_enters_the_output_map(tmp_path):
    (tmp_path / "scale.py").write_text(SCALE_FILE)
    model = Model(RigParams(), (f"{tmp_path / 'scale.py'}:encoder_scale",), {"enc_scale": 0.02})
    obs = controllers.make("observer", omega_ref=3.0, model=model).model
    assert obs.H[0, 0] == pytest.approx(1.02, rel=1e-6)
    x = np.zeros((obs.Ad.shape[0], 1))
    x[0] = 10.0
    assert obs.reading(x)[0] == pytest.approx(10.2)
    two = controllers.make("lqg-2enc", omega_ref=3.0, model=model)
    two.reset({"theta_u": np.zeros(1), "theta_l": np.zeros(1)})
    assert two._C[0, 0, 0] == pytest.approx(1.02, rel=1e-6)  # the motor encoder's row
    assert two._C[0, 1, 0] == pytest.approx(1.0, rel=1e-6) and two._C[0, 1, 2] == pytest.approx(1.0, rel=1e-6)


def test_a_dead_zone_is_compensated_in_the_command():
    model = Model(RigParams(), ("examples/effects/motor_dead_zone.py:dead_zone",), {"u0": 0.5})
    obs = controllers.make("observer", omega_ref=3.0, model=model)
    assert obs.model.compensates
    x = np.zeros((obs.model.Ad.shape[0], 3))
    from controllers.kalman import compensate

    np.testing.assert_allclose(compensate(obs.model, x, np.array([1.0, 0.0, -2.0]), 5.0), [1.5, 0.0, -2.5], atol=1e-9)
    base = controllers.make("observer", omega_ref=3.0).model
    assert not base.compensates


def test_what_cannot_be_represented_is_refused_in_one_line(tmp_path):
    (tmp_path / "second.py").write_text(
        "from drillgym.effects import Input, Parameter, State\n\n\n"
        "class Integrator(Input):\n"
        "    name = 'integrating_drive'\n"
        "    parameters = (Parameter('k_i', '1/s', 0.0, 10.0, 1.0, 1.0, 'gain'),)\n"
        "    states = (State('u_i', 'V'),)\n\n"
        "    def derivative(u, u_i, k_i):\n"
        "        return k_i * (u - u_i)\n\n"
        "    def voltage(u, u_i):\n"
        "        return u_i\n"
    )
    with pytest.raises(InputError) as err:
        controllers.make(
            "lqg-2enc", omega_ref=3.0, model=Model(RigParams(), (f"{tmp_path / 'second.py'}:integrating_drive",), {})
        )
    msg = str(err.value)
    assert "'integrating_drive'" in msg and "a state other than a first-order lag" in msg and "\n" not in msg


@pytest.mark.parametrize("name", ["observer", "lqg", "lqg-2enc"])
def test_a_coupled_model_s_lateral_effects_are_left_out_as_the_lateral_motion_is(name):
    """The controllers' model has no lateral motion: an identified coupled model's lateral effects (a force on the
    disc's centre, the support's anisotropy) are left out with a warning naming them, and the controller is the one
    built on the rest of the model; the same commands."""
    lateral = Model(
        RigParams(),
        ("motor_lag", "lateral_coulomb", "lateral_anisotropy"),
        {"tau_m": 0.03, "dk": 200.0, "db": 3.0},
    )
    with pytest.warns(UserWarning, match=r"leaves out the model's effects of the lateral motion \(lateral_coulomb, "
                      r"lateral_anisotropy\)"):  # fmt: skip
        c = controllers.make(name, config="coupled", omega_ref=np.array([2.0, 3.0]), model=lateral)
    assert c.effects.composition.label == "motor_lag" and set(c.effects.values) == {"tau_m"}
    ref = controllers.make(name, config="coupled", omega_ref=np.array([2.0, 3.0]),
                           model=Model(RigParams(), ("motor_lag",), {"tau_m": 0.03}))  # fmt: skip
    m = {"theta_u": np.zeros(2), "theta_l": np.zeros(2)}
    c.reset(m)
    ref.reset(m)
    for k in range(5):
        m = {"theta_u": np.full(2, 0.01 * k), "theta_l": np.full(2, 0.005 * k)}
        np.testing.assert_array_equal(c.act(m), ref.act(m))


def test_lqg_2enc_told_a_coarse_encoder_takes_its_quantisation_into_its_model():
    """Told 2048 counts, the filter's angle noise is q^2/12 + (1.25 q)^2 + noise^2 and the dead band 0.7 of q/2
    (benchmarks/bench_coarse_encoders.py: the default design limit-cycles at 1.4-1.6 rad/s there)."""
    from controllers.two_encoder import ALIASING, DEAD_BAND

    q = 2 * np.pi / 2048
    ctrl = controllers.make("lqg-2enc", omega_ref=1.5, counts_per_rev=2048, angle_noise=5e-4)
    assert ctrl.design.counts == 2048 and ctrl.design.dead_band == DEAD_BAND
    assert ctrl.design.noise_floor == pytest.approx(np.hypot(ALIASING * q, 5e-4))
    assert controllers.make("lqg-2enc", omega_ref=1.5).design.dead_band == 0.0  # not told: the default design
    with pytest.raises(InputError, match="counts_per_rev"):
        controllers.make("lqg-2enc", omega_ref=1.5, counts_per_rev=0)
