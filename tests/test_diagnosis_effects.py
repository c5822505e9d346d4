"""Diagnosis on synthetic measurements with a hidden effect.

Each recording is simulated with one effect of the library switched on and
measured like the rig (quantized encoders, LVDT noise, 5 Hz zero-phase LVDT
filter); :func:`diagnose` is NOT told the effect.  The true effect must rank
first, be significant, and cut the residual RMS by at least half.  Without a
hidden effect, nothing may be significant.
"""

import numpy as np
import pytest

from drillgym import RigParams
from drillgym.diagnosis import EFFECTS, diagnose, get_effect
from drillgym.diagnosis.refit import refit
from drillgym.identification.synthetic import synthetic_measurement

CASES = [
    ("torsional", 1.0, "string_damping", {"dtheta": 0.01}),
    ("torsional", 1.0, "friction_drift", {"drift": 0.006}),
    ("torsional", 1.0, "position_friction", {"pf_a1": 0.2, "pf_phi1": 1.0}),
    ("torsional", 0.5, "motor_lag", {"tau_m": 0.05}),
    ("torsional", 0.0, "brake_asymmetry", {"asym_s": 0.3, "asym_c": 0.3}),
    ("torsional", 0.5, "input_delay", {"delay": 0.04}),
    ("lateral", 3.0, "lateral_anisotropy", {"dk": 300.0, "db": 5.0}),
    ("lateral", 3.0, "lvdt_offset", {"lvdt_x0": 5e-4, "lvdt_y0": -3e-4}),
    ("lateral", 3.0, "lateral_coulomb", {"Fc_lat": 2.0}),
]


def _measure(config, offset, **effect):
    return synthetic_measurement(config, RigParams().replace(**effect), duration=20.0, rate_hz=250.0,
                                 offset=offset, seed=1)


@pytest.mark.parametrize("config,offset,name,effect", CASES, ids=[c[2] for c in CASES])
def test_hidden_effect_ranks_first_and_halves_residual(config, offset, name, effect):
    d = diagnose(_measure(config, offset, **effect))
    best = d.ranking[0]
    assert best.effect == name, d.text()
    assert best.significant
    assert best.rmse_after <= 0.5 * best.rmse_before
    for k, v in effect.items():  # the fitted extension parameters are the hidden ones
        if k != "pf_phi1":
            assert best.values[k] == pytest.approx(v, rel=0.25), (k, best.values)


def test_no_hidden_effect_nothing_significant():
    d = diagnose(_measure("torsional", 1.0))
    assert d.significant() == [], d.text()
    assert "no effect of the library" in d.text()


def test_json_shape_and_skips():
    d = diagnose(_measure("torsional", 2.0), RigParams().scaled(Ts=1.05), effects=["string_damping", "lvdt_offset"],
                 refit_base=True)
    js = d.to_json()
    assert set(js["base_refit"]) == {"Ts", "Tc", "ws", "delta", "bb"}
    assert js["base_refit"]["Ts"] == pytest.approx(RigParams().Ts, rel=0.01)  # light refit undoes the error
    assert [r["effect"] for r in js["ranking"]] == ["string_damping"]
    assert set(js["ranking"][0]) >= {"effect", "score", "rmse_before", "rmse_after"}
    assert "configuration" in js["skipped"]["lvdt_offset"]
    with pytest.raises(ValueError, match="unknown effect"):
        diagnose(_measure("torsional", 2.0), effects=["bogus"])


def test_effect_library_documented():
    required = {"position_friction", "brake_asymmetry", "string_damping", "motor_lag", "input_delay",
                "lateral_anisotropy", "lvdt_offset", "lvdt_skew", "lateral_coulomb", "friction_drift"}
    assert required <= set(EFFECTS)
    p = RigParams()
    for e in EFFECTS.values():
        assert len(e.explanation) > 80 and e.signature and e.configurations
        for n in e.parameters:
            assert hasattr(p, n)
        z = np.array([v.x0 for v in e.variables(p)])
        RigParams.from_vector(e.apply(p.to_vector(), z))  # initial guesses are valid parameter sets


def test_refit_with_effect_cuts_error():
    ts = _measure("torsional", 1.0, dtheta=0.01)
    res = refit(ts, effects=["string_damping"])
    assert res.params.dtheta == pytest.approx(0.01, rel=0.05)
    assert res.r2_after["alpha"] > res.r2_before["alpha"]
    assert res.rms_after["theta_l"] < 0.2 * res.rms_before["theta_l"]
    with pytest.raises(ValueError, match="does not act"):
        refit(ts, effects=["lvdt_offset"])
    assert get_effect("motor_lag").parameters == ("tau_m",)
