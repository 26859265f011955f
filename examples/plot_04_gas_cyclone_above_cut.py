"""
A gas cyclone measured above its cut
====================================

Gas cyclones often separate fine dust: their cut lies at a few micrometres, below the
finest class a sieve or a laser analysis of the collected dust resolves well. Every
measured class then lies above the cut and every partition number to the fine product
(the gas outlet) is below 1/2. The points below are the grade efficiency of such a
cyclone, 1/(1 + (d/d50)^2) (the form of Lapple's and Plitt's curves with d50 = 2.2 um),
read at seven classes from 3 to 30 um. What does tromplab say?
"""

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

import tromplab

sizes_um = np.array([3.0, 4.5, 6.5, 9.5, 14.0, 20.0, 30.0])
points = pd.DataFrame(
    {"experiment": "cyclone", "size_um": sizes_um, "partition_fine": (1.0 / (1.0 + (sizes_um / 2.2) ** 2)).round(4)}
)
points

# %%
# Fit the nine formulas. The fits succeed; the cut is found below the measured sizes.
experiments = tromplab.read_points(points)
bench = tromplab.fit_experiments(experiments)
bench.summary()[["rank", "formula", "d_cut", "d_cut_stderr", "shape", "F", "adequate", "extrapolated"]]

# %%
# tromplab says so in words: a note on the data before any fit, and statements on the fits
# (which quantities rest on the curve outside the measured sizes: d25 and the efficiency
# eta here, and which formulas the data cannot tell apart).
for note in bench.notes.get("cyclone", ()):
    print("data note:", note)
for verdict in bench.verdicts("cyclone"):
    print("verdict:", verdict)

# %%
# The cut each formula extrapolates to differs by more than its standard error: with no
# point below the cut, the curve's shape there comes from the formula, not the data.
fits = bench.summary().sort_values("d_cut")
fig, ax = plt.subplots(figsize=(6.5, 3.8))
ax.errorbar(fits["d_cut"], fits["formula"], xerr=1.96 * fits["d_cut_stderr"], fmt="o")
ax.axvline(sizes_um.min(), color="C3", linestyle="--", label="finest measured class")
ax.axvline(2.2, color="0.4", linestyle=":", label="cut of the curve that made the points")
ax.set_xlabel("fitted d_cut [um] with 95 % Wald interval")
ax.legend(fontsize=8)
fig.tight_layout()

# %%
# The fits over a wider size range than measured.
ax = bench.plot("cyclone")
ax.set_title("Gas cyclone: every measured class above the cut")
plt.gcf().tight_layout()
