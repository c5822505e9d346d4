"""Integrators: convergence, RK4 against DP5, batch against single runs, input handling."""

import numpy as np
import pytest

from drillgym import BatchSimulator, RigParams, initial_state, simulate, simulate_batch


def test_rk4_converges_on_a_stick_slip_cycle():
    coarse = simulate("torsional", 1.0, 20.0, dt=1e-3)
    fine = simulate("torsional", 1.0, 20.0, dt=2.5e-4, record_every=4)
    assert np.max(np.abs(coarse.omega_l - fine.omega_l)) < 1e-6
    assert np.max(np.abs(coarse.theta_l - fine.theta_l)) < 1e-7


def test_dp5_agrees_with_rk4():
    rk4 = simulate("coupled", 2.0, 10.0, method="rk4")
    dp5 = simulate("coupled", 2.0, 10.0, method="dp5")
    assert np.max(np.abs(rk4.omega_l - dp5.omega_l)) < 1e-6
    assert np.max(np.abs(rk4.r - dp5.r)) < 1e-9
    with pytest.raises(ValueError, match="unknown integration method"):
        simulate("torsional", 1.0, 1.0, method="euler")


def test_batch_equals_single_runs():
    params = [RigParams(), RigParams().scaled(Ts=1.1, Tc=1.1)]
    u = np.stack([np.full(5000, 1.0), np.linspace(0, 3, 5000)])
    batch = simulate_batch("torsional", u, 5.0, params=params, alpha0=[0.0, 0.3])
    for k in range(2):
        single = simulate("torsional", u[k], 5.0, params=params[k], alpha0=[0.0, 0.3][k])
        np.testing.assert_allclose(batch.data[k], single.data, rtol=0, atol=1e-12)
    serial = simulate_batch("torsional", u, 5.0, params=params, alpha0=[0.0, 0.3])
    parallel = simulate_batch("torsional", u, 5.0, params=params, alpha0=[0.0, 0.3], parallel=True)
    np.testing.assert_array_equal(serial.data, parallel.data)


def test_stepping_interface_matches_simulate():
    sim = BatchSimulator("coupled", n=2)
    sim.reset(alpha0=np.array([0.0, 0.2]))
    for _ in range(300):
        sim.advance(np.array([2.0, 2.0]), n_steps=10)
    ref = simulate("coupled", 2.0, 3.0, alpha0=0.2)
    np.testing.assert_allclose(sim.Y[1], ref.final_state, rtol=0, atol=1e-12)
    assert sim.T[1] == pytest.approx(3.0)


def test_signal_input_is_zero_order_hold():
    t = np.array([0.0, 1.0, 2.0])
    u = np.array([0.0, 2.0, 1.0])
    tr = simulate("upper", (t, u), 3.0)
    assert tr.u[500] == 0.0 and tr.u[1500] == 2.0 and tr.u[2500] == 1.0


@pytest.mark.slow
def test_table_input_is_evaluated_in_the_kernel_as_its_per_step_expansion():
    """A (t, u) table stays m entries (never expanded per step) and gives the runs of the per-step
    sequence it stands for (entries before 0, between and on grid points, repeated times), on the
    scalar kernel and on the lanes."""
    from drillgym.simulator import _input_matrix

    ts = np.array([-1.0, 0.0, 0.5, 0.5, 1.0005, 2.0, 2.9999999, 3.0000000001])
    us = np.array([9.0, 1.0, 2.0, 3.0, 0.5, 4.0, 2.5, 1.5])
    n, dt = 4000, 1e-3
    U, first = _input_matrix((ts, us), 8, n, dt)
    assert U.shape == (8, ts.size)
    per_step = us[np.clip(np.searchsorted(ts, np.arange(n) * dt + 1e-12 * dt, side="right") - 1, 0, ts.size - 1)]
    one = simulate("torsional", (ts, us), 4.0, record=("u", "omega_l"))
    np.testing.assert_array_equal(one.data, simulate("torsional", per_step, 4.0, record=("u", "omega_l")).data)
    lanes = simulate_batch("torsional", (ts, us), 4.0, n_batch=8, record=("u", "omega_l"))
    np.testing.assert_array_equal(lanes.data[5], one.data)


