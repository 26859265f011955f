"""
Identifying a sieve classifier
==============================

Akhmadiev, Gizzyatov et al. describe the passage of a particle fraction through a
multi-deck sieve classifier by a velocity law: a particle passes a cell only when its
speed relative to the sieve stays below a critical speed Vk, spread with a standard
deviation sigma. ``datasets/sieve_identify_residues_example.csv`` holds the residues of two
fractions at six relative speeds (generated from the kinetics paper's published laws,
Vk = 0.148 and 0.185 m/s, sigma = 0.051 and 0.069 m/s). Identification recovers them
(``tromplab sieve identify`` in Python: ``tromplab.classifiers.sieve`` on a table read with
the command line's checks).
"""

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from tromplab.classifiers import sieve
from tromplab.loading.tables import read_table

# the repository root (sphinx-gallery runs each example from examples/, without __file__)
ROOT = Path(globals().get("__file__", "example.py")).resolve().parents[1]
RESIDUES = ROOT / "datasets" / "sieve_identify_residues_example.csv"
table = pd.read_csv(RESIDUES, comment="#")
table.head(6)

# %%
# Identify Vk and sigma for each sieve and fraction, with 95 % intervals.
laws = sieve.identify_from_table(read_table(RESIDUES))
laws[["fraction", "n_regimes", "P_g", "v_k", "v_k_low", "v_k_high", "sigma", "sigma_low", "sigma_high", "success"]]

# %%
# The measured residues and the residue curves of the identified laws.
fig, ax = plt.subplots(figsize=(6.5, 4))
for (fraction, rows), (_, law) in zip(table.groupby("fraction", sort=False), laws.iterrows()):
    ax.plot(rows["relative_speed"], rows["residue"], "o", label=f"{fraction} mm, measured")
    speed = np.linspace(rows["relative_speed"].min(), rows["relative_speed"].max(), 200)
    passing = sieve.velocity_probability(speed, law["v_k"], law["sigma"])
    pitch, length = rows["cell_pitch"].iloc[0], rows["sieve_length"].iloc[0]
    ax.plot(speed, np.exp(-law["P_g"] * passing * length / pitch), label=f"{fraction} mm, Vk = {law['v_k']:.3f} m/s")
ax.set_xlabel("relative speed amplitude [m/s]")
ax.set_ylabel("residue on the sieve")
ax.legend(fontsize=8)
fig.tight_layout()
