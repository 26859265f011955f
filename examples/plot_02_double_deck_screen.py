"""
A double-deck screen from a lab table
=====================================

The bundled lab table ``datasets/double_deck_screen_decks_lab.csv`` holds the sieve
analyses of the feed, fine and coarse products of each deck of a 20-over-65-mesh
double-deck screen (a worked exercise on McCabe, Smith & Harriott's quartz analysis),
sizes in mm. It is the README's example of what the data cannot tell: neither deck has a
measured partition between 0.25 and 0.75, so the cut and Ep rest on each formula's shape.
Done in Python: read the table, check the mass balance, fit the nine formulas to each deck,
rank them, and draw the curves.
"""

from pathlib import Path

import matplotlib.pyplot as plt

import tromplab

# the repository root (sphinx-gallery runs each example from examples/, without __file__)
ROOT = Path(globals().get("__file__", "example.py")).resolve().parents[1]
LAB = ROOT / "datasets" / "double_deck_screen_decks_lab.csv"

experiments, balances = tromplab.read_experiments(LAB, estimate_yield=True)
[(points.experiment, len(points.size)) for points in experiments]

# %%
# The mass balance of the first deck: each stream's share per class, the partition
# number to the fine product and whether the class was used.
balances[0].points_table().head(8)

# %%
# Fit, screen and rank the nine formulas on both decks.
bench = tromplab.fit_experiments(experiments, size_unit="mm")
bench.ranking_table()

# %%
# The top-ranked fit of the 20-mesh deck, with parameters, intervals and indices.
print(bench.best_fit("deck_20mesh").report())

# %%
# The measured points and the nine fitted curves of each deck (best fit thick, with its band).
fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
for ax, points in zip(axes, experiments):
    bench.plot(points.experiment, ax=ax)
fig.tight_layout()