def test_bad_inputs_are_refused_with_a_clear_error():
    with pytest.raises(ValueError, match="NaN/inf"):
        simulate("torsional", np.full(1000, np.nan), 1.0)
    with pytest.raises(ValueError, match="unknown configuration 'sideways'"):
        simulate("sideways", 1.0, 1.0)
    with pytest.raises(ValueError, match="duration"):
        simulate("torsional", 1.0, -1.0)
    with pytest.raises(ValueError, match="initial state"):
        simulate("torsional", 1.0, 1.0, x0=np.full(9, np.nan))
    with pytest.raises(ValueError, match="needs 1000"):
        simulate("torsional", np.ones(10), 1.0)


def test_any_voltage_is_accepted_by_the_model():
    tr = simulate("lateral", 50.0, 3.0)
    assert tr.omega_l[-1] > 20.0  # no amplifier limit in the model


def test_free_vibration_keeps_upper_disc_clamped():
    p = RigParams()
    tr = simulate("free_vibration", 0.0, 20.0, alpha0=1.0)
    assert np.all(tr.theta_u == 0.0)
    # lightly damped oscillation at sqrt(ktheta/Jl): speed reversals every half period
    crossings = np.flatnonzero(np.diff(np.sign(tr.omega_l)) != 0)
    period = 2 * np.mean(np.diff(tr.t[crossings[:4]]))
    assert period == pytest.approx(2 * np.pi / np.sqrt(p.ktheta / p.Jl), rel=0.02)
    assert abs(tr.theta_l[-1]) < 0.5


def test_motor_lag_and_input_delay_effects_act():
    step = lambda t: np.where(t >= 0.2, 2.0, 0.0)  # noqa: E731
    base = simulate("upper", step, 1.0)
    lag = simulate("upper", step, 1.0, effects=["motor_lag"], effect_params={"tau_m": 0.1})
    delay = simulate("upper", step, 1.0, effects=["input_delay"], effect_params={"delay": 0.1})
    assert lag.omega_u[300] < base.omega_u[300]
    # before the start the first command was held (as for the delay line): a constant command has no lag
    held = simulate("upper", 2.0, 1.0, effects=["motor_lag"], effect_params={"tau_m": 0.1})
    assert held.u_m[0] == 2.0 and np.array_equal(held.omega_u, simulate("upper", 2.0, 1.0).omega_u)
    assert np.all(delay.omega_u[:300] == 0.0) and delay.omega_u[350] > 0
    assert delay.u[200] == 2.0 and delay.u[199] == 0.0  # the record keeps the commanded voltage
    assert initial_state(alpha0=0.5)[1] == 0.5


def test_motor_lag_far_below_the_step_is_stable_and_exact():
    """The lag state is integrated exactly over each step (MotorLag.lag): tau_m = 1e-4 s at dt = 1 ms
    (explicit RK4 diverges below about 0.36 dt) stays finite, its state follows the input exactly,
    the run tends to the model without the lag, and a batch (lane kernel) gives the scalar run."""
    u = lambda t: np.where(t > 0.4999, 3.0, 1.0)  # noqa: E731  (a step on the grid)
    fx = dict(effects=["motor_lag"], effect_params={"tau_m": 1e-4})
    lag = simulate("torsional", u, 1.5, **fx)
    base = simulate("torsional", u, 1.5)
    assert np.all(np.isfinite(lag.data))
    # u_m(t) = u + (u_m0 - u) exp(-(t - 0.5)/tau): at the grid points after the step it is u to 1e-4
    assert lag.u_m[499] == pytest.approx(1.0) and abs(lag.u_m[501] - 3.0) < 1e-4
    assert np.max(np.abs(lag.omega_l - base.omega_l)) < 5e-3  # O(tau) away from the lag-free model
    batch = simulate_batch("torsional", np.full(8, 2.0), 1.5, **fx)
    np.testing.assert_allclose(batch[3].omega_u, simulate("torsional", 2.0, 1.5, **fx).omega_u, rtol=0, atol=1e-9)
    # a slow lag keeps RK4's accuracy: dt = 1 ms against dt = 0.25 ms
    slow = dict(effects=["motor_lag"], effect_params={"tau_m": 0.02})
    coarse = simulate("torsional", u, 1.5, **slow)
    fine = simulate("torsional", u, 1.5, dt=2.5e-4, record_every=4, **slow)
    assert np.max(np.abs(coarse.omega_l - fine.omega_l)) < 1e-8


