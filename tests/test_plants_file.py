"""A population of plants the user writes (``evaluate --scenarios plants --plants-file FILE``).

Each plant of the file runs as written (its effects and their values, its base parameters, its encoder), as a
run of that plant built directly does; plants of different effects run side by side; reports and errors name
each plant by its name; a file that cannot be used is refused in one line naming the file, the plant and what
is wrong, before anything is written.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from contract import run

from drillgym import RigParams
from drillgym.errors import FitError, InputError, MissingFileError, SimulationError

ROOT = Path(__file__).resolve().parents[1]
CUBIC = ROOT / "examples" / "effects" / "string_cubic.py"

#: two plants of different effects: the nominal rig, and one with a 40 ms motor lag
TWO = """
plants:
  - name: bare
  - name: lagged
    effects:
      - {spec: motor_lag, values: {tau_m: 0.04}}
"""

#: short runs of a cheap controller (compositions the suite compiles anyway: base, motor_lag)
RUN = dict(targets=[2.0, 4.0], duration=3.0, window=1.0, workers=1, progress=False)
METRICS = ("ssi", "tracking_rms", "u_rms", "omega_l_max", "offset")


def write(tmp_path: Path, text: str, name: str = "plants.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_two_plants_of_different_effects_run_as_written(tmp_path):
    """Each plant's rows are those of a run of that plant built directly (the nominal rig; the rig with the lag),
    and the lag changes them."""
    from controllers.evaluation import evaluate

    rows = evaluate(["pi"], ["torsional"], ["plants"], plants_file=write(tmp_path, TWO), **RUN)
    assert [(r["plant"], r["plant_name"], r["effects"]) for r in rows] == [
        (0, "bare", "base"),
        (0, "bare", "base"),
        (1, "lagged", "motor_lag"),
        (1, "lagged", "motor_lag"),
    ]
    assert rows[2]["tau_m"] == 0.04 and "tau_m" not in rows[0]
    bare = evaluate(["pi"], ["torsional"], ["rest"], **RUN)
    lagged = evaluate(["pi"], ["torsional"], ["rest"], effects=["motor_lag"], effect_params={"tau_m": 0.04}, **RUN)
    for got, want in zip(rows, bare + lagged):
        assert got["omega_ref"] == want["omega_ref"]
        for k in METRICS:
            assert got[k] == pytest.approx(want[k], rel=1e-9, abs=1e-12), (got["plant_name"], k)
    assert any(abs(a[k] - b[k]) > 1e-6 for a, b in zip(rows[:2], rows[2:]) for k in METRICS)


def test_a_plant_keeps_its_base_parameters_and_encoder_the_others_nominal(tmp_path):
    from controllers.evaluation.plants_file import load_plants

    text = "plants:\n  - params: {Ts: 0.3}\n    encoders: {counts_per_rev: 2048, angle_noise: 1.0e-4}\n"
    f = write(tmp_path, text)
    (plant,) = load_plants(f).plants
    (older,) = load_plants(write(tmp_path, text.replace("encoders:", "encoder:"), "older.yaml")).plants
    assert (older.counts_per_rev, older.angle_noise) == (2048, 1e-4)
    nominal = RigParams().replace(km=4.0)
    (on_nominal,) = load_plants(f, params=nominal).plants
    assert plant.name == "plant 0" and plant.model.params == RigParams().replace(Ts=0.3)
    assert on_nominal.model.params == nominal.replace(Ts=0.3)
    assert (plant.counts_per_rev, plant.angle_noise) == (2048, 1e-4)
    assert plant.columns() == {"Ts": 0.3, "counts_per_rev": 2048.0, "angle_noise": 1e-4}


def test_plants_are_gathered_by_their_effects(tmp_path):
    from controllers.evaluation.plants_file import load_plants

    text = TWO + "  - name: lagged-too\n    effects: [motor_lag]\n  - name: bare-too\n"
    plants = load_plants(write(tmp_path, text))
    assert plants.groups() == [[0, 3], [1, 2]]
    pop = plants.population([1, 2])
    assert pop.names == ["lagged", "lagged-too"] and pop.matrix.shape[0] == 2
    with pytest.raises(InputError, match="different effects"):
        plants.population([0, 1])


def test_the_cli_runs_the_file_and_names_the_plants(tmp_path):
    write(tmp_path, TWO)
    argv = ["evaluate", "--config", "torsional", "--controllers", "pi", "--scenarios", "plants"]
    argv += ["--plants-file", "plants.yaml", "--targets", "2", "--duration", "2", "--window", "1"]
    code, out, err = run([*argv, "--workers", "1", "--out", "ev"], tmp_path, seconds=900)  # compiles when cold
    assert code == 0, err
    summary = (tmp_path / "ev" / "summary.md").read_text()
    assert "2 plants listed in the plants file" in summary
    assert "| bare | base |" in summary and "| lagged | motor_lag |" in summary
    header = (tmp_path / "ev" / "results.csv").read_text().splitlines()[0].split(",")
    assert {"plant", "plant_name", "effects", "tau_m"} <= set(header)


def test_an_effect_file_beside_the_plants_file_is_trusted_one_outside_is_not(tmp_path):
    from controllers.evaluation.plants_file import load_plants

    shutil.copy(CUBIC, tmp_path / "cubic.py")
    inside = "plants:\n  - name: stiff\n    effects: [{spec: cubic.py:string_cubic, values: {c3: 0.1}}]\n"
    (plant,) = load_plants(write(tmp_path, inside)).plants
    assert plant.model.names == ["string_cubic"] and plant.model.values["c3"] == 0.1
    outside = f"plants:\n  - name: stiff\n    effects: [{{spec: '{CUBIC}:string_cubic'}}]\n"
    sub = tmp_path / "sub"
    sub.mkdir()
    with pytest.raises(InputError, match=r"plant 'stiff' \(#0\): effect .*outside the file's folder.*--trust"):
        load_plants(write(sub, outside))
    assert load_plants(write(sub, outside), trust=True).plants[0].model.names == ["string_cubic"]
    tampered = inside.replace("values:", "sha256: '00', values:")
    with pytest.raises(InputError, match="SHA-256 differs"):
        load_plants(write(tmp_path, tampered, "tampered.yaml"))


BAD = {
    "unknown parameter": ("plants:\n  - name: a\n  - name: b\n    params: {nope: 1}\n", "plant 'b' (#1)", "nope"),
    "unknown effect": ("plants:\n  - effects: [warp_drive]\n", "plant #0", "unknown effect 'warp_drive'"),
    "bad value": (
        "plants:\n  - name: slow\n    effects: [{spec: motor_lag, values: {tau_m: -1}}]\n",
        "plant 'slow' (#0)",
        "'tau_m' = -1.0 s is outside",
    ),
    "not a number": (
        "plants:\n  - name: x\n    effects: [{spec: motor_lag, values: {tau_m: abc}}]\n",
        "plant 'x' (#0)",
        "'tau_m' must be a number",
    ),
    "unknown effect parameter": (
        "plants:\n  - name: x\n    effects: [{spec: motor_lag, values: {delay: 0.01}}]\n",
        "plant 'x' (#0)",
        "unknown effect parameter 'delay'",
    ),
    "bad encoder": (
        "plants:\n  - name: x\n    encoders: {counts_per_rev: 0}\n",
        "plant 'x' (#0)",
        "counts_per_rev must be an integer >= 1",
    ),
    "encoders twice": (
        "plants:\n  - name: x\n    encoders: {counts_per_rev: 2048}\n    encoder: {counts_per_rev: 2048}\n",
        "plant 'x' (#0)",
        "give 'encoders' once",
    ),
    "unknown key": ("plants:\n  - name: x\n    efects: [motor_lag]\n", "plant 'x' (#0)", "unknown key 'efects'"),
    "repeated name": ("plants:\n  - name: x\n  - name: x\n", "plant 'x' (#1)", "plant #0 has that name"),
    "not acting": ("plants:\n  - name: x\n    effects: [lateral_coulomb]\n", "plant 'x' (#0)", "does not act in"),
    "empty list": ("plants: []\n", "plants.yaml", "'plants' is empty"),
    "no list": ("name: x\n", "plants.yaml", "one key, 'plants'"),
    "not YAML": ("plants: [a: 1\n  b: [\n", "plants.yaml", "not valid YAML"),
}


def _evaluate_argv(plants_file: str, *more: str) -> list[str]:
    argv = ["evaluate", "--config", "torsional", "--controllers", "pi", "--scenarios", "plants", "--targets", "2"]
    return [*argv, "--duration", "2", "--window", "1", "--workers", "1", "--plants-file", plants_file, *more, "--out"]


def refused(code: int, err: str) -> str:
    line = err.strip()
    assert code == 2 and "Traceback" not in err, err
    assert line.startswith("drillgym: error: ") and "\n" not in line, err
    return line


@pytest.mark.parametrize("case", list(BAD))
def test_a_file_that_cannot_be_used_is_refused_in_one_line(tmp_path, case):
    text, plant, what = BAD[case]
    write(tmp_path, text)
    code, _, err = run([*_evaluate_argv("plants.yaml"), "ev"], tmp_path)
    line = refused(code, err)
    assert line.startswith("drillgym: error: --plants-file: plants.yaml: ") and plant in line and what in line, line
    assert not (tmp_path / "ev").exists()


def test_a_missing_file_is_refused_in_one_line(tmp_path):
    code, _, err = run([*_evaluate_argv("nowhere.yaml"), "ev"], tmp_path)
    assert refused(code, err) == "drillgym: error: --plants-file: nowhere.yaml: plants file not found"
    assert not (tmp_path / "ev").exists()
    from controllers.evaluation.plants_file import load_plants

    with pytest.raises(MissingFileError):
        load_plants(tmp_path / "nowhere.yaml")


@pytest.mark.parametrize(
    "argv,message",
    [
        (["--scenarios", "rest"], "--plants-file needs --scenarios plants"),
        (["--plants", "3"], "--plants-file cannot go with --plants (the file lists the plants)"),
        (["--uncertainty", "plants.yaml"], "--plants-file cannot go with --uncertainty"),
    ],
    ids=["without-plants-scenario", "with-plants", "with-uncertainty"],
)
def test_options_it_cannot_go_with_are_refused(tmp_path, argv, message):
    write(tmp_path, TWO)
    code, _, err = run([*_evaluate_argv("plants.yaml", *argv), "ev"], tmp_path)
    assert message in refused(code, err)
    assert not (tmp_path / "ev").exists()


def test_the_python_api_refuses_the_same(tmp_path):
    from controllers.evaluation import evaluate

    path = write(tmp_path, TWO)
    with pytest.raises(InputError, match="neither plants nor uncertainty"):
        evaluate(["pi"], ["torsional"], ["plants"], plants_file=path, plants=3, **RUN)
    with pytest.raises(InputError, match="add the scenario 'plants'"):
        evaluate(["pi"], ["torsional"], ["rest"], plants_file=path, **RUN)


def test_an_error_on_a_plant_of_the_file_names_it(tmp_path, monkeypatch):
    """A run that fails, or an identification that fails, names the plant by its name in the file."""
    from controllers.evaluation import harness, identify, population_jobs

    def diverging(controller, config, scenario, targets, base, pop, duration, window, seed, plants, model):
        if 1 in plants:
            raise SimulationError("the run diverged at t = 0.1 s")
        return []

    path = write(tmp_path, TWO)
    monkeypatch.setattr(population_jobs, "_run_plants", diverging)
    with pytest.raises(SimulationError) as e:
        harness.evaluate(["pi"], ["torsional"], ["plants"], plants_file=path, **RUN)
    assert str(e.value) == f"plant 'lagged' (1 of 2 in {path}): the run diverged at t = 0.1 s"

    def failing(rec, names, opts):
        raise FitError("the fit did not converge")

    monkeypatch.setattr(identify, "identify_plant", failing)
    monkeypatch.setattr(identify, "excitation_recording", lambda *args: None)
    with pytest.raises(FitError) as e:
        harness.evaluate(["pi"], ["torsional"], ["plants"], plants_file=path, identify=True, **RUN)
    assert str(e.value).startswith(f"plant 'bare' (0 of 2 in {path}), identifying it: the fit did not converge")


def test_the_example_file_reads():
    """examples/plants.yaml (the docs' example): three plants of three compositions, one an effect file beside it."""
    from controllers.evaluation import load_plants

    plants = load_plants(ROOT / "examples" / "plants.yaml")
    assert [p.name for p in plants.plants] == ["nominal", "worn-brake-slow-amplifier", "stiffening-string"]
    assert plants.groups() == [[0], [1], [2]]
    assert plants.plants[1].model.names == ["motor_lag", "input_delay"] and plants.plants[1].counts_per_rev == 2048


def test_a_plants_file_giving_a_key_twice_is_refused(tmp_path):
    """The second ``params`` of one plant would replace the first without a word: refused, naming the key and line."""
    from controllers.evaluation.plants_file import load_plants
    from drillgym.errors import InputError

    (tmp_path / "p.yaml").write_text("plants:\n  - name: a\n    params: {Ts: 0.3}\n    params: {Ts: 0.4}\n")
    with pytest.raises(InputError, match=r"line 4.*'params' is given twice"):
        load_plants(tmp_path / "p.yaml")


def test_the_identification_table_holds_plants_with_different_effects():
    """A plants file's plants differ in their effects: each row of the identification table shows its own
    parameters and leaves the others' cells empty (the report once failed with a KeyError on the second plant)."""
    import math

    from controllers.evaluation.population_report import identification_table

    base = {"scenario": "plants", "identify_s": 12.0}
    rows = [
        {**base, "plant": 0, "plant_name": "lagged", "selected": "motor_lag", "km": 4.3, "id_km": 4.3 * 1.01,
         "tau_m": 0.03, "id_tau_m": 0.031},
        {**base, "plant": 1, "plant_name": "dead zone", "selected": "motor_lag", "km": 4.3, "id_km": 4.3,
         "u0": 0.2, "id_u0": math.nan, "tau_m": "", "id_tau_m": ""},
    ]  # fmt: skip
    lines = identification_table(rows).splitlines()
    assert lines[0].split("|")[4:7] == [" km ", " tau_m ", " u0 "]
    lagged, dead = (line.split("|")[4:7] for line in lines[2:])
    assert lagged == [" +1.0 % ", " 0.031 (0.03) ", "  "]
    assert dead == [" +0.0 % ", "  ", " - (0.2) "]  # not selected: '-' beside the true value
