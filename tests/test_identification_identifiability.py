"""The standard errors of a fit and what it says about the parameters the data cannot fix."""

import numpy as np
import pytest

from drillgym.identification.least_squares import FitOptions, ScaledBox, identifiability
from drillgym.identification.variables import FitVariable


def _run(J, names=("a", "b", "c")):
    box = ScaledBox([FitVariable(n, 1.0, -10.0, 10.0, 1.0) for n in names])
    z = np.zeros(len(names))
    return identifiability(list(names), np.ones(len(names)), J, 0.04, z, box.zlo, box.zhi, box, FitOptions())


def test_well_posed_errors_are_those_of_the_normal_equations():
    """Three independent columns: s² (JᵀJ)⁻¹ on the diagonal, no message."""
    J = np.random.default_rng(0).normal(size=(200, 3)) * [1.0, 30.0, 0.2]
    std, msgs = _run(J)
    assert std == pytest.approx(np.sqrt(np.diag(np.linalg.inv(J.T @ J)) * 0.04), rel=1e-9)
    assert msgs == []


def test_a_column_finite_differences_barely_move_is_not_identified():
    """A column 1e-12 of the others' (a brake asymmetry's static level on a disc that holds whatever the level: the
    finite differences' round-off) is not identified: an infinite error and the message, where the normal
    equations' inverse cut that direction away and said about 0."""
    rng = np.random.default_rng(1)
    J = rng.normal(size=(200, 3)) * [1e4, 3e3, 1e-8]
    std, msgs = _run(J)
    assert np.isinf(std[2]) and np.all(np.isfinite(std[:2]))
    assert msgs == ["c: the data do not depend on it (not excited): not identifiable"]
    old = np.sqrt(np.diag(np.linalg.pinv(J.T @ J)) * 0.04)
    assert old[2] < 1e-3  # what the normal equations said


def test_parameters_only_their_combination_shows_are_said_together():
    """b and c enter only as b + c: both errors infinite, one message naming both; a stays finite."""
    rng = np.random.default_rng(2)
    x, y = rng.normal(size=(2, 200))
    J = np.column_stack([x, y, y])
    std, msgs = _run(J)
    assert np.isfinite(std[0]) and np.all(np.isinf(std[1:]))
    assert msgs == ["b, c: only a combination of them changes the data: not separately identifiable"]


def test_a_parameter_hidden_among_several_is_said_alone():
    """a's column is the mean of four others seen on their own: the unseen direction a − (b + c + d + e) / 4 holds
    0.89 of a and 0.22 of each other one, so a alone is not identified, said as a combination with the others."""
    rng = np.random.default_rng(3)
    others = rng.normal(size=(200, 4))
    J = np.column_stack([others.mean(axis=1), others])
    std, msgs = _run(J, names=("a", "b", "c", "d", "e"))
    assert np.isinf(std[0]) and np.all(np.isfinite(std[1:]))
    assert msgs == ["a: only its combination with other parameters changes the data: not identifiable on its own"]
