"""How the selection counts evidence: per-channel scores, the noise floor, sensor weights, parallel fits,
the screens of measurement effects."""

import pytest
from test_diagnosis_selection import independent_rig

from drillgym import RigParams
from drillgym.diagnosis.search_model import neutral_values, search_composition
from drillgym.effects import BASE, LIBRARY, compose
from drillgym.identification.synthetic import synthetic_measurement


def test_measurement_effect_scored_per_channel_is_not_drowned_by_another_channel():
    """An effect that removes a y-only residual (an LVDT skew) while a large, correlated residual stays in
    the angle channel: pooled, the angle channel's variance swamps it; per channel it is clearly found."""
    import numpy as np

    from drillgym.diagnosis.scoring import score, significant
    from drillgym.identification.fitting import FitResult

    rng = np.random.default_rng(0)
    n = 4000
    t = np.arange(n) / 50.0
    angle = 30.0 * np.sin(0.3 * t) + rng.standard_normal(n)  # a slowly varying model error, 30 noise units
    y_small = rng.standard_normal(n)
    y_with_skew = y_small + 2.0 * np.sin(2.0 * t)  # what the skew explains: 2 noise units in y only
    r0 = np.concatenate([angle, y_with_skew])
    r1 = np.concatenate([angle, y_small])
    channels = np.repeat([0, 1], n)
    big = FitResult(
        ["lvdt_skew"], {}, {}, RigParams(), np.zeros(1), float(r0 @ r0), float(r1 @ r1), 2 * n, 1, residual=r1
    )
    pooled, _ = score(float(r0 @ r0), big, 1)
    per_channel, ne = score(r0, big, 1, channels=channels)
    assert pooled < 15.0 < per_channel  # SIGNIFICANCE is 15 nats
    assert not significant(per_channel, float(r0 @ r0), float(r1 @ r1), 2 * n)  # pooled RMS cut < 20 %
    assert significant(per_channel, float(r0 @ r0), float(r1 @ r1), 2 * n, r0, r1, channels)
    nothing = FitResult(
        ["lvdt_skew"], {}, {}, RigParams(), np.zeros(1), float(r0 @ r0), float(r0 @ r0), 2 * n, 1, residual=r0.copy()
    )
    assert score(r0, nothing, 1, channels=channels)[0] < 0  # explaining nothing costs the penalty


def test_objective_channel_ids_follow_the_residual_layout():
    import numpy as np

    from drillgym.identification.experiment import prepare_experiment
    from drillgym.identification.fitting import Objective
    from drillgym.identification.segmented import SegmentedModel

    ts = synthetic_measurement("coupled", duration=6.0, seed=3, offset=2.5)
    ex = prepare_experiment(ts, compare_rate_hz=50.0)
    obj = Objective(SegmentedModel([ex], 2.0), {"theta_u": 1.0, "theta_l": 1.0, "x": 1.0, "y": 1.0})
    r = obj.residual_matrix(RigParams().to_vector()[None, :])[0]
    assert obj.channel_ids.shape == r.shape
    assert sorted(set(obj.channel_ids.tolist())) == list(range(len(obj.channels))) and obj.channels == [
        "theta_l",
        "theta_u",
        "x",
        "y",
    ]
    assert np.count_nonzero(np.diff(obj.channel_ids)) == 3  # one experiment: four channels, one block each


def test_each_sensor_is_weighted_by_its_own_misfit():
    """Encoders at 8 noise units (a friction law's systematic error) and LVDTs within the noise: the
    encoders' scales grow 8x, the LVDTs' stay; once balanced, a second call changes nothing; a recording
    of one sensor is never rescaled."""
    from types import SimpleNamespace

    import numpy as np

    from drillgym.diagnosis.scoring import balance_sensors

    rng = np.random.default_rng(1)
    n = 2000
    channels = ["theta_l", "theta_u", "x", "y"]
    ids = np.repeat(np.arange(4), n)
    noise = {"theta_l": 2e-4, "theta_u": 2e-4, "x": 1e-5, "y": 1e-5}
    obj = SimpleNamespace(channels=channels, channel_ids=ids, scales=dict(noise))
    r = np.concatenate(
        [
            8.0 * rng.standard_normal(n),
            8.0 * rng.standard_normal(n),
            0.5 * rng.standard_normal(n),
            0.5 * rng.standard_normal(n),
        ]
    )
    f = balance_sensors(obj, r, noise)
    assert f["encoders"] == pytest.approx(8.0, rel=0.05) and f["LVDTs"] == 1.0
    assert obj.scales["theta_l"] == pytest.approx(8.0 * noise["theta_l"], rel=0.05)
    assert obj.scales["x"] == noise["x"] and obj.scales["y"] == noise["y"]
    r_balanced = r * np.where(ids < 2, noise["theta_l"] / obj.scales["theta_l"], 1.0)
    assert balance_sensors(obj, r_balanced, noise) == {}
    one = SimpleNamespace(
        channels=["theta_l", "theta_u"], channel_ids=np.repeat([0, 1], n), scales={"theta_l": 2e-4, "theta_u": 2e-4}
    )
    assert balance_sensors(one, 8.0 * rng.standard_normal(2 * n), {"theta_l": 2e-4, "theta_u": 2e-4}) == {}
    assert one.scales == {"theta_l": 2e-4, "theta_u": 2e-4}


