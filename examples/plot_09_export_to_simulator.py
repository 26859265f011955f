"""
Export to a simulator
=====================

Flowsheet simulators describe classifiers with their own curves and parameter names:
Whiten's curve in JKSimMet, Plitt's 1976 hydrocyclone model, the Screen unit of Dyssol.
``tromplab export`` (here in Python, ``tromplab.output.export``) writes a fit in each
convention's names, units, direction and cut; fits a convention cannot express are
listed, not approximated. The bundled double-deck screen (sizes in mm) is fitted with the
paper's nine formulas and the curves of other tools, then exported to Dyssol (sizes in
metres, partition to the coarse product).
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import tromplab
from tromplab.output.export import export_fits

# the repository root (sphinx-gallery runs each example from examples/, without __file__)
ROOT = Path(globals().get("__file__", "example.py")).resolve().parents[1]
LAB = ROOT / "datasets" / "double_deck_screen_decks_lab.csv"
experiments, _ = tromplab.read_experiments(LAB, estimate_yield=True)
bench = tromplab.fit_experiments(experiments, formulas=["paper", "other"], size_unit="mm")

# %%
# Save the batch as ``tromplab fit`` would (``fits.csv``), then export it to Dyssol.
outdir = Path(tempfile.mkdtemp()) / "results"
bench.save(outdir)
dyssol = export_fits(outdir, "dyssol", size_unit="mm")
dyssol.table

# %%
# What Dyssol cannot express, and why.
dyssol.skipped[:6]

# %%
# Plitt's 1976 convention (d50c with Plitt's rounded ln 2 = 0.693, m, Rf in percent).
export_fits(outdir, "plitt", size_unit="mm").table

# %%
# Check: Dyssol's "Plitt" model with the exported Xcut and Alpha, written to the coarse
# product as 1 - exp(-0.693 (d/Xcut)^Alpha), is tromplab's Rosin-Rammler fit.
row = dyssol.table.query("experiment == 'deck_20mesh' and formula == 'rosin_rammler'").iloc[0]
fit = next(f for f in bench.fits_of("deck_20mesh") if f.formula.id == "rosin_rammler")
size_mm = np.geomspace(0.05, 5.0, 200)
dyssol_coarse = 1.0 - np.exp(-0.693 * (size_mm * 1e-3 / row["Xcut"]) ** row["Alpha"])
fig, ax = plt.subplots(figsize=(6.5, 4))
ax.plot(size_mm, 1.0 - fit.formula(size_mm, fit.d_cut, fit.shape), lw=4, alpha=0.4, label="tromplab rosin_rammler (to coarse)")
ax.plot(size_mm, dyssol_coarse, "--", label="Dyssol Plitt with the exported parameters")
ax.set_xscale("log")
ax.set_xlabel("size [mm]")
ax.set_ylabel("partition to the coarse product")
ax.legend(fontsize=8)
fig.tight_layout()
print("largest difference:", float(np.max(np.abs(dyssol_coarse - (1.0 - fit.formula(size_mm, fit.d_cut, fit.shape))))))
