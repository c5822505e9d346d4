"""Reading the JSON and YAML files a user writes (parameter, model and plants files) without guessing.

Two things the standard parsers do silently are refused or read as written:

* a key given twice in one mapping (``{"Jl": 0.04, "Jl": 0.05}``): :mod:`json` and PyYAML keep the last one
  without a word; here it is an error naming the key (and, in YAML, its line);
* a number in exponent form without a dot (``1e-2``, ``5E3``): PyYAML follows YAML 1.1 and reads it as the
  text ``'1e-2'``; here it is the number, as YAML 1.2 and JSON read it.
"""

from __future__ import annotations

import json
import re
from typing import Any

__all__ = ["load_json", "load_yaml", "load_structured", "DuplicateKeyError"]


class DuplicateKeyError(ValueError):
    """A mapping of a JSON or YAML text gives one key twice."""


def _no_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise DuplicateKeyError(f"key {key!r} is given twice in one mapping")
        out[key] = value
    return out


def load_json(text: str) -> Any:
    """Parse JSON, refusing a key given twice in one object.

    Parameters
    ----------
    text : str
        The JSON text.

    Returns
    -------
    object
        The parsed value.

    Raises
    ------
    json.JSONDecodeError
        Not JSON.
    DuplicateKeyError
        An object gives one key twice.
    """
    return json.loads(text, object_pairs_hook=_no_duplicates)


_LOADER: Any = None


def _loader() -> Any:
    """PyYAML's safe loader, refusing duplicate keys and reading ``1e-2`` as a number (built once)."""
    global _LOADER
    if _LOADER is not None:
        return _LOADER
    import yaml

    class Loader(yaml.SafeLoader):
        def construct_mapping(self, node: Any, deep: bool = False) -> Any:
            if isinstance(node, yaml.MappingNode):
                seen: set[Any] = set()
                for key_node, _ in node.value:
                    key = self.construct_object(key_node, deep=deep)
                    try:
                        twice = key in seen
                    except TypeError:  # an unhashable key: the parent's construct_mapping says so
                        continue
                    if twice:
                        raise yaml.constructor.ConstructorError(
                            None, None, f"key {key!r} is given twice in one mapping", key_node.start_mark
                        )
                    seen.add(key)
            return super().construct_mapping(node, deep=deep)

    Loader.add_implicit_resolver(
        "tag:yaml.org,2002:float",
        re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
        list("-+0123456789"),
    )
    _LOADER = Loader
    return Loader


def load_yaml(text: str) -> Any:
    """Parse YAML (safe: no Python objects), refusing a key given twice in one mapping and reading ``1e-2`` as a
    number.

    Parameters
    ----------
    text : str
        The YAML text.

    Returns
    -------
    object
        The parsed value.

    Raises
    ------
    yaml.YAMLError
        Not YAML, or a mapping gives one key twice (the message names the key and its line).
    """
    import yaml

    return yaml.load(text, Loader=_loader())  # noqa: S506 - a SafeLoader subclass


def load_structured(text: str, suffix: str) -> Any:
    """Parse ``text`` as YAML for a ``.yaml``/``.yml`` suffix, else as JSON (:func:`load_yaml`, :func:`load_json`).

    Parameters
    ----------
    text : str
        The file's text.
    suffix : str
        The file's suffix, e.g. ``".json"``.

    Returns
    -------
    object
        The parsed value.
    """
    return load_yaml(text) if suffix.lower() in (".yaml", ".yml") else load_json(text)
