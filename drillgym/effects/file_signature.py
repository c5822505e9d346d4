"""What of an effect file its compiled model depends on: the code, not the numbers a user reads.

A composition's kernels are compiled once and cached under a digest of what they are compiled from
(:func:`drillgym.effects.codegen.package_name`).  An effect file holds more than its code: docstrings, comments,
its parameters' guesses, bounds and descriptions (a discovered candidate's regressed coefficients among them).
None of these reaches a kernel: numba compiles the effect's functions, which read module-level names, while the
parameters' layout is written into the generated hooks (hashed on their own).  Keyed on the file's bytes, every
candidate written for a new recording, every copy of a model folder and every file written at another path
compiled the same code again.  :func:`code_signature` is the file's syntax tree without docstrings and without
the class attributes that only describe (:data:`DESCRIPTIVE`), which is what the key hashes.
"""

from __future__ import annotations

import ast

__all__ = ["code_signature", "DESCRIPTIVE"]

#: class attributes of an effect that no kernel reads: the parameters' guesses, bounds and words (their names and
#: order are in the generated hooks), the explanation and the residual it leaves, the note on its order
DESCRIPTIVE = frozenset({"parameters", "explanation", "signature", "order_note"})


def code_signature(source: str) -> str:
    """The part of an effect file's source its compiled code depends on, as a canonical dump of its syntax tree.

    Parameters
    ----------
    source : str
        The file's Python source.

    Returns
    -------
    str
        ``ast.dump`` of the module without comments, docstrings, and, in every class whose name the module's
        other statements do not use, the assignments of :data:`DESCRIPTIVE` attributes.
    """
    tree = ast.parse(source)
    outside = {
        n.id
        for stmt in tree.body
        if not isinstance(stmt, ast.ClassDef)
        for n in ast.walk(stmt)
        if isinstance(n, ast.Name)
    }
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            node.body = [s for s in node.body if not _is_docstring(s)] or [ast.Pass()]
        if isinstance(node, ast.ClassDef) and node.name not in outside:
            node.body = [s for s in node.body if not _describes(s)] or [ast.Pass()]
    return ast.dump(tree, include_attributes=False)


def _describes(stmt: ast.stmt) -> bool:
    """An assignment of a :data:`DESCRIPTIVE` attribute in a class body."""
    if isinstance(stmt, ast.Assign):
        targets = stmt.targets
    elif isinstance(stmt, ast.AnnAssign):
        targets = [stmt.target]
    else:
        return False
    return all(isinstance(t, ast.Name) and t.id in DESCRIPTIVE for t in targets)


def _is_docstring(stmt: ast.stmt) -> bool:
    return isinstance(stmt, ast.Expr) and isinstance(stmt.value, ast.Constant) and isinstance(stmt.value.value, str)