def test_noise_floor_is_in_noise_units_when_sensors_are_weighted():
    """A y residual cut from 1.35 to 1.05 units (one unit = 3 noise units: the LVDTs' misfit) explains
    6.5 noise units², above the floor of 1; read as noise units it would be 0.72, below it."""
    import numpy as np

    from drillgym.diagnosis.scoring import significant

    rng = np.random.default_rng(2)
    n = 3000
    e = rng.standard_normal(n)
    e /= np.sqrt(np.mean(e**2))
    r0, r1 = np.concatenate([e, 1.35 * e]), np.concatenate([e, 1.05 * e])
    channels = np.repeat([0, 1], n)
    unit = np.concatenate([np.full(n, 5.0), np.full(n, 3.0)])
    args = (100.0, float(r0 @ r0), float(r1 @ r1), 2 * n, r0, r1, channels)
    assert not significant(*args)
    assert significant(*args, unit)


def test_noise_floor_follows_a_residual_already_below_one_noise_unit():
    """The noise unit is a prior (an encoder count / sqrt 12, 10 um on an LVDT).  A model that leaves less
    than one unit shows finer sensors: the floor is then what it leaves.  A coupled recording's motor lag
    (0.86 -> 0.48 units, 92 nats) was refused by the fixed floor of one unit²; a cut that explains less
    than what remains (0.9 -> 0.7) is still refused, and above one unit the floor stays one unit²."""
    import numpy as np

    from drillgym.diagnosis.scoring import MIN_EXPLAINED, noise_floor, significant

    assert noise_floor(0.23) == pytest.approx(0.23) and noise_floor(4.0) == MIN_EXPLAINED
    rng = np.random.default_rng(3)
    n = 4000
    e = rng.standard_normal(n)
    e /= np.sqrt(np.mean(e**2))

    def sig(a: float, b: float) -> bool:
        r0, r1 = a * e, b * e
        return significant(92.0, float(r0 @ r0), float(r1 @ r1), n, r0, r1, np.zeros(n, int))

    assert sig(0.86, 0.48)  # explains 0.51 units², leaves 0.23
    assert not sig(0.9, 0.7)  # explains 0.32, leaves 0.49: within what remains
    assert not sig(1.5, 1.15)  # 23 % cut, explains 0.93 < 1 unit² with more than one unit left
    assert sig(1.5, 1.0)

    def pooled_only(a: float, b: float) -> bool:  # a fit that carries no residual vector: the same floor
        return significant(92.0, a * a * n, b * b * n, n)

    assert pooled_only(0.86, 0.48) and pooled_only(1.5, 1.0)
    assert not pooled_only(0.9, 0.7) and not pooled_only(1.5, 1.15)


def test_a_parameter_the_data_do_not_depend_on_has_no_finite_standard_error():
    """A motor lag on a constant input changes nothing after the start: its standard error is infinite
    (the pseudo-inverse alone gave 0, printed as 'tau_m=0.3211±0'), with the identifiability warning."""
    import numpy as np

    from drillgym.identification.experiment import prepare_experiment
    from drillgym.identification.fitting import FitVariable, IdentifiabilityWarning, Objective, fit_parameters
    from drillgym.identification.segmented import SegmentedModel

    ts = synthetic_measurement(
        "torsional", duration=6.0, rate_hz=200.0, signal="steps", amplitude=2.5, offset=2.5, seed=1
    )  # constant 2.5 V
    comp, _ = compose(["motor_lag"], {"tau_m": 0.02})
    ex = prepare_experiment(ts, compare_rate_hz=50.0)
    obj = Objective(SegmentedModel([ex], 2.0, composition=comp), {"theta_u": 1.0, "theta_l": 1.0})
    vec = comp.vector(RigParams(), {"tau_m": 0.02})
    with pytest.warns(IdentifiabilityWarning, match="tau_m"):
        res = fit_parameters(obj, vec, [FitVariable.of_effect(comp, "tau_m", 0.02)], max_nfev=3)
    assert res.std["tau_m"] == np.inf


