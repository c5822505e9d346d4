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
        est[i] = obs.update(th[i : i + 1])[I_WL, 0]
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
    for name, obs in (
        ("kf", KalmanObserver(disturbance_model(dt=DT))),
        ("ekf", ExtendedKalmanObserver(disturbance_model(dt=DT, sigma_upper=0.01, sigma_d=0.005))),
    ):
        obs.reset(th[:1])
        est = np.empty(len(th))
        for i in range(len(th)):
            est[i] = obs.update(th[i : i + 1])[I_WL, 0]
            obs.predict(np.array([1.5]))
        ss = slice(len(th) // 3, None)
        errs[name] = np.sqrt(np.mean((est[ss] - wl[ss]) ** 2))
    assert errs["ekf"] < 0.1 * wl.max() and errs["ekf"] < errs["kf"]
    with pytest.raises(ValueError, match="friction_known"):
        ExtendedKalmanObserver(disturbance_model(friction_known=False))


def test_batched_extended_filter_equals_filterpy_per_trajectory():
    """The batched EKF is filterpy's KalmanFilter (predict with the model's Jacobian, Joseph update) per row."""
    from filterpy.kalman import KalmanFilter

    from controllers.kalman import ExtendedKalmanObserver

    model = disturbance_model(dt=0.002, sigma_upper=1e-3, sigma_lower=1e-3, sigma_d=1e-3)
    us = np.array([1.0, 2.0, 3.5])
    tr = [simulate("torsional", u=u, duration=4.0) for u in us]
    th = np.stack([quantize_angle(t.theta_u[::2]) for t in tr])  # (3, m) at 2 ms
    ekf = ExtendedKalmanObserver(model)
    ekf.reset(th[:, 0])
    ref = []
    for k in range(3):
        kf = KalmanFilter(dim_x=5, dim_z=1)
        kf.F, kf.H, kf.Q, kf.R = model.Ad.copy(), model.H.copy(), model.Qd.copy(), model.R.copy()
        kf.P, kf.x = ekf.P0.copy(), np.zeros((5, 1))
        kf.x[0, 0] = th[k, 0]
        ref.append(kf)
    for i in range(th.shape[1]):
        x = ekf.update(th[:, i])
        for k, kf in enumerate(ref):
            kf.update(np.array([[th[k, i]]]))
            np.testing.assert_allclose(x[:, k], kf.x[:, 0], rtol=1e-9, atol=1e-12)
            np.testing.assert_allclose(ekf.P[k], kf.P, rtol=1e-9, atol=1e-15)
        xs = x.copy()
        F = ekf.jacobians(xs, us)
        mean = model.predict_mean(xs, us)
        for k, kf in enumerate(ref):
            kf.predict(F=F[k])
            kf.x = mean[:, k : k + 1]  # nonlinear mean, linearised covariance
        ekf.predict(us)
    assert x[I_WL, 2] > 1.0  # the 3.5 V run is slipping: the comparison covered the slope term


def test_extended_filter_resets_single_rows():
    from controllers.kalman import ExtendedKalmanObserver

    ekf = ExtendedKalmanObserver(disturbance_model())
    ekf.reset(np.array([0.0, 1.0, 2.0]))
    for _ in range(50):
        ekf.update(np.array([0.0, 1.0, 2.0]))
        ekf.predict(np.array([2.0, 2.0, 2.0]))
    before = ekf.x.copy()
    ekf.reset(5.0, 0.3, index=np.array([1]))
    assert ekf.x[0, 1] == 5.0 and ekf.x[I_AL, 1] == 0.3 and ekf.x[I_WU, 1] == 0.0
    np.testing.assert_array_equal(ekf.x[:, [0, 2]], before[:, [0, 2]])
    np.testing.assert_array_equal(ekf.P[1], ekf.P0)


@pytest.mark.parametrize("factor", [0.8, 1.2])
def test_scale_disturbance_estimates_the_brake_level(factor):
    """A brake 20 % off its identified level (Ts, Tc, bb scaled, as with the oil's temperature): the
    'scale' state converges to the factor - 1 from the motor angle alone, omega_l stays right."""
    from controllers.kalman import ExtendedKalmanObserver

    p = RigParams()
    tr = simulate("torsional", u=4.0, duration=20.0, params=p.scaled(Ts=factor, Tc=factor, bb=factor))
    th = quantize_angle(tr.theta_u[::2])
    ekf = ExtendedKalmanObserver(
        disturbance_model(p, 0.002, sigma_d=0.01, sigma_upper=1e-3, sigma_lower=1e-3, disturbance="scale")
    )
    ekf.reset(th[:1])
    for i in range(len(th)):
        x = ekf.update(th[i : i + 1])
        ekf.predict(np.array([4.0]))
    assert x[I_D, 0] == pytest.approx(factor - 1.0, abs=0.02)
    assert x[I_WL, 0] == pytest.approx(tr.omega_l[-1], abs=0.02)
    with pytest.raises(ValueError, match="disturbance"):
        disturbance_model(disturbance="ratio")
