"""write_timeseries refuses a path that is not one in one line (no traceback of pathlib's)."""

import numpy as np
import pytest

from drillgym.errors import InputTypeError
from drillgym.io import TimeSeries, read_timeseries, write_timeseries


def test_arguments_given_the_other_way_round_are_refused_in_one_line(tmp_path):
    ts = TimeSeries({"t": np.arange(3) * 0.01, "u": np.ones(3), "theta_u": np.zeros(3)}, {"configuration": "upper"})
    with pytest.raises(InputTypeError, match=r"path must be a file's path .*got TimeSeries \(the arguments are"):
        write_timeseries(ts, tmp_path / "x.csv")
    with pytest.raises(InputTypeError, match="got int"):
        write_timeseries(3, ts)
    out = write_timeseries(str(tmp_path / "x.csv"), ts)
    assert np.array_equal(read_timeseries(out).columns["u"], np.ones(3))
