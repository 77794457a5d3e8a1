# Fit a bundled recipe from Python and plot the fitted shapes against the markers (matplotlib).
#
# Fits the suture cantilever recipe (calibration/suture_cantilever/), prints each fitted
# parameter with its standard deviation, solves the recipe's cases with the fitted profile and
# draws each case's centre-line (side view, x-z) with its markers into out/suture_fit.png.
# fit_and_plot.ipynb is this script as a notebook, cell for cell (the "# %%" lines; the test
# suite checks that they agree and runs this script). From the repository root:
#
#     PYTHONPATH=build/python python3 examples/python/fit_and_plot.py [OUTPUT.png]

# %%
import pathlib
import sys

import matplotlib
matplotlib.use("Agg")  # files only: no display needed
import matplotlib.pyplot as plt
import numpy as np

import rodfit

recipe = pathlib.Path("calibration/suture_cantilever")
output = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 and sys.argv[1].endswith(".png")
                      else "out/suture_fit.png")

# %%
# The fit: the profile as a dict with the profile JSON's structure (SI units).
profile = rodfit.fit(recipe / "experiment.yaml")
for name, p in profile["parameters"].items():
    if p.get("fitted"):
        print(f"{name:18s} {p['value']:.6g} +- {p['std']:.2g} {p['unit']}")

# %%
# The recipe's cases solved with the fitted material: {case: (n+1, 3) centre-line [m]}.
shapes = rodfit.simulate(recipe / "experiment.yaml", profile)

# %%
fig, axes = plt.subplots(1, len(shapes), figsize=(4 * len(shapes), 3.2), sharey=True)
for ax, (case, x) in zip(np.atleast_1d(axes), shapes.items()):
    markers = np.genfromtxt(recipe / f"{case}_markers.csv", delimiter=",", names=True)
    ax.plot(x[:, 0] * 1e3, x[:, 2] * 1e3, "-", label="fitted rod")
    ax.plot(markers["x"] * 1e3, markers["z"] * 1e3, "o", ms=4, label="markers")
    ax.set_title(case)
    ax.set_xlabel("x [mm]")
    ax.set_aspect("equal", adjustable="datalim")
np.atleast_1d(axes)[0].set_ylabel("z [mm]")
np.atleast_1d(axes)[0].legend(loc="lower left", fontsize=8)
fig.tight_layout()
output.parent.mkdir(parents=True, exist_ok=True)
fig.savefig(output, dpi=120)
print(f"wrote {output}")
