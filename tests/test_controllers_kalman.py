"""Kalman filter on the motor angle alone: accuracy without stick-slip, tracking of stick phases."""

import numpy as np
import pytest

from controllers.kalman import I_AL, I_D, I_WL, I_WU, KalmanObserver, disturbance_model, steady_state_gain
from drillgym import RigParams, simulate
from drillgym.measurement import quantize_angle

DT = 0.01


def _estimate(u: float, duration: float):
    tr = simulate("torsional", u=u, duration=duration)
    k = int(round(DT / 1e-3))
    th = quantize_angle(tr.theta_u[::k])
    obs = KalmanObserver(disturbance_model(dt=DT))
    obs.reset(th[:1])
    est = np.empty(len(th))
    for i in range(len(th)):
        est[i] = obs.update(th[i:i + 1])[I_WL, 0]
        obs.predict(np.array([u]))
    return est, tr.omega_l[::k], tr.stick_l[::k].astype(bool)


def test_model_is_the_torsional_linearisation_with_friction_as_state():
    p = RigParams()
    m = disturbance_model(p, DT)
    assert m.Ac[I_WU, I_AL] == pytest.approx(p.ktheta / p.Ju, rel=1e-5)
    assert m.Ac[I_WU, I_WU] == pytest.approx(-(p.bu + p.dbu) / p.Ju, rel=1e-5)
    assert m.Ac[I_WL, I_AL] == pytest.approx(-p.ktheta / p.Jl, rel=1e-5)
    assert abs(m.Ac[I_WL, I_WL]) < 1e-6  # the brake's slope is not in the model: it is the state d
    assert m.Ac[I_WL, I_D] == pytest.approx(-1.0 / p.Jl)
    assert m.H.tolist() == [[1.0, 0.0, 0.0, 0.0, 0.0]]  # the motor angle only
    K, L = steady_state_gain(m)
    assert np.all(np.abs(np.linalg.eigvals(m.Ad - L @ m.H)) < 1.0)


def test_speed_estimate_without_stick_slip_within_5_percent():
    est, wl, stuck = _estimate(4.5, 40.0)  # above the fold: no stick-slip from rest
    ss = slice(len(wl) // 2, None)
    assert not stuck[ss].any()
    rms = np.sqrt(np.mean((est[ss] - wl[ss]) ** 2))
    assert rms < 0.05 * wl[ss].mean()


def test_speed_estimate_tracks_stick_phases():
    est, wl, stuck = _estimate(1.0, 40.0)  # developed stick-slip
    ss = slice(len(wl) // 4, None)
    assert stuck[ss].mean() > 0.2
    assert np.corrcoef(est[ss], wl[ss])[0, 1] > 0.95
    assert np.mean(np.abs(est[ss][stuck[ss]])) < 0.05 * wl[ss].max()  # sees the disc stand still
    assert np.max(est[ss]) > 0.8 * np.max(wl[ss])  # and the slip peaks


def test_bad_model_options_are_refused():
    with pytest.raises(ValueError, match="sigma_d"):
        disturbance_model(sigma_d=-1.0)
    with pytest.raises(ValueError, match="dt"):
        disturbance_model(dt=0.0)


def test_extended_filter_tracks_stick_slip_better_than_the_linear_one():
    from controllers.kalman import ExtendedKalmanObserver

    tr = simulate("torsional", u=1.5, duration=30.0)  # developed stick-slip
    k = int(round(DT / 1e-3))
    th, wl = quantize_angle(tr.theta_u[::k]), tr.omega_l[::k]
    errs = {}
    for name, obs in (("kf", KalmanObserver(disturbance_model(dt=DT))),
                      ("ekf", ExtendedKalmanObserver(disturbance_model(dt=DT, sigma_upper=0.01, sigma_d=0.005)))):
        obs.reset(th[:1])
        est = np.empty(len(th))
        for i in range(len(th)):
            est[i] = obs.update(th[i:i + 1])[I_WL, 0]
            obs.predict(np.array([1.5]))
        ss = slice(len(th) // 3, None)
        errs[name] = np.sqrt(np.mean((est[ss] - wl[ss]) ** 2))
    assert errs["ekf"] < 0.1 * wl.max() and errs["ekf"] < errs["kf"]
    with pytest.raises(ValueError, match="friction_known"):
        ExtendedKalmanObserver(disturbance_model(friction_known=False))
