"""Time-series files: round trips, validation errors naming file/line/column, resampling, streaming."""

import json

import numpy as np
import pytest
import scipy.io

from drillgym import simulate
from drillgym.errors import DataFormatError, InputTypeError
from drillgym.io import StreamingCsvWriter, TimeSeries, read_timeseries, write_timeseries, write_trajectory_csv
from drillgym.measurement import MeasurementModel, measure_trajectory, quantize_angle


def test_simulation_round_trips_through_csv(tmp_path):
    tr = simulate("coupled", 2.0, 3.0, record_every=5)
    path = write_trajectory_csv(tr, tmp_path / "run.csv")
    ts = read_timeseries(path)
    assert ts.configuration.label == "coupled" and ts.meta["source"] == "simulation"
    for name in ("t", "u", "theta_u", "theta_l", "x", "y", "omega_l"):
        np.testing.assert_array_equal(ts.columns[name], getattr(tr, name))


def write(tmp_path, text, name="d.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


@pytest.mark.parametrize(
    "body,fragment",
    [
        ("t,u\n0,1\n0.1,1\n", "missing column\\(s\\) theta_u"),
        ("t,u,theta_u\n0,1,0\n0.1,nan,0\n", "line 3, column 'u': value is NaN"),
        ("t,u,theta_u\n0,1,0\n0.1,1,0\n0.1,1,0\n", "line 4, column 't': time is not strictly increasing"),
        ("t,u,theta_u\n0,1,0\n0.1,abc,0\n", "line 3, column 'u': 'abc' is not a number"),
        ("t,u,theta_u\n0,1,0\n0.1,60,0\n", "column 'u': 60.0 V is outside"),
        ("t,u,theta_u\n0,1,0\n0.1,1\n", "line 3: 2 fields, header has 3"),
        ("# meta: {oops\nt,u,theta_u\n", "line 1: metadata is not valid JSON"),
        ("", "no header line"),
    ],
)
def test_bad_files_are_refused_naming_the_problem(tmp_path, body, fragment):
    path = write(tmp_path, body)
    with pytest.raises(DataFormatError, match=fragment) as info:
        read_timeseries(path)
    assert str(path) in str(info.value)


def test_configuration_requirements_and_conflicts(tmp_path):
    path = write(tmp_path, "t,u,theta_u,theta_l\n0,1,0,0\n0.1,1,0,0\n")
    with pytest.raises(DataFormatError, match="missing column\\(s\\) x, y for configuration 'coupled'"):
        read_timeseries(path, config="coupled")
    meta = write(tmp_path, '# meta: {"configuration": "torsional"}\nt,u,theta_u,theta_l\n0,1,0,0\n0.1,1,0,0\n', "m.csv")
    with pytest.raises(DataFormatError, match="file says configuration 'torsional'"):
        read_timeseries(meta, config="lateral")
    assert read_timeseries(meta).configuration.label == "torsional"


def test_x_out_of_range_and_unknown_columns_kept(tmp_path):
    bad = write(tmp_path, "t,u,theta_u,theta_l,x,y\n0,1,0,0,0,0\n0.1,1,0,0,0.2,0\n")
    with pytest.raises(DataFormatError, match="column 'x': 0.2 m is outside"):
        read_timeseries(bad, config="lateral")
    ok = write(tmp_path, "t,u,theta_u,temperature\n0,1,0,20\n0.1,1,0,21\n", "ok.csv")
    assert read_timeseries(ok).columns["temperature"].tolist() == [20.0, 21.0]


def test_mat_files_are_read_by_name_and_mapping(tmp_path):
    t = np.linspace(0, 1, 11)
    scipy.io.savemat(tmp_path / "a.mat", {"time": t, "u": np.ones(11), "theta_u": t, "theta_l": 0.5 * t})
    ts = read_timeseries(tmp_path / "a.mat", config="torsional")
    np.testing.assert_allclose(ts.theta_l, 0.5 * t)
    scipy.io.savemat(tmp_path / "b.mat", {"tout": t, "volts": np.ones(11), "enc1": t})
    ts = read_timeseries(tmp_path / "b.mat", config="upper", mapping={"u": "volts", "theta_u": "enc1"})
    np.testing.assert_allclose(ts.u, 1.0)
    with pytest.raises(DataFormatError, match="missing column\\(s\\) u, theta_u"):
        read_timeseries(tmp_path / "b.mat", config="upper")
    (tmp_path / "c.mat").write_bytes(b"garbage")
    with pytest.raises(DataFormatError, match="c.mat: not a readable MATLAB"):
        read_timeseries(tmp_path / "c.mat")


def test_resample_holds_voltage_and_interpolates_angles():
    tr = simulate("torsional", lambda t: np.where(t < 1.0, 1.0, 2.0), 2.0)
    from drillgym.io import trajectory_to_timeseries

    ts = trajectory_to_timeseries(tr).resample(100.0)
    assert len(ts) == 201 and ts.sample_rate_hz == pytest.approx(100.0)
    assert ts.u[99] == 1.0 and ts.u[100] == 2.0
    np.testing.assert_allclose(ts.theta_u[::10], tr.theta_u[::100], atol=1e-12)


def test_streaming_writer_flushes_blocks(tmp_path):
    path = tmp_path / "rec.csv"
    w = StreamingCsvWriter(
        path, ["t", "u", "theta_u"], {"configuration": "upper", "source": "rig"}, flush_interval_s=0.1
    )
    for i in range(50):
        w.write([i * 0.01, 1.0, 0.001 * i])
    # without close(): everything up to the last block boundary is already on disk
    on_disk = read_timeseries(path)
    assert len(on_disk) >= 40
    w.close()
    assert len(read_timeseries(path)) == 50


def test_synthetic_measurement_quantizes_and_filters():
    tr = simulate("coupled", 3.0, 5.0)
    m = measure_trajectory(tr, model=MeasurementModel(counts_per_rev=8000, lvdt_noise_std=5e-6))
    step = 2 * np.pi / 8000
    assert np.all(np.abs(m.theta_l - tr.theta_l) <= step)
    np.testing.assert_allclose(m.theta_l / step, np.round(m.theta_l / step), atol=1e-6)
    assert np.std(m.x - tr.x) < 5e-6  # 5 Hz low-pass removes most of the noise
    assert json.loads(json.dumps(m.meta))["configuration"] == "coupled"
    assert quantize_angle(0.0) == 0.0


def test_writing_a_series_replaces_the_file_whole_or_says_why(tmp_path):
    from drillgym.errors import OutputPathError

    traj = simulate("torsional", u=2.0, duration=0.2)
    out = tmp_path / "run.csv"
    out.write_text("old\n")
    out.chmod(0o640)
    write_trajectory_csv(traj, out)
    assert read_timeseries(out).columns["omega_l"][-1] == traj.omega_l[-1]
    assert out.stat().st_mode & 0o777 == 0o640  # the replaced file keeps its permissions
    assert [p.name for p in tmp_path.iterdir()] == ["run.csv"]  # no temporary file left
    with pytest.raises(OutputPathError, match=r"missing/run\.csv: cannot write the time series \("):
        write_trajectory_csv(traj, tmp_path / "missing" / "run.csv")


def test_arguments_given_the_other_way_round_are_refused_in_one_line(tmp_path):
    ts = TimeSeries({"t": np.arange(3) * 0.01, "u": np.ones(3), "theta_u": np.zeros(3)}, {"configuration": "upper"})
    with pytest.raises(InputTypeError, match=r"path must be a file's path .*got TimeSeries \(the arguments are"):
        write_timeseries(ts, tmp_path / "x.csv")
    with pytest.raises(InputTypeError, match="got int"):
        write_timeseries(3, ts)
    out = write_timeseries(str(tmp_path / "x.csv"), ts)
    assert np.array_equal(read_timeseries(out).columns["u"], np.ones(3))
