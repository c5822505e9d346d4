"""Effects: physics added to the base model, written by drillgym or by a user, compiled into every path.

An effect is a small class (:mod:`drillgym.effects.base`): a Force, a Friction change, an Input
transformation, a Delay or a Measurement transformation, with documented parameters (unit,
bounds, guess, scale) and the physics as plain functions whose argument names say what they
need.  ``compose`` turns a list of effects (names, ``path/to/file.py:NAME``, classes or
instances with values) into a :class:`Composition`, whose kernels are generated and compiled
once and cached on disk (:mod:`drillgym.effects.codegen`).  Every simulation path (single run,
batch lanes, environments, harness, emulator, identification, bifurcation) runs a composition.

The library (:mod:`drillgym.effects.library`) holds ten effects; ``drillgym effects`` lists
every effect available, installed packages' (entry-point group ``drillgym.effects``) included.
"""

from .base import (
    CONFIGURATIONS,
    FRICTION_VOCABULARY,
    MEASUREMENT_CHANNELS,
    VOCABULARY,
    Delay,
    Effect,
    EffectError,
    Force,
    Friction,
    Input,
    Measurement,
    Parameter,
    State,
)
from .composition import BASE, Composition, compose
from .library import LIBRARY
from .registry import ENTRY_POINT_GROUP, available_effects, load_class_from_file, resolve_effect

__all__ = [
    "Effect",
    "Force",
    "Friction",
    "Input",
    "Delay",
    "Measurement",
    "Parameter",
    "State",
    "EffectError",
    "Composition",
    "compose",
    "BASE",
    "LIBRARY",
    "available_effects",
    "resolve_effect",
    "load_class_from_file",
    "ENTRY_POINT_GROUP",
    "VOCABULARY",
    "FRICTION_VOCABULARY",
    "MEASUREMENT_CHANNELS",
    "CONFIGURATIONS",
]
