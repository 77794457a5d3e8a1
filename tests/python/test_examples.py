"""The Python examples run (from the repository root), and the notebook mirrors its script."""
import json
import os
import sys

from conftest import run


def _env():
    return dict(os.environ, MPLBACKEND="Agg")


def test_runtime_loop_example(source_dir):
    done = run(sys.executable, source_dir / "examples" / "python" / "runtime_loop.py",
               cwd=source_dir)
    assert "1000 of 1000 ticks converged" in done.stdout


def test_fit_and_plot_example(source_dir, tmp_path):
    png = tmp_path / "fit.png"
    done = run(sys.executable, source_dir / "examples" / "python" / "fit_and_plot.py", png,
               cwd=source_dir)
    assert "bend_stiffness" in done.stdout
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10000


def test_notebook_mirrors_its_script(source_dir):
    folder = source_dir / "examples" / "python"
    script = (folder / "fit_and_plot.py").read_text().split("# %%\n")[1:]
    notebook = json.loads((folder / "fit_and_plot.ipynb").read_text())
    cells = ["".join(c["source"]) for c in notebook["cells"] if c["cell_type"] == "code"]
    assert cells == [part.rstrip("\n") for part in script]
