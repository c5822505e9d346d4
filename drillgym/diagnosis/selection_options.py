"""How hard the diagnosis' selection searches: its options, one value every step of the search reads."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["SelectionOptions"]


@dataclass
class SelectionOptions:
    """How hard the selection searches.

    Attributes
    ----------
    n_joint : int
        Candidates refitted jointly with the base parameters per round.  Default 2.
    max_effects : int
        At most this many effects are selected.  Default 4.
    refine : bool
        Fit the segments' initial speeds with every model that changes.  Default True.
    max_nfev_screen, max_nfev_joint, max_nfev_base : int
        Least-squares evaluations of a candidate's screen, of a joint refit, of the first base fit.
    n_group : int
        Candidates fitted together when none is significant alone.  Default 3.
    n_eff_ref : float
        A lower bound of the effectively independent samples of every score.  Default 0.
    guard_base : bool
        Also run the effects-first order on the nominal base (:mod:`.orders`), the guard of the base's first refit;
        off where the base is a kept candidate fit's (the diagnosis run again beside it).  Default True.
    """

    n_joint: int = 2
    max_effects: int = 4
    refine: bool = True
    max_nfev_screen: int = 8
    max_nfev_joint: int = 15
    max_nfev_base: int = 15
    n_group: int = 3
    n_eff_ref: float = 0.0
    guard_base: bool = True
