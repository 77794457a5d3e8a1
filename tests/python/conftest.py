"""Shared fixtures of the Python package's tests (docs/python.md, "Tests").

CTest runs them (test `python_pytest`) with PYTHONPATH=build/python and the paths below in the
environment; run by hand from the repository root they default to the build folder `build/`:

    PYTHONPATH=build/python python3 -m pytest -q tests/python
"""
import os
import pathlib
import subprocess

import pytest

SOURCE_DIR = pathlib.Path(os.environ.get("RODFIT_SOURCE_DIR",
                                         pathlib.Path(__file__).resolve().parents[2]))
BUILD_DIR = SOURCE_DIR / "build"


def _program(variable, default):
    path = pathlib.Path(os.environ.get(variable, BUILD_DIR / default))
    if not path.is_file():
        pytest.fail(f"{path} missing: build it (cmake --build build), or set {variable}")
    return path


@pytest.fixture(scope="session")
def source_dir():
    return SOURCE_DIR


@pytest.fixture(scope="session")
def cli():
    """The rodfit command, the reference the package's results are compared with."""
    return _program("RODFIT_CLI", "rodfit")


@pytest.fixture(scope="session")
def reference():
    """tests/python/python_reference.cc: the C++ runtime loop and timings."""
    return _program("RODFIT_PYTHON_REFERENCE", "python_reference")


def run(*args, cwd=None, check=True):
    """Runs a program; its stdout. Fails the test with its stderr when it fails."""
    done = subprocess.run([str(a) for a in args], cwd=cwd, capture_output=True, text=True)
    if check and done.returncode != 0:
        pytest.fail(f"{' '.join(map(str, args))} exited {done.returncode}: {done.stderr}")
    return done
