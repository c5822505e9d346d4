"""R7-R9 of docs/model.md from simulation: stick-slip from rest, RK4 switch model, dt = 1 ms, 120 s."""

import numpy as np
import pytest

from drillgym import simulate_batch


def steady_swing(config, voltages, duration=120.0, window=20.0):
    """Peak-to-peak of omega_l over the last `window` s and the stuck fraction there."""
    b = simulate_batch(config, np.asarray(voltages, dtype=float), duration, record_every=10, parallel=True)
    n = int(window / (10 * 1e-3))
    w = b.omega_l[:, -n:]
    return np.ptp(w, axis=1), b.stick_l[:, -n:].mean(axis=1)


def test_r7_torsional_second_fold():
    swing, stuck = steady_swing("torsional", [3.7, 3.8, 3.9, 4.0])
    assert swing[0] > 5 and stuck[0] > 0 and swing[1] > 5 and stuck[1] > 0  # stick-slip at 3.7, 3.8 V
    assert swing[2] < 1e-3 and swing[3] < 1e-3 and stuck[2] == 0 and stuck[3] == 0  # none at 3.9, 4.0 V


def test_r8_coupled_second_fold_lies_lower():
    swing, stuck = steady_swing("coupled", [3.4, 3.5, 3.6, 3.7])
    assert swing[0] > 5 and stuck[0] > 0 and swing[1] > 5 and stuck[1] > 0  # stick-slip at 3.4, 3.5 V
    assert swing[2] < 1e-3 and swing[3] < 1e-3  # none at 3.6, 3.7 V: lateral motion shrinks the region


@pytest.mark.parametrize("config", ["torsional", "coupled"])
def test_r9_stick_slip_from_rest_from_0p3_volt_up(config):
    volts = [0.3, 0.6, 1.0, 1.5, 2.0, 2.5, 3.0, 3.4]
    swing, stuck = steady_swing(config, volts, duration=90.0)
    assert np.all(stuck > 0.01), dict(zip(volts, stuck))
    assert np.all(swing > 2.0)
