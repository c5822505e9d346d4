"""The model of a training run: set as the envs' option, recorded in ``config.yml``, held on resume.

``drillgym train --model FILE`` trains on a :class:`drillgym.Model`; the run's ``config.yml`` records it as
JSON-ready base parameters and effect records, and a resumed run (whose options come from the call, not from the
file) is held to that record.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from drillgym.errors import InputError

__all__ = ["with_model", "check_resumed_model"]


def with_model(hp: dict[str, Any], model: Any, trust: bool) -> tuple[dict[str, Any], dict[str, Any]]:
    """(``hp`` with env option ``model`` set, ``hp`` as ``config.yml`` records it: the model as JSON-ready
    base parameters and effect records); refused beside env options that give the model's parts."""
    from drillgym.model import as_model

    m = as_model(model, trust=trust, who="train(): model")
    kw = dict(hp["env_kwargs"])
    clash = [k for k in ("model", "params", "effects", "effect_params") if kw.get(k) is not None]
    if clash:
        raise InputError(
            f"train(): give model= or the env option(s) {', '.join(clash)}, not both (the model holds its own)"
        )
    record = {"label": m.label, "params": m.params.to_dict(), "effects": m.records()}
    return {**hp, "env_kwargs": {**kw, "model": m}}, {**hp, "env_kwargs": {**kw, "model": record}}


def _model_key(record: Any) -> Any:
    """What identifies a model as ``config.yml`` records it: its base parameters and effects with their values
    (not the effect files' paths: a model folder copied elsewhere is the same model)."""
    if not isinstance(record, dict):
        return None
    effects = [(e.get("name"), e.get("values")) for e in record.get("effects") or [] if isinstance(e, dict)]
    return record.get("params"), effects


def check_resumed_model(path: Path, recorded_hp: dict[str, Any]) -> None:
    """Refuse to resume a run on another model than the one its ``config.yml`` (``path``) records: a resumed run
    takes its options from the call (``recorded_hp``: as the new ``config.yml`` would record them), and a model left
    out would continue the run on the nominal rig without a word."""
    out = path.parent
    try:
        before = yaml.safe_load(path.read_text(encoding="utf-8"))["hyperparams"]["env_kwargs"].get("model")
    except (OSError, yaml.YAMLError, KeyError, TypeError, AttributeError):  # no readable record: nothing to hold to
        return
    now = recorded_hp.get("env_kwargs", {}).get("model")
    if _model_key(before) == _model_key(now):
        return
    if now is None:
        raise InputError(
            f"resume: {out} was trained on the model {before.get('label', '?')} ({path}); give the same model "
            "(--model FILE, model=) to continue it"
        )
    if before is None:
        raise InputError(
            f"resume: {out} was trained without a model ({path}); leave out the model to continue it, or train "
            "on the model into another directory"
        )
    raise InputError(
        f"resume: {out} was trained on another model ({before.get('label', '?')}, {path}) than the one given "
        f"({now.get('label', '?')}); give the same model to continue it"
    )
