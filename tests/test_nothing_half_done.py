"""Nothing half-done on bad input: one test per class of fault, generated where a table gives the class.

* Written before refused: a refused ``train`` leaves its OUT as it was (no config.yml replaced or left behind).
* Options that only mean something beside another: every declared dependency of every command
  (:mod:`drillgym.commands.options`) is refused in one line when the option is given alone.
* Networks checked on load: non-finite weights, layers that do not chain, an observation or action size that
  does not fit the task, the same network twice in an average.
* A message with its context: an error on one plant of a population names the plant (and, with --identify,
  that the model was its own).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import typer
from contract import base_argv, build_assets, commands, run, snapshot, valid_value

from drillgym.commands.options import excludes, requires
from drillgym.errors import FitError, InputError, SimulationError

pytestmark = pytest.mark.xdist_group("nothing_half_done")

KEPT = Path(__file__).resolve().parents[1] / "agents" / "policies" / "population_motor_distilled_mean" / "policy.npz"


@pytest.fixture(scope="module")
def a(tmp_path_factory):
    return build_assets(tmp_path_factory.mktemp("half_done") / "assets")


def refused_line(code: int, err: str) -> str:
    line = err.strip()
    assert code == 2 and "Traceback" not in err, err
    assert line.startswith("drillgym: error: ") and "\n" not in line, err
    return line


# --------------------------------------------------------------------------------------- written before refused


@pytest.mark.parametrize(
    "extra",
    [
        ["--teacher", str(KEPT)],  # a teacher not of the 'full' observation
        ["--teacher", "flatness", "--set", "distill.whiten=2"],  # a distillation option refused at its start
    ],
    ids=["teacher-observation", "distill-option"],
)
@pytest.mark.parametrize("existing", [True, False], ids=["existing-out", "fresh-out"])
def test_a_refused_train_leaves_out_as_it_was(tmp_path, extra, existing):
    out = tmp_path / "run"
    if existing:
        out.mkdir()
        (out / "config.yml").write_text("env_id: the user's earlier run\n")
        (out / "notes.txt").write_text("the user's\n")
    before = snapshot(tmp_path)
    argv = ["train", "--env", "drillgym/Population-Motor-v0", "--algo", "ppo", "--timesteps", "0", "--out", "run"]
    code, _, err = run([*argv, "--no-progress", "--no-tensorboard", *extra], tmp_path)
    refused_line(code, err)
    assert snapshot(tmp_path) == before  # nothing created, changed or deleted
    assert existing or not out.exists()


# --------------------------------------------------------------------------------------- writing where it reads


#: command lines whose output is, or holds, one of their inputs (``{P}``: a policy, ``{R}``: a run directory holding
#: model.zip and policy.npz, ``{C}``: a recording)
OUTPUT_IS_INPUT = {
    "combine-policies": ["combine-policies", "{P}", "{R}", "--edges", "3", "--out", "{P}"],
    "combine-policies-run": ["combine-policies", "{P}", "{R}", "--edges", "3", "--out", "{R}/policy.npz"],
    "average-policies": ["average-policies", "{R}", "{P}", "--out", "{P}"],
    "train-init": ["train", "--algo", "ppo", "--timesteps", "64", "--init", "{R}", "--out", "{R}"],
    "train-init-file": ["train", "--algo", "ppo", "--timesteps", "64", "--init", "{R}/model.zip", "--out", "{R}"],
    "train-teacher": ["train", "--algo", "ppo", "--timesteps", "0", "--teacher", "{R}/policy.npz", "--out", "{R}"],
    "simulate-input": ["simulate", "--input", "{C}", "--duration", "0.1", "--out", "{C}"],
    "rig-run-play": ["rig", "run", "--port", "loop://", "--controller", "play:{C}", "--duration", "0.1", "--dry-run"]
    + ["--no-realtime", "--record", "{C}"],
}


@pytest.mark.parametrize("name", sorted(OUTPUT_IS_INPUT))
def test_an_output_that_is_or_holds_an_input_is_refused(name, a, tmp_path):
    """A run that would write over what it reads (the networks it combines, the run it starts from, its teacher,
    its input signal) is refused in one line naming the output, with every file as it was."""
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    shutil.copy(KEPT, run_dir / "policy.npz")
    shutil.copy(KEPT.parents[1] / "torsional_motor_ppo" / "model.zip", run_dir / "model.zip")
    z = dict(np.load(KEPT))
    np.savez(tmp_path / "p.npz", **{k: (v * 1.01).astype(v.dtype) if k.startswith("W") else v for k, v in z.items()})
    shutil.copy(a.signal, tmp_path / "sig.csv")
    names = {"{P}": str(tmp_path / "p.npz"), "{R}": str(run_dir), "{C}": str(tmp_path / "sig.csv")}
    argv = [names.get(w, w) for w in OUTPUT_IS_INPUT[name]]
    argv = [w.replace("{R}", str(run_dir)).replace("{C}", names["{C}"]) for w in argv]
    if argv[0] == "train":
        argv += ["--no-progress", "--no-tensorboard"]
    before = snapshot(tmp_path)
    code, _, err = run(argv, tmp_path)
    assert ("--record" if argv[0] == "rig" else "--out") in refused_line(code, err)
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("report", ["m.json", "m.json/report"], ids=["same", "under"])
def test_two_outputs_of_one_run_on_one_path_are_refused(report, a, tmp_path):
    """identify --out m.json --report m.json: the report's directory where the model file goes (it wrote the model,
    then failed with a traceback). Refused before the recording is read, nothing written."""
    argv = ["identify", a.torsional, "--add-effect", "motor_lag", "--out", "m.json", "--report", report]
    before = snapshot(tmp_path)
    code, _, err = run([*argv, "--max-nfev", "1", "--segment", "none"], tmp_path)
    line = refused_line(code, err)
    assert "--out" in line and "--report" in line
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize(
    "argv",
    [["params", "--out", "{M}"], ["identify-staged", "--upper", "{U}", "--out", "{M}"]],
    ids=["params", "identify-staged"],
)
def test_base_parameters_are_not_written_over_a_model_with_effects(argv, a, tmp_path):
    """A file of base parameters written over a model file that holds effects would lose them: refused, the model
    file as it was."""
    model = tmp_path / "model.json"
    shutil.copy(a.root / "model.json", model)  # a model with motor_lag
    argv = [w.replace("{M}", str(model)).replace("{U}", a.upper) for w in argv]
    before = snapshot(tmp_path)
    code, _, err = run(argv, tmp_path)
    assert "model file with effects (motor_lag)" in refused_line(code, err)
    assert snapshot(tmp_path) == before


# --------------------------------------------------------------------------------------- options needing another


def _dependency_cases():
    for cmd in commands():
        for dep in cmd.dependencies:
            yield pytest.param(cmd, dep, id=f"{' '.join(cmd.path)}:{dep.option}-{dep.kind}-{dep.needs}")


#: a value of an option that satisfies what another needs of it
SATISFY = {"--scenarios": "plants", "--seeds": "2", "--sweep-step": "0.5", "--reconnect": "1"}


@pytest.mark.parametrize("cmd,dep", list(_dependency_cases()))
def test_an_option_that_needs_another_is_refused_alone(cmd, dep, a, tmp_path):
    """Generated from the declared table: the option given without what it needs (or with what it excludes) is
    refused in the table's one line, before anything is read or written."""
    argv = base_argv(cmd, a)
    params = {p.name: p for p in cmd.params} | {p.secondary: p for p in cmd.params if p.secondary}

    def give(argv: list[str], name: str) -> list[str]:
        p = params[name]
        if p.kind == "flag":
            return argv + [name]
        if name in argv:
            i = argv.index(name)
            return argv[:i] + argv[i + 2 :] + [name, valid_value(p, a)]
        return argv + [name, valid_value(p, a)]

    if dep.kind == "requires" and dep.when is None:
        for other in dep.satisfiers:  # what the option needs, left out of the base (checked before the body runs)
            while other in argv and params[other].kind != "flag":
                i = argv.index(other)
                argv = argv[:i] + argv[i + 2 :]
    argv = give(argv, dep.option) if not dep.example else argv + [dep.option, dep.example]
    needs = params[dep.needs]
    if dep.kind == "excludes":
        argv = give(argv, dep.needs)
        for other in cmd.dependencies:  # what the excluded option needs in turn, given
            if other.option == dep.needs and other.kind == "requires":
                argv = argv + [other.needs, SATISFY.get(other.needs, valid_value(params[other.needs], a))]
    elif needs.kind == "flag" and needs.default is True:  # on by default: given alone means switched off
        argv = argv + [needs.secondary]
    before = snapshot(tmp_path)
    code, _, err = run(argv, tmp_path)
    assert refused_line(code, err) == f"drillgym: error: {dep.message()}"
    assert snapshot(tmp_path) == before


