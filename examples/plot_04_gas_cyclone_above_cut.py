"""
A gas cyclone measured above its cut
====================================

Gas cyclones often separate fine dust: their cut lies at a few micrometres, below the
finest class a sieve or a laser analysis of the collected dust resolves well. Every
measured class then lies above the cut and every partition number to the fine product
(the gas outlet) is below 1/2. The points below are the grade efficiency of such a
cyclone, 1/(1 + (d/d50)^2) (the form of Lapple's and Plitt's curves with d50 = 2.2 um),
read at seven classes from 3 to 30 um with a small measurement error. What does tromplab say?
"""

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

import tromplab

sizes_um = np.array([3.0, 4.5, 6.5, 9.5, 14.0, 20.0, 30.0])
# the curve read with a measurement error of 0.005 on each partition number (fixed seed)
measured = 1.0 / (1.0 + (sizes_um / 2.2) ** 2) + np.random.default_rng(7).normal(0.0, 0.005, sizes_um.size)
points = pd.DataFrame({"experiment": "cyclone", "size_um": sizes_um, "partition_fine": np.clip(measured, 0.0, 1.0).round(4)})
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
# Some fits say more in their warnings: a parameter the data do not determine (its
# standard error larger than itself), or a shape that ended on its bound.
fits = bench.summary()
for formula, warning in fits.loc[fits["warnings"] != "", ["formula", "warnings"]].itertuples(index=False):
    print(f"{formula}: {warning}")

# %%
# The cut each formula extrapolates to, with its 95 % Wald interval: with no point below
# the cut, where it lies comes from the formula's shape, not from the data. Fits whose cut
# the data do not determine are left out of the figure.
determined = fits[fits["d_cut_stderr"] < fits["d_cut"]].sort_values("d_cut")
fig, ax = plt.subplots(figsize=(6.5, 3.8))
ax.errorbar(determined["d_cut"], determined["formula"], xerr=1.96 * determined["d_cut_stderr"], fmt="o")
ax.axvline(sizes_um.min(), color="C3", linestyle="--", label="finest measured class")
ax.axvline(2.2, color="0.4", linestyle=":", label="cut of the curve that made the points")
ax.set_xlabel("fitted d_cut [um] with 95 % Wald interval")
left_out = sorted(set(fits["formula"]) - set(determined["formula"]))
ax.set_title("left out (cut not determined): " + (", ".join(left_out) or "none"), fontsize=9)
ax.legend(fontsize=8, loc="lower right")
fig.tight_layout()

# %%
# The fits over a wider size range than measured.
ax = bench.plot("cyclone")
ax.set_title("Gas cyclone: every measured class above the cut")
plt.gcf().tight_layout()
