"""A sampled controller: its command reaches the motor late by the computation time and half a sample.

A user file for drillgym (docs/EFFECTS.md, "Delay"):
``--add-effect examples/effects/sampled_command.py:sampled_command``.  A Delay effect: the motor sees the
command of ``delay(...)`` seconds earlier.
"""

from drillgym.effects import Delay, Parameter


class SampledCommand(Delay):
    """Transport delay t_comp + t_sample / 2 of a command computed and held by a sampled controller."""

    name = "sampled_command"
    parameters = (
        Parameter("t_comp", "s", 0.0, 0.05, 0.002, 0.002, "computation time of the controller", neutral=0.0),
        Parameter("t_sample", "s", 0.0, 0.05, 0.01, 0.005, "sample period of the held command", neutral=0.0),
    )
    configurations = ("upper", "torsional", "lateral", "coupled")
    explanation = (
        "A controller that samples, computes and holds its output delays the command by its computation time "
        "and, on average, half a sample period (the zero-order hold)."
    )
    signature = "the whole response late by t_comp + t_sample / 2; residual proportional to the input's derivative"

    def delay(t_comp, t_sample):
        """The delay (s): parameters only (it sizes the delay line)."""
        return t_comp + 0.5 * t_sample