def test_every_trust_option_says_what_it_trusts():
    """``--trust`` means something only beside a model file; every command that takes it declares which option
    gives that file, so ``--trust`` alone is refused rather than ignored."""
    for cmd in commands():
        if any(p.name == "--trust" for p in cmd.params):
            deps = [d for d in cmd.dependencies if d.option == "--trust" and d.kind == "requires"]
            assert deps, f"{' '.join(cmd.path)}: --trust declares no option it needs"
            names = {p.name for p in cmd.params}
            assert set(deps[0].satisfiers) <= names and ("--model" in names) == ("--model" in deps[0].satisfiers)


def test_the_dependency_table_covers_the_probed_options():
    declared = {(c.path, d.option, d.needs) for c in commands() for d in c.dependencies}
    assert (("evaluate",), "--excitation", "--identify") in declared
    assert (("evaluate",), "--uncertainty", "--scenarios") in declared


def test_a_dependency_is_checked_before_the_command_runs():
    app = typer.Typer()
    ran = []

    @app.command()
    @requires("--excitation", "--identify")
    @excludes("--model", "--identify", why="one model per plant")
    def cmd(identify: bool = typer.Option(False, "--identify"), excitation: float | None = None, model: str = ""):
        ran.append(True)

    from typer.testing import CliRunner

    r = CliRunner().invoke(app, ["--excitation", "10"])
    assert isinstance(r.exception, InputError) and str(r.exception) == "--excitation needs --identify" and not ran
    r = CliRunner().invoke(app, ["--identify", "--model", "m"])
    assert str(r.exception) == "--model cannot go with --identify (one model per plant)" and not ran
    assert CliRunner().invoke(app, ["--identify", "--excitation", "10"]).exit_code == 0 and ran


