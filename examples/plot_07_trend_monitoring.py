"""
Monitoring a classifier over time
=================================

Twenty-four weekly surveys of one classifier (``datasets/classifier_trend_surveys.csv``,
generated with known changes: the bypass rises by 0.08 from survey S13, the cut drifts up
4 % a survey from S19). Each survey is fitted with Plitt's curve with bypass; the first
eight surveys set the baseline; an EWMA chart follows the cut, Ep, eta and the bypass,
and a joint-fit equality test compares each survey with the baseline. This is
``tromplab trend`` in Python (``tromplab.trend``, as docs/lab_tables.md and docs/trend.md document).
"""

from pathlib import Path

import matplotlib.pyplot as plt

from tromplab import trend

# the repository root (sphinx-gallery runs each example from examples/, without __file__)
ROOT = Path(globals().get("__file__", "example.py")).resolve().parents[1]
SURVEYS = ROOT / "datasets" / "classifier_trend_surveys.csv"
surveys = trend.read_surveys(SURVEYS)
result = trend.monitor_surveys(surveys, formula="plitt_bypass")
print(result.report())

# %%
# The flagged surveys: the bypass step is caught at S14, the cut drift at S19-S22.
print(result.change_points())
table = result.table
table[table["changed"] & (table["quantity"] == "bypass")][["survey", "date", "value", "ewma", "ewma_high", "p_baseline"]]

# %%
# Control charts of the cut and the bypass: each survey's estimate with its 95 % interval,
# the EWMA and its limits from the baseline, changed surveys in red.
fig, axes = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
for ax, quantity, label in zip(axes, ["d_cut", "bypass"], ["d_cut (d50c) [um]", "bypass"]):
    rows = table[table["quantity"] == quantity]
    ax.errorbar(
        rows["date"], rows["value"], yerr=[rows["value"] - rows["low"], rows["high"] - rows["value"]], fmt="o", ms=3, color="0.3"
    )
    ax.plot(rows["date"], rows["ewma"], color="C0", label="EWMA")
    ax.fill_between(rows["date"], rows["ewma_low"], rows["ewma_high"], color="C0", alpha=0.15, label="EWMA limits")
    changed = rows[rows["changed"]]
    ax.scatter(changed["date"], changed["value"], color="C3", zorder=3, label="changed")
    ax.set_ylabel(label)
axes[0].legend(fontsize=8, loc="upper left")
fig.autofmt_xdate()
fig.tight_layout()
