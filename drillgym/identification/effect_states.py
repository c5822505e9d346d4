"""Which parameters an effect state's history depends on, when it depends on the input alone.

A multiple-shooting prediction starts each segment's effect states from one free run of the whole record per
parameter row (:meth:`drillgym.identification.segmented.SegmentedModel.predict_arrays`).  Most rows of a
finite-difference Jacobian move a parameter those states never see: a motor lag's filtered voltage, a drive
element's memory, depend on the commanded voltage and on the parameters of the functions on its way to the
motor, not on the discs.  Such rows share one free run.

The dependence is read from what the effects' functions ask for (the argument names the kernels bind): a
composition's states are *input-driven* when no function on the voltage's path (every Input effect's
``voltage`` and ``derivative``, every Delay's ``delay``) and no other effect's ``derivative`` asks for a
quantity of the discs; the parameters those functions ask for (their own, the base parameters they read, an
Input's declared lag time constants) are then the only columns that can change the states.
"""

from __future__ import annotations

import numpy as np

from ..effects import Composition

__all__ = ["INPUT_PATH_QUANTITIES", "input_state_columns"]

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
