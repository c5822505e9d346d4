"""One model file from diagnosis to control: ``diagnose --model-out`` and controllers built on a model's effects."""

import json

import numpy as np
import pytest

from drillgym import RigParams
from drillgym.errors import InputError


@pytest.fixture(scope="module")
def lag_diagnosis():
    """The diagnosis of 6 s of a simulated torsional recording (250 Hz) whose motor lags by 40 ms."""
    from drillgym.diagnosis import DiagnosisOptions, diagnose
    from drillgym.identification.synthetic import synthetic_measurement

    lag = {"effects": ["motor_lag"], "effect_params": {"tau_m": 0.04}}
    ts = synthetic_measurement("torsional", duration=6.0, rate_hz=250.0, offset=1.0, seed=5, **lag)
    return diagnose(ts, options=DiagnosisOptions(effects=["motor_lag", "input_delay"], discover=False))


def test_the_selected_model_is_a_model_file_with_the_fitted_lag(lag_diagnosis, tmp_path):
    from drillgym import Model

    d = lag_diagnosis
    assert d.selected == ["motor_lag"], d.text()
    params, records, base_std = d.selected_model()
    assert [r["name"] for r in records] == ["motor_lag"]
    assert records[0]["values"]["tau_m"] == pytest.approx(0.04, rel=0.05)
    assert records[0]["std"]["tau_m"] > 0
    std = {**base_std, **records[0]["std"]}
    m = Model(params, tuple(r["spec"] for r in records), records[0]["values"], std)
    back = Model.load(m.save(tmp_path / "m.json"))
    assert back.specs == ["motor_lag"] and back.values["tau_m"] == records[0]["values"]["tau_m"]
    assert back.std["tau_m"] == records[0]["std"]["tau_m"] and back.params == params


def test_diagnose_model_out_refuses_a_file_that_is_not_a_model_file(tmp_path):
    from drillgym.cli import main
    from drillgym.identification.synthetic import synthetic_measurement
    from drillgym.io import write_timeseries

    rec = tmp_path / "lag.csv"
    write_timeseries(rec, synthetic_measurement("torsional", duration=2.0, rate_hz=250.0, seed=5))
    bad = tmp_path / "selected.txt"
    with pytest.raises(SystemExit) as exc:
        main(["diagnose", str(rec), "--model-out", str(bad)])
    assert exc.value.code == 2 and not bad.exists()


def test_model_files_carry_standard_errors_and_refuse_bad_ones(tmp_path):
    from drillgym import Model

    p = Model(RigParams(), ("motor_lag",), {"tau_m": 0.03}, {"km": 0.01}).save(tmp_path / "m.json")
    assert dict(Model.load(p).std) == {"km": 0.01}
    data = json.loads(p.read_text())
    data["std"] = {"km": -1}
    p.write_text(json.dumps(data))
    with pytest.raises(Exception, match="standard error of 'km'"):
        Model.load(p)


# ------------------------------------------------------------------------------------------ controllers on a model
def _model(specs, values):
    from drillgym import Model

    return Model(RigParams(), tuple(specs), values)


def test_delay_line_discretisation_is_exact_for_an_integrator():
    from controllers.model import delayed_discretisation

    dt = 0.002
    s = delayed_discretisation(np.zeros((1, 1)), np.ones((1, 1)), dt, 1.5 * dt)
    # x+ = x + (dt/2) u[k-1] + (dt/2) u[k-2]: the line holds u[k-1], u[k-2]
    assert s.n_line == 2
    np.testing.assert_allclose(s.Ad[0], [1.0, dt / 2, dt / 2])
    np.testing.assert_allclose(s.Bd[:, 0], [0.0, 1.0, 0.0])
    np.testing.assert_allclose(s.Ad[2], [0.0, 1.0, 0.0])


def test_filter_model_has_the_lag_state_and_the_delay_line():
    from controllers.kalman import disturbance_model

    base = disturbance_model(dt=0.002)
    lag = disturbance_model(dt=0.002, model=_model(["motor_lag"], {"tau_m": 0.04}))
    both = disturbance_model(dt=0.002, model=_model(["motor_lag", "input_delay"], {"tau_m": 0.04, "delay": 0.005}))
    assert base.Ad.shape == (5, 5) and lag.Ad.shape == (6, 6) and both.Ad.shape == (6 + 3, 6 + 3)
    assert lag.lag_index == 5 and both.line_index == 6 and both.delay_steps == 2
    # a step of the command reaches the motor speed only through the lag: no direct effect in one period
    assert abs(lag.Bd[1, 0]) < 0.05 * abs(base.Bd[1, 0])


