"""The whole open-loop bifurcation diagram of one configuration: equilibria, Hopf points, periodic
branches (from each Hopf point, by shooting and continuation), folds, sweeps, measurements."""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..configurations import Configuration
from ..equilibria import RigModel, as_model, model_or_params, slip_equilibrium, supported_configuration
from ..errors import InputError
from ..params import RigParams
from .continuation import Fold, PeriodicBranch, continue_branch, start_at_hopf
from .equilibrium_branch import EquilibriumBranch, HopfPoint, equilibrium_branch
from .measured import REPORT_POINTS
from .poincare import SectionMap
from .shooting import ShootingFailure
from .sweeps import SweepResult, sweep_constant, sweep_staircase

GRAZING_STICK_TIME = 0.05  # s: a branch that stops with less stick than this ends at a discontinuous fold


@dataclass
class BifurcationDiagram:
    """Everything of one diagram (voltages in V, speeds in rad/s, r in m, periods in s).

    Parameters
    ----------
    config : Configuration
        The rig configuration.
    equilibria : EquilibriumBranch
        The slip equilibrium branch and its Hopf points.
    periodic : list of PeriodicBranch, optional
        Periodic branches born at the Hopf points.
    folds : list of Fold, optional
        Their folds.
    sweeps : list of SweepResult, optional
        Brute-force and quasi-static sweeps.
    measured : list of dict, optional
        Measured points (:func:`measured_diagram`).
    """

    config: Configuration
    equilibria: EquilibriumBranch
    periodic: list[PeriodicBranch] = field(default_factory=list)
    folds: list[Fold] = field(default_factory=list)
    sweeps: list[SweepResult] = field(default_factory=list)
    measured: list[dict] = field(default_factory=list)

    @property
    def hopf(self) -> list[HopfPoint]:
        """The Hopf points of the equilibrium branch."""
        return self.equilibria.hopf

    def to_dict(self) -> dict:
        return {
            "config": self.config.label,
            "hopf": [h.u for h in self.hopf],
            "fold": [f.u for f in self.folds],
            "hopf_points": [h.to_dict() for h in self.hopf],
            "fold_points": [f.to_dict() for f in self.folds],
            "equilibria": self.equilibria.to_dict(every=max(1, len(self.equilibria.u) // 150)),
            "cycles": [s.to_dict() for br in self.periodic for s in br.solutions],
            "cycle_branches": [{"end": br.end_reason, "n": len(br.solutions)} for br in self.periodic],
            "sweeps": [s.to_dict() for s in self.sweeps],
            "measured": self.measured,
            "report_measured_points": REPORT_POINTS.get(self.config.label, {}),
        }

    def save_json(self, path: str | Path) -> Path:
        path = Path(path)
        from ..io.jsonfile import write_json

        write_json(path, self.to_dict(), indent=1)
        return path


def _hopf_start(smap: SectionMap, h: HopfPoint, params: RigModel, amplitude: float):
    eq = slip_equilibrium(smap.config, h.omega, params)
    from ..equilibria import linearise

    lam, V = np.linalg.eig(linearise(eq).A)
    i = int(np.argmin(np.abs(lam - 1j * h.frequency)))
    st = eq.state
    values = {"alpha": eq.alpha, "omega_u": eq.omega, "x": eq.x, "y": eq.y, "vx": 0.0, "vy": 0.0}
    values.update({n: st[8 + j] for j, n in enumerate(eq.model.comp.state_names)})
    z_eq = np.array([values[c] for c in smap.coords]) / smap.scale  # the reduced states without omega_l
    return start_at_hopf(smap, h.u, z_eq, V[:, i], 2, amplitude=amplitude)


def periodic_branches(
    branch: EquilibriumBranch,
    params: RigParams | RigModel | None = None,
    *,
    umin: float = 0.0,
    umax: float = 5.0,
    dt: float = 1e-3,
    ds: float = 0.02,
    ds_max: float = 0.2,
    amplitude: float = 0.01,
    max_points: int = 300,
    progress: Callable[[object], None] | None = None,
    model=None,
) -> tuple[list[PeriodicBranch], list[Fold]]:
    """Periodic branches born at each Hopf point of ``branch`` inside [umin, umax], and their folds.

    Each branch is followed by pseudo-arclength continuation until it leaves the
    window, shrinks back to a Hopf point, or stops at a grazing corner: a
    discontinuous fold, where a stick-slip cycle meets an unstable slip cycle.

    Parameters
    ----------
    branch : EquilibriumBranch
        The equilibrium branch and its Hopf points (:func:`equilibrium_branch`).
    params : RigParams or RigModel, optional
        Base parameters, or a model with effects (:func:`drillgym.equilibria.as_model`); default the
        identified set.
    umin, umax : float, optional
        Voltage window (V).  Default [0, 5].
    dt : float, optional
        Integration step of the shooting (s).  Default 1e-3.
    ds, ds_max : float, optional
        First and largest arclength step of the continuation (scaled).
    amplitude : float, optional
        Amplitude of the first orbit at a Hopf point (rad of winding).
    max_points : int, optional
        Most points per branch.
    progress : callable, optional
        Called with each new periodic solution.
    model : drillgym.Model, str or path, optional
        The rig's model (:class:`drillgym.Model` or a model file's path, read without ``trust``): its base
        parameters, effects and values; refused beside ``params``.

    Returns
    -------
    branches : list of PeriodicBranch
        One branch per Hopf point inside the window.
    folds : list of Fold
        The folds found on them (voltage V, kind).
    """
    if model is not None:
        params = model_or_params(params, model, "periodic_branches()", branch.config.label)
    params = as_model(params if params is not None else branch.params)
    smap = SectionMap(branch.config, params.p, branch.section_speed, dt=dt, composition=params.comp)
    out, folds = [], []
    for h in branch.hopf:
        if not umin <= h.u <= umax:
            continue
        try:
            s1 = _hopf_start(smap, h, params, amplitude)
            s2 = _hopf_start(smap, h, params, 2 * amplitude)
        except ShootingFailure as exc:
            warnings.warn(
                f"no periodic branch from the Hopf point u = {h.u:.4f} V ({exc})", RuntimeWarning, stacklevel=2
            )
            continue
        # a branch that comes back to a Hopf point ends there: once its omega_l range is below half that
        # of the start orbit (a fixed 2e-3 rad/s missed the lateral Hopf point at 8.78 V, where the
        # corrector then slid along the vanishing orbit)
        amp_stop = max(2e-3, 0.5 * (s1.omega_l_max - s1.omega_l_min))
        br = continue_branch(
            smap,
            s1,
            np.sign(s2.u - s1.u) or 1.0,
            umin=umin,
            umax=umax,
            ds=ds,
            ds_max=ds_max,
            max_points=max_points,
            amplitude_min=amp_stop,
            progress=progress,
        )
        out.append(br)
        folds += br.folds
        last = br.solutions[-1]
        # grazing corner: the stick phase shrinks to nothing, or a slip orbit touches omega_l = 0
        # (a corrector failure of an orbit that never sticks and stays away from 0 is no fold)
        if br.end_reason.startswith("corrector") and (
            0 < last.stick_time < GRAZING_STICK_TIME or last.omega_l_min < 1e-2
        ):
            folds.append(Fold(last.u, last.omega_l_max, True))
    return out, _merge_folds(folds)


def _merge_folds(folds: list[Fold], tol: float = 0.01) -> list[Fold]:
    merged: list[Fold] = []
    for f in sorted(folds, key=lambda f: f.u):
        if merged and abs(f.u - merged[-1].u) < tol:
            m = merged[-1]
            merged[-1] = Fold(
                max(m.u, f.u) if m.discontinuous or f.discontinuous else 0.5 * (m.u + f.u),
                max(m.omega_l_max, f.omega_l_max),
                m.discontinuous or f.discontinuous,
            )
        else:
            merged.append(f)
    return merged


#: most voltages one brute-force sweep may simulate (a step of 2.5 mV over 5 V)
MAX_SWEEP_VOLTAGES = 2001

#: the steady-state window at the end of each constant-voltage sweep run (s); a run must be longer
SWEEP_WINDOW = 20.0

#: longest constant-voltage sweep run (s)
SWEEP_DURATION_MAX = 3600.0


def check_diagram_options(
    umin: float,
    umax: float,
    sweep_step: float | None,
    sweep_duration: float,
    ds_max: float,
    sweep_umax: float | None = None,
    names: dict[str, str] | None = None,
) -> None:
    """Refuse, before any work, the settings of :func:`compute_diagram` it cannot use.

    Parameters
    ----------
    umin, umax : float
        Voltage window (V): finite, 0 <= umin < umax.
    sweep_step : float or None
        Voltage step of the sweeps (V): None or 0 for none, else finite, positive and giving at most
        :data:`MAX_SWEEP_VOLTAGES` voltages.
    sweep_duration : float
        Length of each sweep run (s): finite and at least :data:`SWEEP_WINDOW` (its steady-state window).
    ds_max : float
        Largest continuation step: finite and positive.
    sweep_umax : float, optional
        Highest sweep voltage (V); default ``umax``.
    names : dict of str to str, optional
        How to call each setting in the message (the command line gives its options). Default: the
        argument names.

    Raises
    ------
    InputError
        Naming the setting, the value and what would be valid.
    """
    from ..io import U_LIMIT_FILE

    n = {k: k for k in ("umin", "umax", "sweep_step", "sweep_duration", "ds_max")}
    n.update(names or {})
    for key, v in (("umin", umin), ("umax", umax)):
        if not (isinstance(v, (int, float, np.floating, np.integer)) and np.isfinite(v)):
            raise InputError(f"{n[key]} must be a finite voltage (V), got {v!r}")
    if umax > U_LIMIT_FILE:
        raise InputError(
            f"{n['umax']} {umax:g} V is beyond the +-{U_LIMIT_FILE:g} V a recording may hold; "
            f"choose <= {U_LIMIT_FILE:g}"
        )
    if not 0 <= umin < umax:
        raise InputError(f"need 0 <= {n['umin']} < {n['umax']} (V), got {n['umin']} {umin:g}, {n['umax']} {umax:g}")
    if not (np.isfinite(ds_max) and ds_max > 0):
        raise InputError(f"{n['ds_max']} must be a positive finite continuation step, got {ds_max:g}")
    if not sweep_step:
        return
    if not (np.isfinite(sweep_step) and sweep_step > 0):
        raise InputError(
            f"{n['sweep_step']} must be a positive voltage step (V), or 0 for no sweeps; got {sweep_step:g}"
        )
    hi = sweep_umax if sweep_umax is not None else umax
    count = int((hi - umin) / sweep_step + 1e-9) + 1
    if count > MAX_SWEEP_VOLTAGES:
        raise InputError(
            f"{n['sweep_step']} {sweep_step:g} V over [{umin:g}, {hi:g}] V is {count} sweep voltages, more than "
            f"{MAX_SWEEP_VOLTAGES}: choose a step >= {(hi - umin) / (MAX_SWEEP_VOLTAGES - 1):.3g} V (or 0: no sweeps)"
        )
    if not (np.isfinite(sweep_duration) and SWEEP_WINDOW <= sweep_duration <= SWEEP_DURATION_MAX):
        raise InputError(
            f"{n['sweep_duration']} must be at least the {SWEEP_WINDOW:g} s steady-state window each sweep run "
            f"ends with and at most {SWEEP_DURATION_MAX:g} s, got {sweep_duration:g} s"
        )


def compute_diagram(
    config: str,
    params: RigParams | RigModel | None = None,
    *,
    umin: float = 0.0,
    umax: float = 5.0,
    periodic: bool = True,
    sweep_step: float | None = 0.05,
    sweep_duration: float = 120.0,
    staircase: bool = True,
    sweep_umax: float | None = None,
    dt: float = 1e-3,
    sweep_dt: float | None = None,
    ds_max: float = 0.2,
    executor: Executor | None = None,
    measured: Sequence[dict] = (),
    progress: Callable[[str], None] | None = None,
    step: Callable[[str, int], None] | None = None,
    model=None,
) -> BifurcationDiagram:
    """The open-loop bifurcation diagram of one configuration.

    Equilibria and Hopf points, periodic branches and their folds, brute-force sweeps from rest and,
    with ``staircase``, the lab's quasi-static sweeps up and down.

    Parameters
    ----------
    config : str
        Rig configuration: ``"torsional"``, ``"lateral"`` or ``"coupled"``.
    params : RigParams or RigModel, optional
        Base parameters, or a model with effects (:func:`drillgym.equilibria.as_model`); default the
        identified set.
    umin, umax : float, optional
        Voltage window (V), 0 <= umin < umax.  Default [0, 5].
    periodic : bool, optional
        Compute the periodic branches born at the Hopf points.
    sweep_step : float, optional
        Voltage step of the sweeps (V); None or 0: no sweeps.  Default 0.05.
    sweep_duration : float, optional
        Length of each constant-voltage sweep run (s).  Default 120.
    staircase : bool, optional
        Also run the quasi-static sweeps up and down.
    sweep_umax : float, optional
        Highest voltage of the sweeps (V); default ``umax``.
    dt : float, optional
        Integration step of the shooting and the sweeps (s).  Default 1e-3.
    sweep_dt : float, optional
        Integration step of the sweeps (s); default ``dt``.
    ds_max : float, optional
        Largest arclength step of the continuation (scaled).
    executor : concurrent.futures.Executor, optional
        Runs the sweeps; default a process pool.
    measured : sequence of dict, optional
        Measured points to show with the diagram (:func:`measured_diagram`).
    progress : callable, optional
        ``progress(message: str)``: short status messages.
    step : callable, optional
        ``step(kind: str, k: int)``, counting work for progress bars: ``("cycle", 1)`` per continuation
        point, ``("sweep_total", n)`` once before the sweeps (n simulated voltages in all),
        ``("sweep", k)`` as k of them complete.
    model : drillgym.Model, str or path, optional
        The rig's model (:class:`drillgym.Model` or a model file's path, read without ``trust``): its base
        parameters, effects and values; refused beside ``params``.
        Every part of the diagram (equilibria, periodic branches, sweeps) runs it.

    Returns
    -------
    BifurcationDiagram
        Everything for the configuration (``to_json`` writes it).

    Raises
    ------
    InputError
        A setting :func:`check_diagram_options` refuses (a voltage window that is not
        0 <= umin < umax, a sweep step giving too many voltages, sweeps shorter than their window).
    """
    cfg = supported_configuration(config)
    params = model_or_params(params, model, "compute_diagram()", cfg.label)
    check_diagram_options(umin, umax, sweep_step, sweep_duration, ds_max, sweep_umax)
    params.comp.refuse_not_acting(cfg.label, "effect")  # else it fails deep in the kernels
    say = progress or (lambda msg: None)
    count = step or (lambda kind, k: None)

    def on_cycle(s) -> None:
        say(f"cycle u={s.u:.3f} V")
        count("cycle", 1)

    say("equilibria")
    eqb = equilibrium_branch(cfg, params, umax=umax)
    diag = BifurcationDiagram(cfg, eqb, measured=list(measured))
    if periodic and eqb.hopf:
        say("periodic solutions")
        diag.periodic, diag.folds = periodic_branches(
            eqb, params, umin=umin, umax=umax, dt=dt, ds_max=ds_max, progress=on_cycle
        )
    if sweep_step:
        say("sweeps")
        u = np.round(np.arange(umin, (sweep_umax or umax) + 1e-9, sweep_step), 10)
        sdt = sweep_dt or dt
        count("sweep_total", len(u) * (3 if staircase else 1))
        done = lambda k: count("sweep", k)  # noqa: E731
        diag.sweeps.append(
            sweep_constant(
                cfg.label,
                u,
                start="rest",
                duration=sweep_duration,
                dt=sdt,
                params=params,
                executor=executor,
                progress=done,
            )
        )
        if staircase:
            diag.sweeps += list(
                sweep_staircase(
                    cfg.label,
                    u,
                    dwell=max(20.0, sweep_duration / 4),
                    dt=sdt,
                    params=params,
                    executor=executor,
                    progress=done,
                )
            )
    return diag
