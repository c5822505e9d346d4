"""The error hierarchy and how the command line reports errors.

A :class:`drillgym.errors.DrillgymError` is an error the user can act on: the CLI prints it as one
line and exits with code 2. Anything else is a bug: its traceback is printed with one line saying
so, and the exit code is 1.
"""

from __future__ import annotations

import pytest

import drillgym
import drillgym.errors as E
from drillgym.cli import INTERNAL_ERROR_EXIT, USER_ERROR_EXIT, is_user_error, main, one_line

INPUT_KINDS = [
    E.InputError,
    E.InputTypeError,
    E.ParameterError,
    E.DataFormatError,
    E.EffectError,
    E.OutputPathError,
    E.MissingFileError,
]
RUN_KINDS = [E.SimulationError, E.FitError, E.FitFailedError, E.UnavailableError, E.SafetyError]


def run(capsys, *argv: str) -> tuple[int, str]:
    """Exit code and stderr of ``drillgym ARGV`` run in this process."""
    with pytest.raises(SystemExit) as exit_:
        main(list(argv))
    return exit_.value.code, capsys.readouterr().err


def assert_one_line(code: int, err: str, *words: str) -> None:
    assert code == USER_ERROR_EXIT == 2, err
    assert "Traceback" not in err and "internal error" not in err
    line = err.strip()
    assert "\n" not in line and line.startswith("drillgym: error: "), err
    for w in words:
        assert w in line, (w, line)


# --------------------------------------------------------------------------- the hierarchy


@pytest.mark.parametrize("kind", INPUT_KINDS + RUN_KINDS)
def test_every_kind_is_a_drillgym_error_exported_from_the_package(kind):
    assert issubclass(kind, E.DrillgymError)
    assert kind.__name__ in E.__all__ and kind.__name__ in drillgym.__all__
    assert getattr(drillgym, kind.__name__) is kind
    assert kind.__doc__


def test_every_name_of_the_module_is_a_kind():
    assert set(E.__all__) == {k.__name__ for k in INPUT_KINDS + RUN_KINDS} | {"DrillgymError"}


@pytest.mark.parametrize("kind", INPUT_KINDS)
def test_input_kinds_are_value_errors(kind):
    """``except ValueError`` in user code keeps catching bad input."""
    assert issubclass(kind, E.InputError) and issubclass(kind, ValueError)
    with pytest.raises(ValueError, match="bad value"):
        raise kind("bad value")


def test_type_and_missing_file_kinds_keep_their_builtin_bases():
    assert issubclass(E.InputTypeError, TypeError)
    assert issubclass(E.MissingFileError, FileNotFoundError)
    err = E.MissingFileError("x.csv: file not found")
    assert str(err) == "x.csv: file not found" and isinstance(err, OSError)


@pytest.mark.parametrize("kind", RUN_KINDS)
def test_run_kinds_are_runtime_errors_not_value_errors(kind):
    assert issubclass(kind, RuntimeError) and not issubclass(kind, ValueError)


def test_the_errors_of_the_subpackages_are_kinds_of_the_hierarchy():
    import hw.link
    import hw.protocol
    from drillgym.bifurcation import ShootingFailure
    from drillgym.parallel import RayUnavailable

    assert issubclass(RayUnavailable, E.UnavailableError)
    assert issubclass(ShootingFailure, E.FitError)
    assert issubclass(hw.protocol.ProtocolError, E.DrillgymError) and issubclass(hw.protocol.ProtocolError, ValueError)
    for link_error in (
        hw.link.LinkError,
        hw.link.LinkLostError,
        hw.link.LinkTimeoutError,
        hw.link.LinkCorruptError,
        hw.link.LinkSequenceError,
    ):
        assert issubclass(link_error, E.SafetyError)


def test_library_calls_raise_the_kinds():
    from drillgym import parse_configuration
    from drillgym.io import read_timeseries

    with pytest.raises(E.InputError, match="unknown configuration 'nope'"):
        parse_configuration("nope")
    with pytest.raises(E.DataFormatError, match="file not found"):
        read_timeseries("no/such/recording.csv")
    with pytest.raises(E.ParameterError):
        drillgym.RigParams(Jl=-1.0)


