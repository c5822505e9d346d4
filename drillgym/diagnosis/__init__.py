"""Model versus measurement: compare, diagnose the missing effects, propose new terms.

:func:`diagnose` is a pipeline of named steps (:mod:`.pipeline`):

* :mod:`.screening` — the recording prepared and conditioned, the candidates it can show, the search model;
* :mod:`.orders` — the select step: the forward selection (:mod:`.forward`, :mod:`.backward`) in several
  orders, the better model by the criterion (:mod:`.criterion`);
* :mod:`.checks` — the check step: position-dependent effects in both halves (:mod:`.reproducibility`), a
  lag or a delay at the recording's own rate (:mod:`.lag_delay`, :mod:`.timing`), a drift or a position
  friction on a disc that hardly turns;
* :mod:`.ranking` — the report step (:mod:`.one_at_a_time`: each candidate alone against the model);
* :mod:`.discovery` — a candidate effect outside the library from the residual torques on both discs,
  written as an effect file (``diagnose --candidate-out``); :mod:`.sensor_reading` — what each sensor reads
  (a scale error, an offset, free play), candidates only their own fit can show; :mod:`.candidate_fit` — each
  candidate's own fit, the one that removes most kept; :mod:`.reading_in_place` — a reading fitted in the place
  of a library effect it draws as well (an LVDT's gain for ``lateral_anisotropy``);
* :mod:`.reselection` — with a candidate kept, the diagnosis again on the model that holds it.

The steps hand each other what :mod:`.state` holds (the settings, the screened recording, the search's outcome)
and import nothing from each other (an import-linter contract).

Beside it: :mod:`.results` (the typed results), :mod:`.context` (the fit state), :mod:`.scoring` (evidence
and significance), :mod:`.effects` (the candidates), :mod:`.refit` (``identify --add-effect``),
:mod:`.compare` (where the model fails), :mod:`.sparse` (residual torques and a sparse regression),
:mod:`.report` (markdown report: base model -> diagnosis -> effect added -> refit).
"""

from ..effects import Effect
from .effects import EFFECTS, effects_for, get_effect
from .pipeline import DiagnosisOptions, diagnose
from .results import BaseChange, Candidate, Diagnosis, EffectScore, Selection

__all__ = [
    "EFFECTS",
    "Effect",
    "effects_for",
    "get_effect",
    "Diagnosis",
    "DiagnosisOptions",
    "EffectScore",
    "BaseChange",
    "Candidate",
    "Selection",
    "diagnose",
]
