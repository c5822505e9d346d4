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


# --------------------------------------------------------------------- hidden effects of the plant
from pathlib import Path  # noqa: E402

import controllers  # noqa: E402
from controllers.base import Controller  # noqa: E402
from controllers.evaluation import run_closed_loop  # noqa: E402
from drillgym import RigParams  # noqa: E402

CUBIC = f"{Path(__file__).resolve().parents[1] / 'examples' / 'effects' / 'string_cubic.py'}:string_cubic"


def test_plant_runs_hidden_effects_the_controller_is_nominal(monkeypatch):
    built = []
    make = controllers.make

    def spy(name, **kw):
        built.append(kw)
        return make(name, **kw)

    monkeypatch.setattr(controllers, "make", spy)
    kw = dict(targets=[2.0], duration=8.0, window=3.0, workers=1, progress=False)
    base = evaluate(["pi"], ["torsional"], ["rest"], **kw)
    hidden = evaluate(["pi"], ["torsional"], ["rest"], effects=["input_delay"], effect_params={"delay": 0.15}, **kw)
    assert base[0]["plant"] == "base" and hidden[0]["plant"] == "input_delay"
    assert abs(hidden[0]["tracking_rms"] - base[0]["tracking_rms"]) > 1e-3  # the delayed plant behaves differently
    assert built and all(k["params"] == RigParams() and "effects" not in k for k in built)  # nominal controllers
    with pytest.raises(ValueError, match="delay"):
        evaluate(["pi"], ["torsional"], ["rest"], effects=["input_delay"], effect_params={"delay": 9.0}, **kw)


def test_user_file_effect_reaches_worker_processes():
    kw = dict(targets=[3.0], duration=6.0, window=2.0, progress=False)
    rows = evaluate(["baseline"], ["torsional"], ["rest"], workers=2, effects=[CUBIC], effect_params={"c3": 0.1}, **kw)
    same = evaluate(["baseline"], ["torsional"], ["rest"], workers=1, effects=[CUBIC], effect_params={"c3": 0.1}, **kw)
    base = evaluate(["baseline"], ["torsional"], ["rest"], workers=1, **kw)
    assert rows[0]["plant"] == "string_cubic" and rows == same
    assert rows[0]["omega_l_max"] != base[0]["omega_l_max"]


class _Recorder(Controller):
    """Holds 3 V and keeps what it measured."""

    def __init__(self, **kw):
        super().__init__(3.0, **kw)
        self.seen = []

    def _act(self, m):
        self.seen.append({k: np.array(v, dtype=float) for k, v in m.items()})
        return np.full(m["theta_u"].shape, 3.0)


def test_closed_loop_measurements_pass_through_measurement_effects():
    x0, skew = 2e-3, 0.2
    rec = _Recorder(config="coupled")
    run_closed_loop(rec, "coupled", np.array([3.0, 3.0]), 0.5, counts_per_rev=0, effects=["lvdt_offset", "lvdt_skew"],
                    effect_params={"lvdt_x0": x0, "lvdt_y0": 0.0, "lvdt_skew": skew})
    plain = _Recorder(config="coupled")
    run_closed_loop(plain, "coupled", np.array([3.0, 3.0]), 0.5, counts_per_rev=0)
    m, p = rec.seen[-1], plain.seen[-1]
    np.testing.assert_allclose(m["x"], p["x"] + x0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(m["y"], p["y"] * np.cos(skew) + (p["x"] + x0) * np.sin(skew), rtol=0, atol=1e-12)
    np.testing.assert_allclose(m["theta_u"], p["theta_u"], rtol=0, atol=1e-12)


def test_evaluate_cli_with_hidden_effects(tmp_path, capsys):
    out = tmp_path / "ev"
    with pytest.raises(SystemExit) as ok:
        main(["evaluate", "--config", "torsional", "--controllers", "pi", "--targets", "2", "--duration", "6",
              "--window", "2", "--workers", "1", "--out", str(out), "--add-effect", "input_delay",
              "--effect-param", "delay=0.1"])
    assert ok.value.code == 0
    assert "Plant: hidden effects: input_delay(delay=0.1)" in (out / "summary.md").read_text()
    with open(out / "results.csv") as f:
        assert [r["plant"] for r in csv.DictReader(f)] == ["input_delay"]
    with pytest.raises(SystemExit) as e:
        main(["evaluate", "--config", "torsional", "--controllers", "pi", "--out", str(out), "--effect-param",
              "delay=0.1"])
    assert e.value.code == 2 and "--add-effect" in capsys.readouterr().err
