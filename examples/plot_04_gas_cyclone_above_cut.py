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
bench.fits_table()[["rank", "formula", "d_cut", "d_cut_stderr", "shape", "F", "adequate", "extrapolated"]]

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
fits = bench.fits_table()
for formula, warning in fits.loc[fits["warnings"] != "", ["formula", "warnings"]].itertuples(index=False):
    print(f"{formula}: {warning}")

# %%
# With ``ci`` the fits get their intervals, but not the quantities that rest on where the cut
# is: with no point between partitions 0.25 and 0.75 the cut is not bracketed by the data,
# so d_cut, d50, d25, d75 and Ep get no interval (``method`` ``none``), while the shape,
# the slope, eta and epsilon keep theirs.
with_intervals = tromplab.fit_experiments(experiments, ci=0.95).fits_table()
with_intervals[["formula", "d_cut", "d_cut_low", "d_cut_high", "d_cut_method", "shape_low", "shape_high", "eta_low", "eta_high"]]

# %%
# The cut each formula extrapolates to: one point per formula and no error bar, since the
# data cannot tell where the cut is. The spread between the formulas is how much the answer
# depends on the shape chosen, not a measurement error.
ordered = with_intervals.sort_values("d_cut")
fig, ax = plt.subplots(figsize=(6.5, 3.8))
ax.plot(ordered["d_cut"], ordered["formula"], "o")
ax.axvline(sizes_um.min(), color="C3", linestyle="--", label="finest measured class")
ax.axvline(2.2, color="0.4", linestyle=":", label="cut of the curve that made the points")
ax.set_xscale("log")
ax.set_xlabel("fitted d_cut [um] (no interval: the cut is not bracketed by the data)")
ax.legend(fontsize=8, loc="lower right")
fig.tight_layout()

# %%
# The fits over a wider size range than measured.
ax = bench.plot("cyclone")
ax.set_title("Gas cyclone: every measured class above the cut")
plt.gcf().tight_layout()
