"""Model versus measurement: compare, diagnose the missing effect, propose new terms.

* :mod:`.effects` — the candidates (the effect library of :mod:`drillgym.effects`, or any effect)
  and their fit variables;
* :mod:`.selection` — which SET of effects: forward selection with refit, the base parameters
  re-identified alongside, backward check, base-model decision, lag versus delay;
* :mod:`.ranking` — :func:`diagnose` (the selection, formatted) and the one-at-a-time ranking;
* :mod:`.discovery` — a candidate effect outside the library from the residual torques on both
  discs, written as an effect file (``diagnose --candidate-out``);
* :mod:`.refit` — add effects to the model and fit them (``drillgym identify --add-effect``);
* :mod:`.compare` — where the model fails (time, speed, angle, lateral amplitude, spectrum);
* :mod:`.sparse` — data-driven candidate term for the residual torque (sparse regression);
* :mod:`.report` — markdown report: base model -> diagnosis -> effect added -> refit.
"""

from ..effects import Effect
from .effects import EFFECTS, effects_for, get_effect
from .ranking import Diagnosis, EffectScore, diagnose

__all__ = ["EFFECTS", "Effect", "effects_for", "get_effect", "Diagnosis", "EffectScore", "diagnose"]
