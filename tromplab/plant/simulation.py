"""Do the plant's intervals cover the truth?  Tracer tests simulated from known curves, fitted, propagated.

Each simulation draws a tracer test of every device from its true curve (30 tracers per density
over rho50 +/- 3 Ep in steps of Ep/2, each recovered with probability 0.9: a test as a plant runs
it), writes the tests as a CSV file, reads and fits them as ``tromplab density fit`` does
(binomial maximum likelihood, the normal curve), takes each size fraction's curve with its
covariance (:func:`tromplab.plant.inputs.devices_from_fits`) and predicts the plant with its
intervals (:func:`tromplab.plant.predict`).  The share of simulations whose interval holds the
value the true curves give is the coverage (``benchmarks/plant_coverage.py``; a small version in
``tests/test_plant.py``).
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from ..density.results import fit_density
from ..density.simulation import simulate_tracer_test
from .inputs import Device, SizeFraction
from .prediction import predict

#: The quantities whose coverage is measured, for each size fraction and the plant.
COVERED = ("clean_yield_pct", "clean_ash_pct", "organic_efficiency_pct")


def tracer_tests(devices: list[Device], rng: np.random.Generator, *, placed: int = 30, retrieval: float = 0.9) -> pd.DataFrame:
    """One simulated tracer test per device from its curve, the test named after the size fraction."""
    tests = []
    for device in devices:
        ep = float(device.ep_at(device.rho50))
        densities = np.round(device.rho50 + ep * np.arange(-6, 7) / 2.0, 4)
        params = {"rho50": device.rho50, "ep": ep}
        tests.append(simulate_tracer_test(device.curve, params, densities, placed=placed, retrieval=retrieval, rng=rng,
                                          test=device.size_fraction))  # fmt: skip
    return pd.concat(tests, ignore_index=True)


def coverage_runs(
    fractions: list[SizeFraction],
    truth: list[Device],
    *,
    simulations: int,
    ci: float = 0.95,
    draws: int = 1000,
    seed: int = 1,
    progress=None,
) -> pd.DataFrame:
    """One row per simulation, size fraction (and ``total``) and quantity: the truth, the estimate and the interval.

    Columns ``simulation, size_fraction, quantity, truth, estimate, low, high, covered``.
    """
    exact = predict(fractions, curves_from=[_exact(device) for device in truth], draws=0).products.set_index("size_fraction")
    rng = np.random.default_rng(seed)
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "tracers.csv"
        for run in range(simulations):
            tracer_tests(truth, rng).to_csv(path, index=False)
            fits = fit_density(path, curves="normal")
            products = predict(fractions, curves_from=fits, ci=ci, draws=draws, seed=int(rng.integers(2**31))).products
            for row in products.itertuples(index=False):
                for quantity in COVERED:
                    true, low, high = (
                        exact.loc[row.size_fraction, quantity],
                        getattr(row, f"{quantity}_low"),
                        getattr(row, f"{quantity}_high"),
                    )
                    rows.append({"simulation": run, "size_fraction": row.size_fraction, "quantity": quantity, "truth": true,
                                 "estimate": getattr(row, quantity), "low": low, "high": high,
                                 "covered": bool(low <= true <= high)})  # fmt: skip
            if progress is not None:
                progress(run + 1, simulations, "simulations")
    return pd.DataFrame(rows)


def coverage_table(runs: pd.DataFrame) -> pd.DataFrame:
    """Coverage per size fraction and quantity, with its binomial standard error and the mean interval width."""
    grouped = runs.assign(width=runs["high"] - runs["low"]).groupby(["size_fraction", "quantity"], sort=False)
    table = grouped.agg(coverage=("covered", "mean"), simulations=("covered", "size"), mean_width=("width", "mean"))
    table["coverage_se"] = np.sqrt(table["coverage"] * (1 - table["coverage"]) / table["simulations"])
    return table.reset_index()


def _exact(device: Device) -> Device:
    from dataclasses import replace

    return replace(device, covariance=np.zeros((2, 2)))
