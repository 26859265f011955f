"""
Many experiments: workers and Dask
==================================

``tromplab.fit_experiments`` fits each formula to many experiments at once with the
batched engine, in fixed chunks of experiments, so the results are the same whatever runs
the chunks: the calling process, worker processes (``jobs=``) or a Dask cluster
(``client=``). The 24 surveys of ``datasets/classifier_trend_surveys.csv`` (Tromp points
of one classifier, sizes in um) serve as 24 experiments here.
"""

import time
from pathlib import Path

import matplotlib.pyplot as plt
import pandas as pd

import tromplab

# the repository root (sphinx-gallery runs each example from examples/, without __file__)
ROOT = Path(globals().get("__file__", "example.py")).resolve().parents[1]
SURVEYS = ROOT / "datasets" / "classifier_trend_surveys.csv"
frame = pd.read_csv(SURVEYS, comment="#")
points = frame.rename(columns={"survey": "experiment"})[["experiment", "size", "partition_fine"]]
experiments = tromplab.read_points(points, size_unit="um")
print(len(experiments), "experiments of", len(experiments[0].size), "points")

# %%
# In this process, then with ``jobs=2``: the same table, byte for byte. (The experiments
# travel in chunks of 64, so these 24 make one chunk; the speed-up of more workers shows
# from a few hundred experiments on, as the performance page measures.)
start = time.perf_counter()
serial = tromplab.fit_experiments(experiments, jobs=1)
print(f"1 process: {time.perf_counter() - start:.2f} s")
start = time.perf_counter()
pooled = tromplab.fit_experiments(experiments, jobs=2)
print(f"jobs=2: {time.perf_counter() - start:.2f} s")
pd.testing.assert_frame_equal(serial.fits_table(), pooled.fits_table())
print("identical fits table")

# %%
# The same on Dask (here an in-process cluster of threads, which starts in a moment; give
# ``Client("tcp://scheduler:8786")`` to use a real cluster). Skipped when Dask is not installed.
try:
    from dask.distributed import Client
except ImportError:
    Client = None
if Client is not None:
    with Client(processes=False, n_workers=1, threads_per_worker=2, dashboard_address=None) as client:
        on_dask = tromplab.fit_experiments(experiments, client=client)
    pd.testing.assert_frame_equal(serial.fits_table(), on_dask.fits_table())
    print("Dask: identical fits table")

# %%
# The ranking over the 24 experiments and the formula that won most often.
ranking = serial.ranking_table()
ranking

# %%
top = serial.fits_table().query("rank == 1")
wins = top["formula"].value_counts()
fig, (left, right) = plt.subplots(1, 2, figsize=(10, 3.8))
wins.plot.barh(ax=left)
left.set_xlabel("experiments where the formula ranked first")
right.hist(top["d_cut"], bins=10)
right.set_xlabel("d_cut of the top-ranked fit [um]")
right.set_ylabel("experiments")
fig.tight_layout()