def test_a_dependency_with_alternatives_is_met_by_any_of_them():
    app = typer.Typer()
    ran = []

    @app.command()
    @requires("--trust", "--model", alternatives=("--params",), why="it trusts a model file")
    def cmd(trust: bool = typer.Option(False, "--trust"), model: str | None = None, params: str | None = None):
        ran.append(True)

    from typer.testing import CliRunner

    r = CliRunner().invoke(app, ["--trust"])
    assert str(r.exception) == "--trust needs --model or --params (it trusts a model file)" and not ran
    for other in ("--model", "--params"):
        assert CliRunner().invoke(app, ["--trust", other, "m.json"]).exit_code == 0
    assert len(ran) == 2


# --------------------------------------------------------------------------------------- networks checked on load


def _policy(tmp: Path, name: str, change) -> str:
    z = dict(np.load(KEPT))
    change(z)
    np.savez(tmp / name, **z)
    return str(tmp / name)


def _nan(z):
    z["W1"] = z["W1"].copy()
    z["W1"][3, 4] = np.nan


def _inf_bias(z):
    z["b0"] = z["b0"].copy()
    z["b0"][0] = np.inf


def _broken_chain(z):
    z["W1"] = z["W1"][:, :-2]


def _two_actions(z):
    z["W2"] = np.vstack([z["W2"], z["W2"]])
    z["b2"] = np.concatenate([z["b2"], z["b2"]])
    z["action_low"] = np.array([-1.0, -1.0], dtype=np.float32)
    z["action_high"] = np.array([1.0, 1.0], dtype=np.float32)


def _wider_observation(z):
    meta = json.loads(str(z["meta"]))
    meta["obs_dim"] += 3
    z["meta"] = np.array(json.dumps(meta))
    z["W0"] = np.hstack([z["W0"], np.zeros((z["W0"].shape[0], 3), dtype=z["W0"].dtype)])


BAD_NETWORKS = {
    "nan-weight": (_nan, "W1 holds 1 non-finite"),
    "inf-bias": (_inf_bias, "b0 holds 1 non-finite"),
    "broken-chain": (_broken_chain, "layer 1"),
    "two-actions": (_two_actions, "2 actions"),
    "wider-observation": (_wider_observation, "observation entries"),
}


