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
    rows = evaluate(
        ["baseline", "pi"],
        ["torsional"],
        ["rest", "friction+20"],
        targets=[2.0, 7.5],
        duration=30.0,
        window=10.0,
        workers=1,
        progress=False,
    )
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
    run_closed_loop(
        rec,
        "coupled",
        np.array([3.0, 3.0]),
        0.5,
        counts_per_rev=0,
        effects=["lvdt_offset", "lvdt_skew"],
        effect_params={"lvdt_x0": x0, "lvdt_y0": 0.0, "lvdt_skew": skew},
    )
    plain = _Recorder(config="coupled")
    run_closed_loop(plain, "coupled", np.array([3.0, 3.0]), 0.5, counts_per_rev=0)
    m, p = rec.seen[-1], plain.seen[-1]
    np.testing.assert_allclose(m["x"], p["x"] + x0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(m["y"], p["y"] * np.cos(skew) + (p["x"] + x0) * np.sin(skew), rtol=0, atol=1e-12)
    np.testing.assert_allclose(m["theta_u"], p["theta_u"], rtol=0, atol=1e-12)


def test_evaluate_cli_with_hidden_effects(tmp_path, capsys):
    out = tmp_path / "ev"
    with pytest.raises(SystemExit) as ok:
        main(
            [
                "evaluate",
                "--config",
                "torsional",
                "--controllers",
                "pi",
                "--targets",
                "2",
                "--duration",
                "6",
                "--window",
                "2",
                "--workers",
                "1",
                "--out",
                str(out),
                "--add-effect",
                "input_delay",
                "--effect-param",
                "delay=0.1",
            ]
        )
    assert ok.value.code == 0
    assert "Plant: hidden effects: input_delay(delay=0.1)" in (out / "summary.md").read_text()
    with open(out / "results.csv") as f:
        assert [r["plant"] for r in csv.DictReader(f)] == ["input_delay"]
    with pytest.raises(SystemExit) as e:
        main(
            [
                "evaluate",
                "--config",
                "torsional",
                "--controllers",
                "pi",
                "--out",
                str(out),
                "--effect-param",
                "delay=0.1",
            ]
        )
    assert e.value.code == 2 and "--add-effect" in capsys.readouterr().err


def test_evaluate_cli_builds_the_model_based_controllers_on_model(tmp_path, capsys):
    import json

    lag = tmp_path / "lag.json"
    lag.write_text(json.dumps({"effects": [{"spec": "motor_lag", "values": {"tau_m": 0.04}}]}))
    force = tmp_path / "force.json"
    force.write_text(json.dumps({"effects": [{"spec": "string_damping", "values": {"dtheta": 0.002}}]}))
    out = tmp_path / "ev"
    args = ["evaluate", "--config", "torsional", "--targets", "3", "--duration", "1", "--window", "0.5"]
    args += ["--workers", "1", "--out", str(out), "--controllers", "observer,pi"]
    with pytest.raises(SystemExit) as ok:
        main(args + ["--model", str(lag)])
    assert ok.value.code == 0
    assert f"the plant is the nominal rig (add --params {lag}" in capsys.readouterr().err
    with open(out / "results.csv") as f:
        assert {r["controller"]: r["model"] for r in csv.DictReader(f)} == {"observer": "motor_lag", "pi": "base"}
    assert "observer on motor_lag" in (out / "summary.md").read_text()
    with pytest.raises(SystemExit) as e:  # a force in the string: the controllers run it too (no whitelist)
        main(args + ["--model", str(force), "--out", str(tmp_path / "ev2")])
    assert e.value.code == 0
    with open(tmp_path / "ev2" / "results.csv") as f:
        assert {r["controller"]: r["model"] for r in csv.DictReader(f)}["observer"] == "string_damping"


# --------------------------------------------------------------------- plant population
from controllers.evaluation.harness import short_run_warnings  # noqa: E402
from controllers.evaluation.population import load_uncertainty, sample_plants  # noqa: E402


def test_uncertainty_set_default_file_and_one_line_errors(tmp_path):
    us = load_uncertainty()
    assert us.relative["km"] == 0.05 and us.effects["delay"] == (0.0, 0.02)
    assert us.effect_names() == ["motor_lag", "input_delay", "position_friction"]
    for text, match in (
        ("windy: {a: 1}", "unknown section 'windy'"),
        ("relative: {kmm: 0.1}", "not a base parameter"),
        ("relative: {km: 2}", r"in \[0, 1\)"),
        ("effects: {tau_x: [0, 1]}", "unknown effect parameter"),
        ("effects: {delay: [0.1, 0.0]}", "lo <= hi"),
        ("relative: [", "not valid YAML"),
    ):
        f = tmp_path / "u.yaml"
        f.write_text(text)
        with pytest.raises(ValueError, match=match):
            load_uncertainty(f)


def test_sampled_plants_are_reproducible_nested_and_inside_the_set():
    pop = sample_plants(6, seed=3)
    again = sample_plants(3, seed=3)
    assert np.array_equal(pop.matrix[:3], again.matrix) and pop.columns[:3] == again.columns  # plant k ignores n
    assert not np.array_equal(sample_plants(3, seed=4).matrix, again.matrix)
    nominal = controllers.make("pi", omega_ref=1.0).params
    us = pop.uncertainty
    for col, row in zip(pop.columns, pop.matrix):
        named = pop.composition.named(row)
        for k, r in us.relative.items():
            assert abs(col[k] / getattr(nominal, k) - 1) <= r + 1e-12 and named[k] == col[k]
        assert us.effects["tau_m"][0] <= named["tau_m"] <= us.effects["tau_m"][1]
        assert 0 <= named["delay"] <= 0.02 and np.hypot(named["pf_c1"], named["pf_s1"]) <= 0.2 + 1e-12
        assert 2048 <= col["counts_per_rev"] <= 8000 and 0 <= col["angle_noise"] <= 5e-4
    with pytest.raises(ValueError, match="positive integer"):
        sample_plants(0)


def test_plants_scenario_rows_columns_summary_and_figure(tmp_path, capsys):
    """CLI: one row per (controller, plant, target) with the plant's values; median/p90 table; figure."""
    with pytest.raises(SystemExit) as ok:
        main(
            [
                "evaluate",
                "--config",
                "torsional",
                "--controllers",
                "baseline",
                "--scenarios",
                "plants",
                "--plants",
                "3",
                "--seed",
                "5",
                "--targets",
                "2.0,7.5",
                "--duration",
                "12",
                "--window",
                "4",
                "--workers",
                "1",
                "--out",
                str(tmp_path),
            ]
        )
    assert ok.value.code == 0
    with open(tmp_path / "results.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 3 * 2 and {r["plant"] for r in rows} == {"0", "1", "2"}
    pop = sample_plants(3, seed=5)
    for r in rows:
        for k in ("km", "Jl", "tau_m", "delay", "pf_c1", "pf_s1", "counts_per_rev"):
            assert float(r[k]) == pytest.approx(pop.columns[int(r["plant"])][k])
    assert all(r["stick_slip"] == "True" for r in rows if r["omega_ref"] == "2.0")  # open loop sticks at 2 rad/s
    out = capsys.readouterr().out
    assert "median lowest held" in out and "| baseline | 10 | torsional | 3 |" in out
    assert (tmp_path / "plants_lowest_held.png").stat().st_size > 10_000
    with pytest.raises(ValueError, match="do not combine"):
        evaluate(
            ["baseline"], ["torsional"], ["plants"], targets=[1.0], plants=2, effects=["input_delay"], progress=False
        )


def test_short_run_warning_names_the_controller_and_the_duration_needed():
    lines = short_run_warnings(["observer", "pi"], "torsional", [1.0, 3.0], duration=30.0, window=10.0)
    assert len(lines) == 1 and lines[0].startswith("observer:") and "1 rad/s" in lines[0] and "--duration" in lines[0]
    assert short_run_warnings(["observer"], "torsional", [1.0, 3.0], duration=60.0, window=20.0) == []
    with pytest.warns(UserWarning, match="steady window starts at 5 s"):
        evaluate(
            ["observer"], ["torsional"], ["rest"], targets=[1.0], duration=6.0, window=1.0, workers=1, progress=False
        )


# --------------------------------------------------------------------- identify, then control
def test_excitation_run_records_what_the_plants_encoders_report():
    from controllers.evaluation.identify import ExcitationOptions, excitation_recording

    pop = sample_plants(2, 0)
    ts = excitation_recording(pop.matrix[1], pop.composition, 2048, 0.0, 3, ExcitationOptions(duration=1.0))
    assert len(ts) == 500 and ts.configuration.label == "torsional" and ts.meta["counts_per_rev"] == 2048
    counts = np.asarray(ts.theta_u) / (2 * np.pi / 2048)
    np.testing.assert_allclose(counts, np.round(counts), atol=1e-6)  # the plant's encoder, not the nominal 8000
    assert np.ptp(ts.u) > 2.0 and 0.0 <= ts.u.min() and ts.u.max() <= 5.0 and np.ptp(ts.theta_u) > 0


def test_a_coupled_excitation_run_records_the_lvdts_a_coupled_diagnosis_reads():
    from controllers.evaluation.identify import ExcitationOptions, excitation_recording
    from drillgym.identification.experiment import prepare_experiment

    pop = sample_plants(2, 0)
    o = ExcitationOptions(duration=6.0)  # long enough for the lower disc to break away and whirl
    ts = excitation_recording(pop.matrix[0], pop.composition, 8000, 0.0, 3, o, "coupled")
    assert ts.configuration.label == "coupled" and {"x", "y"} <= set(ts.columns)
    assert np.all(np.isfinite(ts.columns["x"])) and np.ptp(ts.columns["x"]) > 0
    prepare_experiment(ts)  # what diagnose reads: refused before when x, y were missing


def test_a_plants_own_model_compares_at_the_noise_of_its_excitation_run():
    """The population's encoders add noise after the count: the plant's own model compared with its excitation run
    is at the noise of those readings (it read 24-79 noise units when the 0.1 mrad floor was taken for it)."""
    from controllers.evaluation.identify import ExcitationOptions, excitation_recording
    from drillgym import Model, RigParams
    from drillgym.diagnosis.model_compare import compare_models
    from drillgym.identification.experiment import prepare_experiment

    pop = sample_plants(1, 0)
    cols = pop.columns[0]
    base = RigParams(**{**RigParams().to_dict(), **{k: v for k, v in cols.items() if k in RigParams().to_dict()}})
    values = {k: v for k, v in cols.items() if k in pop.composition.effect_param_names}
    ts = excitation_recording(pop.matrix[0], pop.composition, 5000, 4e-4, 3, ExcitationOptions(duration=16.0))
    ex = prepare_experiment(ts, compare_rate_hz=100.0)
    mc = compare_models(ex, Model(base, list(pop.composition.names), values), segment_s=4.0)
    assert mc.model.noise["theta_u"] == pytest.approx(np.hypot(4e-4, 2 * np.pi / 5000 / np.sqrt(12.0)), rel=0.2)
    assert max(mc.ratios(mc.model).values()) < 2.5, mc.ratios(mc.model)


@pytest.mark.parametrize("config", ["torsional", "coupled"])
def test_the_compiled_excitation_run_records_what_the_step_by_step_one_does(config):
    from controllers.evaluation.identify import _Playback
    from controllers.evaluation.runner import run_closed_loop
    from drillgym.signals import quasi_random

    pop = sample_plants(2, 0)
    _, u = quasi_random(3.0, rate_hz=500.0, seed=3, amplitude=5.0, offset=2.5)
    channels = ("theta_u", "theta_l", "x", "y") if config == "coupled" else ("theta_u", "theta_l")
    got = []
    for compiled in (True, False):
        play = _Playback(u, 1 / 500.0, channels)
        run = run_closed_loop(play, config, np.ones(1), 3.0, params=np.atleast_2d(pop.matrix[1]),
                              counts_per_rev=2048, angle_noise=2e-4, seed=5, effects=pop.composition,
                              compiled=compiled)  # fmt: skip
        got.append((run.u, play.reports()))
    (u_c, seen_c), (u_s, seen_s) = got
    np.testing.assert_array_equal(u_c, u_s)
    assert set(seen_c) == set(channels) and np.ptp(seen_c["theta_u"]) > 0
    for key in channels:  # the same noise stream, the same quantisation: the same numbers
        np.testing.assert_array_equal(seen_c[key], seen_s[key])


def test_identify_is_refused_without_a_population(tmp_path, capsys):
    args = ["evaluate", "--config", "torsional", "--controllers", "pi", "--out", str(tmp_path / "ev"), "--identify"]
    with pytest.raises(SystemExit) as e:
        main(args + ["--scenarios", "rest"])
    err = capsys.readouterr().err
    assert e.value.code == 2 and "--identify" in err and "plants" in err and not (tmp_path / "ev").exists()


def test_each_plant_is_identified_once_in_its_own_task_and_runs_every_controller(monkeypatch):
    """``identify=`` runs one task per plant (identify, then every controller on that model): each plant identified
    once, and the rows those of the same identifications handed over as a mapping."""
    from dataclasses import replace

    from controllers.evaluation import population_jobs
    from controllers.evaluation.identify import IdentifiedPlant
    from drillgym import Model, RigParams

    seen = []

    def identified(k, *args):
        seen.append(k)
        return IdentifiedPlant(Model(replace(RigParams(), km=4.0 + 0.1 * k)), [], 1.0 + k)

    monkeypatch.setattr(population_jobs, "_identify_one", identified)
    kw = dict(duration=1.0, window=0.5, plants=3, workers=1, progress=False)
    rows = evaluate(["pi", "baseline"], ["torsional"], ["plants"], [2.0, 3.0], identify=True, **kw)
    assert sorted(seen) == [0, 1, 2]
    given = evaluate(["pi", "baseline"], ["torsional"], ["plants"], [2.0, 3.0], identify={k: identified(k) for k in
                     range(3)}, **kw)  # fmt: skip
    assert len(rows) == 2 * 3 * 2 and [r["identify_s"] for r in rows[:6:2]] == [1.0, 2.0, 3.0]
    assert rows == given


def test_a_single_timing_effect_is_tried_again_as_a_lag_and_a_delay():
    from drillgym.identified import LAG_SHARE, _with_both_timing_effects

    specs, values = _with_both_timing_effects(["input_delay", "position_friction"], {"delay": 0.05, "pf_c1": 0.1})
    assert specs == ["motor_lag", "input_delay", "position_friction"]  # the lag first on the signal path
    assert values["tau_m"] == pytest.approx(LAG_SHARE * 0.05) and values["delay"] == pytest.approx(0.015)
    assert values["pf_c1"] == 0.1
    assert _with_both_timing_effects(["motor_lag", "input_delay"], {"tau_m": 0.04, "delay": 0.01}) is None
    assert _with_both_timing_effects(["position_friction"], {"pf_c1": 0.1}) is None
