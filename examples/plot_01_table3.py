"""
Table 2 -> Table 3 of Shuvalov et al. (2018)
============================================

Shuvalov, Novoseltseva & Zhukov (2018) screened nine separation-curve formulas with
Fisher's F in ten industrial classifier experiments (their Table 2) and ranked them
(their Table 3): within each experiment the largest F ranks first, and the points of a
formula are the sum of its ranks, the rank of an inadequate fit counted twice.
:func:`tromplab.rank_formulas` recomputes Table 3 from the published F values
(``datasets/shuvalov2018_table2_F.csv``) and the comparison with the printed table
(``datasets/shuvalov2018_table3_ranks.csv``) shows where the paper's arithmetic slipped
(the details are in the errata page).
"""

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

import tromplab

# the repository root (sphinx-gallery runs each example from examples/, without __file__)
ROOT = Path(globals().get("__file__", "example.py")).resolve().parents[1]
DATASETS = ROOT / "datasets"

table2 = pd.read_csv(DATASETS / "shuvalov2018_table2_F.csv", comment="#")
table2.head(9)

# %%
# Rank the formulas within each experiment by F, with the adequacy marks as Table 3 prints them.
table3 = tromplab.rank_formulas(table2[["experiment", "equation", "F", "adequate"]], by="F")
table3

# %%
# The printed Table 3 beside the recomputed one: the points and places that differ.
printed = pd.read_csv(DATASETS / "shuvalov2018_table3_ranks.csv", comment="#")
both = table3[["equation", "points", "place"]].merge(
    printed[["equation", "points", "place"]], on="equation", suffixes=("", "_printed")
)
both["differs"] = (both["points"] != both["points_printed"]) | (both["place"] != both["place_printed"])
both

# %%
# The ranks as a heat map: Plitt's (7) and the log-normal (9) lead, Molerus' (3) trails.
ranks = table3.set_index("equation").drop(columns=["points", "place"])
fig, ax = plt.subplots(figsize=(7, 4))
image = ax.imshow(ranks.to_numpy(dtype=float), cmap="viridis_r", aspect="auto")
ax.set_xticks(np.arange(ranks.shape[1]), labels=ranks.columns)
ax.set_yticks(np.arange(ranks.shape[0]), labels=[f"({eq}) {tromplab.get_formula(int(eq)).id}" for eq in ranks.index])
ax.set_xlabel("experiment of Table 1")
fig.colorbar(image, ax=ax, label="rank (1 = largest F)")
ax.set_title("Ranks recomputed from Table 2")
fig.tight_layout()
