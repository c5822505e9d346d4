"""Metrics, the harness, the report and the CLI."""

import csv

import numpy as np
import pytest

from controllers.evaluation import evaluate, lowest_free_speed, stick_slip_severity
from controllers.evaluation.report import markdown_table, write_report
from drillgym.cli import main


def test_ssi_definition():
    t = np.linspace(0, 6 * np.pi, 3000, endpoint=False)
    assert stick_slip_severity(2.0 + 0.5 * np.sin(t)) == pytest.approx(0.25, rel=1e-3)
    assert stick_slip_severity(np.zeros(10), 1.0) == np.inf  # a disc that stands still
    assert stick_slip_severity(np.full(10, 3.0)) == 0.0


def test_lowest_free_speed_is_contiguous_from_the_top():
    t = np.array([0.5, 1.0, 1.5, 2.0, 2.5])
    assert lowest_free_speed(t, np.array([0.0, 1.0, 0.05, 0.01, 0.0])) == 1.5
    assert np.isnan(lowest_free_speed(t, np.array([0, 0, 0, 0, 0.5])))
    # smooth but 30 % too fast at 1.5 rad/s is not holding that target
    assert lowest_free_speed(t, np.array([0.0, 1.0, 0.05, 0.01, 0.0]), offset=np.array([0, 0, 0.3, 0, 0])) == 2.0


def test_harness_rows_and_report(tmp_path):
    rows = evaluate(["baseline", "pi"], ["torsional"], ["rest", "friction+20"], targets=[2.0, 7.5],
                    duration=30.0, window=10.0, workers=1, progress=False)
    assert len(rows) == 2 * 2 * 2
    base = {(r["scenario"], r["omega_ref"]): r for r in rows if r["controller"] == "baseline"}
    assert base[("rest", 2.0)]["stick_slip"] and not base[("rest", 7.5)]["stick_slip"]
    assert base[("rest", 7.5)]["stuck"] == 0.0 and base[("rest", 2.0)]["stuck"] > 0.1
    files = write_report(rows, tmp_path)
    with open(files["csv"]) as f:
        assert len(list(csv.DictReader(f))) == len(rows)
    assert files["figure"].stat().st_size > 10_000
    table = markdown_table(rows)
    assert "| baseline | 10 | 7.50 |" in table


def test_bad_input_is_refused(capsys):
    with pytest.raises(ValueError, match="unknown scenario"):
        evaluate(["baseline"], ["torsional"], ["windy"], targets=[1.0], progress=False)
    with pytest.raises(ValueError, match="unknown controller 'pid@10'"):
        evaluate(["pid@10"], ["torsional"], ["rest"], targets=[1.0], progress=False)
    with pytest.raises(ValueError, match="window"):
        evaluate(["baseline"], ["torsional"], ["rest"], targets=[1.0], duration=10, window=20, progress=False)
    with pytest.raises(SystemExit) as e:
        main(["evaluate", "--config", "torsional", "--controllers", "pid", "--out", "/tmp/x_eval"])
    assert e.value.code == 2 and "unknown controller 'pid'" in capsys.readouterr().err
