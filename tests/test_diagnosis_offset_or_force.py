"""An LVDT offset in the model is stated as indistinguishable from a constant lateral force on the disc."""

from drillgym.diagnosis.ranking import _offset_or_force
from drillgym.effects import compose


def test_a_selected_lvdt_offset_names_the_constant_force_it_reads_as():
    comp, values = compose(["lvdt_offset"], {"lvdt_x0": -7.3e-4, "lvdt_y0": 6.5e-4})
    vec = comp.vector(None, values)
    k = float(vec[comp.param_index("k")])
    (line,) = _offset_or_force(["lvdt_offset"], comp, vec)
    assert "(-0.730, +0.650) mm" in line and "does not tell them apart" in line
    assert f"{k * -7.3e-4:+.3g}" in line and f"{k * 6.5e-4:+.3g}" in line  # F = k x0: the force that shifts it so
    # held in the model beside a candidate (not selected), it is stated too; switched off in the search model, not
    assert _offset_or_force(["lateral_anisotropy"], comp, vec) == [line]
    off = comp.vector(None, {"lvdt_x0": 0.0, "lvdt_y0": 0.0})
    assert _offset_or_force(["lateral_anisotropy"], comp, off) == []