@pytest.mark.parametrize("kind", sorted(BAD_NETWORKS))
@pytest.mark.parametrize("command", ["benchmark", "evaluate", "average-policies", "combine-policies"])
def test_a_bad_network_is_refused_on_load(tmp_path, kind, command):
    change, words = BAD_NETWORKS[kind]
    bad = _policy(tmp_path, "bad.npz", change)
    good = str(tmp_path / "good.npz")
    shutil.copy(KEPT, good)
    argv = {
        "benchmark": ["benchmark", "drillgym/Nominal-Motor-v0", "--policy", f"agent:{bad}", "--duration", "0.5"]
        + ["--window", "0.2", "--targets", "1"],
        "evaluate": ["evaluate", "--config", "torsional", "--controllers", f"agent:{bad}", "--targets", "1"]
        + ["--duration", "0.2", "--window", "0.1", "--workers", "1", "--out", "ev"],
        "average-policies": ["average-policies", good, bad, "--out", "avg.npz"],
        "combine-policies": ["combine-policies", good, bad, "--edges", "3", "--out", "comb.npz"],
    }[command]
    if command in ("average-policies", "combine-policies") and kind in ("two-actions", "wider-observation"):
        pytest.skip("a network that loads: the average and the switch refuse it against their first member")
    before = snapshot(tmp_path)
    code, _, err = run(argv, tmp_path)
    line = refused_line(code, err)
    assert words in line, line
    assert snapshot(tmp_path) == before


def test_an_average_refuses_one_network_twice(tmp_path):
    copy = tmp_path / "copy.npz"
    shutil.copy(KEPT, copy)
    code, _, err = run(["average-policies", str(KEPT), str(KEPT), "--out", "avg.npz"], tmp_path)
    assert "the same file as network 1" in refused_line(code, err)
    code, _, err = run(["average-policies", str(copy), str(KEPT), "--out", "avg.npz"], tmp_path)
    assert "the same weights as network 1" in refused_line(code, err)
    assert not (tmp_path / "avg.npz").exists()


# --------------------------------------------------------------------------------------- a message with its context


def test_an_error_on_one_plant_names_it(monkeypatch):
    """A batch of plants that fails is run plant by plant: the one that fails names itself."""
    from controllers.evaluation import harness, population_jobs

    def diverging(controller, config, scenario, targets, base, pop, duration, window, seed, plants, model):
        if 2 in plants:
            raise SimulationError("the run diverged at t = 0.1 s")
        return []

    monkeypatch.setattr(population_jobs, "_run_plants", diverging)
    with pytest.raises(SimulationError) as e:
        harness.evaluate(["baseline"], ["torsional"], ["plants"], [2.0], duration=0.2, window=0.1, plants=3,
                         workers=1, progress=False)  # fmt: skip
    msg = str(e.value)
    assert msg.startswith("plant 2 of 3 (seed 0: km ") and msg.endswith("the run diverged at t = 0.1 s"), msg
    assert "identified" not in msg


def test_an_error_identifying_a_plant_names_it(monkeypatch):
    from controllers.evaluation import harness, identify
    from controllers.evaluation.identify import ExcitationOptions

    def failing(rec, names, opts):
        raise FitError("the fit did not converge")

    monkeypatch.setattr(identify, "identify_plant", failing)
    monkeypatch.setattr(identify, "excitation_recording", lambda *args: None)
    with pytest.raises(FitError) as e:
        harness.evaluate(["baseline"], ["torsional"], ["plants"], [2.0], duration=0.2, window=0.1, plants=2,
                         workers=1, progress=False, identify=ExcitationOptions(duration=2.0))  # fmt: skip
    msg = str(e.value)
    assert msg.startswith("plant 0 of 2 (seed 0: ") and ", identifying it: the fit did not converge" in msg, msg


