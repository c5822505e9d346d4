"""The ``drillgym`` command line: one program, one subcommand per job.

    drillgym simulate     simulate a configuration, write the run (DATA_FORMAT csv) and a figure
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

app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False,
                  help="drillgym: drill-string rig simulator, environments, analysis and hardware twin.")


@app.callback()
def _root() -> None:
    """drillgym: drill-string rig simulator, environments, analysis and hardware twin."""


register_commands(app)  # the core's commands, then those of installed packages (entry points)


def main(argv: list[str] | None = None) -> None:
    """Console entry point.

    A :class:`~drillgym.errors.DrillgymError` (bad input, a safety stop, a run that cannot give a
    valid result) is printed as one line on stderr with exit code 2. Any other exception is a bug
    in drillgym: its traceback is printed, followed by one line saying so, and the exit code is 1.
    """
    from .errors import DrillgymError

    try:
        app(args=argv, standalone_mode=True)
    except DrillgymError as exc:
        print(f"drillgym: error: {exc}", file=sys.stderr)
        sys.exit(2)
    except Exception:
        traceback.print_exc()
        print("drillgym: internal error: the traceback above is a bug in drillgym, not in your input; "
              "please report it with the command you ran", file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
