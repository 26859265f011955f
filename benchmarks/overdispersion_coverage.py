"""Coverage of the 95 % intervals of rho50 and Ep on overdispersed (beta-binomial) tracer counts, rule by rule.

Each cell (number of densities x beta precision) simulates ``--tests`` tracer tests of a separator
with the normal partition curve (rho50 1.55, Ep 0.04; 30 tracers at each density, densities evenly
from rho50 - 3 Ep to rho50 + 3 Ep), whose tracers of one density share a fate: the sink
probability of each density is drawn from a beta distribution with mean P(density) and the given
precision (``inf``: binomial counts).  The tests are written ``--tests-per-file`` to a CSV file of
whole counts, read back through ``tromplab.density.read_density`` as a lab file is, and the tests
of a file are fitted together with the normal curve and its profile intervals
(``tromplab.density.simulation.overdispersion_coverage_study``), by the rule of two sessions ago
(the quasi-binomial scale only where the Pearson test rejects at 5 %, with the chi-square(1)
threshold), by the Pearson test with the F(1, n - p) threshold, by a test's own max(1, Pearson
chi2/df) with F(1, n - p) (``at_least_one``, the rule before this one) and by the policy in use
(``tromplab.density.dispersion.SCALE_POLICY``, ``file_floor``: the wider of the test's own
interval and the one on the file's pooled dispersion).  The table is printed (as Markdown, for
docs/density_columns.md) and written to benchmarks/output/density_overdispersion_coverage.csv.
The test suite runs the acceptance cell
(``test_overdispersed_tracer_intervals_cover_at_the_acceptance_setting``).

    python benchmarks/overdispersion_coverage.py --tests 1000 --seed 1 --precision 10 inf
    python benchmarks/overdispersion_coverage.py --tests 150 --seed 0 1 2 3 4 --precision 10 \
        --rules at_least_one file_floor
"""

import argparse
import itertools
import math
import time
from pathlib import Path

import pandas as pd

from tromplab.density.simulation import INTERVAL_RULES, overdispersion_coverage_study

OUTPUT = Path(__file__).resolve().parent / "output"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tests", type=int, default=1000, help="simulated tests per cell")
    parser.add_argument("--seed", type=int, nargs="+", default=[1], help="one cell per seed")
    parser.add_argument("--tests-per-file", type=int, default=10, help="tests written to one file and fitted together")
    parser.add_argument("--rules", nargs="+", default=list(INTERVAL_RULES), choices=INTERVAL_RULES)
    parser.add_argument("--densities", type=int, nargs="+", default=[7, 13])
    parser.add_argument("--precision", type=float, nargs="+", default=[4.0, 10.0, 30.0, 100.0, math.inf])
    args = parser.parse_args(argv)
    start = time.perf_counter()
    cells = []
    for densities, precision, seed in itertools.product(args.densities, args.precision, args.seed):
        cell = overdispersion_coverage_study(densities=densities, precision=precision, tests=args.tests, seed=seed,
                                             tests_per_file=args.tests_per_file, rules=args.rules)  # fmt: skip
        cells.append(cell.assign(seed=seed))
        print(f"{densities} densities, precision {precision:g}, seed {seed}: {time.perf_counter() - start:.0f} s", flush=True)
        OUTPUT.mkdir(exist_ok=True)  # each cell as it is done: a long run interrupted keeps the cells it made
        pd.concat(cells, ignore_index=True).to_csv(OUTPUT / "density_overdispersion_coverage.csv", index=False)
    table = pd.concat(cells, ignore_index=True)
    print(markdown(table))
    return table


def markdown(table: pd.DataFrame) -> str:
    """The table as docs/density_columns.md shows it: coverage (per cent) and median width per rule."""
    lines = [
        "| densities | precision | seed | rule | scaled | rho50 coverage | Ep coverage | rho50 median width | Ep median width |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for row in table.itertuples():
        precision = "binomial" if math.isinf(row.precision) else f"{row.precision:g}"
        lines.append(
            f"| {row.densities} | {precision} | {row.seed} | {row.rule} | {row.scaled} | {100 * row.rho50_coverage:.1f} % "
            f"| {100 * row.ep_coverage:.1f} % | {row.rho50_median_width:.4f} | {row.ep_median_width:.4f} |"
        )
    return "\n".join(lines)


if __name__ == "__main__":
    main()
