"""rodfit.rollout against `rodfit rollout`: the predicted markers of rollout.csv, the fit of
motion_fit.json; a recording given as an array gives what its file gives."""
import csv
import json

import numpy as np
import pytest

import rodfit
from conftest import run
from test_fit import assert_documents_match

MARKERS = 6


@pytest.fixture(scope="module")
def recording(tmp_path_factory, source_dir, cli):
    """A synthetic recording of the bundled cable scene (`simulate --markers`)."""
    folder = tmp_path_factory.mktemp("cable")
    run(cli, "simulate", source_dir / "data" / "scenes" / "cable_drive.yaml", "-o", folder,
        "--markers", MARKERS, "-q")
    return folder / "markers.csv"


def _rollout_csv(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    frames = max(int(r["frame"]) for r in rows) + 1
    x = np.full((frames, MARKERS, 3), np.nan)
    for r in rows:
        x[int(r["frame"]), int(r["marker"])] = [float(r[c]) for c in "xyz"]
    return x


def test_rollout_equals_cli(tmp_path, source_dir, cli, recording):
    scene = source_dir / "data" / "scenes" / "cable_drive.yaml"
    run(cli, "rollout", scene, recording, "-o", tmp_path / "cli", "-q")
    expected = _rollout_csv(tmp_path / "cli" / "rollout.csv")
    result = rodfit.rollout(scene, [recording])
    predicted = result["recordings"][0]["predicted"]
    assert predicted.shape == expected.shape
    assert np.abs(predicted - expected).max() <= 1e-12
    assert result["error_predicted"] > 0 and result["recordings"][0]["held"][0]


def test_rollout_from_an_array_equals_from_its_file(source_dir, recording):
    with open(recording) as f:
        rows = list(csv.DictReader(f))
    times = sorted({float(r["t"]) for r in rows})
    frames = np.full((len(times), MARKERS, 3), np.nan)
    index = {t: k for k, t in enumerate(times)}
    for r in rows:
        frames[index[float(r["t"])], int(r["marker"])] = [float(r[c]) for c in "xyz"]
    rate = 1.0 / (times[1] - times[0])
    scene = source_dir / "data" / "scenes" / "cable_drive.yaml"
    from_file = rodfit.rollout(scene, [recording])
    from_array = rodfit.rollout(scene, [frames], frame_rate=round(rate))
    assert np.array_equal(from_file["recordings"][0]["predicted"],
                          from_array["recordings"][0]["predicted"])


def test_rollout_fit_equals_cli(tmp_path, source_dir, cli, recording):
    scene = source_dir / "data" / "scenes" / "cable_drive.yaml"
    # Exit 5: the noise-free recording's estimated noise is round-off, which no held-end model
    # explains; the fit is written all the same.
    done = run(cli, "rollout", scene, recording, "-o", tmp_path / "cli", "-q", "--fit",
               "bend_stiffness", check=False)
    assert done.returncode in (0, 5), done.stderr
    expected = json.loads((tmp_path / "cli" / "motion_fit.json").read_text())
    result = rodfit.rollout(scene, [recording], fit=["bend_stiffness"])
    assert expected["converged"] and expected["evaluations"] > 1
    assert_documents_match(expected, result["fit"])
    # The fit's profile.json, as the CLI writes it (the inputs' digests aside: the same files).
    profile = json.loads((tmp_path / "cli" / "profile.json").read_text())
    assert_documents_match(profile["parameters"], result["profile"]["parameters"])
    assert_documents_match(profile["rod"], result["profile"]["rod"])
    assert_documents_match(expected["parameters"]["bend_stiffness"]["value"],
                           profile["parameters"]["bend_stiffness"]["value"])


def test_rollout_fit_that_does_not_converge_returns_its_best_point(tmp_path, source_dir, cli, recording):
    scene = source_dir / "data" / "scenes" / "cable_drive.yaml"
    done = run(cli, "rollout", scene, recording, "-o", tmp_path / "cli", "-q", "--fit",
               "bend_stiffness", "--max-evaluations", 3, check=False)
    # Exit 4 (not converged, its best point written), or 5 where the misfit verdict (the
    # higher status) applies too.
    assert done.returncode in (4, 5) and "before converging" in done.stderr, done.stderr
    expected = json.loads((tmp_path / "cli" / "motion_fit.json").read_text())
    assert not expected["converged"]
    with pytest.warns(rodfit.FitWarning, match="did not converge"):
        result = rodfit.rollout(scene, [recording], fit=["bend_stiffness"], max_evaluations=3)
    assert result["fit_not_converged"]
    assert_documents_match(expected, result["fit"])


def test_rollout_settings_given_equal_the_cli_options(tmp_path, source_dir, cli, recording):
    # A setting given by keyword is the command line's option (the same declaration reads
    # both); Python may spell a word with an underscore (free_roll).
    scene = source_dir / "data" / "scenes" / "cable_drive.yaml"
    run(cli, "rollout", scene, recording, "-o", tmp_path / "cli", "-q", "--smooth", 2,
        "--held-ends", "free-roll")
    expected = _rollout_csv(tmp_path / "cli" / "rollout.csv")
    result = rodfit.rollout(scene, [recording], smooth_frames=2, held_ends="free_roll")
    predicted = result["recordings"][0]["predicted"]
    assert predicted.shape == expected.shape
    assert np.abs(predicted - expected).max() <= 1e-12
    # ... and differs from the defaults' run (the settings were applied).
    default = rodfit.rollout(scene, [recording])["recordings"][0]["predicted"]
    assert np.nanmax(np.abs(default - predicted)) > 0


@pytest.mark.parametrize("settings, message", [
    ({"smooth_frames": 5000}, "smooth_frames: must be an integer in [0, 1000], got 5000"),
    ({"smooth_frames": 2.5}, "smooth_frames: must be an integer in [0, 1000], got 2.5"),
    ({"held_ends": "sideways"}, "held_ends: must be 'grippers', 'free_roll' or 'pins', got 'sideways'"),
    ({"initial": "rest"}, "initial: must be 'equilibrium' or 'markers', got 'rest'"),
    ({"method": "newton"}, "method: must be 'lm' or 'bobyqa', got 'newton'"),
    ({"max_evaluations": True}, "max_evaluations: must be an integer in [1, 100000], got True"),
    ({"marker_sigma": -1.0}, "marker_sigma: must be in [0, 1000000000], got -1"),
    ({"held_markers": [0, "one"]}, "held_markers: expected a list of integers, got 'one'"),
])
def test_rollout_settings_are_checked_by_their_declaration(source_dir, recording, settings, message):
    scene = source_dir / "data" / "scenes" / "cable_drive.yaml"
    with pytest.raises(ValueError) as error:
        rodfit.rollout(scene, [recording], **settings)
    assert str(error.value) == message
