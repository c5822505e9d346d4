"""The selection's fits go to convergence (:func:`drillgym.diagnosis.context.converged_fit`): nested models
are compared each at its optimum, and the model is left in the state of the fit returned."""

import dataclasses

import numpy as np

from drillgym import RigParams
from drillgym.diagnosis.context import CONVERGE_ROUNDS, SelectionContext, converged_fit, fit_free
from drillgym.diagnosis.screening import default_segment, default_weights
from drillgym.diagnosis.search_model import base_free_parameters, search_composition, selection_model
from drillgym.diagnosis.segments import robust_noise
from drillgym.effects import compose
from drillgym.identification.experiment import prepare_experiment
from drillgym.identification.fitting import Objective, SpeedVariables, base_vector
from drillgym.identification.synthetic import synthetic_measurement


def _state():
    """A 12 s torsional recording of a rig with Ts -7 %, km -5 %, bb +5 %, and the selection's objective on it
    at the identified base parameters."""
    p = RigParams()
    rig = dataclasses.replace(p, Ts=0.93 * p.Ts, km=0.95 * p.km, bb=1.05 * p.bb)
    ts = synthetic_measurement("torsional", rig, duration=12.0, rate_hz=200.0, seed=11, offset=1.0, amplitude=3.0)
    ex, scales = robust_noise(prepare_experiment(ts, compare_rate_hz=50.0))
    comp = search_composition(compose(None, None)[0], [])
    vec0 = base_vector(comp, p, {})
    model = selection_model([ex], default_segment(ex.config), comp)
    obj = Objective(model, default_weights(ex.config), scales)
    names = base_free_parameters(ex.config, True)
    return SelectionContext(obj, comp, vec0.copy(), vec0.copy(), tuple(names), {}), vec0, list(names)


def test_converged_fit_reaches_lower_rss_than_one_round_and_leaves_its_speeds():
    st, vec0, names = _state()
    obj = st.obj
    obj.model.refine_initial_speeds(vec0, obj.weights, obj.scales, fresh=True)
    one = fit_free(st, vec0, names, 4)  # one short round, as an under-converged fit
    full = converged_fit(st, vec0, names, 4)
    assert full.rss_after <= one.rss_after
    assert full.rss_after < 0.9 * one.rss_after, (one.rss_after, full.rss_after)  # more rounds did gain
    # the model holds the speeds the returned fit was made with: its residual is reproduced
    r = obj.residual_matrix(full.vector[None, :])[0]
    np.testing.assert_allclose(r @ r, full.rss_after, rtol=1e-9)
    assert CONVERGE_ROUNDS >= 2
    # the speeds were fitted with the parameters, each within three standard deviations of its estimate's noise
    ex = obj.model.experiments[0]
    for k, j, c, limit in obj.model.speed_variables():
        assert abs(obj.model.speed_offsets[k][j, c]) <= limit * (1 + 1e-12)
        assert limit == 3.0 * ex.speed_noise[("omega_u", "omega_l")[c]]


def test_each_speed_column_is_its_own_segments_sensitivity():
    """The joint fit's Jacobian columns for the segment-start speeds come from two batched rows (every
    segment's ω_u, then ω_l, raised): each column equals the finite difference of raising that one segment's
    speed alone, and is zero outside its segment."""
    st, vec0, _ = _state()
    obj, h = st.obj, 0.005
    model = obj.model
    sv = SpeedVariables(obj)
    assert sv.count >= len(model.segments(0)[0])  # the upper disc turns at every start (the lower one may stick)
    r0 = obj.residual_matrix(vec0[None, :])[0]
    D = (obj.residual_matrix(np.repeat(vec0[None, :], 2, axis=0), dspeed=np.diag([h, h])) - r0) / h
    J = sv.columns(D)
    for i in (0, 1, sv.count // 2, sv.count - 1):
        k, j, c = sv.exp[i], sv.seg[i], sv.comp[i]
        with model.speeds_kept():
            model.speed_offsets[k][j, c] += h
            alone = (obj.residual_matrix(vec0[None, :])[0] - r0) / h * sv.scale[i]
        np.testing.assert_allclose(J[:, i], alone, rtol=1e-9, atol=1e-9 * np.abs(alone).max())
        assert np.abs(alone).max() > 0 and np.all(J[obj.segment_ids != obj.segment_offsets[k] + j, i] == 0.0)


def test_speeds_kept_restores_the_corrections_a_trial_fit_changed():
    """A trial fit inside ``speeds_kept`` refines the segment-start speeds; on leaving, the model's speeds (and
    with them its residual) are those of before, and a snapshot taken inside is an independent copy."""
    st, vec0, names = _state()
    model = st.obj.model
    before = model.speeds_snapshot()
    r_before = st.obj.residual_matrix(vec0[None, :])[0]
    with model.speeds_kept():
        model.refine_initial_speeds(vec0, st.obj.weights, st.obj.scales, fresh=True)
        inside = model.speeds_snapshot()
        assert any(np.any(a != b) for a, b in zip(inside, before))  # the trial did change them
        model.speed_offsets[0][:] += 1.0  # a snapshot is a copy, not a view
        assert not np.shares_memory(inside[0], model.speed_offsets[0])
    for a, b in zip(model.speed_offsets, before):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(st.obj.residual_matrix(vec0[None, :])[0], r_before)
