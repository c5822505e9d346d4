"""Bifurcation analysis: Hopf points, folds of the periodic branches (R3, R7, R8), Floquet accuracy,
sweeps through an executor, measured points, CLI.  Coarse continuation steps keep it quick."""

import json
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from drillgym import Model, RigParams, simulate
from drillgym.bifurcation import equilibrium_branch, measured_point, periodic_branches, sweep_constant, sweep_staircase
from drillgym.bifurcation.poincare import SectionMap
from drillgym.bifurcation.shooting import residual_and_jacobian
from drillgym.effects import EffectError
from drillgym.equilibria import as_model
from drillgym.errors import DataFormatError


@pytest.fixture(scope="module")
def branches():
    return {c: equilibrium_branch(c, umax=5.0, n=150) for c in ("torsional", "coupled")}


@pytest.mark.parametrize("config", ["torsional", "coupled"])
def test_hopf_points(branches, config):
    assert np.allclose([h.u for h in branches[config].hopf], [0.1849, 1.6851], atol=1e-3)


def test_lateral_r_eq_peaks_near_8V_and_tends_to_3_69mm():
    b = equilibrium_branch("lateral", umax=50.0, n=300)
    assert 7.5 < b.u[np.argmax(b.r)] < 9.0
    assert 3.69e-3 < b.r[-1] < 3.85e-3 and b.r[-1] < b.r[-10]  # decreasing towards e mr / m


def _second_fold(branch):
    brs, folds = periodic_branches(branch, umin=1.6, umax=5.0, ds_max=1.0, dt=2e-3)
    return [f for f in folds if f.u > 2.0]


@pytest.fixture(scope="module")
def second_folds(branches):
    return {c: _second_fold(branches[c]) for c in ("torsional", "coupled")}


def test_torsional_second_fold(second_folds):
    (f,) = second_folds["torsional"]
    assert 3.75 <= f.u <= 3.95 and f.discontinuous


def test_coupled_second_fold_below_torsional(second_folds):
    (f,) = second_folds["coupled"]
    assert 3.45 <= f.u <= 3.65
    assert second_folds["torsional"][0].u - f.u >= 0.15


def test_first_fold_below_first_hopf(branches):
    brs, folds = periodic_branches(branches["torsional"], umin=0.0, umax=0.3, ds_max=0.5)
    h1 = branches["torsional"].hopf[0].u
    assert folds and folds[0].u < h1
    assert not brs[0].solutions[1].stable  # unstable cycle born at the subcritical Hopf
    assert any(s.stable and s.stick_slip for s in brs[0].solutions)  # it turns into the stick-slip cycle


def test_finite_difference_monodromy_is_accurate(branches):
    b = branches["torsional"]
    z = None
    res = {}
    for dt, h in ((1e-3, 1e-6), (1e-3, 1e-7), (5e-4, 1e-6)):
        sm = SectionMap(b.config, RigParams().to_vector(), b.section_speed, dt=dt)
        if z is None:
            traj = simulate("torsional", 1.0, 40.0)
            z = sm.flow_states(traj.final_state[None, :], np.array([1.0]))[0][0]
        H, J, _ = residual_and_jacobian(sm, z, 1.0, h=h)
        res[(dt, h)] = np.sort(np.abs(np.linalg.eigvals(J[:, :2] + np.eye(2))))
    # stick-slip cycle: the stick phase collapses the section (multipliers ~ 0), robust to h and dt
    for v in res.values():
        assert v.max() < 1e-3


def test_sweep_through_an_executor_reproduces_r7():
    with ThreadPoolExecutor(2) as ex:
        r = sweep_constant("torsional", [3.8, 3.9], duration=120.0, window=20.0, executor=ex)
    assert r.stick_fraction[0] > 0 and r.omega_l_min[0] == 0.0 and 4.0 < r.period[0] < 5.5
    assert r.stick_fraction[1] == 0 and r.omega_l_max[1] - r.omega_l_min[1] < 0.05


