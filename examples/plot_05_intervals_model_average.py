"""
Intervals and model averages
============================

A cut size without an interval is half an answer, and the choice among nine formulas that
fit about equally well is itself uncertain. This example takes the 20-mesh deck of the
bundled double-deck screen (``datasets/double_deck_screen_decks_lab.csv``) and shows the
profile-likelihood and delta-method intervals of one fit
(:func:`tromplab.interval_table`), a bootstrap of it (:func:`tromplab.bootstrap`), the
Akaike weights of the formulas (:func:`tromplab.akaike_weights`) and the model-averaged
cut, Ep and efficiency with their unconditional intervals (:func:`tromplab.model_averages`).
"""

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import tromplab

# the repository root (sphinx-gallery runs each example from examples/, without __file__)
ROOT = Path(globals().get("__file__", "example.py")).resolve().parents[1]
LAB = ROOT / "datasets" / "double_deck_screen_decks_lab.csv"
experiments, _ = tromplab.read_experiments(LAB, estimate_yield=True)
bench = tromplab.fit_experiments(experiments, size_unit="mm")
fit = bench.best_fit("deck_20mesh")
print(fit.formula.id, "ranked first on the 20-mesh deck")

# %%
# Intervals of the parameters (profile likelihood) and of the indices (delta method).
intervals = tromplab.interval_table(fit, level=0.95)
intervals

# %%
# A residual bootstrap of the same fit (200 resamples, fixed seed: the same intervals each run).
boot = tromplab.bootstrap(fit, n=200, seed=1)
boot.intervals

# %%
# Akaike weights of the nine formulas on this deck: how much the data prefer each.
table = bench.fits_table()
deck = table[table["experiment"] == "deck_20mesh"].copy()
deck["weight"] = tromplab.akaike_weights(deck["aicc"].to_numpy())
deck[["formula", "rank", "F", "aicc", "delta_aicc", "weight", "d50", "ep"]].sort_values("weight", ascending=False)

# %%
# Model averages: d50, Ep and eta averaged over the formulas with their Akaike weights,
# with standard errors that include the spread between formulas.
averages = tromplab.model_averages(bench)
averages

# %%
# Each formula's cut with its interval and Akaike weight w, and the model average.
rows = deck.sort_values("d50")
average = averages[(averages["experiment"] == "deck_20mesh") & (averages["quantity"] == "d50")].iloc[0]
fig, ax = plt.subplots(figsize=(6.5, 4))
ax.errorbar(rows["d50"], rows["formula"], xerr=1.96 * rows["d_cut_stderr"], fmt="o", label="single formula (Wald 95 %)")
for d50, formula, weight in rows[["d50", "formula", "weight"]].itertuples(index=False):
    ax.annotate(f"w = {weight:.2f}", (d50, formula), xytext=(0, 6), textcoords="offset points", ha="center", fontsize=7)
ax.axvline(average["value"], color="C3", label="model average d50")
if np.isfinite(average["low"]) and np.isfinite(average["high"]):
    ax.axvspan(average["low"], average["high"], color="C3", alpha=0.15, label="its 95 % interval")
ax.set_xlabel("d50 [mm]")
ax.legend(fontsize=8, loc="lower right")
fig.tight_layout()
