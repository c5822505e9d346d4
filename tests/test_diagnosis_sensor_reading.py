"""Every sensor's reading as a candidate: an encoder whose counts per revolution are off, or an LVDT whose gain is,
found by the reading's own fit on recordings of a simulator other than drillgym's, not taken for a library effect."""

import sys
from functools import cache
from pathlib import Path

import numpy as np
import pytest

from drillgym import RigParams
from drillgym.configurations import Configuration
from drillgym.diagnosis import diagnose
from drillgym.diagnosis.effect_file import write_effect_file
from drillgym.diagnosis.reading_terms import SENSORS
from drillgym.diagnosis.sensor_reading import START_PLAY_RAD, reading_candidates
from drillgym.diagnosis.unexplained import Unexplained
from drillgym.effects import Measurement, compose
from drillgym.io import TimeSeries
from drillgym.signals import quasi_random

RATE_HZ = 250.0


@cache
def _rig_recording(lower_scale: float = 0.0, motor_scale: float = 0.0) -> TimeSeries:
    """10 s of benchmarks/independent_rig.py (numpy, semi-implicit Euler at 0.25 ms, Karnopp's stick) driven by a
    quasi-random voltage about 2 V; its motor encoder reads (1 + motor_scale) θu (the rig's own ``enc_scale``),
    and the lower encoder's counts are converted with counts per revolution off by lower_scale: it reads
    (1 + lower_scale) θl, quantisation included."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from independent_rig import IndependentRig, Plant

    t, u = quasi_random(10.0, rate_hz=RATE_HZ, seed=3, amplitude=4.0, offset=2.0)
    rig = IndependentRig([Plant(effects={"enc_scale": motor_scale}, noise=1e-4)], seed=3)
    tu, tl = np.empty(t.size), np.empty(t.size)
    for i in range(t.size):
        read = rig.measure()
        tu[i], tl[i] = read["theta_u"][0], read["theta_l"][0]
        rig.step(u[i], 1.0 / RATE_HZ)
    cols = {"t": t, "u": u, "theta_u": tu, "theta_l": tl * (1.0 + lower_scale)}
    meta = {"configuration": "torsional", "source": "emulator", "sample_rate_hz": RATE_HZ}
    return TimeSeries(cols, meta, "<independent rig>")


@pytest.mark.parametrize("group", list(SENSORS))
def test_each_reading_is_written_as_a_measurement_that_reads_like_its_terms(tmp_path, group):
    """A fitted reading's file is a Measurement of its sensor's channel that reads what the compiled terms read,
    and its words say what the sensor does wrong."""
    sensor = SENSORS[group]
    cand = reading_candidates_for(group)
    cand.terms = dict(zip(cand.terms, (0.01, 0.002, 0.003)))  # k, the offset (rad or m), the play (rad)
    write_effect_file(cand, tmp_path / "cand.py", "reading")
    comp, _ = compose([cand.effect_file])
    effect = comp.effects[0]
    assert issubclass(effect, Measurement) and effect.channels == (sensor.variable,)
    vals = {f"reading_c{i}": c for i, c in enumerate(cand.terms.values(), 1)}
    if sensor.play:
        vals[f"reading_w{len(cand.terms)}"] = 0.05
    terms = dict(zip(sensor.terms.values(), cand.terms.values()), **({sensor.width: 0.05} if sensor.width else {}))
    ref, _ = compose([sensor.effect])
    x, w = np.linspace(-2.0, 3.0, 6), np.linspace(-1.0, 1.0, 6)
    got = comp.measure(x, x, x, x, comp.vector(RigParams(), vals), w, w)
    want = ref.measure(x, x, x, x, ref.vector(RigParams(), terms), w, w)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-14)
    words = cand.reading()
    assert words.startswith(f"{sensor.what} reads (1 + k) {sensor.symbol} with k = +0.0100")
    assert ("counts per revolution are off by +1.00 %" if sensor.unit == "rad" else "gain is off by +1.00 %") in words


def reading_candidates_for(group: str):
    """The reading candidate of one sensor, from a diagnosis whose residual is above the noise on its channel."""
    config = "coupled" if group.startswith("lvdt") else "torsional"
    return next(c for c in reading_candidates(_diagnosis(config, {SENSORS[group].channel: 50.0})) if c.group == group)


def _diagnosis(config: str, channels: dict[str, float]):
    """What reading_candidates reads of a diagnosis: its final model, configuration and residual per channel."""
    un = Unexplained(float(np.sqrt(np.mean(np.square(list(channels.values()))))), channels)
    return type("D", (), {"vector": np.zeros(1), "unexplained": un, "config": Configuration[config.upper()]})()


def test_readings_are_proposed_for_the_channels_above_the_noise_largest_first():
    """theta_l and theta_u above the noise: both encoders, the larger residual first, their terms at the start
    (the play off 0, where its width has a gradient); a channel at the noise or a sensor the configuration lacks
    proposes none; a recording explained proposes none."""
    got = reading_candidates(_diagnosis("torsional", {"theta_l": 40.0, "theta_u": 6.0, "x": 50.0}))
    assert [c.group for c in got] == ["lower_encoder", "motor_encoder"]
    assert got[0].terms == {"θl": 0.0, "1": 0.0, "tanh(ωl/w)": START_PLAY_RAD}
    got = reading_candidates(_diagnosis("coupled", {"theta_l": 2.0, "theta_u": 1.5, "x": 8.0, "y": 12.0}))
    assert [c.group for c in got] == ["lvdt_y", "lvdt_x"]
    assert got[0].terms == {"y": 0.0, "1": 0.0} and got[0].unit == "m"
    assert reading_candidates(_diagnosis("torsional", {"theta_l": 1.2, "theta_u": 1.4})) == []


def _reading_and_k(d, group: str) -> float:
    """The kept reading's scale error k (its fitted value, by the name its file gives it)."""
    c = d.candidate
    assert c is not None and c.group == group, d.text()
    return c.terms[SENSORS[group].symbol]


@pytest.mark.slow
@pytest.mark.parametrize(
    ("lower_scale", "motor_scale", "group", "truth"),
    [(0.005, 0.0, "lower_encoder", 0.005), (0.0, 0.01, "motor_encoder", 0.01)],
)
def test_an_encoder_scale_error_is_found_by_its_reading_not_taken_for_a_library_effect(
    tmp_path, record_property, lower_scale, motor_scale, group, truth
):
    """An encoder whose counts per revolution are off by 0.5-1 % on the independent rig: the diagnosis keeps the
    reading candidate of that encoder, its scale error within 20 %, its fit removing at least half the unexplained
    variance; with it in the model the reselection takes no library effect (a friction drift was taken for it)."""
    ts = _rig_recording(lower_scale, motor_scale)
    d = diagnose(ts, effects=LIBRARY_SHOWN, discover=True, candidate_out=tmp_path / "cand.py")
    k = _reading_and_k(d, group)
    record_property("reading", f"{d.candidate.found_line()} / {d.candidate.fit.line()}")
    assert k == pytest.approx(truth, rel=0.2), d.candidate.found_line()
    assert d.candidate.fit.variance_cut >= 0.5, d.candidate.fit.line()
    assert "counts per revolution are off by" in d.candidate.found_line()
    assert d.reselection is not None and "friction_drift" not in d.reselection.selected, d.reselection.text()
    assert d.reselection.selected == [], d.reselection.text()


#: the library effect offered: what took the scale error before (beside a position friction and a brake asymmetry)
LIBRARY_SHOWN = ["friction_drift"]
