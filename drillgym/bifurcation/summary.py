"""Columns of the per-flow summary of a Poincare section flow (see :mod:`.flows`)."""

F_OK, F_T, F_WL_MIN, F_WL_MAX, F_R_MIN, F_R_MAX, F_STICK = 0, 1, 2, 3, 4, 5, 6
N_SUMMARY = 7
