"""
A washing plant from washability and partition curves, with error bars
======================================================================

A raw coal is screened into three size fractions, each washed by its own device: a
dense-medium vessel (50x12 mm), a dense-medium cyclone (12x1 mm) and spirals (1x0.15 mm),
and the clean coals are blended into one product. The washability of each size fraction and
the devices' partition curves, with the standard deviations a tracer test gives them, are
**synthetic** (``datasets/plant_washability_synthetic.csv`` and
``datasets/plant_devices_synthetic.csv``, made up in the shape of published tables). This is
``tromplab plant predict`` and ``tromplab plant optimize`` in Python (``tromplab.plant``, see
the plant page of the user guide).
"""

from pathlib import Path

import matplotlib.pyplot as plt

from tromplab.plant import optimize, predict

# the repository root (sphinx-gallery runs each example from examples/, without __file__)
ROOT = Path(globals().get("__file__", "example.py")).resolve().parents[1]
WASH = ROOT / "datasets" / "plant_washability_synthetic.csv"
DEVICES = ROOT / "datasets" / "plant_devices_synthetic.csv"

# %%
# What the plant makes at the cuts of the plant table: clean coal and ash of each size
# fraction and of the blend, the theoretical yield at the same ash and the organic
# efficiency, each with its 95 % interval from 2,000 parametric-bootstrap draws of the curves.
plant = predict(WASH, DEVICES, seed=1)
shown = ["size_fraction", "device", "clean_yield_pct", "clean_yield_pct_low", "clean_yield_pct_high", "clean_ash_pct",
         "clean_ash_pct_low", "clean_ash_pct_high", "organic_efficiency_pct", "near_gravity_pct"]  # fmt: skip
plant.products[shown]

# %%
# Yield against ash: the theoretical curves (dashed), the curves the devices make as their
# cuts move (solid) and the predicted points with their intervals; then the partition curves
# with their bands.
fig, (left, right) = plt.subplots(1, 2, figsize=(13, 5))
plant.plot_yield_ash(ax=left)
plant.plot_partition(ax=right)
fig.tight_layout()

# %%
# The cuts that give the most clean coal at 10 % ash: the incremental ash - the ash of the
# marginal clean coal - is the same in every circuit (the equal-incremental-ash principle).
best = optimize(WASH, DEVICES, target_ash_pct=10, seed=1)
best.cuts

# %%
# With the uncertainty of the curves the blended ash is itself uncertain: the cuts above meet
# 10 % only about half the time (``target_met_probability``). Asking for 95 % confidence
# lowers the design ash and costs some yield.
sure = optimize(WASH, DEVICES, target_ash_pct=10, confidence=0.95, draws=1000, seed=1)
print(sure.notes[0])
sure.cuts
