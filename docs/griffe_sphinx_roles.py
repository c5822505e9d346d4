"""Griffe extension for the docs site: Sphinx cross-reference roles in docstrings as links.

The docstrings follow numpydoc, whose cross-references are Sphinx roles (``:class:`~a.B```,
``:func:`f```). mkdocstrings renders docstrings as Markdown, where a role would show as
literal text. This extension rewrites each role into an optional autorefs link: a link to the
object's page where the API reference documents it, its name as code otherwise (no warning).
"""

from __future__ import annotations

import re
from typing import Any

import griffe

ROLE = re.compile(r":(?:py:)?(?:class|func|meth|mod|attr|data|obj|exc|const):`(~?)([^`<>]+?)`")


def _link(match: re.Match[str]) -> str:
    short, target = match.group(1), match.group(2).strip()
    shown = target.rsplit(".", 1)[-1] if short else target
    return f'<autoref identifier="{target}" optional><code>{shown}</code></autoref>'


def rewrite_roles(text: str) -> str:
    """Return ``text`` with every Sphinx role replaced by an optional autorefs link."""
    return ROLE.sub(_link, text)


class SphinxRoles(griffe.Extension):
    """Rewrite Sphinx roles in every docstring griffe loads (see the module docstring)."""

    def on_object(self, *, obj: griffe.Object, **kwargs: Any) -> None:  # noqa: D102
        if obj.docstring is not None:
            obj.docstring.value = rewrite_roles(obj.docstring.value)