def test_controllers_refuse_effects_they_cannot_use_and_leave_out_the_lateral_ones():
    import controllers

    with pytest.warns(UserWarning, match=r"effects of the lateral motion \(lateral_anisotropy\)"):
        left = controllers.make("observer", omega_ref=3.0, model=_model(["lateral_anisotropy"], {}))
    assert not left.effects.composition.effects  # as the lateral motion itself
    ok = controllers.make("observer", omega_ref=3.0, model=_model(["string_damping"], {}))  # a Force: in its model
    assert ok.model.dynamics.nz == 5
    with pytest.raises(InputError, match="'motor_lag'"):
        controllers.make("descent", omega_ref=3.0, model=_model(["motor_lag"], {"tau_m": 0.04}))
    ok = controllers.make("observer", omega_ref=3.0, model=_model(["lvdt_offset"], {}))  # off the motor encoder
    assert ok.effects.label == "lvdt_offset"


def test_an_observer_that_knows_the_motor_lag_holds_where_the_lag_free_one_does_worse():
    """Plant with a 40 ms motor lag, 2.5 rad/s from rest (12 s, the last 5 s judged)."""
    import controllers
    from controllers.evaluation.metrics import run_metrics
    from controllers.evaluation.runner import run_closed_loop

    lag = _model(["motor_lag"], {"tau_m": 0.04})
    res = {}
    for name, model in (("with", lag), ("without", None)):
        ctrl = controllers.make("observer", omega_ref=2.5, model=model)
        run = run_closed_loop(
            ctrl, "torsional", np.array([2.5]), 12.0, effects=lag.composition, effect_params=dict(lag.values)
        )
        res[name] = run_metrics(run, 5.0, RigParams())
    assert res["with"]["ssi"][0] < 0.1, res
    assert res["without"]["ssi"][0] > 2 * res["with"]["ssi"][0], res


# ------------------------------------------------------------------------------------------ margins
def test_margin_compares_the_limit_with_the_identified_km():
    from controllers.margin import model_margins
    from drillgym import Model

    p = RigParams()
    tight, loose = (Model(p, std={"km": f * p.km}) for f in (0.001, 0.02))
    m_tight, m_loose = model_margins(tight, [4.0, 2.0]), model_margins(loose, [2.0, 4.0])
    assert [g.omega for g in m_tight] == [2.0, 4.0]
    assert m_tight[0].needed == pytest.approx(0.011, rel=0.2) and np.isinf(m_tight[1].needed)
    assert m_tight[0].achieved == pytest.approx(0.002) and m_tight[0].enough is True
    assert m_loose[0].enough is False and m_loose[1].enough is True
    assert model_margins(Model(p), [2.0])[0].enough is None  # no standard error: not known


def test_margin_counts_a_lag_and_a_delay_at_the_unstable_modes_frequency():
    """A lag's 1 ms standard error costs 2 x 1 ms x |p| of input accuracy at the target, on top of km's, in
    quadrature; a lag without a standard error leaves the accuracy unknown."""
    from controllers.limits import motor_angle_limit
    from controllers.margin import model_margins
    from drillgym import Model
    from drillgym.effects import compose

    p = RigParams()
    comp, values = compose(["motor_lag", "input_delay"], {"tau_m": 0.03, "delay": 0.005})
    std = {"km": 0.001 * p.km, "tau_m": 1e-3, "delay": 2e-3}
    (g,) = model_margins(Model.from_composition(p, comp, values, std), [2.0])
    mode = max(abs(z) for z in motor_angle_limit(p, 2.0).rhp_poles)
    assert g.parts["tau_m"] == pytest.approx(2 * mode * 1e-3) and g.parts["delay"] == pytest.approx(4 * mode * 1e-3)
    assert g.achieved == pytest.approx(np.sqrt(0.002**2 + (2e-3 * mode) ** 2 + (4e-3 * mode) ** 2))
    assert g.achieved > model_margins(Model(p, std={"km": 0.001 * p.km}), [2.0])[0].achieved
    no_lag_std = Model.from_composition(p, comp, values, {"km": 0.001 * p.km, "delay": 2e-3})
    assert model_margins(no_lag_std, [2.0])[0].achieved is None


def test_observer_warns_and_falls_back_to_descent_where_its_model_is_not_good_enough():
    import controllers
    from drillgym import Model

    p = RigParams()
    loose = Model(p, std={"km": 0.02 * p.km})
    meas = {"t": 0.0, "theta_u": np.zeros(2)}
    ctrl = controllers.make("observer", omega_ref=np.array([2.0, 4.0]), model=loose, fallback=True)
    with pytest.warns(UserWarning, match=r"observer at 2 rad/s tolerates 1\.\d+ %.*NOT enough; descent drives it"):
        ctrl.reset(meas)
    ref = controllers.make("descent", omega_ref=np.array([2.0, 4.0]), dt=ctrl.dt)
    ref.reset(meas)
    u, u_ref = ctrl(meas), ref(meas)
    assert list(ctrl._short) == [True, False]
    assert u[0] == u_ref[0] and u[1] != u_ref[1]
