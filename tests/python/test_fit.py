"""rodfit.fit against `rodfit fit`: every bundled recipe gives the CLI's profile (every number
within 1e-9 relative), and a fit from numpy arrays gives the fit from the files."""
import json
import warnings

import numpy as np
import pytest

import rodfit
from conftest import run

RECIPES = [
    "calibration/suture_cantilever/experiment.yaml",
    "calibration/tissue_drag/experiment.yaml",
    "calibration/tissue_poke/experiment.yaml",
    "data/suture_swing_fit/experiment.yaml",
    "data/suture_swing_fit/experiment_density.yaml",
]
RELATIVE = 1e-9


def assert_documents_match(expected, actual, where="", skip=()):
    """Same keys, same strings and booleans, numbers within RELATIVE (relative to the larger
    magnitude; exact zeros equal)."""
    if where in skip:
        return
    if isinstance(expected, dict):
        assert isinstance(actual, dict), where
        assert set(expected) == set(actual), (where, set(expected) ^ set(actual))
        for key in expected:
            assert_documents_match(expected[key], actual[key], f"{where}.{key}", skip)
    elif isinstance(expected, list):
        assert isinstance(actual, list) and len(expected) == len(actual), where
        for k, (e, a) in enumerate(zip(expected, actual)):
            assert_documents_match(e, a, f"{where}[{k}]", skip)
    elif isinstance(expected, bool) or expected is None or isinstance(expected, str):
        assert expected == actual, (where, expected, actual)
    else:
        assert isinstance(actual, (int, float)) and not isinstance(actual, bool), where
        scale = max(abs(expected), abs(actual))
        assert abs(expected - actual) <= RELATIVE * scale, (where, expected, actual)


def count_numbers(document):
    if isinstance(document, dict):
        return sum(count_numbers(v) for v in document.values())
    if isinstance(document, list):
        return sum(count_numbers(v) for v in document)
    return int(isinstance(document, (int, float)) and not isinstance(document, bool))


@pytest.mark.parametrize("recipe", RECIPES)
def test_fit_equals_cli_profile(tmp_path, source_dir, cli, recipe, monkeypatch):
    done = run(cli, "fit", recipe, "-o", tmp_path / "cli.json", "-q", cwd=source_dir, check=False)
    assert done.returncode in (0, 4, 5), done.stderr  # 4, 5: written, with a verdict
    expected = json.loads((tmp_path / "cli.json").read_text())
    # The same relative path as the CLI was given: the profile names its inputs as given.
    monkeypatch.chdir(source_dir)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        profile = rodfit.fit(recipe)
    assert count_numbers(expected) > 10
    assert_documents_match(expected, profile)
    # The CLI's warnings (stderr) are the Python warnings.
    cli_warned = "warning:" in done.stderr
    assert cli_warned == any(issubclass(w.category, rodfit.FitWarning) for w in caught)


def test_fit_writes_the_profile_when_asked(tmp_path, source_dir):
    recipe = source_dir / "calibration" / "tissue_poke" / "experiment.yaml"
    profile = rodfit.fit(recipe, output=tmp_path / "p.json")
    assert json.loads((tmp_path / "p.json").read_text()) == profile


def _csv(path):
    with open(path) as f:
        header = f.readline().strip().split(",")
    return header, np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


def test_fit_from_numpy_arrays_equals_fit_from_files(source_dir):
    folder = source_dir / "calibration" / "tissue_drag"
    tables = {}
    for name in ("rest_markers", "drag_markers", "drag_force"):
        columns, data = _csv(folder / f"{name}.csv")
        tables[name] = rodfit.Table(data, columns=columns, name=f"{name}.csv")
    clamp = {"position": np.zeros(3), "tangent": np.array([1.0, 0, 0]),
             "normal": np.array([0.0, 0, 1])}
    # calibration/tissue_drag/experiment.yaml as Python objects, its files as arrays.
    experiment = {
        "rod": {"length": 0.15, "segments": 40, "radius": 0.012, "linear_density": 0.45},
        "parameters": {
            "bend_stiffness": {"value": 2.0e-4}, "twist_stiffness": {"value": 1.5e-4},
            "stretch_stiffness": {"value": 40},
            "spring_stiffness": {"value": 50, "fit": True, "min": 1.0, "max": 1.0e5},
            "mesentery": {"value": 1000, "fit": True, "min": 1.0, "max": 1.0e5}},
        "gravity": np.array([0, 0, -9.81]),
        "springs": [{"from": 0.0, "to": 0.07},
                    {"from": 0.07, "to": 0.15, "parameter": "mesentery"}],
        "cases": [
            {"name": "rest", "clamp": clamp, "observations": [
                {"type": "markers3d", "file": tables["rest_markers"], "sigma": 5.0e-4,
                 "count": 10}]},
            {"name": "drag", "clamp": clamp,
             "grasp": {"s": 0.1, "position": [0.1, 0.015, 0.02]},
             "observations": [
                 {"type": "markers3d", "file": tables["drag_markers"], "sigma": 5.0e-4,
                  "count": 10},
                 {"type": "grasp_force", "file": tables["drag_force"], "sigma": 0.01, "s": 0.1,
                  "count": 8, "max_speed": 1.0e-3}]}],
    }
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rodfit.FitWarning)  # the recipe's stretched-span note
        from_arrays = rodfit.fit(experiment)
        from_files = rodfit.fit(folder / "experiment.yaml")
    # Everything but the inputs' names and digests (temporary CSV files, not the recipe's).
    assert_documents_match(from_files, from_arrays, skip=(".fit.inputs",))
    assert from_arrays["parameters"]["mesentery"]["identifiable"]
    assert from_arrays["parameters"]["mesentery"]["std"] > 0


def test_failed_fit_raises(source_dir, tmp_path):
    # A start outside its bounds is an input error naming the key.
    experiment = {
        "rod": {"length": 0.2, "segments": 10, "radius": 2.5e-4, "linear_density": 2.24e-4},
        "parameters": {"bend_stiffness": {"value": 1.0, "fit": True, "min": 1e-8, "max": 1e-3},
                       "twist_stiffness": {"value": 6.8e-6}, "stretch_stiffness": {"value": 589}},
        "cases": [{"clamp": {"position": [0, 0, 0], "tangent": [1, 0, 0], "normal": [0, 0, 1]}}],
    }
    with pytest.raises(rodfit.InputError) as caught:
        rodfit.fit(experiment, base_dir=tmp_path)
    assert caught.value.key.startswith("parameters.bend_stiffness")
