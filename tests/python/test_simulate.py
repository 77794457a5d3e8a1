"""rodfit.simulate against `rodfit simulate`: shapes.csv to 1e-12 m, trajectory.csv likewise."""
import csv
import json

import numpy as np
import pytest

import rodfit
from conftest import run

TOLERANCE_M = 1e-12


def read_rows(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def cli_shapes(path):
    shapes = {}
    for row in read_rows(path):
        shapes.setdefault(row["case"], []).append([float(row[c]) for c in "xyz"])
    return {case: np.array(x) for case, x in shapes.items()}


@pytest.mark.parametrize("scene, profile", [
    ("data/scenes/cantilever.yaml", None),
    ("data/scenes/bowel_drag.yaml", None),
    ("data/scenes/bowel_poke.yaml", None),
    ("calibration/suture_cantilever/experiment.yaml", "data/profiles/suture.json"),
])
def test_simulate_equals_shapes_csv(tmp_path, source_dir, cli, scene, profile):
    args = [cli, "simulate", source_dir / scene, "-o", tmp_path / "cli", "-q"]
    if profile:
        args += ["--profile", source_dir / profile]
    run(*args)
    expected = cli_shapes(tmp_path / "cli" / "shapes.csv")
    result = rodfit.simulate(source_dir / scene,
                             None if profile is None else source_dir / profile)
    assert not result.moving and list(result) == list(expected)
    for case, x in expected.items():
        assert result[case].shape == x.shape
        assert np.abs(result[case] - x).max() <= TOLERANCE_M, case
    # Held points' forces, as forces.csv has them.
    forces = read_rows(tmp_path / "cli" / "forces.csv")
    assert len(result.forces) == len(forces)
    for row, mine in zip(forces, result.forces):
        assert (row["case"], row["point"]) == (mine["case"], mine["point"])
        f = np.array([float(row[c]) for c in ("fx", "fy", "fz")])
        assert np.abs(mine["force"] - f).max() <= 1e-12 * max(1.0, np.abs(f).max())


def test_simulate_with_a_fitted_profile_dict(source_dir):
    path = source_dir / "data" / "profiles" / "suture.json"
    scene = source_dir / "calibration" / "suture_cantilever" / "experiment.yaml"
    from_dict = rodfit.simulate(scene, json.loads(path.read_text()))
    from_path = rodfit.simulate(scene, path)
    for case in from_path:
        assert np.array_equal(from_dict[case], from_path[case])


def test_moving_scene_equals_trajectory_csv(tmp_path, source_dir, cli):
    scene = source_dir / "data" / "scenes" / "suture_swing.yaml"
    run(cli, "simulate", scene, "-o", tmp_path / "cli", "-q")
    rows = read_rows(tmp_path / "cli" / "trajectory.csv")
    result = rodfit.simulate(scene)
    assert result.moving
    for case, motion in result.items():
        mine = [r for r in rows if r["case"] == case]
        frames, vertices = motion["x"].shape[:2]
        assert len(mine) == frames * vertices
        x = np.array([[float(r[c]) for c in "xyz"] for r in mine]).reshape(frames, vertices, 3)
        t = np.array([float(r["t"]) for r in mine[::vertices]])
        assert np.abs(motion["x"] - x).max() <= TOLERANCE_M
        assert np.abs(motion["t"] - t).max() <= 1e-15
        assert "clamp" in motion["reactions"]


def test_case_that_does_not_solve_raises(tmp_path):
    scene = {
        "rod": {"length": 0.2, "segments": 10, "radius": 2.5e-4, "linear_density": 2.24e-4},
        "parameters": {"bend_stiffness": {"value": 3e-6}, "twist_stiffness": {"value": 6.8e-6},
                       "stretch_stiffness": {"value": 589}},
        "solver": {"max_iterations": 1},
        "cases": [{"name": "pulled",
                   "clamp": {"position": [0, 0, 0], "tangent": [1, 0, 0], "normal": [0, 0, 1]},
                   "tip_force": [0, 0.5, 0]}],
    }
    with pytest.raises(rodfit.SolveError, match="pulled"):
        rodfit.simulate(scene, base_dir=tmp_path)
