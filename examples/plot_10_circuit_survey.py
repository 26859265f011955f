"""
A whole circuit survey: balance, diagnosis, worth, design, partition curves
===========================================================================

The bundled **synthetic** survey (``datasets/circuit_example_*.csv``: a two-deck screen whose
undersize feeds a ball mill closed with a hydrocyclone, generated from known curves) taken
through what a plant metallurgist does with a survey: reconcile it, find the bad measurement,
say what each measurement is worth, plan the next survey, and read every separator's
partition curve with its uncertainty.  This is ``tromplab circuit`` and ``tromplab circuit
design`` in Python (docs/circuit.md documents every table).
"""

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

import tromplab.circuit as circuit
from tromplab.circuit.design import observability_table
from tromplab.circuit.outputs import next_steps
from tromplab.circuit.planning import design_advice

# the repository root (sphinx-gallery runs each example from examples/, without __file__)
ROOT = Path(globals().get("__file__", "example.py")).resolve().parents[1]
FLOWSHEET = ROOT / "datasets" / "circuit_example_flowsheet.csv"
SURVEY = ROOT / "datasets" / "circuit_example_survey.csv"

sheet = circuit.read_flowsheet(FLOWSHEET)
survey = pd.read_csv(SURVEY, comment="#")
balance = circuit.reconcile(sheet, survey)
print(balance.report())

# %%
# The flowsheet with its reconciled solids flows (t/h, +/- one sd); the cyclone underflow
# returns to the mill and is drawn back below the nodes.
ax = balance.plot("flowsheet")

# %%
# Diagnosis
# ---------
# Say the plant also had three flowmeters, one of them reading 230 t/h on the cyclone
# overflow where the balances say about 155.  The global test rejects; serial elimination
# with compensation names the measurement and says whether the survey then passes.  It is a
# proposal: nothing is changed until the survey is reconciled again without it.
metered = survey.copy()
meters = {"cyclone_overflow": (230.0, 10.0), "oversize": (100.0, 10.0), "middlings": (160.0, 16.0)}
for stream, (flow, sd) in meters.items():
    metered.loc[metered.index[metered["stream"] == stream][0], ["solids_flow", "solids_flow_sd"]] = [flow, sd]
suspect = circuit.reconcile(sheet, metered)
print(suspect.elimination_table()[["step", "stream", "kind", "estimated_error", "chi_square", "dof", "p_value"]])
print("\n".join(next_steps(suspect)))

# %%
# Acting on the proposal: the survey without the overflow's flowmeter passes the global test.
cleaned = circuit.reconcile(sheet, metered, exclude="cyclone_overflow:flow")
print(f"chi-square {cleaned.chi_square:.3g} on {cleaned.dof} dof, p = {cleaned.p_value:.3g}")

# %%
# What each measurement is worth
# ------------------------------
# The share of the circulating load's variance that each measurement carries: the samples to
# take with the most care.  A just-determined measurement is not checked by any balance.
worth = balance.worth_table()
load = worth[worth["result"] == "circulating load cyclone"].sort_values("variance_share", ascending=False)
print(load[["measurement", "solvability", "redundancy", "shift_per_sd", "variance_share"]].head(6).to_string(index=False))
print(observability_table(balance)[["stream", "quantity", "observable", "reconciled", "reconciled_sd"]])

# %%
# Survey design advice
# --------------------
# Which measurement to add next time, predicted from the linearised covariance at the
# reconciled values: the sd of each separator's partition at its cut and of the circulating
# load, before and with the candidate.
advice = design_advice(sheet, survey)
print(advice.report(top=4))

# %%
# The same advice for a plant not yet surveyed: from the flowsheet alone, at a survey
# simulated under stated assumptions (every stream analysed, the screen feed weighed).
planned = design_advice(sheet, flows="screen_feed")
print(planned.report(top=3))

fig, ax = plt.subplots(figsize=(7, 3.5))
best = advice.table.drop_duplicates(["stream", "measurement"]).head(8)
labels = [f"{m} of {s}" for s, m in zip(best["stream"], best["measurement"])]
ax.barh(labels[::-1], 100 * best["reduction"].to_numpy()[::-1], color="C0")
ax.set_xlabel("predicted reduction of the sd of its result (%)")
ax.set_title("Measurements to add, best first")
fig.tight_layout()

# %%
# Partition curves per separator
# ------------------------------
# The reconciled partition to the fine product in each class, +/- 2 sd, for each separator
# (and, where the survey holds per-class assays, for each component: the table then has a
# ``component`` column, drawn as one curve per component).
partition = balance.partition_table()
partition = partition[partition["used"].astype(bool)]
if "component" not in partition.columns:
    partition = partition.assign(component="solids")
fig, axes = plt.subplots(1, partition["experiment"].nunique(), figsize=(11, 3.5), sharey=True)
for ax, (node, rows) in zip(np.atleast_1d(axes), partition.groupby("experiment", sort=False)):
    for k, (component, part) in enumerate(rows.groupby("component", sort=False)):
        ax.errorbar(part["size"], part["partition_fine"], yerr=2 * part["partition_sd"], fmt="o-", ms=3,
                    color=f"C{k}", label=component, capsize=2)  # fmt: skip
    ax.set_xscale("log")
    ax.set_title(node)
    ax.set_xlabel(f"size ({balance.survey.size_unit})")
np.atleast_1d(axes)[0].set_ylabel("partition to the fine product")
np.atleast_1d(axes)[0].legend(fontsize=8)
fig.tight_layout()
