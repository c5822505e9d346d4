"""The robust observer built on a model (``model=``), as the other model-based controllers are."""

import numpy as np
import pytest

import controllers
from drillgym import Model, RigParams


def _model() -> Model:
    return Model(RigParams().replace(Ts=0.3), ("motor_lag",), {"tau_m": 0.03})


def test_the_robust_observer_takes_a_model_and_keeps_its_margin_on_the_models_motor(tmp_path):
    m = _model()
    for given in (m, m.save(tmp_path / "model.json")):
        c = controllers.make("observer-robust", model=given, omega_ref=3.0)
        assert c.effects.label == "motor_lag" and c.effects.values["tau_m"] == pytest.approx(0.03)
        assert c.params.Ts == 0.3 and c.params.bu == pytest.approx(m.params.bu / 1.1)  # least damped motor
        c.reset({"theta_u": np.zeros(1)})
        u = c.act({"theta_u": np.zeros(1)})
        assert np.all(np.isfinite(u))
    c = controllers.make("observer-robust", model=m, omega_ref=3.0, bu_margin=1.0)
    assert c.params.bu == m.params.bu


def test_the_robust_observer_refuses_params_beside_a_different_model_in_one_line():
    with pytest.raises(ValueError, match="either as params or in its model, not both"):
        controllers.make("observer-robust", model=_model(), params=RigParams(), omega_ref=3.0)