# --------------------------------------------------------------------------- what the CLI prints


def test_a_drillgym_error_is_one_line_with_exit_code_2(capsys, tmp_path):
    code, err = run(capsys, "simulate", "--config", "nope", "--u", "1", "--out", str(tmp_path / "run.csv"))
    assert_one_line(code, err, "unknown configuration 'nope'", "torsional")
    assert not (tmp_path / "run.csv").exists()


@pytest.mark.parametrize(
    "bug",
    [ZeroDivisionError("division by zero"), KeyError("omega_l"), ValueError("an internal ValueError is a bug too")],
)
def test_an_internal_error_prints_its_traceback_and_one_line_saying_so(capsys, monkeypatch, tmp_path, bug):
    """A bare ValueError is no longer taken for bad input: only a DrillgymError is."""
    import drillgym.configurations

    def broken(config):
        raise bug

    monkeypatch.setattr(drillgym.configurations, "parse_configuration", broken)
    code, err = run(capsys, "simulate", "--u", "1", "--duration", "0.01", "--out", str(tmp_path / "run.csv"))
    assert code == INTERNAL_ERROR_EXIT and code not in (0, 2)
    assert err.startswith("Traceback (most recent call last):")
    assert f"{type(bug).__name__}: " in err and "in broken" in err
    last = err.strip().splitlines()[-1]
    assert last.startswith("drillgym: internal error: ") and "bug in drillgym" in last
    assert err.count("internal error") == 1 and "drillgym: error:" not in err


def test_a_failed_task_is_one_line_when_its_task_refused_the_input():
    from drillgym.parallel import TaskFailed

    def job(x):
        return x

    assert is_user_error(E.FitError("no orbit"))
    assert is_user_error(TaskFailed(job, (3,), {}, E.SimulationError("diverged at t = 2 s")))
    assert not is_user_error(TaskFailed(job, (3,), {}, ZeroDivisionError("division by zero")))
    assert not is_user_error(TaskFailed(job, (3,), {}, "its worker process died"))
    assert not is_user_error(ValueError("not ours"))


def test_a_message_on_several_lines_is_printed_on_one():
    assert one_line(E.InputError("first part\n   second part\n")) == "first part second part"
    assert one_line(E.InputError("")) == "InputError"


# --------------------------------------------------------------------------- bad inputs across commands


def test_simulate_refuses_a_figure_format_before_the_run(capsys, tmp_path):
    code, err = run(
        capsys,
        "simulate",
        "--u",
        "1",
        "--duration",
        "0.01",
        "--out",
        str(tmp_path / "run.csv"),
        "--plot",
        str(tmp_path / "run.xyz"),
    )
    assert_one_line(code, err, "--plot", "run.xyz", ".png")
    assert not (tmp_path / "run.csv").exists()


def test_simulate_names_a_missing_parameter_file(capsys, tmp_path):
    code, err = run(
        capsys,
        "simulate",
        "--u",
        "1",
        "--duration",
        "0.01",
        "--params",
        str(tmp_path / "nope.yaml"),
        "--out",
        str(tmp_path / "run.csv"),
    )
    assert_one_line(code, err, "nope.yaml")


def test_params_names_the_option_of_a_bad_output_name(capsys, tmp_path):
    code, err = run(capsys, "params", "--out", str(tmp_path / "p.txt"))
    assert_one_line(code, err, "--out", "p.txt", ".json, .yaml or .yml")


def test_bifurcation_refuses_an_output_directory_that_is_a_file_before_the_work(capsys, tmp_path):
    (tmp_path / "taken").write_text("x")
    code, err = run(capsys, "bifurcation", "--out", str(tmp_path / "taken" / "diagram"))
    assert_one_line(code, err, "--out", "taken", "is a file")
    assert not (tmp_path / "taken" / "diagram").exists()


def test_signal_names_a_bad_amplitude(capsys, tmp_path):
    code, err = run(capsys, "signal", str(tmp_path / "u.csv"), "--amplitude", "100")
    assert_one_line(code, err, "amplitude", "100")