def test_fits_run_in_parallel_come_back_in_order_with_their_errors():
    """The selection runs a round's independent fits on two threads: results in the jobs' order, a fit that names
    why it failed (FitFailedError) returned in its place (the selection excludes that candidate), any other error
    (a bare ValueError among them: a bug) raised."""
    import threading
    import time

    from drillgym.diagnosis.context import in_parallel
    from drillgym.errors import FitFailedError

    threads = set()

    def job(i):
        def run():
            threads.add(threading.get_ident())
            time.sleep(0.05 * (3 - i))  # the first job finishes last
            if i == 1:
                raise FitFailedError("no fit")
            return i * 10

        return run

    out = in_parallel([job(i) for i in range(3)])
    assert out[0] == 0 and out[2] == 20 and isinstance(out[1], FitFailedError) and str(out[1]) == "no fit"
    assert len(threads) == 2
    with pytest.raises(ZeroDivisionError):
        in_parallel([lambda: 1, lambda: 1 / 0])

    def bug():
        raise ValueError("a bug inside a fit")

    with pytest.raises(ValueError, match="a bug inside a fit"):
        in_parallel([lambda: 1, bug])


def test_a_measurement_effect_is_screened_with_the_segments_start_speeds_on_its_own_copy_of_the_model():
    """A measurement effect changes the readings the segments restart from (the lateral initial states), and
    through them the torsional prediction; its screen fits the segments' start speeds with it, on a copy of
    the model (the screens run side by side on the shared one, whose speeds stay as they were), and fits
    at least as well as with the speeds held, the skew's value close to the rig's."""
    import numpy as np

    from drillgym.diagnosis.context import SelectionContext, fit_free, screen_fit
    from drillgym.diagnosis.screening import default_segment, default_weights
    from drillgym.diagnosis.search_model import selection_model
    from drillgym.diagnosis.segments import robust_noise
    from drillgym.identification.experiment import prepare_experiment
    from drillgym.identification.fitting import Objective, base_vector

    ts = independent_rig()(
        "coupled",
        "sum_of_sines",
        12.0,
        200.0,
        5,
        {"lvdt_skew": {"lvdt_skew": -0.044}, "lateral_coulomb": {"Fc_lat": 1.06}},
        {},
        2.31,
        1.5,
    )
    ex, scales = robust_noise(prepare_experiment(ts, compare_rate_hz=50.0))
    cands = [LIBRARY["lateral_coulomb"], LIBRARY["lvdt_skew"]]
    comp = search_composition(BASE, cands)
    vec = base_vector(comp, RigParams(), {**neutral_values(cands), "Fc_lat": 1.06})
    obj = Objective(selection_model([ex], default_segment(ex.config), comp), default_weights(ex.config), scales)
    obj.model.refine_initial_speeds(vec, obj.weights, obj.scales, fresh=True)
    speeds = obj.model.speeds_snapshot()
    st = SelectionContext(obj, comp, vec.copy(), vec.copy(), (), {c.name: c for c in cands})
    screened = screen_fit(st, vec, "lvdt_skew", 8)
    assert all(np.array_equal(a, b) for a, b in zip(obj.model.speeds_snapshot(), speeds))
    held = fit_free(st, st.best_start(vec, "lvdt_skew"), ["lvdt_skew"], 8)
    assert screened.rss_after <= held.rss_after * (1 + 1e-9), (screened.rss_after, held.rss_after)
    assert screened.values["lvdt_skew"] == pytest.approx(-0.044, rel=0.15)
    # a dynamic effect is screened with the speeds held, as before
    coulomb = screen_fit(st, vec, "lateral_coulomb", 4)
    assert "lvdt_skew" not in coulomb.names and all(
        np.array_equal(a, b) for a, b in zip(obj.model.speeds_snapshot(), speeds)
    )
