"""drillgym.Model: one value from identification to every consumer; model files that are explicit about code."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from drillgym import Model, ParameterError, RigParams, simulate, simulate_batch
from drillgym.errors import InputError, MissingFileError
from drillgym.model import UntrustedCodeError, code_files

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "effects" / "string_cubic.py"
STEP = (np.array([0.0, 0.3]), np.array([0.0, 2.0]))  # 0 V, then 2 V from 0.3 s: a lag shows


def _lagged() -> Model:
    return Model(RigParams().replace(km=4.2), ("motor_lag",), {"tau_m": 0.05}, {"tau_m": 0.002, "km": 0.01})


@pytest.mark.parametrize("suffix", [".json", ".yaml"])
def test_a_model_file_reads_back_the_same_model(tmp_path, suffix):
    m = _lagged()
    path = m.save(tmp_path / f"model{suffix}")
    back = Model.load(path)
    assert back == m
    assert back.params.km == 4.2 and back.values["tau_m"] == 0.05 and back.std["km"] == 0.01


def test_the_effect_file_travels_with_the_model_and_is_hashed(tmp_path):
    src = tmp_path / "elsewhere" / "string_cubic.py"
    src.parent.mkdir()
    shutil.copy(EXAMPLE, src)
    m = Model(effects=(f"{src}:string_cubic",), values={"c3": 0.02})
    path = m.save(tmp_path / "model" / "model.json")
    assert (path.parent / "string_cubic.py").read_bytes() == src.read_bytes()  # copied into the model's folder
    rec = json.loads(path.read_text())["effects"][0]
    assert rec["file"] == "string_cubic.py" and len(rec["sha256"]) == 64
    moved = shutil.copytree(path.parent, tmp_path / "copied")  # the folder travels whole
    back = Model.load(moved / "model.json")
    assert back.values["c3"] == 0.02 and back.names == ["string_cubic"]
    assert [c.trusted for c in code_files(moved / "model.json")] == [True]


def test_code_outside_the_folder_or_changed_is_refused_without_trust(tmp_path):
    m = Model(effects=(f"{EXAMPLE}:string_cubic",), values={"c3": 0.02})
    path = m.save(tmp_path / "model.json")
    data = json.loads(path.read_text())
    data["effects"][0]["spec"] = f"{EXAMPLE}:string_cubic"  # points outside the folder
    data["effects"][0]["file"] = str(EXAMPLE)
    outside = tmp_path / "outside.json"
    outside.write_text(json.dumps(data))
    with pytest.raises(UntrustedCodeError, match="outside the model's folder"):
        Model.load(outside)
    assert Model.load(outside, trust=True).values["c3"] == 0.02
    (tmp_path / "string_cubic.py").write_text(EXAMPLE.read_text() + "\n# edited\n")
    with pytest.raises(UntrustedCodeError, match="changed since"):
        Model.load(path)


def test_an_older_model_file_reads_with_trust(tmp_path):
    old = {"params": {"km": 4.1}, "effects": [{"name": "motor_lag", "spec": "motor_lag", "values": {"tau_m": 0.03}}]}
    path = tmp_path / "old.json"
    path.write_text(json.dumps(old))
    m = Model.load(path)  # library effects only: no code, no trust needed
    assert m.params.km == 4.1 and m.values["tau_m"] == 0.03
    old["effects"].append({"name": "string_cubic", "spec": f"{EXAMPLE}:string_cubic", "values": {"c3": 0.01}})
    path.write_text(json.dumps(old))
    with pytest.raises(UntrustedCodeError, match="string_cubic"):
        Model.load(path)


def test_base_parameters_read_from_a_model_file_are_refused_not_half_read(tmp_path):
    path = _lagged().save(tmp_path / "model.json")
    with pytest.raises(ParameterError, match="model file with effects \\(motor_lag\\)"):
        RigParams.from_file(path)


def test_simulate_runs_the_model_and_differs_from_the_base_by_its_effects():
    m = _lagged()
    with_model = simulate("torsional", u=STEP, duration=1.0, model=m)
    by_hand = simulate(
        "torsional", u=STEP, duration=1.0, params=m.params, effects=["motor_lag"], effect_params={"tau_m": 0.05}
    )
    without = simulate("torsional", u=STEP, duration=1.0, params=m.params)
    assert np.array_equal(with_model.omega_u, by_hand.omega_u)
    assert np.abs(with_model.omega_u - without.omega_u).max() > 0.05  # the lag delays the spin-up
    batch = simulate_batch("torsional", u=STEP, duration=1.0, model=m, n_batch=2)
    assert np.array_equal(batch[1].omega_u, with_model.omega_u)


def test_a_model_beside_its_own_parts_is_refused():
    with pytest.raises(InputError, match="give model= or params"):
        simulate("torsional", u=1.0, duration=0.1, model=_lagged(), params=RigParams())


def test_simulate_takes_a_model_file(tmp_path):
    path = _lagged().save(tmp_path / "m.json")
    a = simulate("torsional", u=STEP, duration=0.5, model=path)
    b = simulate("torsional", u=STEP, duration=0.5, model=_lagged())
    assert np.array_equal(a.theta_u, b.theta_u)


def test_a_model_pickles_and_copies_with_its_effect_files(tmp_path):
    import copy
    import pickle

    m = Model(effects=("motor_lag", f"{EXAMPLE}:string_cubic"), values={"tau_m": 0.02, "c3": 0.03}, std={"c3": 0.001})
    for back in (pickle.loads(pickle.dumps(m)), copy.deepcopy(m)):
        assert back == m and back.std["c3"] == 0.001


def test_a_link_to_a_model_file_runs_its_effect_files(tmp_path):
    """A model file reached through a symbolic link (``current.json -> runs/a/model.json``) finds its effect files
    beside the file it links to, trusted as there, not a file of that name beside the link (here the original)."""
    src = Path(__file__).resolve().parents[1] / "examples" / "effects" / "string_cubic.py"
    shutil.copy(src, tmp_path / "string_cubic.py")
    m = Model(effects=("motor_lag", str(tmp_path / "string_cubic.py") + ":string_cubic"), values={"c3": 0.1})
    m.save(tmp_path / "runs" / "a" / "model.json")
    (tmp_path / "current.json").symlink_to(tmp_path / "runs" / "a" / "model.json")
    assert Model.load(tmp_path / "current.json") == Model.load(tmp_path / "runs" / "a" / "model.json")
    assert [c.trusted for c in code_files(tmp_path / "current.json")] == [True]
    (tmp_path / "runs" / "a" / "string_cubic.py").write_text("# edited\n")
    with pytest.raises(UntrustedCodeError, match=r"current\.json.*changed since"):
        Model.load(tmp_path / "current.json")


def test_a_saved_model_loads_though_its_folder_holds_a_link_of_the_effect_files_name(tmp_path):
    """A link named like the effect file in the model's folder (pointing at the file itself) is not taken for the
    model's copy: loading would resolve it outside the folder and refuse what save wrote."""
    src = Path(__file__).resolve().parents[1] / "examples" / "effects" / "string_cubic.py"
    shutil.copy(src, tmp_path / "string_cubic.py")
    (tmp_path / "m").mkdir()
    (tmp_path / "m" / "string_cubic.py").symlink_to(tmp_path / "string_cubic.py")
    m = Model(effects=(f"{tmp_path / 'string_cubic.py'}:string_cubic",), values={"c3": 0.1})
    m.save(tmp_path / "m" / "model.json")
    loaded = Model.load(tmp_path / "m" / "model.json")  # trusted: the copy lies in the folder
    assert loaded.values == m.values and [c.trusted for c in code_files(tmp_path / "m" / "model.json")] == [True]
    assert (tmp_path / "m" / "string_cubic.py").is_symlink()  # the user's link as it was


COG_EFFECT = """
from drillgym.effects import Force, Parameter


class Cog(Force):
    name = "cog"
    acts_on = "upper"
    parameters = (Parameter("cog_c", "N m", -1.0, 1.0, 0.0, 0.1, neutral=0.0),)

    def torque(theta_u, cog_c):
        return cog_c * theta_u
"""


@pytest.mark.parametrize("trust", [False, True])
def test_a_model_folder_copied_without_its_effect_file_is_refused_as_a_missing_file(tmp_path, trust):
    (tmp_path / "cog.py").write_text(COG_EFFECT)
    path = Model(effects=(f"{tmp_path / 'cog.py'}:cog",), values={"cog_c": 0.1}).save(tmp_path / "m" / "model.json")
    (tmp_path / "m" / "cog.py").unlink()
    with pytest.raises(MissingFileError, match=r"effect 'cog': its file .*cog\.py is not found") as e:
        Model.load(path, trust=trust)
    assert "trust" not in str(e.value)
