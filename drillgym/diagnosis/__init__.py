"""Model versus measurement: compare, diagnose the missing effect, propose new terms.

* :mod:`.effects` — the candidates (the effect library of :mod:`drillgym.effects`, or any effect)
  and their fit variables;
* :mod:`.ranking` — try each candidate as the model + candidate, rank by a BIC-like score;
* :mod:`.refit` — add effects to the model and fit them (``drillgym identify --add-effect``);
* :mod:`.compare` — where the model fails (time, speed, angle, lateral amplitude, spectrum);
* :mod:`.sparse` — data-driven candidate term for the residual torque (sparse regression);
* :mod:`.report` — markdown report: base model -> diagnosis -> effect added -> refit.
"""

from ..effects import Effect
from .effects import EFFECTS, effects_for, get_effect
from .ranking import Diagnosis, EffectScore, diagnose

__all__ = ["EFFECTS", "Effect", "effects_for", "get_effect", "Diagnosis", "EffectScore", "diagnose"]
