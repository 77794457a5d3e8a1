"""The Python package's call overhead (docs/python.md, "Overhead"): a runtime tick and a fit,
through rodfit (Python) and through the C++ library directly (build/python_reference), the same
work on the same machine. From the repository root, after building:

    PYTHONPATH=build/python python3 tests/bench/python_overhead.py [build]

Prints per-call times and the difference. Timings only: no assertion (tests hold none).
"""
import math
import pathlib
import subprocess
import sys
import time
import warnings

import numpy as np

import rodfit

BUILD = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else "build")
REFERENCE = BUILD / "python_reference"
PROFILE, TOOL_S, MODE, TICKS = "data/profiles/suture.json", 0.2, "dynamic", 5000
EXPERIMENT, FITS = "calibration/tissue_drag/experiment.yaml", 20


def cpp(*args):
    out = subprocess.run([str(REFERENCE), *map(str, args)], capture_output=True, text=True,
                         check=True)
    return float(out.stdout)


def python_tick():
    """python_reference's timed loop, in Python: 10 untimed ticks, then TICKS timed."""
    runtime = rodfit.Runtime(PROFILE, mode=MODE, tool_s=TOOL_S)
    home = runtime.tool_position()
    radius = 0.05 * rodfit.profile(PROFILE).length
    def tool(k):
        phase = 2.0 * math.pi * k / TICKS
        return home + radius * np.array([math.cos(phase) - 1.0, math.sin(phase), 0.0])
    for k in range(1, 11):
        runtime.step(tool(k))
    tools = [tool(k) for k in range(11, TICKS + 11)]  # the path computed outside the timing
    start = time.perf_counter()
    total = 0.0
    for t in tools:
        total += runtime.step(t)[0]
    return (time.perf_counter() - start) / TICKS


def python_fit():
    ex = rodfit.experiment(EXPERIMENT)
    rodfit.fit(ex)
    start = time.perf_counter()
    for _ in range(FITS):
        rodfit.fit(ex)
    return (time.perf_counter() - start) / FITS


def call_round_trip():
    """The binding's own cost per call: a method that does no work (tool_force copies 3
    doubles out) and a step's argument conversion (numpy (3,) in) on top, per call."""
    runtime = rodfit.Runtime(PROFILE, mode=MODE, tool_s=TOOL_S)
    n = 200000
    start = time.perf_counter()
    for _ in range(n):
        runtime.tool_force()
    return (time.perf_counter() - start) / n


def best_of_interleaved(n, a, b):
    """min over n alternating runs of a and b: both see the same load of a shared machine."""
    ta, tb = [], []
    for _ in range(n):
        ta.append(a())
        tb.append(b())
    return min(ta), min(tb)


def main():
    # The recipe's run warns (stretched spans) on every fit; not what is timed here.
    warnings.simplefilter("ignore", rodfit.FitWarning)
    c_tick, p_tick = best_of_interleaved(
        5, lambda: cpp("time-ticks", PROFILE, TOOL_S, MODE, TICKS), python_tick)
    print(f"runtime tick ({PROFILE}, {MODE}, best of 5 runs of {TICKS} ticks each): "
          f"C++ {c_tick * 1e6:.2f} us, Python {p_tick * 1e6:.2f} us, "
          f"difference {(p_tick - c_tick) * 1e6:+.2f} us per tick")
    print(f"a call that does no work (Runtime.tool_force): {call_round_trip() * 1e6:.3f} us")
    if hasattr(rodfit, "fit"):
        c_fit, p_fit = best_of_interleaved(
            3, lambda: cpp("time-fit", EXPERIMENT, FITS), python_fit)
        print(f"fit ({EXPERIMENT}, best of 3 runs of {FITS} fits each): C++ {c_fit * 1e3:.3f} "
              f"ms, Python {p_fit * 1e3:.3f} ms, difference {(p_fit - c_fit) * 1e3:+.3f} ms "
              f"per fit")


if __name__ == "__main__":
    main()
