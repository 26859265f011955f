"""
Washability prediction and organic efficiency
=============================================

The float-sink analysis of a raw coal with the ash of each density fraction
(``datasets/density_washability_synthetic.csv``, a synthetic table in the shape of
published raw-coal washability) gives its washability curves: the cumulative floats and
sinks and the near-gravity material. A dense-medium separator with Tromp's normal curve and
Ep = 0.035 is then applied at several cut densities: the yield and ash of floats and sinks,
the theoretical yield of an ideal separation at the same floats ash and the organic
efficiency (their ratio). Last, the cut density giving floats of 8 % ash. This is
``tromplab density predict`` in Python (``tromplab.density.washability``).
"""

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from tromplab.density.washability import predict, read_washability

ROOT = Path(globals().get("__file__", "example.py")).resolve().parents[1]
WASHABILITY = ROOT / "datasets" / "density_washability_synthetic.csv"
coarse, fine = read_washability(WASHABILITY)
print(f"{coarse.test}: feed ash {coarse.feed_ash_pct:.2f} %; {fine.test}: feed ash {fine.feed_ash_pct:.2f} %")

# %%
# The washability table of the coarse feed: the cumulative floats at each fraction's upper
# density and the cumulative sinks at its lower density, with the near-gravity material
# (per cent of the feed within +/- 0.1 of the fraction's upper density).
coarse.cumulative_table().drop(columns=["test", "density_from"])

# %%
# Predictions at cut densities 1.40 to 1.80 with Ep = 0.035: the organic efficiency rises
# from about 95 % at 1.40 to nearly 100 % as the cut moves away from the middlings, where the
# near-gravity material at the cut is small (fewer particles lie within one Ep of the cut).
cuts = np.round(np.arange(1.40, 1.801, 0.05), 2)
table = predict(WASHABILITY, curve="normal", rho50=cuts, ep=0.035)
shown = [
    "test",
    "rho50",
    "floats_yield_pct",
    "floats_ash_pct",
    "sinks_ash_pct",
    "theoretical_yield_pct",
    "organic_efficiency_pct",
    "near_gravity_pct",
]
table[table["test"] == coarse.test][shown]

# %%
# The same cut with a less sharp separator (Ep = 0.10) gives dirtier floats at a lower
# yield; an ideal separation at that ash would yield more: the organic efficiency drops from
# about 99.8 % to about 93 %.
pd.concat([predict(coarse, curve="normal", rho50=1.55, ep=ep) for ep in (0.035, 0.10)])[["ep", *shown[2:]]]

# %%
# The cut density that gives floats of 8 % ash, found by Brent's method, for each feed.
predict(WASHABILITY, curve="normal", target_ash_pct=8.0, ep=0.035)[
    ["test", "rho50", "floats_yield_pct", "floats_ash_pct", "organic_efficiency_pct"]
]

# %%
# The cumulative floats curve (yield against ash: the best any separation by density can
# do) with the predicted products of the cut sweep; the horizontal distance to the curve is
# what the imperfect separation loses.
fig, ax = plt.subplots(figsize=(6.4, 4.2))
for feed, colour in ((coarse, "C0"), (fine, "C1")):
    curve = feed.cumulative_table()
    # at a vanishing yield the floats have the ash of the lightest fraction
    ash = np.append(feed.ash_pct[0], curve["cumulative_floats_ash_pct"])
    ax.plot(ash, np.append(0.0, curve["cumulative_floats_mass_pct"]), "-", color=colour, label=f"{feed.test}: cumulative floats")
    rows = table[table["test"] == feed.test]
    ax.plot(rows["floats_ash_pct"], rows["floats_yield_pct"], "o", color=colour, label=f"{feed.test}: predicted, Ep 0.035")
ax.set_xlabel("floats ash (%)")
ax.set_ylabel("floats yield (% of feed)")
ax.set_xlim(0, 25)
ax.legend(fontsize=8, loc="lower right")
fig.tight_layout()
plt.show()
