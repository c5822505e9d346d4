"""Closed loop: the observer-based controller removes stick-slip where the open-loop baseline cannot."""

import numpy as np

import controllers
from controllers.evaluation import run_closed_loop, run_metrics


def test_observer_removes_stick_slip_from_rest_at_3_rad_s_where_baseline_cannot():
    out = {}
    for name in ("baseline", "observer"):
        c = controllers.make(name, config="torsional", omega_ref=3.0)
        run = run_closed_loop(c, "torsional", np.array([3.0]), 40.0)
        out[name] = run_metrics(run, 15.0)
    assert out["baseline"]["ssi"][0] > 0.5 and out["baseline"]["stuck"][0] > 0.1
    assert out["observer"]["ssi"][0] < 0.1 and out["observer"]["stuck"][0] == 0.0
    assert out["observer"]["tracking_rms"][0] < 0.1
    assert out["observer"]["u_peak"][0] <= 5.0


def test_observer_holds_2_rad_s_from_rest_where_baseline_cannot():
    """The feedback-linearising observer controller: lowest stick-slip-free target reached (torsional)."""
    tg = np.array([2.0, 2.5])
    out = {}
    for name in ("baseline", "observer"):
        run = run_closed_loop(controllers.make(name, config="torsional", omega_ref=tg), "torsional", tg, 45.0)
        out[name] = run_metrics(run, 15.0)
    assert np.all(out["baseline"]["ssi"] > 0.5)
    assert np.all(out["observer"]["ssi"] < 0.1) and np.all(out["observer"]["stuck"] == 0.0)
    assert np.all(np.abs(out["observer"]["omega_l_max"] - tg) < 0.2)


def test_observer_reads_only_the_motor_angle():
    for name in ("observer", "lqg", "pi", "softtorque"):
        assert controllers.CONTROLLERS[name].uses == ("theta_u",)
    assert controllers.CONTROLLERS["baseline"].uses == ()
