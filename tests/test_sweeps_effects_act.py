"""The brute-force sweeps refuse an effect that does not act in the configuration swept, as ``simulate`` does."""

import pytest

from drillgym import Model
from drillgym.bifurcation import sweep_constant, sweep_staircase
from drillgym.effects import EffectError
from drillgym.equilibria import as_model

LATERAL = Model(effects=("lateral_anisotropy",), values={"dk": 200.0})  # acts in lateral and coupled only


@pytest.mark.parametrize("sweep", [sweep_constant, sweep_staircase])
def test_an_effect_that_does_not_act_in_the_swept_configuration_is_refused(sweep):
    kw = {"duration": 21.0} if sweep is sweep_constant else {"dwell": 21.0}
    with pytest.raises(EffectError, match=r"the model's effects lateral_anisotropy: the effect does not act in the "):
        sweep("torsional", [1.0, 2.0], window=20.0, model=LATERAL, **kw)
    rig = as_model(LATERAL.params, effects=LATERAL.composition, effect_params=dict(LATERAL.values))
    with pytest.raises(EffectError, match=r"^effects lateral_anisotropy: the effect does not act in the torsional"):
        sweep("torsional", [1.0, 2.0], window=20.0, params=rig, **kw)
