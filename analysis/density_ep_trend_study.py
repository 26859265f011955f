"""Coverage of the Ep-by-size trend's intervals over simulated tracer tests, end to end.

Each simulated test is the bundled dense-medium cyclone design (four tracer sizes 2-4, 4-8,
8-16 and 16-32 mm; densities 1.40 to 1.70 in steps of 0.02; 30 tracers per density and size,
each recovered with probability 0.9; Tromp's normal curve with Ep = 0.05 d^-0.35 and
rho50 = 1.52 + 0.04 d^-0.5), written as the CSV a lab would write and read back through
``tromplab.density.readers.read_density``. Every size fraction is fitted with the normal
curve by binomial maximum likelihood with 95 % profile intervals, and the trend
Ep = a d^-b by ``tromplab.density.by_size``. Reported: how often the 95 % intervals of a and
b, and of each fraction's Ep, cover the truth, the mean of b, and how many trends were
weighted by all four fractions.

Usage: ``python analysis/density_ep_trend_study.py [--tests 300] [--seed 1] [--outdir results/analysis]``
(about 1 s a test on one core).
"""

import argparse
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from tromplab.density.by_size import by_size_table
from tromplab.density.fitting import fit_density_curve
from tromplab.density.readers import read_density
from tromplab.density.simulation import simulate_tracer_test

SIZES_MM = ((2.0, 4.0), (4.0, 8.0), (8.0, 16.0), (16.0, 32.0))
DENSITIES = np.round(np.arange(1.40, 1.7001, 0.02), 2)
TRUE_A, TRUE_B = 0.05, 0.35


def one_test(rng, folder: Path) -> dict:
    parts = []
    for lower, upper in SIZES_MM:
        size = np.sqrt(lower * upper)
        params = {"rho50": 1.52 + 0.04 * size**-0.5, "ep": TRUE_A * size**-TRUE_B}
        table = simulate_tracer_test("normal", params, DENSITIES, placed=30, retrieval=0.9, rng=rng, test="dmc")
        parts.append(table.assign(size_lower_mm=lower, size_upper_mm=upper))
    path = folder / "tracers.csv"
    pd.concat(parts, ignore_index=True).to_csv(path, index=False)
    fits = [fit_density_curve(sample, "normal", ci=0.95) for sample in read_density(path)]
    by_size, trends = by_size_table(fits, ci=0.95)
    trend = trends.iloc[0]
    ep_true = TRUE_A * by_size["size"] ** -TRUE_B
    has_ep_interval = by_size["ep_low"].notna() & by_size["ep_high"].notna()
    ep_covered = (by_size["ep_low"] <= ep_true) & (ep_true <= by_size["ep_high"])
    return {
        "b": trend.b,
        "b_covered": trend.b_low <= TRUE_B <= trend.b_high,
        "a_covered": trend.a_low <= TRUE_A <= trend.a_high,
        "n_sizes": trend.n_sizes,
        "ep_intervals": int(has_ep_interval.sum()),
        "ep_covered": int((ep_covered & has_ep_interval).sum()),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tests", type=int, default=300)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--outdir", type=Path, default=Path("results/analysis"))
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    with tempfile.TemporaryDirectory() as folder:
        rows = [one_test(rng, Path(folder)) for _ in range(args.tests)]
    table = pd.DataFrame(rows)
    full = table[table.n_sizes == 4]
    summary = pd.DataFrame(
        [
            {
                "tests": len(table),
                "trends_of_four_fractions": len(full),
                "b_coverage": full.b_covered.mean(),
                "a_coverage": full.a_covered.mean(),
                "b_mean": full.b.mean(),
                "b_sd": full.b.std(),
                "fraction_ep_intervals": int(table.ep_intervals.sum()),
                "fraction_ep_coverage": table.ep_covered.sum() / table.ep_intervals.sum(),
            }
        ]
    )
    args.outdir.mkdir(parents=True, exist_ok=True)
    path = args.outdir / "density_ep_trend_study.csv"
    summary.to_csv(path, index=False)
    print(summary.to_string(index=False))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
