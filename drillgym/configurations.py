"""The rig's experimental configurations (docs/model.md) and the state layout.

==============  ==============  =====  ==================  ==========
name            lateral motion  brake  lower friction law  upper disc
==============  ==============  =====  ==================  ==========
upper           -               -      - (string off)      driven
torsional       held x = y = 0  on     Stribeck brake      driven
lateral         free            off    bearing             driven
coupled         free            on     Stribeck brake      driven
free_vibration  held            off    bearing             clamped
==============  ==============  =====  ==================  ==========

``free_vibration`` is the identification experiment of report 3.3: the upper
disc is held, the lower disc is twisted by alpha0 and released.

State vector (length ``N_STATE`` for the base model), SI units, used by every kernel:

=====  =========  =========================================================================
index  name       meaning
=====  =========  =========================================================================
0      theta_u    upper disc angle (rad)
1      theta_l    lower disc angle (rad); alpha = theta_l - theta_u
2      omega_u    upper disc speed (rad/s)
3      omega_l    lower disc speed (rad/s)
4      x          lateral displacement of centre B, frame rotating with theta_u (m)
5      y          idem (m)
6      vx         dx/dt in the rotating frame (m/s)
7      vy         dy/dt (m/s)
8 ...  (effects)  continuous states of the composition's effects, e.g. ``u_m`` of motor_lag
=====  =========  =========================================================================

Friction modes (length 2 integer vector: upper, lower): +1 / -1 slipping in
that direction, 0 stuck (velocity exactly zero, friction torque inside the
stick set).
"""

from __future__ import annotations

from enum import IntEnum

from .errors import InputError

__all__ = ["Configuration", "N_STATE", "STATE_NAMES", "parse_configuration"]


class Configuration(IntEnum):
    """How the rig is set up (docs/model.md).

    ``UPPER``: the upper disc alone; ``TORSIONAL``: both discs, lateral motion held, brake on;
    ``LATERAL``: lower disc free to whirl, brake off; ``COUPLED``: lateral motion free, brake on;
    ``FREE_VIBRATION``: the lateral free-vibration experiment.
    """

    UPPER = 0
    TORSIONAL = 1
    LATERAL = 2
    COUPLED = 3
    FREE_VIBRATION = 4

    @property
    def label(self) -> str:
        """Lower-case name, as the command line and files spell it (``"torsional"``)."""
        return self.name.lower()

    @property
    def has_lower(self) -> bool:
        """True when the lower disc is part of the model (every configuration but ``UPPER``)."""
        return self is not Configuration.UPPER

    @property
    def lateral_free(self) -> bool:
        """True when the lower disc moves laterally (``LATERAL``, ``COUPLED``)."""
        return self in (Configuration.LATERAL, Configuration.COUPLED)

    @property
    def brake(self) -> bool:
        """True when the brake acts on the lower disc (``TORSIONAL``, ``COUPLED``)."""
        return self in (Configuration.TORSIONAL, Configuration.COUPLED)


#: the mechanical state of the base model; a composition of effects appends its effects' states
STATE_NAMES = ("theta_u", "theta_l", "omega_u", "omega_l", "x", "y", "vx", "vy")
N_STATE = len(STATE_NAMES)


def parse_configuration(config: str | Configuration | int) -> Configuration:
    """The Configuration of a name, member or number.

    Parameters
    ----------
    config : str, Configuration or int
        ``"torsional"`` (any case, ``-`` for ``_``), ``Configuration.TORSIONAL`` or ``1``.

    Returns
    -------
    Configuration
        The configuration.

    Raises
    ------
    InputError
        An unknown configuration; the message lists the valid names.
    """
    if isinstance(config, Configuration):
        return config
    if isinstance(config, str):
        key = config.strip().upper().replace("-", "_")
        if key in Configuration.__members__:
            return Configuration[key]
    elif isinstance(config, int) and config in set(c.value for c in Configuration):
        return Configuration(config)
    names = ", ".join(c.label for c in Configuration)
    raise InputError(f"unknown configuration {config!r}; expected one of: {names}")
