"""Excitation signals: band limit, range, seeding, input-file round trip, errors."""

import numpy as np
import pytest

from drillgym.errors import DataFormatError
from drillgym.signals import quasi_random, read_input_file, sum_of_sines, write_input_file
from drillgym.simulator import simulate


@pytest.mark.parametrize("gen", [quasi_random, sum_of_sines])
def test_signal_inside_range_and_below_5_hz(gen):
    t, u = gen(60.0, rate_hz=200.0, seed=3)
    assert np.max(np.abs(u)) <= 5.0 + 1e-12
    assert np.max(np.abs(u)) > 3.0  # uses the range
    assert u[0] == 0.0  # fades in from rest
    spec = np.abs(np.fft.rfft(u - u.mean())) ** 2
    f = np.fft.rfftfreq(len(u), 1 / 200.0)
    assert spec[f > 5.5].sum() < 1e-3 * spec.sum()


def test_seeded_and_offset():
    a = quasi_random(10.0, seed=1)[1]
    b = quasi_random(10.0, seed=1)[1]
    c = quasi_random(10.0, seed=2)[1]
    assert np.array_equal(a, b) and not np.allclose(a, c)
    t, u = quasi_random(20.0, seed=1, offset=2.0, amplitude=3.0)
    assert u[t > 0.5].min() >= -1.0 - 1e-9 and u.max() <= 5.0 + 1e-9


def test_input_file_round_trip_drives_simulator(tmp_path):
    t, u = sum_of_sines(5.0, rate_hz=100.0, seed=0, amplitude=2.0, offset=1.0)
    path = write_input_file(tmp_path / "in.csv", t, u, "validation")
    t2, u2 = read_input_file(path)
    assert np.array_equal(t, t2) and np.array_equal(u, u2)
    traj = simulate("upper", (t2, u2), 5.0)
    assert traj.omega_u[-1] > 0.1


def test_bad_arguments():
    with pytest.raises(ValueError, match="duration"):
        quasi_random(-1.0)
    with pytest.raises(ValueError, match="f_max"):
        sum_of_sines(10.0, frequencies=(0.1, 7.0))
    with pytest.raises(ValueError, match="amplitude"):
        quasi_random(10.0, amplitude=0.0)


def test_read_input_file_errors(tmp_path):
    p = tmp_path / "bad.csv"
    p.write_text("t,v\n0,1\n")
    with pytest.raises(DataFormatError, match="missing column\\(s\\) u"):
        read_input_file(p)
    p.write_text("t,u\n0,1\n0,2\n")
    with pytest.raises(DataFormatError, match="increasing"):
        read_input_file(p)
    with pytest.raises(DataFormatError, match="none.csv: file not found"):
        read_input_file(tmp_path / "none.csv")