def test_simd_lane_kernel_matches_scalar_kernel():
    """Batches of the diagonal-mass configurations run on the SIMD lane kernel; the scalar kernel
    (used for single runs) must give the same runs, events included."""
    from drillgym.simulator import LANES_MIN_BATCH

    volts = np.linspace(0.2, 4.5, LANES_MIN_BATCH * 2)
    alphas = np.linspace(-2.0, 2.0, volts.size)
    for config in ("torsional", "coupled", "lateral"):
        batch = simulate_batch(config, volts, 30.0, alpha0=alphas, record_every=10)
        for k in (0, 5, 11, 15):
            single = simulate(config, volts[k], 30.0, alpha0=alphas[k], record_every=10)
            np.testing.assert_allclose(batch.data[k], single.data, rtol=0, atol=1e-8)
            np.testing.assert_array_equal(batch.stick_l[k], single.stick_l)
        if config != "lateral":
            assert batch.stick_l.mean() > 0.05  # many stick/slip events were crossed


@pytest.mark.slow
def test_adaptive_dp45_matches_the_fixed_step_run_events_included():
    """method='dp45' (adaptive steps between located events, outputs on the grid) gives the fine
    fixed-step run: same stick pattern, speeds within 1e-6 rad/s, also across command changes."""
    u = (np.array([0.0, 12.0, 20.0]), np.array([1.0, 3.0, 0.6]))  # stick-slip, steady slip, back
    fine = simulate("torsional", u, 30.0, dt=2.5e-4, record_every=4)
    ad = simulate("torsional", u, 30.0, method="dp45")
    assert ad.t.shape == fine.t.shape and np.array_equal(ad.u, fine.u)
    np.testing.assert_array_equal(ad.stick_l, fine.stick_l)
    assert fine.stick_l.mean() > 0.1  # many stick phases were located
    assert np.max(np.abs(ad.omega_l - fine.omega_l)) < 1e-6
    assert np.max(np.abs(ad.Tfl - fine.Tfl)) < 1e-6
    part = simulate("coupled", 2.0, 10.0, method="dp45", record=("omega_l", "r"), record_every=8)
    ref = simulate("coupled", 2.0, 10.0, dt=2.5e-4, record_every=32)
    assert np.max(np.abs(part.omega_l - ref.omega_l)) < 1e-6 and np.max(np.abs(part.r - ref.r)) < 1e-9
    with pytest.raises(ValueError, match="fixed grid"):
        BatchSimulator("torsional", 8, method="dp45")


def test_fixed_step_paths_refuse_the_adaptive_method():
    from drillgym.integrators import fixed_step_tableau

    with pytest.raises(ValueError, match="dp45.*adaptive"):
        fixed_step_tableau("dp45", "identification")
    assert [len(fixed_step_tableau(m, "x")) for m in ("rk4", "dp5")] == [3, 3]


def test_lane_chunks_are_whole_vector_blocks():
    """Every chunk of a lane-kernel call starts on a block boundary and is padded to whole blocks."""
    from drillgym.simulator import LANE_BLOCK, lane_chunks

    for n in (8, 15, 16, 17, 33, 100):
        for parallel in (False, True):
            chunks = lane_chunks(n, parallel)
            assert chunks[0][0] == 0 and chunks[-1][1] == n
            assert all(a[1] == b[0] for a, b in zip(chunks, chunks[1:]))
            assert all(lo % LANE_BLOCK == 0 and w % LANE_BLOCK == 0 and hi - lo <= w for lo, hi, w in chunks)
    assert len(lane_chunks(100, False)) == 1


