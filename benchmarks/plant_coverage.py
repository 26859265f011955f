"""Coverage of the plant's intervals: tracer tests simulated from known curves, fitted, propagated.

The bundled three-circuit plant (``datasets/plant_washability_synthetic.csv``, the devices of
``datasets/plant_devices_synthetic.csv`` with the spiral's Ep at its cut) is the truth. Each simulation
draws a tracer test of each device (30 tracers per density over rho50 +/- 3 Ep in steps of Ep/2, 90 %
recovered), writes it as CSV, fits it as ``tromplab density fit`` does and predicts the plant with
``--draws`` parametric-bootstrap draws (``tromplab.plant.simulation``). Printed: the share of
simulations whose 95 % interval holds the value the true curves give, per size fraction and quantity.

Usage: ``python benchmarks/plant_coverage.py [--simulations 200] [--draws 1000] [--seed 1]`` (minutes;
the suite runs 40 simulations, ``tests/test_plant.py::test_intervals_cover_the_true_plant_yield_and_ash``).
"""

import argparse
import time
from pathlib import Path

import pandas as pd

from tromplab.plant import read_plant, read_plant_washability
from tromplab.plant.simulation import coverage_runs, coverage_table

DATASETS = Path(__file__).resolve().parent.parent / "datasets"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--simulations", type=int, default=200)
    parser.add_argument("--draws", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args(argv)
    start = time.perf_counter()
    fractions = read_plant_washability(DATASETS / "plant_washability_synthetic.csv")
    truth = read_plant(DATASETS / "plant_devices_synthetic.csv", fractions)
    runs = coverage_runs(fractions, truth, simulations=args.simulations, draws=args.draws, seed=args.seed)
    table = coverage_table(runs)
    with pd.option_context("display.width", 160):
        print(table.to_string(index=False, float_format=lambda v: f"{v:.4f}"))
    print(f"\n{args.simulations} simulations, {args.draws} draws each, seed {args.seed}: {time.perf_counter() - start:.0f} s")
    return table


if __name__ == "__main__":
    main()
