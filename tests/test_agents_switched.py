"""Target-switched policies (agents/switched.py): learned networks chosen by the target speed."""

from __future__ import annotations

import json

import numpy as np
import pytest

import agents
from agents.controller import AgentController, TargetSwitchedController
from agents.export import ExportedPolicy
from agents.switched import TargetSwitchedPolicy, combine, read_policy
from controllers.evaluation import SCENARIOS, run_job
from drillgym.measurement import quantize_angle

POLICIES = agents.KEPT_POLICY.parents[1]
NOMINAL = POLICIES / "torsional_motor_learned_nominal" / "policy.npz"
ROBUST = POLICIES / "torsional_motor_learned_robust" / "policy.npz"
SWITCHED = POLICIES / "torsional_motor_learned" / "policy.npz"


def test_a_combined_file_keeps_each_network_and_its_band(tmp_path) -> None:
    path = combine([NOMINAL, ROBUST], [3.0], tmp_path / "sw" / "policy.npz", note="why")
    assert isinstance(read_policy(NOMINAL), ExportedPolicy)  # a single network stays one
    with pytest.raises(FileNotFoundError, match="missing.npz"):
        read_policy(tmp_path / "missing.npz")
    sw = agents.load_policy(str(path))
    assert isinstance(sw, TargetSwitchedPolicy) and sw.edges == (3.0,) and sw.note == "why"
    assert list(sw.member_of([1.0, 2.999, 3.0, 8.0])) == [0, 0, 1, 1]
    obs = np.random.default_rng(0).normal(size=(5, sw.members[0].obs_dim)).astype(np.float32)
    for member, original in zip(sw.members, (NOMINAL, ROBUST)):
        np.testing.assert_array_equal(member.act(obs), ExportedPolicy.load(original).act(obs))
        assert member.config == ExportedPolicy.load(original).config
    with pytest.raises(ValueError, match="target-switched"):
        ExportedPolicy.load(path)  # a single-network loader names what the file is


@pytest.mark.parametrize(
    "edges, match",
    [([], "need 1 target edge"), ([3.0, 4.0], "need 1 target edge"), ([-1.0], "positive"), ([float("nan")], "finite")],
)
def test_bad_bands_are_refused_with_the_reason(tmp_path, edges, match) -> None:
    with pytest.raises(ValueError, match=match):
        combine([NOMINAL, ROBUST], edges, tmp_path / "x.npz")
    assert not (tmp_path / "x.npz").exists()


def test_networks_that_cannot_share_one_rig_loop_are_refused() -> None:
    low, high = ExportedPolicy.load(NOMINAL), ExportedPolicy.load(ROBUST)
    meta = json.loads(json.dumps(high.meta))
    meta["config"]["hyperparams"].setdefault("env_kwargs", {})["control_dt"] = 0.02
    slow = ExportedPolicy.from_arrays(meta, high.to_arrays())
    with pytest.raises(ValueError, match="different control periods"):
        TargetSwitchedPolicy([low, slow], [3.0])
    meta = json.loads(json.dumps(high.meta))
    meta["config"]["env_id"] = "drillgym/Coupled-v0"
    with pytest.raises(ValueError, match="different environments"):
        TargetSwitchedPolicy([low, ExportedPolicy.from_arrays(meta, high.to_arrays())], [3.0])


def test_each_rig_runs_the_network_of_its_target_exactly_as_alone(tmp_path) -> None:
    """Four rigs with targets in both bands: every voltage equals that of the band's network run alone on
    that rig's readings (its own observation history, command schedule and integral)."""
    path = combine([NOMINAL, ROBUST], [3.0], tmp_path / "policy.npz")
    targets = np.array([2.0, 4.0, 2.5, 3.0])
    both = TargetSwitchedController(agents.load_policy(str(path)), config="torsional")
    alone = [AgentController(ExportedPolicy.load(NOMINAL if w < 3.0 else ROBUST), config="torsional") for w in targets]
    both.reset({"t": np.zeros(4), "theta_u": np.zeros(4), "omega_ref": targets})
    for i, c in enumerate(alone):
        c.reset({"t": 0.0, "theta_u": 0.0, "omega_ref": float(targets[i])})
    rng = np.random.default_rng(1)
    theta = np.zeros(4)
    for k in range(300):
        theta = theta + 0.01 * (targets + 0.5 * rng.normal(size=4))
        meas = quantize_angle(theta, 2000)
        u = both({"t": np.full(4, 0.01 * k), "theta_u": meas})
        u_alone = [c({"t": 0.01 * k, "theta_u": float(meas[i])}) for i, c in enumerate(alone)]
        np.testing.assert_allclose(u, u_alone, rtol=0, atol=1e-4)  # float32 sums in other batch shapes
    assert np.ptp(u) > 0.05  # the networks answer differently: a wrong routing could not pass


def test_kept_switched_policy_holds_both_bands_on_the_simulated_rig() -> None:
    """The kept policy: 2.5 rad/s on the nominal rig from rest (the nominal-trained network's band) and
    3.5 rad/s with the brake 20 % weaker (the population-trained network's), where the open loop sticks."""
    assert isinstance(read_policy(SWITCHED), TargetSwitchedPolicy)
    low = run_job(f"agent:{SWITCHED}", "torsional", SCENARIOS["rest"], [2.5], duration=60.0, window=20.0)[0]
    high, base = (
        run_job(c, "torsional", SCENARIOS["friction-20"], [3.5], duration=60.0, window=20.0)[0]
        for c in (f"agent:{SWITCHED}", "baseline")
    )
    assert low["ssi"] < 0.1 and abs(low["offset"]) < 0.1
    assert base["ssi"] > 1.0 and high["ssi"] < 0.1 and abs(high["offset"]) < 0.1
