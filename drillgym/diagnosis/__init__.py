"""Model versus measurement: compare, diagnose the missing effect, propose new terms.

* :mod:`.effects` — the effect library (documented model extensions);
* :mod:`.ranking` — fit each effect, rank by a BIC-like score;
* :mod:`.compare` — where the model fails (time, speed, angle, lateral amplitude, spectrum);
* :mod:`.sparse` — data-driven candidate term for the residual torque (sparse regression);
* :mod:`.report` — markdown report: base model -> diagnosis -> effect added -> refit.
"""

from .effects import EFFECTS, Effect, effects_for, get_effect
from .ranking import Diagnosis, EffectScore, diagnose

__all__ = ["EFFECTS", "Effect", "effects_for", "get_effect", "Diagnosis", "EffectScore", "diagnose"]
