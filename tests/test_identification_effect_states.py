"""Rows of a prediction that differ only where the effect states cannot see share one free run of the record.

The states a segment starts from come from a free run of the whole record per parameter row; when every state
depends on the voltage alone (a lag behind a dead zone, a delay), the rows of a Jacobian that move a base
parameter get the same states, so the prediction computes them once.  The outputs must be those of one free run
per row, to the bit; a state that reads the discs' motion keeps one run per row.
"""

from pathlib import Path

import numpy as np

from drillgym.effects import Composition, Input, Parameter, State, compose
from drillgym.identification import SegmentedModel, prepare_experiment
from drillgym.identification.effect_states import input_state_columns
from drillgym.identification.synthetic import synthetic_measurement

ROOT = Path(__file__).resolve().parents[1]
DEAD_ZONE = f"{ROOT}/examples/effects/motor_dead_zone.py:dead_zone"


class SpeedLoadedDrive(Input):
    """A drive whose memory loads with the motor's speed (its state reads a disc quantity)."""

    name = "speed_loaded_drive"
    parameters = (Parameter("k_w", "V s/rad", 0.0, 1.0, 0.01, 0.01, "speed loading"),)
    states = (State("u_w", "V"),)

    def derivative(u, u_w, omega_u, k_w):
        return 50.0 * (u - k_w * omega_u - u_w)

    def voltage(u, u_w):
        return u_w


def test_the_state_columns_are_the_voltage_paths_parameters():
    comp, _ = compose([DEAD_ZONE, "input_delay", "motor_lag"])
    cols = input_state_columns(comp)
    assert [comp.param_names[i] for i in cols] == sorted(["u0", "delay", "tau_m"], key=comp.param_index)
    assert input_state_columns(Composition((SpeedLoadedDrive,))) is None


def _jacobian_rows(comp, values):
    v = comp.matrix(None, 1)[0]
    for name, x in values.items():
        v[comp.param_index(name)] = x
    P = np.repeat(v[None], comp.n_params + 1, axis=0)
    for j in range(comp.n_params):
        P[j + 1, j] *= 1.001
    return P


def test_shared_free_runs_give_the_predictions_of_one_run_per_row():
    effects, values = [DEAD_ZONE, "motor_lag"], {"u0": 0.3, "tau_m": 0.03}
    ts = synthetic_measurement(
        "torsional", None, duration=8, rate_hz=250, signal="steps", offset=1.2, seed=3, effects=effects,
        effect_params=values,
    )  # fmt: skip
    ex = prepare_experiment(ts, "torsional", compare_rate_hz=50)
    comp, _ = compose(effects)  # the lag behind the dead zone: simulated with its state, not filtered ahead
    model = SegmentedModel([ex], segment_s=2.0, composition=comp)
    assert model._state_cols is not None and len(model._state_cols) == 2
    P = _jacobian_rows(comp, values)
    runs = []
    real = model._effect_states
    model._effect_states = lambda *a: runs.append(a[2].shape[0]) or real(*a)
    shared = model.predict_arrays(P)
    assert runs == [3]  # the unmoved row, and the rows that move u0 and tau_m
    model._state_cols = None
    one_per_row = model.predict_arrays(P)
    assert runs[1:] == [P.shape[0]]
    for channel, y in one_per_row[0].items():
        np.testing.assert_array_equal(shared[0][channel], y)


def test_a_model_computes_a_voltage_paths_states_once():
    effects, values = [DEAD_ZONE, "motor_lag"], {"u0": 0.3, "tau_m": 0.03}
    ts = synthetic_measurement("torsional", None, duration=6, rate_hz=250, signal="steps", offset=1.2, seed=4)
    comp, _ = compose(effects)
    model = SegmentedModel([prepare_experiment(ts, "torsional", compare_rate_hz=50)], segment_s=2.0, composition=comp)
    P = _jacobian_rows(comp, values)
    first = model.predict_arrays(P[:1])
    runs = []
    real = model._effect_states
    model._effect_states = lambda *a: runs.append(a[2].shape[0]) or real(*a)
    again = model.predict_arrays(P)  # the unmoved row's states are those of the first prediction
    assert runs == [2]
    np.testing.assert_array_equal(again[0]["theta_u"][0], first[0]["theta_u"][0])
    other = model.with_composition(compose([DEAD_ZONE, "input_delay", "motor_lag"])[0])
    assert other._state_memo == {}  # another model computes its own


def test_a_segment_starting_under_voltage_starts_its_lag_at_the_command():
    """A record that starts with the motor driven (the second half of a recording): a lag behind another Input
    effect starts at the first command held, as the simulator starts it, not at 0 V (whose transient made a real
    position friction 'not seen' in the second half of a recording, and dropped it)."""
    from drillgym.diagnosis.reproducibility import split_halves
    from drillgym.measurement import MeasurementModel

    effects, values = [DEAD_ZONE, "motor_lag"], {"u0": 0.3, "tau_m": 0.08}
    ts = synthetic_measurement(
        "torsional", None, duration=8, rate_hz=250, signal="steps", offset=2.5, amplitude=1.0, seed=5,
        effects=effects, effect_params=values, model=MeasurementModel(counts_per_rev=2**30),
    )  # fmt: skip
    _, second = split_halves(prepare_experiment(ts, "torsional", compare_rate_hz=50))
    assert abs(float(np.interp(second.t[0], second.u_time, second.u_value))) > 1.0  # it starts under voltage
    comp, _ = compose(effects)
    v = comp.matrix(None, 1)[0]
    for name, x in values.items():
        v[comp.param_index(name)] = x
    model = SegmentedModel([second], segment_s=None, composition=comp)
    theta_u = model.predict_arrays(v[None])[0]["theta_u"][0, 0]
    measured = second.meas["theta_u"]
    assert np.max(np.abs(theta_u - measured)) < 1e-6  # rad: the run that made it; the lag started at 0 V: 0.18


def test_lag_states_from_the_input_path_are_those_of_the_free_run():
    """Lags the input alone drives (a lag behind a dead zone, a delay ahead) start each segment from their run along
    the input's path, not from a simulation of the discs: the same predictions as the free run of the whole model
    (to round-off: the kernel splits a step at a stick-slip event), and not when a state reads the discs."""
    effects = [DEAD_ZONE, "motor_lag", "input_delay"]
    values = {"u0": 0.3, "tau_m": 0.03, "delay": 0.0113}
    ts = synthetic_measurement(
        "torsional", None, duration=8, rate_hz=250, signal="steps", offset=1.2, seed=6, effects=effects,
        effect_params=values,
    )  # fmt: skip
    ex = prepare_experiment(ts, "torsional", compare_rate_hz=50)
    comp, _ = compose(effects)
    P = _jacobian_rows(comp, values)
    path = SegmentedModel([ex], segment_s=2.0, composition=comp)
    assert path._lags_only
    runs = []
    real = path._simulate
    path._simulate = lambda *a: runs.append(a[5].shape[0]) or real(*a)
    along_path = path.predict_arrays(P)
    assert all(n == P.shape[0] * len(path._plans[0]["starts"]) for n in runs)  # only the segments were simulated
    free = SegmentedModel([ex], segment_s=2.0, composition=comp)
    free._lags_only = False
    free_run = free.predict_arrays(P)
    for channel, y in free_run[0].items():
        np.testing.assert_allclose(along_path[0][channel], y, rtol=0, atol=1e-9)
    assert not SegmentedModel([ex], segment_s=2.0, composition=Composition((SpeedLoadedDrive,)))._lags_only
