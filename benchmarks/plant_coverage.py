"""Coverage of the plant's intervals: tracer tests simulated from known curves, fitted, propagated.

The bundled three-circuit plant (``datasets/plant_washability_synthetic.csv``, the devices of
``datasets/plant_devices_synthetic.csv`` with the spiral's Ep at its cut) is the truth. Each simulation
draws a tracer test of each device (30 tracers per density over rho50 +/- 3 Ep in steps of Ep/2, 90 %
recovered), writes it as CSV, fits it as ``tromplab density fit`` does and predicts the plant with
``--draws`` parametric-bootstrap draws (``tromplab.plant.simulation``). Printed, for each seed and pooled
over the seeds: the share of simulations whose 95 % interval holds the value the true curves give, per size
fraction and quantity, with its binomial standard error; and, for the plant's clean yield and ash, the
chance that a 200-simulation estimate of an interval whose coverage is the pooled one falls below 93 %.

Usage: ``python benchmarks/plant_coverage.py [--simulations 200] [--draws 1000] [--seeds 1 2 3 4 5]``
(about two minutes per seed on a quiet core; the suite runs 40 simulations,
``tests/test_plant.py::test_intervals_cover_the_true_plant_yield_and_ash``).
"""

import argparse
import time
from pathlib import Path

import pandas as pd
from scipy.stats import binom

from tromplab.plant import read_plant, read_plant_washability
from tromplab.plant.simulation import coverage_runs, coverage_table

DATASETS = Path(__file__).resolve().parent.parent / "datasets"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--simulations", type=int, default=200)
    parser.add_argument("--draws", type=int, default=1000)
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    args = parser.parse_args(argv)
    fractions = read_plant_washability(DATASETS / "plant_washability_synthetic.csv")
    truth = read_plant(DATASETS / "plant_devices_synthetic.csv", fractions)
    tables, runs = [], []
    for seed in args.seeds:
        start = time.perf_counter()
        seed_runs = coverage_runs(fractions, truth, simulations=args.simulations, draws=args.draws, seed=seed)
        runs.append(seed_runs.assign(seed=seed))
        tables.append(coverage_table(seed_runs).assign(seed=seed))
        print(f"seed {seed}: {args.simulations} simulations, {args.draws} draws each, {time.perf_counter() - start:.0f} s")
    wide = pd.concat(tables).pivot_table(index=["size_fraction", "quantity"], columns="seed", values="coverage", sort=False)
    pooled = coverage_table(pd.concat(runs)).set_index(["size_fraction", "quantity"])
    wide["pooled"], wide["pooled_se"], wide["mean_width"] = pooled["coverage"], pooled["coverage_se"], pooled["mean_width"]
    with pd.option_context("display.width", 200):
        print(wide.to_string(float_format=lambda v: f"{v:.4f}"))
    for quantity in ("clean_yield_pct", "clean_ash_pct"):
        coverage = pooled.loc[("total", quantity), "coverage"]
        below = binom.cdf(int(0.93 * args.simulations) - 1, args.simulations, coverage)
        print(
            f"total {quantity}: pooled coverage {coverage:.4f}; P(a {args.simulations}-simulation estimate < 93 %) = {below:.3f}"
        )
    return wide


if __name__ == "__main__":
    main()
