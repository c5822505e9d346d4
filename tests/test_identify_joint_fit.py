"""identify's joint fit runs on the diagnosis' search model: the same runs as the selected model, no compilation."""

import numpy as np
import pytest

from drillgym import simulate
from drillgym.diagnosis.effects import get_effect
from drillgym.diagnosis.search_model import neutral_values, vanishes_exactly
from drillgym.effects import compose
from drillgym.identified import _search_model_for
from drillgym.signals import quasi_random

SEARCH = ["motor_lag", "position_friction", "brake_asymmetry", "string_damping", "input_delay", "friction_drift"]


def _run(comp, values, t, u):
    return simulate(config="torsional", u=(t, u), duration=float(t[-1]), effects=comp, effect_params=values)


def test_the_search_model_without_a_lag_runs_the_selected_model_to_the_bit():
    search, _ = compose(SEARCH)
    selected, values = compose(["input_delay", "position_friction"], {"delay": 0.02, "pf_c1": -0.09, "pf_s1": 0.05})
    on = _search_model_for(search, selected)
    assert on is not None and "motor_lag" not in on.names  # a 0.1 ms lag is not nothing
    assert not vanishes_exactly(get_effect("motor_lag")) and vanishes_exactly(get_effect("string_damping"))
    start = {**neutral_values(on.effects), **values}
    t, u = quasi_random(20.0, rate_hz=500.0, seed=3, amplitude=5.0, offset=2.5)
    a, b = _run(selected, values, t, u), _run(on, start, t, u)
    assert np.array_equal(a.theta_l, b.theta_l) and np.array_equal(a.theta_u, b.theta_u)


def test_a_selected_lag_keeps_the_lag_and_a_signal_path_in_another_order_is_refused():
    search, _ = compose(SEARCH)
    with_lag, _ = compose(["motor_lag", "position_friction"])
    assert "motor_lag" in _search_model_for(search, with_lag).names
    outside, _ = compose(["lateral_coulomb"])
    assert _search_model_for(search, outside) is None  # not in the search model: the selected one is compiled
    reordered, _ = compose(["examples/effects/motor_dead_zone.py:dead_zone", "motor_lag"])
    searched, _ = compose(["motor_lag", "examples/effects/motor_dead_zone.py:dead_zone"])
    assert _search_model_for(searched, reordered) is None


def test_an_effect_fitted_to_where_it_does_nothing_is_left_out_of_the_model():
    """A delay the joint fit took to its bound of 0 s (the time moved into the lag) is not written into the model;
    a delay of a few ms, and effects that declare no neutral value (a lag, a candidate's width), stay."""
    from drillgym.identified import _without_idle_effects

    comp, values = compose(["motor_lag", "input_delay", "position_friction"])
    values = {**values, "tau_m": 0.03, "delay": 1.7e-18, "pf_c1": 0.05, "pf_s1": 0.0}
    std = {"tau_m": 1e-4, "delay": 1e-4, "pf_c1": 1e-3}
    notes = []
    kept, kept_values, kept_std = _without_idle_effects(comp, values, std, notes)
    assert kept.names == ("motor_lag", "position_friction") and "delay" not in kept_values and "delay" not in kept_std
    assert len(notes) == 1 and notes[0].startswith("input_delay fitted to where it does nothing")
    same, _, _ = _without_idle_effects(comp, {**values, "delay": 0.004}, std, [])
    assert same is comp


def test_beside_a_candidate_read_another_way_a_library_effect_that_removes_little_is_left_out(monkeypatch):
    from types import SimpleNamespace

    import drillgym.identified as identified

    comp, _ = compose(["motor_lag", "brake_asymmetry", "friction_drift"])
    # the residual (noise units²) of the model without each effect: the asymmetry removes 2 %, the drift 60 %
    without = {"motor_lag": 9.0, "brake_asymmetry": 1.02, "friction_drift": 2.5}

    def joint_fit(ts, d, params, specs, values, o, notes, held=()):
        names = {e.name for e in specs}
        missing = [n for n in without if n not in names]
        ss = without[missing[0]] if len(missing) == 1 else 1.0 if not missing else 1.02 * without[missing[-1]]
        return compose(list(specs))[0], values, SimpleNamespace(rms_after={"theta_u": ss**0.5})

    monkeypatch.setattr(identified, "_joint_fit", joint_fit)
    notes: list[str] = []
    best = (comp, {}, SimpleNamespace(rms_after={"theta_u": 1.0}))
    kept_comp, _, _ = identified._library_earned(None, None, None, None, [], best, notes)
    assert kept_comp.names == ("motor_lag", "friction_drift")
    assert len(notes) == 1 and notes[0].startswith("brake_asymmetry left out")


def test_the_whole_models_residual_weighs_every_channel_by_its_noise():
    """An LVDT's misfit in metres counts as much as an encoder's in radians at the same multiple of their noise:
    a reading that leaves the angles a little better and the LVDTs seven times their noise loses to one that
    leaves every channel near the noise (the coupled rig's lower encoder zero read as the motor encoder's)."""
    from types import SimpleNamespace

    from drillgym.identified import _sum_of_squares

    noise = {"theta_u": 2e-4, "theta_l": 2e-4, "x": 5e-6, "y": 5e-6}
    near = SimpleNamespace(rms_after={"theta_u": 3e-4, "theta_l": 3e-4, "x": 6e-6, "y": 6e-6}, noise=noise)
    lvdts_off = SimpleNamespace(rms_after={"theta_u": 2.5e-4, "theta_l": 2.5e-4, "x": 3.5e-5, "y": 1.5e-5}, noise=noise)
    assert _sum_of_squares(near) == pytest.approx(1.5**2 * 2 + 1.2**2 * 2)
    assert _sum_of_squares(lvdts_off) > 5 * _sum_of_squares(near)  # in rad² and m² summed, it looked better
    plain = SimpleNamespace(rms_after={"theta_u": 3e-4}, noise={})  # no noise estimate: its own unit
    assert _sum_of_squares(plain) == pytest.approx(3e-4**2)
