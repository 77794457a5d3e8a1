"""rodfit.synth makes the bytes `rodfit synth` writes."""
import numpy as np

import rodfit
from conftest import run


def test_synth_equals_cli(tmp_path, source_dir, cli):
    protocol = source_dir / "calibration" / "tissue_drag" / "protocol.yaml"
    run(cli, "synth", protocol, "-o", tmp_path / "cli", "--seed", 7)
    result = rodfit.synth(protocol, seed=7)
    assert result["files"], "synth made no files"
    for name, data in result["files"].items():
        assert (tmp_path / "cli" / name).read_bytes() == data, name
    assert set(result["truth"]) == {"rest", "drag"}
    assert result["truth"]["drag"].shape == (41, 3)
    # Written too when asked, the same bytes.
    rodfit.synth(protocol, seed=7, output=tmp_path / "py")
    for name, data in result["files"].items():
        assert (tmp_path / "py" / name).read_bytes() == data, name


def test_synth_noise_free_samples_lie_on_the_truth(source_dir):
    protocol = source_dir / "calibration" / "tissue_drag" / "protocol.yaml"
    result = rodfit.synth(protocol, noise_free=True)
    rows = result["files"]["rest_markers.csv"].decode().split("\n")
    assert rows[0] == "s,x,y,z"
    tip = np.array([float(v) for v in rows[-2].split(",")])
    assert tip[0] == 0.15  # the last marker at the tip
    assert np.array_equal(tip[1:], result["truth"]["rest"][-1])
