"""Coverage study of the 95 % intervals of d_cut, Ep, eta and epsilon (issue 10).

Seeded synthetic experiments with a known curve (Plitt, Rosin-Rammler, log-normal and
Lynch; 8-12 sizes from d_cut/4 to 4 d_cut; Gaussian noise 0.02), each fitted with the
formula that generated it; the intervals are those ``tromplab fit --ci 0.95`` reports
(``tromplab.uncertainty.interval_table``) and the true values come from the generating
parameters (``tromplab._coverage``).  Prints coverage per case and quantity and the
shares of intervals lying wholly below / above the truth, then the pooled coverage.
Usage: ``python benchmarks/coverage.py [--replicates 500] [--seed 0] [--profile]
[--level 0.95]`` (``--profile``: parameter intervals by profile likelihood, as ``fit
--ci`` makes them; slower).  Not part of the tests; tests/test_coverage.py runs a
smaller seeded version.
"""

import argparse
import time

import pandas as pd

from tromplab._coverage import CASES, coverage_run, coverage_table


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--replicates", type=int, default=500)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--level", type=float, default=0.95)
    parser.add_argument("--profile", action="store_true", help="profile-likelihood intervals for the parameters")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    runs = {
        case.label: coverage_run(case, args.replicates, seed=args.seed + i, level=args.level, profile=args.profile)
        for i, case in enumerate(CASES)
    }
    table = coverage_table(runs)
    pd.set_option("display.width", 200)
    print(table.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    pooled = pd.concat(runs.values()).groupby("quantity", sort=False)["covered"].agg(["mean", "count"])
    print("\npooled coverage: " + ", ".join(f"{q} {row['mean']:.3f} (n={int(row['count'])})" for q, row in pooled.iterrows()))
    print(f"{args.replicates} replicates per case, seed {args.seed}, level {args.level:g}, {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
