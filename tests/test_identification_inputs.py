"""Identification refuses what it cannot fit, before any fit, and never returns statistics it could not compute.

* a base parameter that does not act in the recording's configuration (``--fit k`` on torsional) and a
  staged-identification stage given a recording of another configuration are refused in one line;
* the table of acting parameters is the simulator's: changing a parameter changes a run exactly when
  the table says it acts;
* a model that gives non-finite states on the recording is a FitError naming the time, not an R² null;
* a partial model file keeps the defaults of the parameters it does not name.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import drillgym
from drillgym.configurations import Configuration
from drillgym.diagnosis.refit import refit
from drillgym.errors import FitError, InputError
from drillgym.identification import prepare_experiment
from drillgym.identification.acting import parameters_acting
from drillgym.identification.staged import STAGES, identify_stage, identify_staged
from drillgym.identification.synthetic import synthetic_measurement
from drillgym.model import Model
from drillgym.params import PARAM_INFO, RigParams


@pytest.fixture(scope="module")
def torsional():
    return synthetic_measurement("torsional", duration=4.0, rate_hz=100.0, seed=1)


def test_fit_of_a_parameter_that_does_not_act_is_refused(torsional) -> None:
    with pytest.raises(InputError) as err:
        refit(torsional, fit=["k"])
    msg = str(err.value)
    assert msg.startswith("--fit k: the lateral stiffness does not act in configuration torsional")
    assert "parameters that do: Ju, km" in msg and ", k," not in msg


def test_a_stage_refuses_a_recording_of_another_configuration(torsional) -> None:
    with pytest.raises(InputError, match=r"^stage 'upper': .* configuration torsional; the stage needs the upper"):
        identify_staged({"upper": torsional})
    with pytest.raises(InputError, match=r"^stage 'lateral': "):  # checked before the upper stage is fitted
        identify_staged({"upper": synthetic_measurement("upper", duration=2.0, rate_hz=100.0), "lateral": torsional})
    with pytest.raises(InputError, match=r"^stage 'brake': parameter k: the lateral stiffness does not act"):
        identify_stage("brake", torsional, RigParams(), parameters=["Ts", "k"])
    with pytest.raises(InputError, match="recording is of configuration torsional, but upper was requested"):
        prepare_experiment(torsional, "upper")


STAGE_CONFIG = {  # the stage's experiment: configuration, brake (None: the configuration's)
    "upper": (Configuration.UPPER, None),
    "free_vibration": (Configuration.FREE_VIBRATION, None),
    "lower": (Configuration.TORSIONAL, False),
    "lateral": (Configuration.LATERAL, None),
    "brake": (Configuration.TORSIONAL, None),
}


@pytest.mark.parametrize("stage", list(STAGES))
def test_every_stage_fits_parameters_that_act_in_its_experiment(stage: str) -> None:
    config, brake = STAGE_CONFIG[stage]
    assert set(STAGES[stage].parameters) <= set(parameters_acting(config, brake=brake))


@pytest.mark.slow
@pytest.mark.parametrize("config", ["upper", "torsional", "lateral", "coupled"])
def test_the_parameters_acting_are_those_that_change_a_run(config: str) -> None:
    names = [n for n in PARAM_INFO if n not in ("dTcu", "dbu")]  # asymmetries: signed, tested through Tcu/bu
    nominal = RigParams()
    rows = [nominal] + [nominal.replace(**{n: getattr(nominal, n) * 1.3 + 1e-3}) for n in names]
    t = np.arange(0.0, 2.0, 1e-3)
    u = 3.0 + 1.5 * np.sin(2 * np.pi * t)  # slip, stick and speed changes
    batch = drillgym.simulate_batch(config, (t, u), 2.0, params=rows, alpha0=0.5, record=("theta_u", "theta_l", "x"))
    changed = {n for k, n in enumerate(names, start=1) if not np.array_equal(batch.data[k], batch.data[0])}
    expected = set(parameters_acting(Configuration[config.upper()])) - {"dTcu", "dbu"}
    assert changed == expected


def test_a_model_with_non_finite_states_is_a_fit_error(torsional, tmp_path) -> None:
    effect = tmp_path / "nan_after.py"
    effect.write_text(
        "import math\n"
        "from drillgym.effects import Force, Parameter\n\n\n"
        "class NanAfter(Force):\n"
        "    name = 'nan_after'\n"
        "    acts_on = 'lower'\n"
        "    parameters = (Parameter('t_nan', unit='s', lo=0.0, hi=100.0, guess=50.0, scale=1.0, doc='NaN time'),)\n"
        "    explanation = 'a broken formula'\n"
        "    signature = 'none'\n\n"
        "    def torque(t, t_nan):\n"
        "        if t < t_nan:\n"
        "            return 0.0\n"
        "        return math.nan\n",
        encoding="utf-8",
    )
    from drillgym.diagnosis.compare import compare

    with pytest.raises(FitError) as err:
        compare(torsional, effects=[f"{effect}:nan_after"], effect_params={"t_nan": 2.0})
    msg = str(err.value)
    assert msg.startswith("compare: the model nan_after (t_nan = 2) gives non-finite states on ")
    t = float(msg.split("from t = ")[1].split(" s")[0])
    assert 2.0 <= t < 2.1


def test_a_partial_model_file_keeps_the_other_defaults(tmp_path) -> None:
    path = tmp_path / "partial.json"
    path.write_text(json.dumps({"params": {"km": 4.0}}), encoding="utf-8")
    params = Model.load(path).params
    assert params.km == 4.0 and params.Ju == RigParams().Ju