def test_measured_point_from_a_file_matches_the_simulation(tmp_path):
    traj = simulate("torsional", 1.0, 40.0, record_every=2)
    path = tmp_path / "run.csv"
    traj.to_csv(path)
    m = measured_point(path, "torsional")
    half = traj.omega_l[len(traj.omega_l) // 2 :]
    assert m["u"] == pytest.approx(1.0)
    assert m["omega_l_max"] == pytest.approx(half.max(), rel=0.02)
    assert m["period"] == pytest.approx(6.66, rel=0.02)


def test_measured_point_refuses_varying_voltage(tmp_path):
    traj = simulate("torsional", lambda t: 0.5 + 0.1 * t, 10.0, record_every=10)
    path = tmp_path / "ramp.csv"
    traj.to_csv(path)
    with pytest.raises(DataFormatError, match="not constant"):
        measured_point(path, "torsional")


def test_cli_writes_branches_and_figures(tmp_path):
    from typer.testing import CliRunner

    from drillgym.cli import app

    res = CliRunner().invoke(
        app,
        [
            "bifurcation",
            "--config",
            "torsional",
            "--out",
            str(tmp_path),
            "--umin",
            "1.6",
            "--umax",
            "2.2",
            "--sweep-step",
            "0.3",
            "--sweep-duration",
            "30",
        ],
    )
    assert res.exit_code == 0, res.output
    d = json.loads((tmp_path / "branches.json").read_text())
    assert {"hopf", "fold", "equilibria", "cycles"} <= set(d)
    assert np.isclose(d["hopf"][1], 1.6851, atol=1e-3) and d["cycles"]
    assert (tmp_path / "bifurcation_torsional_omega_l.png").stat().st_size > 10000


def test_lateral_whirl_branch_starts_at_the_hopf_point_near_8_78V():
    """The whirl branch born at ~8.78 V (lateral configuration) is found and starts stable (supercritical)."""
    b = equilibrium_branch("lateral", umax=50.0, n=300)
    brs, folds = periodic_branches(b, umin=8.7, umax=8.79, max_points=15)
    (br,) = brs  # the Hopf point at ~10.59 V is outside the window
    assert folds == []  # the first fold of this branch is at ~8.831 V
    u = br.array("u")
    assert abs(u[0] - b.hopf[0].u) < 1e-3 and np.all(np.diff(u) > 0)
    first = br.solutions[1]
    assert first.stable and 0.9 < abs(first.multipliers[0]) < 1.0
    assert not any(s.stick_slip for s in br.solutions)
    assert first.r_min > 0.02  # whirl around the eccentric equilibrium (r_eq ~ 28.6 mm)


def test_cli_refuses_a_non_positive_continuation_step(tmp_path, capsys):
    from drillgym.cli import main

    with pytest.raises(SystemExit) as e:
        main(["bifurcation", "--config", "torsional", "--out", str(tmp_path), "--ds-max", "0"])
    assert e.value.code == 2 and "--ds-max must be a positive finite continuation step" in capsys.readouterr().err


LATERAL_ONLY = Model(effects=("lateral_anisotropy",), values={"dk": 200.0})  # acts in lateral and coupled only


@pytest.mark.parametrize("sweep", [sweep_constant, sweep_staircase])
def test_an_effect_that_does_not_act_in_the_swept_configuration_is_refused_unless_a_model_holds_it(sweep):
    kw = {"duration": 21.0} if sweep is sweep_constant else {"dwell": 21.0}
    with pytest.warns(UserWarning, match=r"the model's effect lateral_anisotropy does not act in the torsional"):
        left_out = sweep("torsional", [1.0, 2.0], window=20.0, model=LATERAL_ONLY, **kw)
    base = sweep("torsional", [1.0, 2.0], window=20.0, model=Model(), **kw)
    pairs = zip(*(r if isinstance(r, tuple) else (r,) for r in (left_out, base)), strict=True)
    for a, b in pairs:  # the model's base parameters alone
        np.testing.assert_array_equal(a.stats, b.stats)
    rig = as_model(LATERAL_ONLY.params, effects=LATERAL_ONLY.composition, effect_params=dict(LATERAL_ONLY.values))
    with pytest.raises(EffectError, match=r"^effects lateral_anisotropy: the effect does not act in the torsional"):
        sweep("torsional", [1.0, 2.0], window=20.0, params=rig, **kw)
