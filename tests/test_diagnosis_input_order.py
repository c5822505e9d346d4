"""The order of two Input effects on the signal path: the diagnosis fits both and reports the better.

A motor lag before a dead zone (the motor sees dead_zone(lag(u))) is not the same motor as the dead zone
before the lag; the model diagnosed here has them the wrong way round.
"""

import pytest
from test_diagnosis_unexplained import DEAD_ZONE, steps

from drillgym.diagnosis import diagnose
from drillgym.identification.synthetic import synthetic_measurement


@pytest.mark.slow
def test_two_input_effects_are_tried_in_both_orders_and_the_better_reported():
    ts = synthetic_measurement(
        "torsional",
        duration=8.0,
        rate_hz=250.0,
        input=steps(8.0),
        seed=3,
        effects=["motor_lag", DEAD_ZONE],
        effect_params={"u0": 0.4, "tau_m": 0.08},
    )
    d = diagnose(ts, effects=["motor_lag"], base_effects=[DEAD_ZONE], effect_params={"u0": 0.4}, fixed_base=True)
    assert d.selected == ["motor_lag"], d.text()
    order = d.to_json()["input_order"]
    assert order["diagnosed"] == ["dead_zone", "motor_lag"] == d.to_json()["signal_path"]
    assert order["better"] == ["motor_lag", "dead_zone"] and not order["tie"], order
    assert order["rss_swapped"] < 0.1 * order["rss_diagnosed"] and order["score_gap_nats"] > 10.0
    assert "motor_lag -> dead_zone (swapped) fits better by" in d.text()


def test_one_input_effect_has_no_order_to_try():
    ts = synthetic_measurement(
        "torsional",
        duration=8.0,
        rate_hz=250.0,
        input=steps(8.0),
        seed=3,
        effects=["motor_lag"],
        effect_params={"tau_m": 0.05},
    )
    d = diagnose(ts, effects=["motor_lag", "input_delay"], fixed_base=True)
    assert d.input_order is None and d.to_json()["input_order"] is None
    assert "order of the Input effects" not in d.text()
