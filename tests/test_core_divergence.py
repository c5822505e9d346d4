"""A run that diverges is one SimulationError naming the run, the time and the state.

Divergence: a state that is not finite (an effect's formula gave NaN), or a disc speed beyond
100 times the motor's no-load speed at 50 V (``drillgym.trajectory.speed_limit``). Single runs,
batches (lane kernel), the adaptive method and the stepping BatchSimulator all say so.
"""

from __future__ import annotations

import numpy as np
import pytest

import drillgym
from drillgym import BatchSimulator, RigParams
from drillgym.errors import SimulationError
from drillgym.trajectory import SPEED_FACTOR, U_REACH, speed_limit

EFFECT = """
import math

from drillgym.effects import Force, Parameter


class NanAfter(Force):
    name = "nan_after"
    acts_on = "lower"
    parameters = (Parameter("t_nan", unit="s", lo=0.0, hi=100.0, guess=50.0, scale=1.0, doc="time of the NaN"),)
    explanation = "a broken formula: NaN after t_nan"
    signature = "none"

    def torque(t, t_nan):
        if t < t_nan:
            return 0.0
        return math.nan
"""


@pytest.fixture(scope="module")
def nan_effect(tmp_path_factory) -> str:
    path = tmp_path_factory.mktemp("effects") / "nan_after.py"
    path.write_text(EFFECT, encoding="utf-8")
    return f"{path}:nan_after"


def test_speed_limit_is_the_no_load_speed_at_50_volts_times_the_factor() -> None:
    p = RigParams()
    expected = SPEED_FACTOR * p.km * U_REACH / (p.bu + p.bl + p.bb)
    assert speed_limit(p.to_vector())[0] == pytest.approx(expected)
    assert 5e3 < expected < 2e4  # far above the rig's 30 rad/s, far below a divergence
    no_viscous = p.to_vector()
    no_viscous[[list(p.to_dict()).index(n) for n in ("bu", "bl", "bb")]] = 0.0
    assert np.isinf(speed_limit(no_viscous)[0])


@pytest.mark.parametrize("method", ["rk4", "dp45"])
def test_a_huge_winding_is_refused_with_the_time_and_the_speed(method: str) -> None:
    with pytest.raises(SimulationError) as err:
        drillgym.simulate("torsional", u=1.0, duration=0.5, alpha0=1e9, method=method)
    msg = str(err.value)
    assert msg.startswith("the run diverged at t = ") and "\n" not in msg
    assert "omega_" in msg and "rad/s exceed" in msg and "no-load speed" in msg


def test_a_nan_effect_names_the_time_and_states(nan_effect: str) -> None:
    with pytest.raises(SimulationError) as err:
        drillgym.simulate("torsional", u=3.0, duration=1.0, effects=[nan_effect], effect_params={"t_nan": 0.25})
    msg = str(err.value)
    assert msg.startswith("the run diverged at t = 0.25") and "= nan" in msg and "nan_after" in msg
    # not recorded: the time still follows from the sample index
    with pytest.raises(SimulationError, match=r"at t = 0\.2[5-9]"):
        drillgym.simulate(
            "torsional",
            u=3.0,
            duration=1.0,
            effects=[nan_effect],
            effect_params={"t_nan": 0.25},
            record=("theta_l",),
            record_every=8,  # not every step: the time still comes from the run
        )


@pytest.mark.slow
def test_a_batch_names_the_run_that_diverged_first(nan_effect: str) -> None:
    params = np.tile(drillgym.effects.compose([nan_effect])[0].vector(RigParams(), {"t_nan": 50.0}), (16, 1))
    params[5, -1] = 0.3  # run 5 breaks first (once its lower disc slips), run 9 much later
    params[9, -1] = 1.8
    with pytest.raises(SimulationError, match=r"^run 5 of the batch diverged at t = ") as err:
        drillgym.simulate_batch("torsional", u=3.0, duration=2.0, params=params, effects=[nan_effect])
    assert 0.3 <= float(str(err.value).split("t = ")[1].split(" s")[0]) < 1.8
    ok = drillgym.simulate_batch("torsional", u=3.0, duration=0.2, params=params, effects=[nan_effect])
    assert np.isfinite(ok.data).all()


def test_the_stepping_simulator_raises_at_the_step_that_diverged(nan_effect: str) -> None:
    sim = BatchSimulator("torsional", n=2, effects=[nan_effect], effect_params={"t_nan": 0.1})
    sim.reset(alpha0=np.zeros(2))
    with pytest.raises(SimulationError, match=r"^run 0 of the batch diverged at t = 0\.1"):
        for _ in range(100):
            sim.advance(np.array([3.0, 3.0]), 10)
    healthy = BatchSimulator("torsional", n=1)
    healthy.reset(alpha0=np.zeros(1))
    healthy.advance(np.ones(1), 1000)
    assert np.isfinite(healthy.Y).all()
