"""Fits on threads share their lane-kernel calls (drillgym.identification.lane_batch): the same outputs, bit for bit,
as each run alone, in fewer kernel calls, with delay lines of different lengths joined."""

import numpy as np
import pytest

from drillgym import RigParams
from drillgym.effects import compose
from drillgym.errors import InputError
from drillgym.identification import lane_batch
from drillgym.identification.experiment import prepare_experiment
from drillgym.identification.segmented import SegmentedModel
from drillgym.identification.synthetic import synthetic_measurement


@pytest.fixture(scope="module")
def setting():
    ts = synthetic_measurement("torsional", duration=12.0, rate_hz=200.0, signal="steps", seed=3)
    ex = prepare_experiment(ts, compare_rate_hz=50.0)
    comp, _ = compose(["motor_lag", "input_delay"], {"tau_m": 0.02, "delay": 0.01})
    # per job, two parameter rows: delays of 4 ms to 40 ms, so that the jobs' delay lines differ in length
    rows = [
        np.stack([comp.vector(RigParams(), {"tau_m": t, "delay": d}) for t in (0.01, 0.03)])
        for d in (0.004, 0.012, 0.04)
    ]
    return ex, comp, rows


def _predict(ex, comp, P):
    return SegmentedModel([ex], 1.0, composition=comp).predict_arrays(P)[0]


def test_shared_runs_are_the_runs_alone_bit_for_bit_in_fewer_calls(setting, monkeypatch):
    ex, comp, rows = setting
    alone = [_predict(ex, comp, P) for P in rows]
    calls = []
    run_alone = lane_batch.LaneRequest.run_alone
    monkeypatch.setattr(lane_batch.LaneRequest, "run_alone", lambda self: (calls.append(self.n), run_alone(self))[1])
    shared = lane_batch.run_jobs([lambda P=P: _predict(ex, comp, P) for P in rows], workers=3)
    # every job's lanes ran (each job one request), at least two jobs' in one kernel call
    assert 0 < len(calls) < len(rows) and sum(calls) == sum(
        P.shape[0] * len(a["theta_u"][0]) for P, a in zip(rows, alone)
    )
    for a, b in zip(alone, shared, strict=True):
        assert a.keys() == b.keys()
        for c in a:
            np.testing.assert_array_equal(a[c], b[c], err_msg=c)


def test_a_job_error_reaches_the_caller_and_the_other_jobs_finish(setting):
    ex, comp, rows = setting

    def broken():
        raise RuntimeError("a bug inside a fit")

    with pytest.raises(RuntimeError, match="a bug inside a fit"):
        lane_batch.run_jobs([lambda: _predict(ex, comp, rows[0]), broken, lambda: _predict(ex, comp, rows[1])], 3)


def test_delay_lines_of_different_widths_without_a_delay_effect_are_refused():
    """Lines are lengthened at their old end only where the kernel never reads them: a line without a Delay
    effect (head < 0) has no such end."""
    lanes = lambda width, head: (None, None, None, None, np.zeros((2, width)), np.full(2, head), None)  # noqa: E731
    short = lane_batch.LaneRequest("k", None, lanes(3, -1), (), (1, 1))
    long = lane_batch.LaneRequest("k", None, lanes(5, -1), (), (1, 1))
    with pytest.raises(InputError, match="without a Delay effect"):
        lane_batch._delay_lines_of_width([short, long])