@pytest.mark.parametrize("kind", [SimulationError, InputError])
def test_an_error_on_a_plant_s_identified_model_says_so(monkeypatch, kind):
    """A run that fails on a plant's identified model names the plant and says the model was its own; a model the
    controller refuses (an InputError) is that one warning line and the other plants go on."""
    from controllers.evaluation import harness, population_jobs

    class Identified:
        model = object()

        def columns(self):
            return {}

    def refusing(controller, config, scenario, targets, base, pop, duration, window, seed, plants, model):
        raise kind("the observer cannot run this model's lag")

    monkeypatch.setattr(population_jobs, "_run_plants", refusing)
    monkeypatch.setattr(population_jobs, "_identify_one", lambda *args: Identified())
    run_ = lambda: harness.evaluate(["baseline"], ["torsional"], ["plants"], [2.0], duration=0.2, window=0.1,  # noqa: E731
                                    plants=2, workers=1, progress=False, identify=True)  # fmt: skip
    if kind is InputError:
        with pytest.warns(UserWarning) as caught:
            assert run_() == []
        msg = str(caught[0].message)
    else:
        with pytest.raises(kind) as e:
            run_()
        msg = str(e.value)
    assert msg.startswith("plant 0 of 2 (seed 0: ") and "the model identified on that plant" in msg, msg
    assert msg.endswith("the observer cannot run this model's lag"), msg


@pytest.mark.parametrize(
    "W,b,words",
    [
        (np.array([[np.nan, 0.0, 1.0]]), np.zeros(1), "non-finite"),
        (np.zeros((1, 3)), np.array([np.inf]), "non-finite"),
        (np.zeros((2, 3)), np.zeros(2), "one action"),
        (np.array([["a", "b"]]), np.zeros(1), "of numbers"),
    ],
    ids=["nan-weight", "inf-offset", "two-actions", "text"],
)
def test_a_bad_linear_policy_is_refused_on_load(tmp_path, W, b, words):
    from hw.runner import LinearPolicy

    np.savez(tmp_path / "p.npz", W=W, b=b)
    with pytest.raises(InputError) as e:
        LinearPolicy.load(tmp_path / "p.npz")
    assert words in str(e.value) and "\n" not in str(e.value)


def test_a_benchmark_refuses_one_network_as_two_seeds(tmp_path):
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    shutil.copy(KEPT, run_dir / "policy.npz")
    argv = ["benchmark", "drillgym/Population-Motor-v0", "--policy", "agent:run", "--policy", "agent:run/policy.npz"]
    code, _, err = run(argv, tmp_path)
    assert "the same network as agent:run" in refused_line(code, err)


def test_a_run_that_diverges_leaves_no_directory(tmp_path):
    """simulate's outputs (and their missing directories) are created once the run succeeded."""
    (tmp_path / "stiff.json").write_text('{"Jl": 1e-6, "ktheta": 1000, "km": 50, "Ts": 50}')
    before = snapshot(tmp_path)
    argv = ["simulate", "--u", "3", "--duration", "0.5", "--params", "stiff.json", "--out", "new/x.csv"]
    code, _, err = run([*argv, "--plot", "fig/x.png"], tmp_path)
    assert "diverged" in refused_line(code, err)
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("command", ["average-policies", "combine-policies"])
def test_a_refused_network_leaves_no_output_directory(tmp_path, command):
    bad = _policy(tmp_path, "bad.npz", _nan)
    argv = [command, str(KEPT), bad, "--out", "new/dir/out.npz"] + (["--edges", "3"] if command[0] == "c" else [])
    before = snapshot(tmp_path)
    code, _, err = run(argv, tmp_path)
    assert "non-finite" in refused_line(code, err)
    assert snapshot(tmp_path) == before


def test_a_run_refused_midway_is_one_line_after_the_progress_bar(tmp_path, monkeypatch):
    """evaluate's progress bar is cleared before the refusal of a run that diverged: one line on the terminal."""
    from controllers.evaluation import harness

    def diverging(*args, **kw):
        raise SimulationError("the run diverged at t = 0.05 s")

    monkeypatch.setattr(harness, "run_job", diverging)
    argv = ["evaluate", "--config", "torsional", "--controllers", "baseline", "--targets", "1", "--duration", "0.2"]
    code, _, err = run([*argv, "--window", "0.1", "--workers", "1", "--out", "ev"], tmp_path)
    assert code == 2 and "\n" not in err.strip(), err
    assert err.strip().split("\r")[-1].startswith("drillgym: error: the run diverged"), err
    assert not (tmp_path / "ev").exists()
