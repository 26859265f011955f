"""
A hydrocyclone with bypass and water recovery: d50 against d50c
===============================================================

In a hydrocyclone a share of every size short-circuits to the underflow with the water
(the bypass, Kelsall 1953), so the actual partition curve never reaches 1 at the fine
end and its cut, d50, lies below the corrected cut d50c of the classified part. This
example takes the feed of the bundled hydrocyclone sieve sheet
(``tests/data/hydrocyclone_size_class_um.csv``: classes written as ``+1168``,
``-1168+589``, ..., ``-74`` um, streams named overflow and underflow) and gives it a
cyclone with a 25 % water recovery to the underflow: Plitt's curve with bypass,
d50c = 250 um, ks = 2.5. The products follow from the mass balance. tromplab fits the
nine formulas and the curves with bypass, and compares the fitted bypass with the
measured water recovery (``water_recovery=``).
"""

from pathlib import Path

import matplotlib.pyplot as plt
import pandas as pd

import tromplab

# the repository root (sphinx-gallery runs each example from examples/, without __file__)
ROOT = Path(globals().get("__file__", "example.py")).resolve().parents[1]
SHEET = ROOT / "tests" / "data" / "hydrocyclone_size_class_um.csv"
sheet = pd.read_csv(SHEET, comment="#")
sheet[["size_class_um", "feed_pct"]]

# %%
# The cyclone: partition to the overflow of each class from Plitt's curve with bypass at
# the class's geometric-mean size (the pan at 37 um), then the two products' analyses.
WATER_RECOVERY = 0.25
curve = tromplab.get_formula("plitt_bypass")
sizes_um = [1650.0, 830.0, 417.0, 208.0, 105.0, 37.0]
to_overflow = curve(sizes_um, 250.0, 2.5, bypass=WATER_RECOVERY)
feed = sheet["feed_pct"] / 100.0
overflow_yield = float((feed * to_overflow).sum())
lab = pd.DataFrame(
    {
        "experiment": "cyclone",
        "size_class_um": sheet["size_class_um"],
        "feed_pct": sheet["feed_pct"],
        "overflow_pct": (100.0 * feed * to_overflow / overflow_yield).round(4),
        "underflow_pct": (100.0 * feed * (1.0 - to_overflow) / (1.0 - overflow_yield)).round(4),
        "overflow_yield": round(overflow_yield, 6),
    }
)
lab

# %%
# Read the sheet with the measured water recovery, then fit the nine formulas and the
# curves with bypass (``--extended`` on the command line).
experiments, balances = tromplab.read_experiments(lab, water_recovery=WATER_RECOVERY)
formulas = ["plitt", "rosin_rammler", "lognormal", "plitt_bypass", "lognormal_bypass"]
bench = tromplab.fit_experiments(experiments, formulas=formulas, size_unit="um", water_recovery=WATER_RECOVERY)
fits = bench.fits_table()
fits[["formula", "d50", "d50c", "ep", "ep_c", "bypass", "F", "adequate", "water_recovery_check"]]

# %%
# The curves without bypass put their cut (d50 = d_cut) where the actual partition
# crosses 1/2; the curves with bypass report both: d50c (their d_cut) near the 250 um of
# the classified part, and the lower actual d50. Their fitted bypass agrees with the
# water recovery, as the last column says.
with_bypass = fits[fits["formula"].isin(["plitt_bypass", "lognormal_bypass"])]
with_bypass[["formula", "d50", "d50c", "bypass"]]

# %%
# The points and the fitted curves: the curves with bypass level off at 1 - bypass.
ax = bench.plot("cyclone")
ax.axhline(1.0 - WATER_RECOVERY, color="0.5", linestyle=":", linewidth=1)
ax.set_title("Hydrocyclone: actual partition to the overflow")
plt.gcf().tight_layout()
