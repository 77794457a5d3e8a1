"""Bad input raises InputError / ProfileError carrying file, line and key (one line)."""
import json

import numpy as np
import pytest

import rodfit

TISSUE = {
    "rod": {"length": 0.15, "segments": 40, "radius": 0.012, "linear_density": 0.45},
    "parameters": {"bend_stiffness": {"value": 2.0e-4}, "twist_stiffness": {"value": 1.5e-4},
                   "stretch_stiffness": {"value": 40}},
    "cases": [{"name": "rest",
               "clamp": {"position": [0, 0, 0], "tangent": [1, 0, 0], "normal": [0, 0, 1]}}],
}


def test_yaml_file_error_names_file_line_key(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("rod:\n  length: 0.2\n  segments: -3\n  radius: 1e-4\n"
                    "parameters:\n  bend_stiffness: {value: 1e-6}\n")
    with pytest.raises(rodfit.InputError) as caught:
        rodfit.experiment(path)
    e = caught.value
    assert isinstance(e, ValueError)
    assert e.file == str(path) and e.line == 3 and e.key == "rod.segments"
    assert str(e).startswith(f"{path}:3: rod.segments: ") and "\n" not in str(e)
    assert e.message and e.message in str(e)


def test_dict_error_names_the_key_and_the_line_of_its_text(tmp_path):
    bad = json.loads(json.dumps(TISSUE))
    bad["cases"][0]["clamp"]["normal"] = [1, 0, 0]  # along the tangent
    with pytest.raises(rodfit.InputError) as caught:
        rodfit.experiment(bad, base_dir=tmp_path)
    e = caught.value
    assert e.file == str(tmp_path / "<dict>")
    assert e.key.startswith("cases[0].clamp")
    # The line is the key's in the text experiment_text renders.
    text = rodfit.experiment_text(bad).split("\n")
    assert e.line is not None
    assert '"normal"' in text[e.line - 1] or '"clamp"' in text[e.line - 1], (e, text[e.line - 1])


def test_table_error_names_column_and_row(tmp_path):
    good = rodfit.experiment(TISSUE)  # the dict itself is valid
    assert good.case_names == ["rest"]
    bad = json.loads(json.dumps(TISSUE))
    markers = np.array([[0.05, 0.05, 0.0, -0.001], [0.1, 0.1, 0.0, np.nan]])
    bad["cases"][0]["observations"] = [
        {"type": "markers3d", "sigma": 5e-4, "file": rodfit.Table(markers, columns="s x y z".split())}]
    bad["parameters"]["spring_stiffness"] = {"value": 50, "fit": True, "min": 1, "max": 1e5}
    with pytest.raises(rodfit.InputError) as caught:
        rodfit.fit(bad)
    e = caught.value
    assert e.file.endswith(".csv") and e.line == 3 and e.key == "z"


def test_missing_file(tmp_path):
    with pytest.raises(rodfit.InputError) as caught:
        rodfit.experiment(tmp_path / "none.yaml")
    assert caught.value.file == str(tmp_path / "none.yaml")


def test_profile_error_names_the_key(tmp_path, source_dir):
    document = json.loads((source_dir / "data" / "profiles" / "suture.json").read_text())
    document["parameters"]["bend_stiffness"]["value"] = -1.0
    with pytest.raises(rodfit.ProfileError) as caught:
        rodfit.Runtime(document)
    e = caught.value
    assert isinstance(e, ValueError) and e.key == "parameters.bend_stiffness.value"
    assert str(e).startswith("<dict>: parameters.bend_stiffness.value: ")
    path = tmp_path / "p.json"
    path.write_text(json.dumps(document))
    with pytest.raises(rodfit.ProfileError, match=r"p\.json: parameters\.bend_stiffness\.value"):
        rodfit.profile(path)
