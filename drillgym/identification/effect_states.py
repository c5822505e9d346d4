"""Which parameters an effect state's history depends on, when it depends on the input alone.

A multiple-shooting prediction starts each segment's effect states from one free run of the whole record per
parameter row (:meth:`drillgym.identification.segmented.SegmentedModel.predict_arrays`).  Most rows of a
finite-difference Jacobian move a parameter those states never see: a motor lag's filtered voltage, a drive
element's memory, depend on the commanded voltage and on the parameters of the functions on its way to the
motor, not on the discs.  Such rows share one free run.

:class:`SegmentStartStates` is the part of :class:`~drillgym.identification.segmented.SegmentedModel` that
computes those states (one free run, or where every state is a lag the input alone drives, the input's path
only) and keeps them for the rows that share them.

The dependence is read from what the effects' functions ask for (the argument names the kernels bind): a
composition's states are *input-driven* when no function on the voltage's path (every Input effect's
``voltage`` and ``derivative``, every Delay's ``delay``) and no other effect's ``derivative`` asks for a
quantity of the discs; the parameters those functions ask for (their own, the base parameters they read, an
Input's declared lag time constants) are then the only columns that can change the states.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..configurations import N_STATE
from ..effects import Composition
from ..integrators import OUTPUT_NAMES
from .experiment import Experiment

__all__ = ["INPUT_PATH_QUANTITIES", "STATE_MEMO_SIZE", "SegmentStartStates", "input_state_columns"]

#: parameter rows whose effect states a model keeps from earlier predictions
#: (:meth:`SegmentStartStates._shared_effect_states`)
STATE_MEMO_SIZE = 256

#: quantities that are the same for every parameter row of one record: its clock, its voltage on the way to the
#: motor, its brake schedule
INPUT_PATH_QUANTITIES = frozenset({"t", "u", "brake"})


def input_state_columns(composition: Composition) -> np.ndarray | None:
    """The columns of the composition's parameter rows its effect states depend on, or None when a state may
    depend on the discs' motion (then every column may).

    Parameters
    ----------
    composition : Composition
        The model simulated.

    Returns
    -------
    numpy.ndarray of int or None
        Sorted column indices (``composition.param_names``); None when any function on the voltage's path or
        any state's derivative asks for a quantity other than the record's clock, voltage and brake schedule,
        its own states and parameters.
    """
    names = set(composition.param_names)
    read: set[str] = set()
    for effect in composition.effects:
        functions = [fn for fn in effect.defined_functions() if fn == "derivative" or effect.kind in ("input", "delay")]
        own_states = {s.name for s in effect.states}
        for fn in functions:
            for arg in effect.argument_names(fn):
                if arg in names:
                    read.add(arg)
                elif arg not in own_states and arg not in INPUT_PATH_QUANTITIES:
                    return None
        read.update(n for n in getattr(effect, "lag", {}).values() if n in names)
    return np.array(sorted(composition.param_index(n) for n in read), dtype=int)


class SegmentStartStates:
    """The effect states at the segment starts of a segmented model; the model provides ``composition`` (the
    model), ``_sim`` (the composition simulated), ``_state_cols`` (:func:`input_state_columns` of it),
    ``_lags_only``, ``_state_memo``, ``_exp_k`` (the experiment predicted), ``_delay_lines``, ``_full_rows`` and
    ``_simulate``."""

    _state_memo: dict[tuple, np.ndarray]

    def _shared_effect_states(
        self, ex: Experiment, plan: dict, S: np.ndarray, drive: np.ndarray, starts: np.ndarray, taus: Any
    ) -> np.ndarray:
        """:meth:`_effect_states`, one free run for the rows that differ only where the states cannot see
        (:func:`.effect_states.input_state_columns`; the drive's lag, applied here, is part of the key), and
        none for rows whose states an earlier prediction of this model computed (the last
        :data:`STATE_MEMO_SIZE`: a fit evaluates its accepted point again for the Jacobian, and the selection
        fits other parameters beside the same voltage path)."""
        cols = self._state_cols
        if cols is None:
            return self._effect_states(ex, plan, S, drive, starts)
        key = S[:, cols] if taus is None else np.column_stack([S[:, cols], taus])
        _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
        tag = (self._exp_k, np.asarray(starts).tobytes())
        keys = [(tag, key[i].tobytes()) for i in first]
        memo = self._state_memo
        found = {k: memo.get(k) for k in keys}
        todo = [j for j, k in enumerate(keys) if found[k] is None]
        ns = len(starts)
        if todo:
            rows = first[todo]
            fresh = self._effect_states(ex, plan, S[rows], drive[rows], starts).reshape(len(todo), ns, -1)
            if len(memo) + len(todo) > STATE_MEMO_SIZE:
                memo.clear()
            for j, states in zip(todo, fresh):
                found[keys[j]] = memo[keys[j]] = states
        states = np.stack([found[k] for k in keys])
        return states[inverse.ravel()].reshape(S.shape[0] * ns, -1)

    def _effect_states(
        self, ex: Experiment, plan: dict, S: np.ndarray, drive: np.ndarray, starts: np.ndarray
    ) -> np.ndarray:
        """Effect states at each segment start (B*ns, n_states) from one free run of the record per row; the run
        starts as the simulator's: lag states at the first command held, the others at 0 (a record that starts
        under voltage, the second half of a recording, would otherwise start its lag at 0 V)."""
        rec, dt = plan["rec"], plan["dt"]
        n_steps = int(starts[-1] * rec)
        B, ns, sim = S.shape[0], len(starts), self._sim
        lags = [c - N_STATE for c in sim.lag_state_columns]  # NaN: the kernel starts them at the first command
        if n_steps == 0:
            states = np.zeros((B * ns, sim.n_states))
            states[:, lags] = np.nan
            return states
        X0 = np.zeros((B, sim.n_state))
        X0[:, N_STATE + np.asarray(lags, dtype=int)] = np.nan
        HIST, HEAD = self._delay_lines(S, drive, np.zeros(1, dtype=int), rec, dt, 1)
        if self._lags_only:  # the input alone drives them: its path, not the discs, is run
            out = np.empty((B, ns, sim.n_states))
            U = np.ascontiguousarray(drive[:, :n_steps], dtype=np.float64)
            at = np.ascontiguousarray(starts, dtype=np.int64)
            rows = np.ascontiguousarray(S, dtype=np.float64)
            sim.hook_calls().lag_states(U, rows, int(ex.config), float(dt), n_steps, int(rec), at, X0, HIST, HEAD, out)
            return out.reshape(B * ns, sim.n_states)
        X0[:, :N_STATE] = ex.initial_states(np.zeros(B, dtype=int), self._full_rows(S), self.composition)
        D = self._simulate(
            ex.config, np.ascontiguousarray(drive[:, :n_steps]), dt, S, X0, np.zeros(B), HIST, HEAD, rec, n_steps, 1
        )
        return D[:, starts, len(OUTPUT_NAMES) :].reshape(B * ns, sim.n_states)