_INVARIANCE_CHECK = """
import numpy as np
from drillgym import BatchSimulator, simulate_batch

volts = np.linspace(0.6, 4.0, 70)
ref = simulate_batch("coupled", volts[:32], 8.0, record_every=10, parallel=False)
assert ref.stick_l.mean() > 0.01  # events were crossed
for n, parallel in ((9, True), (17, False), (40, True), (70, False)):
    batch = simulate_batch("coupled", volts[:n], 8.0, record_every=10, parallel=parallel)
    np.testing.assert_array_equal(batch.data[:9], ref.data[:9])
states = []
for n in (9, 40):
    sim = BatchSimulator("coupled", n)
    sim.advance(volts[:n], 4000)
    sim.advance(4.6 - volts[:n], 4000)  # a second command, per lane its own
    states.append(sim.Y[:9].copy())
np.testing.assert_array_equal(states[0], states[1])
print("invariant")
"""


def test_a_lane_does_not_depend_on_the_batch_around_it(tmp_path):
    """The same trajectory is bit-identical whatever the batch size, its place in the batch and the chunking
    over cores, in simulate_batch and in BatchSimulator (every lane runs the vectorised loop bodies; no
    remainder).  Checked for the kernels compiled with drillgym's default CPU settings (the host's features,
    full vector width), in a fresh process: a process keeps the kernels it compiled first, and another test
    here compiles under other settings (NUMBA_CPU_FEATURES=+avx2, no FMA), for which it is not guaranteed.
    The process compiles all of them itself (a kernel cache of its own): a kernel compiled in the running
    process and the same one loaded from numba's disk cache can differ by ~1e-12 (docs/CORE_API.md), and on a
    fresh machine the earlier tests leave some of the variants used here cached and others not."""
    import os
    import subprocess
    import sys

    import llvmlite.binding as ll

    from drillgym._simd import full_width_features

    ll.initialize_native_target()
    if full_width_features(ll.get_host_cpu_features().flatten()) is None:
        pytest.skip("host without AVX-512: lane invariance checked on AVX-512 hosts only")
    env = {k: v for k, v in os.environ.items() if k not in ("DRILLGYM_SIMD", "NUMBA_CPU_FEATURES", "NUMBA_CPU_NAME")}
    env["DRILLGYM_KERNEL_CACHE"] = str(tmp_path / "kernels")
    p = subprocess.run([sys.executable, "-c", _INVARIANCE_CHECK], env=env, capture_output=True, text=True, timeout=600)
    assert p.returncode == 0 and "invariant" in p.stdout, p.stderr[-2000:]


def test_the_lvdt_lowpass_is_scipys_sosfiltfilt_sample_for_sample():
    """The offline zero-phase low-pass of the predictions (compiled, without the GIL) gives scipy's
    ``sosfiltfilt`` bit for bit: short segments just past the padding, long ones, a row with a NaN."""
    from scipy import signal

    from drillgym.measurement import lowpass_zero_phase

    rng = np.random.default_rng(3)
    for shape, fs in (((272, 201), 50.0), ((3, 16), 50.0), ((2, 4000), 1000.0), ((40,), 50.0)):
        x = np.cumsum(rng.standard_normal(shape), axis=-1) * 1e-4
        if len(shape) == 2:
            x[0, 7] = np.nan
        ref = signal.sosfiltfilt(signal.butter(4, 5.0, fs=fs, output="sos"), x, axis=-1)
        assert np.array_equal(lowpass_zero_phase(x, fs, 5.0), ref, equal_nan=True)
    assert np.array_equal(lowpass_zero_phase(x, 8.0, 5.0), x)  # cut-off above Nyquist: unfiltered


_FORKED_CHUNKS = """
import multiprocessing as mp
import numpy as np
from drillgym import simulate_batch

def run(n):
    return float(simulate_batch("torsional", np.linspace(1.0, 3.0, n), 1.0, parallel=True).data[-1, -1, 2])

first = run(80)  # the parent's chunk threads are started
with mp.get_context("fork").Pool(1) as pool:
    child = pool.apply_async(run, (80,)).get(timeout=120)
assert child == first
print("forked ok")
"""


def test_a_forked_process_runs_the_lane_chunks_on_threads_of_its_own():
    """The lane kernel's chunk threads are started once per process; a child forked after the parent started
    them (a process pool of the harness) does not have them and starts its own instead of waiting forever."""
    import subprocess
    import sys

    p = subprocess.run([sys.executable, "-c", _FORKED_CHUNKS], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0 and "forked ok" in p.stdout, p.stderr[-2000:]
