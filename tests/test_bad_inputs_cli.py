"""Generated bad inputs for every ``drillgym`` command and subcommand.

Each test draws one option of one command and a bad value for it (a number out of range or not a
number, an empty string, a missing file, a directory for a file and a file for a directory, garbage
file contents, an unwritable or occupied output path, a value inconsistent with the configuration
or the recording) and runs the command in this process on tiny durations. The case passes when the
command refuses it in one line ``drillgym: error: ...`` with exit 2 naming the option (or gives the
documented valid result), and no file that existed before is changed or deleted.
"""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import pytest
from bad_inputs import (
    HOSTILE_MODELS,
    HUGE,
    Case,
    assert_refused,
    build_assets,
    build_hostile_models,
    check_case,
    choice_bad,
    finite_file,
    finite_float_bad,
    fresh_dir,
    input_file_bad,
    nonneg_int_bad,
    output_dir_bad,
    output_file_bad,
    positive_float_bad,
    positive_int_bad,
    run_cli,
)
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

pytestmark = pytest.mark.xdist_group("bad_inputs_cli")  # one worker builds the assets once

CONFIGS = ["upper", "torsional", "lateral", "coupled", "free_vibration"]


def examples(n: int):
    """Deterministic Hypothesis settings with ``n`` examples."""
    return settings(
        derandomize=True,
        deadline=None,
        max_examples=n,
        database=None,
        phases=[Phase.explicit, Phase.generate],  # no shrinking: a case is one command line already
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much],
    )


