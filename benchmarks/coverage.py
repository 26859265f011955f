"""Coverage study: how often the reported 95 % intervals cover the true value.

Seeded replicates of a known curve (cut 80, 10 sizes from 20 to 320, noise 0.02; see
``tromplab._synthetic.interval_coverage``) are fitted with the same formula, and the share of
replicates whose interval (as written to ``fits.csv`` by ``--ci``) contains the true d_cut,
shape, slope, eta, epsilon, d25, d75 and Ep is printed per formula. A nominal 95 % interval
should cover 90-99 % of the time.

Usage: ``python benchmarks/coverage.py [--replicates 400] [--profile-replicates 150]
[--formula lognormal --shape 0.3] [--clip]`` (``--clip``: partitions clipped to [0, 1] as
measured ones are; with a sharp ``--shape`` several sizes then sit exactly at 0 or 1)
(minutes; the suite runs a smaller version, ``test_reported_intervals_cover_the_truth`` and
``test_clipped_partitions_lower_the_coverage``, with tolerances from the binomial sd).
"""

import argparse
import time

import pandas as pd

from tromplab._synthetic import COVERAGE_TRUTH, interval_coverage


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--replicates", type=int, default=400)
    parser.add_argument("--profile-replicates", type=int, default=150, help="replicates with profile-likelihood parameters")
    parser.add_argument("--level", type=float, default=0.95)
    parser.add_argument("--formula", choices=sorted(COVERAGE_TRUTH), default=None, help="one formula only (default: all three)")
    parser.add_argument("--shape", type=float, default=None, help="true shape instead of the default one (needs --formula)")
    parser.add_argument("--clip", action="store_true", help="clip the noisy partitions to [0, 1]")
    args = parser.parse_args(argv)
    if args.shape is not None and args.formula is None:
        parser.error("--shape needs --formula")
    start = time.perf_counter()
    formulas = [args.formula] if args.formula else list(COVERAGE_TRUTH)
    tables = [
        interval_coverage(formula, args.replicates, level=args.level, shape=args.shape, clip=args.clip) for formula in formulas
    ]
    if args.profile_replicates:
        tables.append(interval_coverage("plitt", args.profile_replicates, level=args.level, profile=True))
    table = pd.concat(tables, ignore_index=True)
    with pd.option_context("display.width", 160):
        print(table.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    outside = table[(table["coverage"] < 0.90) | (table["coverage"] > 0.99)]
    print(f"\n{len(table)} coverages at level {args.level}; outside 90-99 %: {len(outside)}")
    print(f"{time.perf_counter() - start:.0f} s")
    return table


if __name__ == "__main__":
    main()
