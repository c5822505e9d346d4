"""What a command writes: the rule is :mod:`drillgym.io.outputs`; here the sentence its ``--help`` ends with."""

from __future__ import annotations

from ..io.outputs import (
    check_distinct_outputs,
    check_figure_file,
    check_not_inputs,
    check_output_dir,
    check_output_file,
    figure_file,
    output_dir,
    output_file,
)

__all__ = [
    "CREATES_DIRS",
    "check_output_file",
    "output_file",
    "output_dir",
    "check_output_dir",
    "figure_file",
    "check_figure_file",
    "check_not_inputs",
    "check_distinct_outputs",
]

#: the sentence the --help of every written path ends with
CREATES_DIRS = "missing directories are created"
