"""Run a fitted rod in a Python loop, as a simulator's haptic thread would.

Loads a fitted profile (default: the bundled suture, data/profiles/suture.json), grasps the rod
at its tip and moves the tool along a horizontal circle (radius 5 % of the rod's length) for
1000 ticks of 1 ms in dynamic mode; prints the force on the tool every 100 ticks and the tick
times. Exits 1 when a tick does not converge. From the repository root, with the package built:

    PYTHONPATH=build/python python3 examples/python/runtime_loop.py [PROFILE.json TOOL_S]
"""
import math
import sys
import time

import numpy as np

import rodfit


def main(argv):
    profile = argv[1] if len(argv) > 1 else "data/profiles/suture.json"
    tool_s = float(argv[2]) if len(argv) > 2 else None  # None: the tip
    runtime = rodfit.Runtime(profile, mode="dynamic", tool_s=tool_s, time_step=1e-3)
    home = runtime.tool_position()                  # [m] where the tool took hold
    radius = 0.05 * rodfit.profile(profile).length  # [m]
    ticks, failed, tick_seconds = 1000, 0, []
    for k in range(1, ticks + 1):
        phase = 2.0 * math.pi * k / ticks
        tool = home + radius * np.array([math.cos(phase) - 1.0, math.sin(phase), 0.0])
        start = time.perf_counter()
        force = runtime.step(tool)                  # [N] the rod's force on the tool
        tick_seconds.append(time.perf_counter() - start)
        status = runtime.status()
        if not status["ok"]:
            failed += 1
            print(f"  tick {k}: {status['status']}: {status['message']}", file=sys.stderr)
        if k % 100 == 0:
            print(f"  tick {k:4d}  force [{force[0]: .4e} {force[1]: .4e} {force[2]: .4e}] N  "
                  f"{status['iterations']} iterations")
    t = np.sort(np.array(tick_seconds)) * 1e3
    print(f"tick time: median {t[len(t) // 2]:.3f} ms, p99 {t[int(0.99 * len(t))]:.3f} ms, "
          f"max {t[-1]:.3f} ms; {ticks - failed} of {ticks} ticks converged")
    shape = runtime.shape()
    print(f"tip at {shape[-1]} m after {runtime.time:.3f} s")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
