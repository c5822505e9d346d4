"""The contract of the Python entry points, over combinations of their arguments (Hypothesis).

``drillgym.simulate``, ``drillgym.simulate_batch`` and ``gymnasium.make`` of a drillgym environment, called with
several arguments drawn at once, each valid or not (wrong types, NaN, inf, negative, zero, out of range, unknown
names, settings that contradict each other): either a result whose numbers are finite, or a
:class:`drillgym.errors.DrillgymError` with a message; never another exception (a ``TypeError``,
``ZeroDivisionError``, ``OverflowError`` from deep inside), never a NaN result.
"""

from __future__ import annotations

import math
import os
from contextlib import contextmanager

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

import drillgym
from drillgym.errors import DrillgymError

pytestmark = pytest.mark.xdist_group("contract_api")

NAN, INF = float("nan"), float("inf")


def examples(n: int):
    return settings(
        derandomize=True,
        deadline=None,
        max_examples=n,
        database=None,
        phases=[Phase.explicit, Phase.generate],
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
    )


def draw_arguments(data, table: dict[str, tuple[list, list]], at_most: int = 3) -> dict:
    """Each argument of ``table`` (name -> (valid values, bad values)) left out, valid, or bad: at least one bad,
    at most ``at_most`` set."""
    names = data.draw(st.lists(st.sampled_from(sorted(table)), min_size=1, max_size=at_most, unique=True))
    kw = {}
    for i, name in enumerate(names):
        valid, bad = table[name]
        pool = bad if i == 0 or not valid else valid + bad
        kw[name] = data.draw(st.sampled_from(pool), label=name)
    return kw


@contextmanager
def surveyed(what: str, kw: dict):
    """With ``CONTRACT_LOG`` set, a failing call is logged there instead of failing (a survey in one run)."""
    log = os.environ.get("CONTRACT_LOG")
    try:
        yield
    except Exception as exc:
        if not log:
            raise
        with open(log, "a", encoding="utf-8") as fh:
            fh.write(f"{what}({kw!r}): {type(exc).__name__}: {' '.join(str(exc).split())[:300]}\n")


def refused_well(exc: DrillgymError) -> None:
    msg = " ".join(str(exc).split())
    assert msg and "Traceback" not in msg, repr(exc)
    assert "np.float64" not in msg, msg


def finite(*arrays) -> None:
    for a in arrays:
        a = np.asarray(a, dtype=float)
        assert a.size and np.isfinite(a).all(), "a non-finite result"


# --------------------------------------------------------------------------------------- simulate

SIMULATE = {
    "config": (["torsional", "upper", "coupled"], ["nope", "", None, 3, "free_vibration"]),
    "u": ([0.0, 1.0, 3.0, -2.0], [NAN, INF, "abc", None, 1e6, [1.0, NAN], np.array([1.0, 2.0])]),
    "duration": ([0.05, 0.1], [0.0, -1.0, NAN, INF, "1", None, 1e308]),
    "dt": ([1e-3, 5e-4], [0.0, -1e-3, NAN, 0.03, 1.0, "x", 1e-300]),
    "alpha0": ([0.0, 0.5], [NAN, INF, 1e9, "a"]),
    "method": (["rk4", "dp5"], ["nope", "", None]),
    "record_every": ([1, 5], [0, -1, 1.5, "2", 7, 10**30]),
    "friction": (["exact", "smooth"], ["nope", None]),
    "smooth_eps": ([1e-3], [0.0, -1.0, NAN, INF]),
    "effects": ([None, ["motor_lag"]], [["nope"], "nope", 3, ["lateral_anisotropy"], [None]]),
    "effect_params": ([None], [{"tau_m": NAN}, {"nope": 1.0}, {"tau_m": -1.0}, {"tau_m": "a"}, [1, 2]]),
    "record": ([None, ["theta_u"]], [["nope"], "theta_u", [3], []]),
    "rtol": ([1e-9], [0.0, -1.0, NAN, INF]),
    "x0": ([None], [np.full(4, NAN), np.zeros(2), "x", np.full(8, 1e308)]),
}


@examples(int(os.environ.get("CONTRACT_EXAMPLES", 40)))
@given(data=st.data())
def test_simulate_keeps_the_contract(data):
    kw = {"config": "torsional", "u": 3.0, "duration": 0.05, "dt": 1e-3}
    kw.update(draw_arguments(data, SIMULATE))
    with surveyed("simulate", dict(kw)):
        try:
            traj = drillgym.simulate(kw.pop("config"), kw.pop("u"), kw.pop("duration"), **kw)
        except DrillgymError as exc:
            refused_well(exc)
            return
        finite(traj.data)


SIMULATE_BATCH = {
    **SIMULATE,
    "n_batch": ([None, 2], [0, -1, 1.5, "2", NAN]),
    "alpha0": ([0.0, [0.0, 0.1]], [NAN, [0.0, NAN], [0.0, 0.1, 0.2, 0.3, 0.4], "a"]),
    "t0": ([0.0], [NAN, -1.0, INF, [0.0, NAN]]),
    "params": ([None], [[{"Jl": NAN}], {"Jl": -1.0}, "nope", [None, 3]]),
    "parallel": ([False], ["yes", None]),
}


@examples(int(os.environ.get("CONTRACT_EXAMPLES", 30)))
@given(data=st.data())
def test_simulate_batch_keeps_the_contract(data):
    kw = {"config": "torsional", "u": 3.0, "duration": 0.05, "dt": 1e-3, "n_batch": 2}
    kw.update(draw_arguments(data, SIMULATE_BATCH))
    with surveyed("simulate_batch", dict(kw)):
        try:
            traj = drillgym.simulate_batch(kw.pop("config"), kw.pop("u"), kw.pop("duration"), **kw)
        except DrillgymError as exc:
            refused_well(exc)
            return
        finite(traj.data)


# --------------------------------------------------------------------------------------- gymnasium.make

ENV = {
    "omega_ref": ([2.0, None], [NAN, INF, -1.0, "abc", 1e9, 0.0]),
    "episode_duration": ([0.5], [0.0, -1.0, NAN, "abc", INF]),
    "control_dt": ([0.01, 0.02], [0.0, -0.01, NAN, 10.0, 1e-9]),
    "observation": (["full", "sensors", "motor"], ["nope", "", 3]),
    "randomize": ([0.0, 0.1], [-0.5, NAN, 2.0]),
    "effects": ([None, ["motor_lag"]], [["nope"], ["lateral_anisotropy"], "x"]),
    "effect_params": ([None], [{"tau_m": NAN}, {"nope": 1.0}]),
    "normalize_action": ([True, False], ["yes"]),
    "nope_kwarg": ([], [1]),
}


@examples(int(os.environ.get("CONTRACT_EXAMPLES", 25)))
@given(data=st.data())
def test_gymnasium_make_keeps_the_contract(data):
    import gymnasium

    import drillgym.envs  # noqa: F401  (registers the ids)

    kw = draw_arguments(data, ENV)
    env_id = data.draw(st.sampled_from(["drillgym/Torsional-v0", "drillgym/Coupled-v0"]), label="id")
    with surveyed(f"gymnasium.make({env_id!r})", dict(kw)):
        try:
            env = gymnasium.make(env_id, **kw)
        except DrillgymError as exc:
            refused_well(exc)
            return
        try:
            obs, _ = env.reset(seed=0)
            finite(obs)
            obs, reward, *_ = env.step(env.action_space.sample() * 0)
            finite(obs)
            assert math.isfinite(float(reward))
        except DrillgymError as exc:  # refused as the episode starts: allowed, a message
            refused_well(exc)
        finally:
            env.close()
