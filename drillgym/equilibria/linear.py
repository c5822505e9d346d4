"""Linearisation of the rig about a slip equilibrium, its eigenvalues and the torsional Routh-Hurwitz analysis."""

from __future__ import annotations

import control
import numpy as np

from .model import (
    Equilibrium,
    from_full_derivative,
    state_index,
    state_names,
    to_full_state,
)

FD_STEP = 1e-6  # relative central-difference step of the linearisation


def linearise(eq: Equilibrium, variant: str = "reduced", rel_step: float = FD_STEP) -> control.StateSpace:
    """Linearisation about a slip equilibrium as a ``control.StateSpace``.

    Central finite differences of the composition's ``state_derivative`` in the
    equilibrium's slip modes, step ``rel_step`` relative to each state's scale.

    Parameters
    ----------
    eq : Equilibrium
        A slip equilibrium (:func:`slip_equilibrium`, :func:`slip_equilibria`).
    variant : str, optional
        ``"reduced"`` (default): states (alpha, omega_u, omega_l), plus (x, y, vx, vy) in the rotating
        frame for lateral/coupled (upper: omega_u only), outputs all states.  ``"angles"``: theta_u,
        theta_l instead of alpha, outputs the encoder angles (and r for lateral/coupled).
    rel_step : float, optional
        Finite-difference step relative to each state's scale.

    Returns
    -------
    control.StateSpace
        Named states, input ``u`` (V) and outputs; the effects' states are appended.  Units: rad,
        rad/s, m, m/s.  It describes deviations from the equilibrium.
    """
    cfg = eq.config
    rig = eq.model
    comp = rig.comp
    names = state_names(cfg, variant, rig)
    base = eq.state
    z0 = np.array([eq.alpha if n == "alpha" else base[state_index(n, comp)] for n in names])
    scale = np.array([1e-3 if n in ("x", "y", "vx", "vy") else 1.0 for n in names])
    mode = eq.modes
    n = len(names)
    A = np.zeros((n, n))

    def f(y: np.ndarray, u: float) -> np.ndarray:
        return from_full_derivative(rig.f(y, mode, u, cfg), names, comp)

    for j in range(n):
        h = rel_step * scale[j]
        zp, zm = z0.copy(), z0.copy()
        zp[j] += h
        zm[j] -= h
        A[:, j] = (f(to_full_state(zp, names, base, comp), eq.u) - f(to_full_state(zm, names, base, comp), eq.u)) / (
            2 * h
        )
    hu = rel_step
    yb = to_full_state(z0, names, base, comp)
    Bm = ((f(yb, eq.u + hu) - f(yb, eq.u - hu)) / (2 * hu))[:, None]
    if variant == "reduced":
        outs = list(names)
        C = np.eye(n)
    else:
        outs = [o for o in ("theta_u", "theta_l") if o in names]
        C = np.array([[1.0 if s == o else 0.0 for s in names] for o in outs])
        if cfg.lateral_free:
            outs.append("r")
            row = np.zeros(n)
            if eq.r > 0:
                row[names.index("x")] = eq.x / eq.r
                row[names.index("y")] = eq.y / eq.r
            C = np.vstack([C, row])
    D = np.zeros((C.shape[0], 1))
    return control.ss(A, Bm, C, D, states=names, inputs=["u"], outputs=outs)


def eigenvalues(eq: Equilibrium) -> np.ndarray:
    """Eigenvalues (1/s) of the reduced linearisation, sorted by decreasing real part."""
    lam = np.linalg.eigvals(linearise(eq).A)
    return lam[np.argsort(-lam.real)]