def test_evaluate_names_an_unknown_controller(capsys, tmp_path):
    code, err = run(capsys, "evaluate", "--controllers", "nope", "--out", str(tmp_path / "e"))
    assert_one_line(code, err, "unknown controller 'nope'", "baseline")


def test_rig_run_names_a_missing_serial_port(capsys, tmp_path):
    code, err = run(
        capsys, "rig", "run", "--port", str(tmp_path / "ttyNOPE"), "--controller", "const:1", "--duration", "1"
    )
    assert_one_line(code, err, "ttyNOPE", "does not exist")


def test_evaluate_refuses_an_output_directory_that_is_a_file_before_the_runs(capsys, monkeypatch, tmp_path):
    import controllers.evaluation

    def no_runs(*args, **kwargs):
        raise AssertionError("evaluate ran before its --out was checked")

    monkeypatch.setattr(controllers.evaluation, "evaluate", no_runs)
    taken = tmp_path / "results.txt"
    taken.write_text("x")
    code, err = run(
        capsys, "evaluate", "--controllers", "baseline", "--config", "torsional", "--targets", "1", "--out", str(taken)
    )
    assert_one_line(code, err, "--out", "results.txt", "is a file")
    assert taken.read_text() == "x"


@pytest.mark.parametrize("content", [b"not an npz", b"PK\x03\x04 not a zip archive", b""])
def test_rig_run_names_a_policy_file_that_is_not_an_npz_archive(capsys, tmp_path, content):
    bad = tmp_path / "policy.npz"
    bad.write_bytes(content)
    code, err = run(  # a port that exists (pyserial's loop): the policy is what is refused
        capsys, "rig", "run", "--port", "loop://", "--policy", str(bad), "--duration", "1", "--dry-run", "--no-realtime"
    )
    assert_one_line(code, err, "--policy", "policy.npz", "not a policy file")


def test_a_linear_policy_file_that_is_not_one_is_named(tmp_path):
    from hw.runner import load_policy

    bad = tmp_path / "linear.npz"
    for content in (b"PK\x03\x04 not a zip archive", b"not an npz"):
        bad.write_bytes(content)
        with pytest.raises(E.InputError, match="linear.npz: not a linear policy file"):
            load_policy(bad)
    with pytest.raises(E.MissingFileError, match="does not exist"):
        load_policy(tmp_path / "missing.npz")


@pytest.mark.parametrize(
    ("options", "words"),
    [
        (("--duration", "1", "--dt", "0.003"), ("--dt 0.003", "does not divide --duration 1", "0.999 s")),
        (("--duration", "2", "--record-every", "300"), ("--record-every 300", "2000 steps", "not be recorded")),
        (("--duration", "2", "--record-every", "100000"), ("--record-every 100000", "2000 steps")),
    ],
)
def test_simulate_refuses_a_step_grid_that_cuts_the_run_or_its_end(capsys, tmp_path, options, words):
    code, err = run(capsys, "simulate", "--u", "1", *options, "--out", str(tmp_path / "run.csv"))
    assert_one_line(code, err, *words)
    assert not (tmp_path / "run.csv").exists()


def test_simulate_records_the_end_of_the_run_when_the_grid_divides_it(capsys, tmp_path):
    from drillgym.io import read_timeseries

    with pytest.raises(SystemExit) as exit_:
        main(["simulate", "--u", "1", "--duration", "0.2", "--record-every", "40", "--out", str(tmp_path / "r.csv")])
    assert exit_.value.code in (0, None)
    assert read_timeseries(tmp_path / "r.csv").t[-1] == pytest.approx(0.2)


@pytest.mark.parametrize("rate", ["0", "-100", "nan"])
def test_compare_names_a_rate_that_is_not_positive(capsys, tmp_path, rate):
    with pytest.raises(SystemExit):
        main(["simulate", "--u", "1", "--duration", "1", "--out", str(tmp_path / "a.csv")])
    capsys.readouterr()
    code, err = run(capsys, "compare", str(tmp_path / "a.csv"), "--rate", rate, "--out", str(tmp_path / "cmp"))
    assert_one_line(code, err, "--rate", "positive")