@pytest.fixture(scope="module")
def root(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("bad_inputs")


@pytest.fixture(scope="module")
def a(root):
    return build_assets(root / "assets")


def with_option(argv: list[str], option: str, value: str) -> list[str]:
    """``argv`` with ``option`` set to ``value`` (replaced if present, else appended)."""
    argv = list(argv)
    if option in argv:
        argv[argv.index(option) + 1] = value
    else:
        argv += [option, value]
    return argv


def draw_case(data, table: dict, base: list[str]) -> Case:
    """One option of ``table`` (option -> strategy or list of bad values) set to a bad value in ``base``."""
    option = data.draw(st.sampled_from(sorted(table)), label="option")
    bad = table[option]
    value = data.draw(bad if isinstance(bad, st.SearchStrategy) else st.sampled_from(bad), label="value")
    if isinstance(value, Case):
        return value
    return Case(with_option(base, option, value), (option,))


def effect_bad(a, config: str = "torsional") -> list[str]:
    """--add-effect values to refuse: unknown names, missing files, a file without the effect, a file that
    exits or raises on import, an effect that does not act in ``config``."""
    wrong = {"torsional": "lateral_anisotropy", "upper": "string_damping", "lateral": "brake_asymmetry"}[config]
    return [
        "nope",
        "",
        "position friction",
        f"{a.missing[:-4]}.py:NAME",
        f"{a.text}:NAME",
        f"{a.exiting_effect}:NAME",
        f"{a.raising_effect}:NAME",
        f"{a.adir}:NAME",
        wrong,
    ]


EFFECT_PARAM_BAD = ["tau_m", "=1", "tau_m=abc", "tau_m=", "nope=1", "tau_m=nan", "tau_m=inf", "tau_m=-5"]


def _completed(work: Path, *names: str):
    def check(root: Path, out: str) -> None:
        for n in names:
            assert (work / n).exists(), n

    return check


# --------------------------------------------------------------------------------------- simulate


@examples(25)
@given(data=st.data())
def test_simulate(data, a, root):
    work = fresh_dir(root)
    base = ["simulate", "--u", "3", "--duration", "0.1", "--out", str(work / "run.csv")]
    table = {
        "--config": choice_bad(CONFIGS),
        "--u": st.one_of(finite_float_bad(), st.sampled_from(["51", "-1e6", HUGE])),
        "--input": input_file_bad(a, kinds=("missing", "dir", "garbage_csv", "empty", "binary", "garbage_npz")),
        "--duration": st.one_of(positive_float_bad(), st.sampled_from(["0.1234567", "1e12"])),
        "--dt": st.one_of(positive_float_bad(), st.sampled_from(["0.3", "0.03", "0.07", "1e-12"])),
        "--method": choice_bad(["rk4", "dp5"]),
        "--params": input_file_bad(a, kinds=("missing", "dir", "not_params_json", "broken_json", "empty", "binary")),
        "--alpha0": st.one_of(finite_float_bad(), st.sampled_from(["1e9", "-1e9", HUGE])),
        "--record-every": st.one_of(positive_int_bad(), st.sampled_from(["7", "100000", "300"])),
        "--out": output_file_bad(a, work),
        "--plot": output_file_bad(a, work, ".png") + [str(work / "fig.xyz"), str(work / "keep.txt")],
        "--add-effect": effect_bad(a),
        "--effect-param": EFFECT_PARAM_BAD,
    }
    case = draw_case(data, table, base)
    if "--input" in case.argv:
        case.argv.remove("--u"), case.argv.remove("3")
    if "--effect-param" in case.argv and "tau_m=" in case.argv[-1] and case.argv[-1] != "tau_m=":
        case.argv += ["--add-effect", "motor_lag"]
    check_case(case, root)


def test_simulate_free_vibration_and_upper_combinations(a, root):
    work = fresh_dir(root)
    out = str(work / "r.csv")
    for argv, names in [
        (["--config", "free_vibration", "--u", "1", "--alpha0", "1"], ("--u",)),
        (["--config", "free_vibration"], ("--alpha0",)),
        (["--config", "upper", "--u", "1", "--add-effect", "string_damping"], ("string_damping",)),
        (["--u", "1", "--input", a.signal], ("--u", "--input")),
        (["--input", a.signal, "--duration", "5"], ("--duration",)),
        (["--u", "1", "--duration", "0.1", "--dt", "0.2"], ("--dt",)),
    ]:
        code, _, err = run_cli("simulate", *argv, "--out", out)
        assert_refused(code, err, *names)
    assert not Path(out).exists()


def test_simulate_summary_is_the_final_state_of_the_run(a, root):
    """The printed final speed is the run's last state, also when --record-every thins the output."""
    from drillgym import simulate
    from drillgym.configurations import Configuration

    work = fresh_dir(root)
    code, out, err = run_cli(
        "simulate", "--u", "4", "--duration", "0.2", "--record-every", "50", "--out", str(work / "r.csv")
    )
    assert code == 0, err
    traj = simulate(Configuration.TORSIONAL, 4.0, 0.2, dt=1e-3)
    assert f"final omega_l = {traj.omega_l[-1]:.4f} rad/s" in out
    finite_file(work / "r.csv")


# --------------------------------------------------------------------------------------- signal, params, effects


@examples(12)
@given(data=st.data())
def test_signal(data, a, root):
    work = fresh_dir(root)
    out = str(work / "sig.csv")
    base = ["signal", out, "--duration", "0.2", "--rate", "100"]
    table = {
        "OUT": [
            Case(["signal", p, "--duration", "0.2", "--rate", "100"], (p, "OUT")) for p in output_file_bad(a, work)
        ],
        "--kind": choice_bad(["quasi_random", "sum_of_sines"]),
        "--duration": st.one_of(positive_float_bad(), st.just("1e12")),
        "--rate": st.one_of(positive_float_bad(), st.just("1e12")),
        "--amplitude": st.one_of(positive_float_bad(), st.just("51")),
        "--offset": st.one_of(finite_float_bad(), st.sampled_from(["6", "-6"])),
        "--seed": ["abc", "1.5", "", "-1"],
    }
    check_case(draw_case(data, table, base), root)


@examples(8)
@given(data=st.data())
def test_params(data, a, root):
    work = fresh_dir(root)
    table = {
        "--out": output_file_bad(a, work, ".yaml") + [str(work / "p.csv"), str(work / "p.txt")],
        "--params": input_file_bad(
            a, kinds=("missing", "dir", "not_params_json", "broken_json", "binary", "garbage_csv")
        ),
    }
    check_case(draw_case(data, table, ["params"]), root)


@examples(10)
@given(show=st.sampled_from(["nope", "", "x.py:", ":NAME", "__init__"]) | st.just(None))
def test_effects_show(show, a, root):
    if show is None:
        return
    check_case(Case(["effects", "--show", show], ("--show", show or "effect")), root)


@pytest.mark.parametrize("which", ["exiting_effect", "raising_effect", "text", "missing"])
def test_effects_show_of_a_broken_file(a, root, which):
    spec = f"{getattr(a, which) if which != 'missing' else a.missing[:-4] + '.py'}:NAME"
    check_case(Case(["effects", "--show", spec], (Path(spec.split(":")[0]).name,)), root)


# --------------------------------------------------------------------------------------- compare, identify, diagnose


def recording_bad(a) -> list[str]:
    return [a.missing, a.adir, a.garbage_csv, a.empty, a.binary, a.garbage_npz, a.not_params_json, a.text]


@examples(20)
@given(data=st.data())
def test_compare(data, a, root):
    work = fresh_dir(root)
    base = ["compare", a.torsional, "--out", str(work / "cmp")]
    table = {
        "DATA": [Case(["compare", p, "--out", str(work / "cmp")], (Path(p).name,)) for p in recording_bad(a)],
        "--params": input_file_bad(a, kinds=("missing", "dir", "not_params_json", "broken_json", "binary")),
        "--config": choice_bad(CONFIGS) | st.just("lateral"),
        "--out": output_dir_bad(a, work),
        "--segment": st.sampled_from(["-1", "abc", "nan", "inf", "-inf", "", "1e300", "0.0001", "-0.5"]),
        "--rate": st.one_of(positive_float_bad(), st.sampled_from(["1e9", "100000"])),
        "--add-effect": effect_bad(a),
        "--effect-param": EFFECT_PARAM_BAD,
        "--map": ["theta_u", "=enc1", "theta_u=", "nope=enc1", "theta_u=nope", "theta_u=ScopeData:0"],
    }
    case = draw_case(data, table, base)
    check_case(case, root)


@examples(15)
@given(data=st.data())
def test_identify(data, a, root):
    work = fresh_dir(root)
    out = str(work / "model.json")
    base = ["identify", a.torsional, "--out", out, "--max-nfev", "1", "--segment", "none"]
    table = {
        "DATA": [Case(["identify", p, "--out", out], (Path(p).name,)) for p in recording_bad(a)],
        "--out": output_file_bad(a, work, ".json") + [str(work / "model.csv"), a.params],
        "--config": choice_bad(CONFIGS),
        "--add-effect": effect_bad(a),
        "--effect-param": EFFECT_PARAM_BAD,
        "--params": input_file_bad(a, kinds=("missing", "dir", "not_params_json", "broken_json", "binary")),
        "--fit": ["nope", "", "k", "kx", "Jl=1", "dk"],
        "--report": output_dir_bad(a, work),
        "--segment": st.sampled_from(["-1", "abc", "nan", "inf", "", "1e300", "-0.5"]),
        "--rate": st.one_of(positive_float_bad(), st.just("1e9")),
        "--max-nfev": positive_int_bad(),
        "--map": ["theta_u", "theta_u=nope"],
    }
    check_case(draw_case(data, table, base), root)


@examples(12)
@given(data=st.data())
def test_identify_staged(data, a, root):
    work = fresh_dir(root)
    out = str(work / "staged.json")
    base = ["identify-staged", "--upper", a.upper, "--out", out]
    table = {
        "--out": output_file_bad(a, work, ".json") + [str(work / "p.csv"), a.params],
        "--upper": recording_bad(a) + [a.torsional, a.lateral],
        "--free-vibration": recording_bad(a) + [a.torsional],
        "--lower": recording_bad(a) + [a.upper],
        "--lateral": recording_bad(a) + [a.upper],
        "--brake": recording_bad(a),
        "--validate": [
            "upper",
            "nope=" + a.upper,
            "upper=" + a.missing,
            "upper=" + a.garbage_csv,
            "upper=" + a.lateral,
        ],
        "--params": input_file_bad(a, kinds=("missing", "dir", "not_params_json", "broken_json")),
    }
    case = draw_case(data, table, base)
    case.names += tuple(Path(v.split("=")[-1]).name for v in case.argv[1:] if "/" in v)
    check_case(case, root)


@examples(15)
@given(data=st.data())
def test_diagnose(data, a, root):
    """Only refused values: a diagnosis that runs takes minutes."""
    work = fresh_dir(root)
    base = ["diagnose", a.torsional, "--segment", "none", "--candidate-out", str(work / "cand.py")]
    table = {
        "DATA": [Case(["diagnose", p], (Path(p).name,)) for p in recording_bad(a)],
        "--params": input_file_bad(a, kinds=("missing", "dir", "not_params_json", "broken_json")),
        "--config": choice_bad(CONFIGS),
        "--segment": st.sampled_from(["-1", "abc", "nan", "inf", "", "-0.5"]),
        "--rate": positive_float_bad(),
        "--candidate-out": output_file_bad(a, work, ".py") + [str(work / "cand.txt"), a.exiting_effect],
        "--add-effect": effect_bad(a),
        "--effect-param": EFFECT_PARAM_BAD,
        "--candidate": ["nope", "", f"{a.exiting_effect}:NAME", f"{a.text}:NAME"],
        "--map": ["theta_u", "theta_u=nope"],
        "--plot": output_file_bad(a, work, ".png") + [str(work / "fig.xyz"), str(work / "keep.txt")],
    }
    check_case(draw_case(data, table, base), root)


# --------------------------------------------------------------------------------------- bifurcation


@examples(20)
@given(data=st.data())
def test_bifurcation(data, a, root):
    """Only refused values: a diagram takes tens of seconds; every refusal comes before the work."""
    work = fresh_dir(root)
    base = ["bifurcation", "--out", str(work / "bif"), "--umax", "1", "--sweep-step", "0"]
    table = {
        "--config": choice_bad(["torsional", "lateral", "coupled"]) | st.sampled_from(["upper", "free_vibration"]),
        "--out": output_dir_bad(a, work),
        "--umin": st.one_of(finite_float_bad(), st.sampled_from(["2", "-60", HUGE])),
        "--umax": st.one_of(finite_float_bad(), st.sampled_from(["-1", "0", "60", HUGE])),
        "--measured": recording_bad(a) + [a.lateral],
        "--params": input_file_bad(a, kinds=("missing", "dir", "not_params_json", "broken_json")),
        "--sweep-step": st.one_of(finite_float_bad(), st.sampled_from(["-0.05", "5", "1e-9"])),
        "--sweep-duration": positive_float_bad(),
        "--ds-max": positive_float_bad(),
        "--ray": ["", "nope", "127.0.0.1:1", "host:notaport"],
        "--add-effect": effect_bad(a),
        "--effect-param": EFFECT_PARAM_BAD,
    }
    case = draw_case(data, table, base)
    if "--sweep-duration" in case.argv:
        case.argv = with_option(case.argv, "--sweep-step", "0.5")
    check_case(case, root)


# --------------------------------------------------------------------------------------- evaluate, train, policies


@examples(15)
@given(data=st.data())
def test_evaluate(data, a, root):
    work = fresh_dir(root)
    base = [
        "evaluate",
        "--config",
        "torsional",
        "--controllers",
        "baseline",
        "--targets",
        "1",
        "--duration",
        "0.2",
        "--window",
        "0.1",
        "--workers",
        "1",
        "--out",
        str(work / "ev"),
    ]
    table = {
        "--config": choice_bad(["torsional", "coupled", "lateral"]) | st.sampled_from(["upper", ",", "free_vibration"]),
        "--controllers": [
            "nope",
            ",",
            "baseline@0",
            "baseline@-5",
            "baseline@abc",
            "agent:" + a.missing,
            "agent:" + a.garbage_npz,
            "agent:" + a.adir,
        ],
        "--out": output_dir_bad(a, work),
        "--scenarios": choice_bad(["rest", "cycle", "friction-20", "friction+20", "noisy", "plants"]),
        "--plants": positive_int_bad(),
        "--seed": ["abc", "1.5", ""],
        "--uncertainty": input_file_bad(a, kinds=("missing", "dir", "garbage_csv", "binary", "not_params_json")),
        "--targets": ["abc", ",", "1,,2", "nan", "inf", "-1", "0", "1e9", "1;2"],
        "--duration": st.one_of(positive_float_bad(), st.just("1e12")),
        "--window": st.one_of(positive_float_bad(), st.just("0.5")),
        "--workers": positive_int_bad(),
        "--ray": ["nope", "127.0.0.1:1", "host:notaport", "256.1.1.1:6379"],
        "--params": input_file_bad(a, kinds=("missing", "dir", "not_params_json", "broken_json")),
        "--add-effect": effect_bad(a),
        "--effect-param": EFFECT_PARAM_BAD,
    }
    case = draw_case(data, table, base)
    if "--uncertainty" in case.argv or "--plants" in case.argv:
        case.argv = with_option(case.argv, "--scenarios", "plants")
        case.argv = with_option(
            case.argv, "--plants", case.argv[case.argv.index("--plants") + 1] if "--plants" in case.argv else "2"
        )
    check_case(case, root)


@examples(12)
@given(data=st.data())
def test_train(data, a, root):
    """Only refused values: training is minutes."""
    work = fresh_dir(root)
    base = ["train", "--out", str(work / "run"), "--timesteps", "1", "--no-progress", "--no-tensorboard"]
    table = {
        "--env": ["nope", "", "drillgym/Nope-v0", "CartPole-v1"],
        "--algo": choice_bad(["ppo", "sac", "td3", "recurrentppo"]),
        "--out": output_dir_bad(a, work),
        "--obs": choice_bad(["full", "sensors", "motor"]),
        "--timesteps": nonneg_int_bad(),
        "--seed": ["abc", "1.5", "", "-1"],
        "--seeds": positive_int_bad(),
        "--workers": positive_int_bad(),
        "--ray": ["", "nope", "127.0.0.1:1"],
        "--eval-every": nonneg_int_bad(),
        "--n-envs": positive_int_bad(),
        "--hyperparams": input_file_bad(a, kinds=("missing", "dir", "binary", "not_params_json", "broken_json")),
        "--set": ["nope", "=1", "nope_key=1", "learning_rate=abc", "env_kwargs.nope=1"],
        "--checkpoint-every": positive_int_bad(),
        "--teacher": input_file_bad(a, kinds=("missing", "dir", "garbage_npz", "binary")),
        "--add-effect": effect_bad(a),
        "--effect-param": EFFECT_PARAM_BAD,
    }
    case = draw_case(data, table, base)
    if "--ray" in case.argv or "--workers" in case.argv:
        case.argv = with_option(case.argv, "--seeds", "2")
    check_case(case, root)


@pytest.mark.parametrize("setting", ["nope_key=1", "env_kwargs.nope=1"])
def test_a_refused_train_setting_leaves_no_run_directory(setting, root):
    """The run directory (and its config.yml) is written once the algorithm took every --set key."""
    run = fresh_dir(root) / "run"
    code, _, err = run_cli("train", "--out", str(run), "--timesteps", "1", "--no-progress", "--no-tensorboard",
                           "--set", setting)  # fmt: skip
    assert_refused(code, err, "--set")
    assert not run.exists()


@examples(8)
@given(data=st.data())
def test_combine_policies(data, a, root):
    work = fresh_dir(root)
    out = str(work / "combined.npz")
    table = {
        "POLICIES": [
            Case(["combine-policies", p, p, "--edges", "3", "--out", out], (Path(p).name,))
            for p in recording_bad(a) + [a.policy_zip]
        ],
        "--edges": [
            Case(
                ["combine-policies", a.garbage_npz, a.garbage_npz, "--edges", e, "--out", out],
                ("--edges", a.garbage_npz),
            )
            for e in ["abc", "", "nan", "3,2", "-1"]
        ],
        "--out": [
            Case(
                ["combine-policies", a.garbage_npz, a.garbage_npz, "--edges", "3", "--out", p], ("--out", "garbage.npz")
            )
            for p in output_file_bad(a, work, ".npz")
        ],
    }
    check_case(draw_case(data, table, []), root)


@examples(5)
@given(config=choice_bad(["torsional", "coupled", "lateral", "upper"]))
def test_prepare(config, a, root):
    check_case(Case(["prepare", "--config", config], ("--config",)), root)


# --------------------------------------------------------------------------------------- rig


def _alarm(signum, frame):  # pragma: no cover - only when a command hangs
    raise KeyboardInterrupt


def check_case_within(case: Case, root: Path, seconds: int) -> None:
    """:func:`check_case`, interrupted after ``seconds`` (a value wrongly accepted would run on)."""
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(seconds)
    try:
        check_case(case, root)
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


@examples(12)
@given(data=st.data())
def test_rig_run(data, a, root):
    """Refused before the port is opened: nothing on the port answers."""
    work = fresh_dir(root)
    base = [
        "rig",
        "run",
        "--port",
        "loop://",
        "--controller",
        "const:1",
        "--duration",
        "0.1",
        "--record",
        str(work / "r.csv"),
        "--dry-run",
        "--no-realtime",
    ]
    table = {
        "--port": ["", a.missing, a.adir, a.text],
        "--controller": ["nope", "const:abc", "const:nan", "const:1e9", "play:" + a.missing, "play:" + a.garbage_csv],
        "--params": input_file_bad(a, kinds=("missing", "dir", "not_params_json", "broken_json")),
        "--policy": input_file_bad(a, kinds=("missing", "dir", "garbage_npz", "binary")),
        "--duration": positive_float_bad(),
        "--record": [p for p in output_file_bad(a, work) if p not in (a.adir, str(work))],  # a directory: documented
        "--config": choice_bad(["torsional", "lateral", "coupled"]),
        "--observation": choice_bad(["full", "sensors", "motor"]),
        "--omega-ref": finite_float_bad(),
        "--control-ms": positive_float_bad(),
        "--seed": ["abc", "1.5", ""],
        "--reply-timeout-ms": positive_float_bad(),
        "--reconnect": nonneg_int_bad(),
        "--reconnect-wait": st.one_of(finite_float_bad(), st.just("-1")),
    }
    check_case_within(draw_case(data, table, base), root, seconds=20)


@examples(10)
@given(data=st.data())
def test_rig_tune(data, a, root):
    """Refused before the port is opened and before the excitation moves anything."""
    work = fresh_dir(root)
    base = ["rig", "tune", "--port", "loop://", "--model-out", str(work / "m.json"), "--record", str(work / "r.csv")]
    base += ["--duration", "0.1", "--no-realtime"]
    table = {
        "--port": ["", a.missing, a.adir, a.text],
        "--model-out": [str(work / "m.txt"), *[p for p in output_file_bad(a, work, ".json") if p != str(work)]],
        "--record": [p for p in output_file_bad(a, work) if p not in (a.adir, str(work))],
        "--duration": positive_float_bad(),
        "--control-ms": positive_float_bad(),
        "--config": choice_bad(["torsional", "coupled"]),
        "--seed": ["abc", "1.5", ""],
    }
    check_case_within(draw_case(data, table, base), root, seconds=20)


@examples(10)
@given(data=st.data())
def test_rig_emulate(data, a, root):
    """Refused before the pseudo-terminal opens (an accepted value would run until the alarm)."""
    work = fresh_dir(root)
    base = ["rig", "emulate", "--port", str(work / "tty"), "--no-realtime"]
    table = {
        "--port": [a.text, str(work / "keep.npz"), a.adir, a.under_file, "/proc/drillgym_tty", ""],
        "--config": choice_bad(["torsional", "lateral", "coupled"]),
        "--params": input_file_bad(a, kinds=("missing", "dir", "not_params_json", "broken_json")),
        "--add-effect": effect_bad(a),
        "--effect-param": EFFECT_PARAM_BAD,
        "--counts-per-rev": positive_int_bad(),
        "--lvdt-noise": st.one_of(finite_float_bad(), st.just("-1")),
        "--latency-ms": st.one_of(finite_float_bad(), st.just("-1")),
        "--jitter-ms": st.one_of(finite_float_bad(), st.just("-1")),
        "--period-ms": positive_float_bad(),
        "--watchdog-ms": positive_float_bad(),
        "--dt": positive_float_bad(),
        "--alpha0": st.one_of(finite_float_bad(), st.just("1e9")),
        "--seed": ["abc", "1.5", ""],
    }
    check_case_within(draw_case(data, table, base), root, seconds=10)


@examples(6)
@given(data=st.data())
def test_rig_estop(data, a, root):
    table = {
        "--port": ["", a.missing, a.adir, a.text],
        "--attempts": positive_int_bad(),
        "--timeout-ms": positive_float_bad(),
    }
    check_case(draw_case(data, table, ["rig", "estop", "--port", a.missing]), root)


# --------------------------------------------------------------------------------------- the parser


@pytest.mark.parametrize(
    "argv,name",
    [
        (["simulate", "--u", "1"], "--out"),
        (["simulate", "--u", "abc", "--out", "x.csv"], "--u"),
        (["simulate", "--nope", "1"], "--nope"),
        (["nope"], "nope"),
        (["rig", "nope"], "nope"),
        (["compare"], "DATA"),
        (["identify", "x.csv"], "--out"),
        (["train", "--seeds", "abc", "--out", "x"], "--seeds"),
    ],
)
def test_usage_errors_are_one_line(argv, name, root):
    check_case(Case(argv, (name, name.lower())), root)


# --------------------------------------------------------------------------------------- real exit codes


@pytest.mark.parametrize(
    "argv,name",
    [
        (["simulate", "--u", "1", "--duration", "0.1", "--out", "{w}/r.csv", "--plot", "/proc/x.png"], "--plot"),
        (["simulate", "--u", "abc", "--out", "{w}/r.csv"], "--u"),
    ],
)
def test_real_exit_codes(argv, name, root):
    work = fresh_dir(root)
    argv = [v.replace("{w}", str(work)) for v in argv]
    proc = subprocess.run(
        [sys.executable, "-m", "drillgym.cli", *argv], capture_output=True, text=True, timeout=120, cwd=work
    )
    assert_refused(proc.returncode, proc.stderr, name)
    assert sorted(p.name for p in work.iterdir()) == ["keep.npz", "keep.txt"]


# --------------------------------------------------------------------------------------- model files


def _model_consumers(a, work: Path) -> dict[str, list[str]]:
    """A command line of every consumer of ``--model`` (the model file appended by the test)."""
    return {
        "simulate": ["simulate", "--u", "1", "--duration", "0.1", "--out", str(work / "run.csv")],
        "compare": ["compare", a.torsional, "--out", str(work / "cmp")],
        "bifurcation": ["bifurcation", "--out", str(work / "bif"), "--umax", "1", "--sweep-step", "0"],
        "evaluate": ["evaluate", "--controllers", "observer", "--targets", "1", "--duration", "0.2"]
        + ["--window", "0.1", "--workers", "1", "--out", str(work / "ev")],
        "benchmark": ["benchmark", "drillgym/Nominal-Motor-v0", "--policy", "baseline", "--duration", "0.5"]
        + ["--window", "0.2", "--targets", "1"],
        "train": ["train", "--out", str(work / "run"), "--timesteps", "1", "--no-progress", "--no-tensorboard"],
        "rig run": ["rig", "run", "--port", "loop://", "--controller", "observer", "--duration", "0.1", "--dry-run"]
        + ["--no-realtime", "--record", str(work / "r.csv")],
        "rig emulate": ["rig", "emulate", "--port", str(work / "tty"), "--no-realtime"],
    }


@pytest.fixture(scope="module")
def hostile_models(root):
    return build_hostile_models(root / "hostile")


@pytest.mark.parametrize("name", sorted(HOSTILE_MODELS))
@pytest.mark.parametrize("consumer", ["simulate", "compare", "evaluate", "rig emulate"])
def test_a_hostile_model_file_is_refused_by_its_consumers(consumer, name, hostile_models, a, root):
    """A model file with one thing wrong (a number no float holds, provenance of the wrong types, a later
    version, a value or standard error filed under the wrong effect or no parameter, an unknown record key) is
    refused in one line naming --model, before anything is written."""
    work = fresh_dir(root)
    argv = [*_model_consumers(a, work)[consumer], "--model", hostile_models[name]]
    assert check_case(Case(argv, ("--model",)), root) == "refused"


@pytest.mark.parametrize("consumer", ["bifurcation", "benchmark", "train", "rig run"])
def test_every_consumer_of_a_model_file_refuses_a_hostile_one(consumer, hostile_models, a, root):
    work = fresh_dir(root)
    for name in ("huge_integer", "provenance_types", "later_version"):
        argv = [*_model_consumers(a, work)[consumer], "--model", hostile_models[name]]
        assert check_case(Case(argv, ("--model",)), root) == "refused", name


#: an evaluation of the plants scenario, the file option to add
EVALUATE_PLANTS = ["evaluate", "--controllers", "baseline", "--targets", "1", "--scenarios", "plants"]


@pytest.mark.parametrize(
    "argv, option",
    [
        (["simulate", "--u", "1", "--duration", "0.1", "--params", "{F}"], "--params"),
        (["simulate", "--u", "1", "--duration", "0.1", "--model", "{F}"], "--model"),
        ([*EVALUATE_PLANTS, "--uncertainty", "{F}"], "--uncertainty"),
        ([*EVALUATE_PLANTS, "--plants-file", "{F}"], "--plants-file"),
        (["train", "--timesteps", "1", "--no-progress", "--no-tensorboard", "--hyperparams", "{F}"], "--hyperparams"),
    ],
    ids=["params", "model", "uncertainty", "plants-file", "hyperparams"],
)
def test_every_reader_of_a_yaml_file_refuses_a_key_given_twice(argv, option, a, root):
    """A key given twice is refused by every reader of a user's YAML file (the parsers keep the last without a word)."""
    work = fresh_dir(root)
    argv = [w.replace("{F}", a.duplicate_key_yaml) for w in argv] + ["--out", str(work / "out")]
    line = assert_refused(*run_cli(*argv)[::2], option)
    assert "twice" in line, line


@pytest.mark.parametrize(
    "argv",
    [
        ["simulate", "--u", "1", "--duration", "0.1", "--out", "{W}/run.csv"],
        ["compare", "{A}/torsional.csv", "--out", "{W}/cmp"],
        ["identify", "{A}/torsional.csv", "--out", "{W}/m.json", "--max-nfev", "1", "--segment", "none"],
        ["bifurcation", "--out", "{W}/bif", "--umax", "1", "--sweep-step", "0"],
        ["evaluate", "--controllers", "baseline", "--targets", "1", "--out", "{W}/ev"],
        ["train", "--out", "{W}/run", "--timesteps", "1", "--no-progress", "--no-tensorboard"],
        ["rig", "emulate", "--port", "{W}/tty", "--no-realtime"],
    ],
    ids=lambda argv: " ".join(argv[:2]) if argv[0] == "rig" else argv[0],
)
def test_an_effect_parameter_given_twice_is_refused(argv, a, root):
    """``--effect-param tau_m=0.03 --effect-param tau_m=0.04``: which value was meant is not the tool's to guess."""
    work = fresh_dir(root)
    argv = [w.replace("{W}", str(work)).replace("{A}", str(a.root)) for w in argv]
    argv += ["--add-effect", "motor_lag", "--effect-param", "tau_m=0.03", "--effect-param", "tau_m=0.04"]
    check_case_within(Case(argv, ("--effect-param 'tau_m=0.04': 'tau_m' is given twice",)), root, seconds=60)


def test_identify_refuses_an_effect_the_params_model_holds(a, root):
    """identify --params MODEL --add-effect E, MODEL holding E: which of the two is fitted is not for the tool to
    guess (compare and diagnose refuse it as an effect given twice)."""
    work = fresh_dir(root)
    model = work / "model.json"
    model.write_text('{"effects": [{"spec": "motor_lag", "values": {"tau_m": 0.03}}]}')
    argv = ["identify", a.torsional, "--params", str(model), "--add-effect", "motor_lag", "--out", str(work / "m.json")]
    check_case(Case([*argv, "--max-nfev", "1", "--segment", "none"], ("--add-effect motor_lag",)), root)
