"""rodfit.Runtime against the C++ runtime: the same 1000 ticks give the same bits."""
import numpy as np
import pytest

import rodfit
from conftest import run

TICKS = 1000


def _c_loop(reference, profile, tool_s, mode):
    out = run(reference, "ticks", profile, tool_s, mode, TICKS).stdout.split("\n")
    tools, forces, statuses, shape = [], [], [], []
    for line in out:
        words = line.split()
        if words and words[0] == "tick":
            tools.append([float.fromhex(w) for w in words[2:5]])
            forces.append([float.fromhex(w) for w in words[5:8]])
            statuses.append(int(words[8]))
        elif words and words[0] == "vertex":
            shape.append([float.fromhex(w) for w in words[2:5]])
    return np.array(tools), np.array(forces), statuses, np.array(shape)


@pytest.mark.parametrize("name, tool_s, mode", [
    ("suture.json", 0.2, "dynamic"),
    ("bowel_drag.json", 0.1, "quasi_static"),
    ("bowel_drag.json", 0.1, "dynamic"),
])
def test_python_loop_equals_cpp_loop_bit_for_bit(source_dir, reference, name, tool_s, mode):
    path = source_dir / "data" / "profiles" / name
    tools, c_forces, c_statuses, c_shape = _c_loop(reference, path, tool_s, mode)
    assert len(tools) == TICKS and c_shape.shape[1] == 3
    runtime = rodfit.Runtime(path, mode=mode, tool_s=tool_s)
    forces = np.empty_like(c_forces)
    converged = 0
    for k in range(TICKS):
        forces[k] = runtime.step(tools[k])
        converged += runtime.status()["status"] == "converged"
        assert (runtime.status()["status"] == "converged") == (c_statuses[k] == 0), k
    # Bit for bit: float64 compared as integers, so -0.0 != 0.0 and NaN would show.
    assert np.array_equal(forces.view(np.int64), c_forces.view(np.int64))
    assert np.array_equal(runtime.shape().view(np.int64), c_shape.view(np.int64))
    assert converged == TICKS  # the path is gentle: every tick converges in both
    assert np.abs(forces).max() > 0  # the tool is pulling: the forces are not trivially zero


def test_runtime_api(source_dir):
    path = source_dir / "data" / "profiles" / "suture.json"
    runtime = rodfit.Runtime(str(path), mode="dynamic", tool_s=0.1)
    assert runtime.status()["status"] == "constructed"
    home = runtime.tool_position()
    assert home.shape == (3,) and home.dtype == np.float64
    force = runtime.step(home + [1e-3, 0.0, 0.0])
    assert force.shape == (3,) and np.all(np.isfinite(force))
    assert np.array_equal(force, runtime.tool_force())
    status = runtime.status()
    assert status["ok"] and status["ticks"] == 1 and status["time"] == pytest.approx(1e-3)
    shape = runtime.shape()
    assert shape.shape == (51, 3)  # the suture's 50 segments
    mesh = runtime.mesh()
    assert mesh["vertices"].shape == (51 * 16, 3) and mesh["triangles"].shape[1] == 3
    assert mesh["triangles"].max() < len(mesh["vertices"])
    assert runtime.energy() != 0 and runtime.kinetic_energy() >= 0


def test_runtime_from_profile_dict_equals_from_file(source_dir):
    import json
    path = source_dir / "data" / "profiles" / "bowel_drag.json"
    with open(path) as f:
        document = json.load(f)
    a = rodfit.Runtime(path, tool_s=0.1)
    b = rodfit.Runtime(document, tool_s=0.1)
    target = a.tool_position() + [0.0, 5e-3, 5e-3]
    assert np.array_equal(a.step(target), b.step(target))
    assert np.array_equal(a.shape(), b.shape())


def test_refused_tick_keeps_state_and_says_so(source_dir):
    runtime = rodfit.Runtime(source_dir / "data" / "profiles" / "suture.json", tool_s=0.1)
    before = runtime.shape()
    runtime.step([np.nan, 0.0, 0.0])
    status = runtime.status()
    assert status["status"] == "tool_refused" and not status["ok"] and status["message"]
    assert np.array_equal(before, runtime.shape())


def test_runtime_option_errors(source_dir):
    path = source_dir / "data" / "profiles" / "suture.json"
    with pytest.raises(ValueError, match="mode"):
        rodfit.Runtime(path, mode="fast")
    with pytest.raises(ValueError, match="tool_s"):
        rodfit.Runtime(path, tool_s=5.0)


def test_runtime_options_are_read_through_their_declaration(source_dir):
    # RuntimeOptions' Serialize reads the keywords: its words (either spelling), its ranges,
    # and no keyword it does not declare.
    path = source_dir / "data" / "profiles" / "suture.json"
    with pytest.raises(ValueError) as error:
        rodfit.Runtime(path, tool="hammer")
    assert str(error.value) == "tool: must be 'grasp' or 'poke', got 'hammer'"
    with pytest.raises(ValueError) as error:
        rodfit.Runtime(path, max_iterations=0)
    assert str(error.value) == "max_iterations: must be an integer in [1, 10000], got 0"
    with pytest.raises(TypeError, match="unexpected keyword argument 'time_stepp'"):
        rodfit.Runtime(path, time_stepp=1e-3)
    assert rodfit.Runtime(path, mode="quasi-static", tool_s=None).status()["ok"]
