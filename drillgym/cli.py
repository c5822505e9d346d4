"""The ``drillgym`` command line: one program, one subcommand per job.

    drillgym simulate     simulate a configuration, write the run (csv, docs/data_format.md) and a figure
    drillgym bifurcation  open-loop bifurcation diagrams
    drillgym compare / diagnose / identify   model versus measurements
    drillgym evaluate     controllers and agents on the evaluation harness
    drillgym train        RL training
    drillgym rig ...      hardware twin (run, emulate)

Errors the user can fix (bad file, bad parameter, bad option) are printed as
one line naming what is wrong, with exit code 2; anything else is a bug and
prints its traceback.
"""

from __future__ import annotations

import sys
import traceback

import typer

from .commands import register_commands

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="drillgym: drill-string rig simulator, environments, analysis and hardware twin.",
)


@app.callback()
def _root() -> None:
    """drillgym: drill-string rig simulator, environments, analysis and hardware twin."""


register_commands(app)  # the core's commands, then those of installed packages (entry points)


def unset_help_is_false(group: typer.Typer) -> dict:
    """The ``default_map`` giving False to the ``--help`` of ``group`` and of its subgroups (by name).

    A group's ``--help`` not given is otherwise None, for which typer (0.29) builds a pydantic validator:
    pydantic would load (0.14 s, 20 MB) before every subcommand's help and every refused option.
    """
    return {"help": False, **{g.name: unset_help_is_false(g.typer_instance) for g in group.registered_groups if g.name}}


app.info.context_settings = {**(app.info.context_settings or {}), "default_map": unset_help_is_false(app)}


#: exit code of an error the user can act on (a :class:`~drillgym.errors.DrillgymError`)
USER_ERROR_EXIT = 2
#: exit code of a bug (any other exception): its traceback is printed
INTERNAL_ERROR_EXIT = 1
#: exit code of a run interrupted by the user (Ctrl-C), as a shell reports SIGINT
INTERRUPTED_EXIT = 130


def is_user_error(exc: BaseException) -> bool:
    """Whether ``exc`` is an error the user can act on, printed as one line.

    Parameters
    ----------
    exc : BaseException
        The exception that ended a command.

    Returns
    -------
    bool
        True for a :class:`~drillgym.errors.DrillgymError`, and for a
        :class:`~drillgym.parallel.TaskFailed` whose task raised one (a worker refused its
        input or its run diverged); False for anything else, which is a bug.
    """
    from .errors import DrillgymError

    if isinstance(exc, DrillgymError):
        return True
    from .parallel import TaskFailed

    return isinstance(exc, TaskFailed) and isinstance(exc.error, DrillgymError)


def one_line(exc: BaseException) -> str:
    """The message of ``exc`` on one line (line breaks of a wrapped message become spaces)."""
    return " ".join(part.strip() for part in str(exc).splitlines() if part.strip()) or type(exc).__name__


def main(argv: list[str] | None = None) -> None:
    """Run the ``drillgym`` command line (the console entry point).

    Parameters
    ----------
    argv : list of str, optional
        The arguments after the program name. Default: ``sys.argv[1:]``.

    Raises
    ------
    SystemExit
        Always, with the command's exit code: 0 on success, 2 (:data:`USER_ERROR_EXIT`) for a
        :class:`~drillgym.errors.DrillgymError` (bad input, a run or fit that cannot give a valid
        result, an unreachable service), printed as one line ``drillgym: error: ...`` on stderr,
        and 1 (:data:`INTERNAL_ERROR_EXIT`) for any other exception: a bug in drillgym, whose
        traceback is printed, followed by one line saying so. Usage errors found by the option
        parser exit 2 with its usage message; ``rig run`` has its own codes for a safety stop.
    """
    try:
        result = app(args=argv, standalone_mode=False)
    except typer.TyperException as exc:  # the option parser's usage errors: one line too
        if not is_help_request(exc):  # (the help of a group called alone is printed already)
            print(f"drillgym: error: {usage_message(exc)}", file=sys.stderr)
        sys.exit(USER_ERROR_EXIT)
    except typer.Abort:
        print("drillgym: aborted", file=sys.stderr)
        sys.exit(INTERRUPTED_EXIT)
    except Exception as exc:
        if is_user_error(exc):
            print(f"drillgym: error: {one_line(exc)}", file=sys.stderr)
            sys.exit(USER_ERROR_EXIT)
        traceback.print_exc()
        print(
            "drillgym: internal error: the traceback above is a bug in drillgym, not in your input; "
            "please report it with the command you ran",
            file=sys.stderr,
        )
        sys.exit(INTERNAL_ERROR_EXIT)
    # without standalone mode the parser returns a command's typer.Exit code (or None when it returned)
    sys.exit(result if isinstance(result, int) else 0)


def is_help_request(exc: typer.TyperException) -> bool:
    """Whether the parser's ``exc`` is a group called without a command (its message is the help)."""
    return type(exc).__name__ == "NoArgsIsHelpError"


def usage_message(exc: typer.TyperException) -> str:
    """A usage error of the option parser as one line, with where to find the valid options.

    Parameters
    ----------
    exc : typer.TyperException
        The parser's error (an unknown option or command, a missing option, a value of the wrong type).

    Returns
    -------
    str
        ``"<message> (see 'drillgym <command> --help')"`` on one line.
    """
    message = " ".join(part.strip() for part in exc.format_message().splitlines() if part.strip())
    ctx = getattr(exc, "ctx", None)
    if ctx is None:
        return message
    return f"{message} (see '{ctx.command_path} --help')"


if __name__ == "__main__":
    main()
