"""Benchmark: ``--bootstrap 1000`` for the nine formulas of one experiment (target <= 5 s).

Times ``uncertainty.bootstrap`` (all resamples refitted in one batched call) for each of the
nine fits of one seeded synthetic experiment, and prints the time per formula and in total.
Usage: ``python benchmarks/bootstrap.py [--resamples 1000] [--seed 3]`` (not part of the tests).
"""

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fit_robustness import synthetic  # noqa: E402

from tromplab.statistics.uncertainty import bootstrap  # noqa: E402
from tromplab.workbench import fit_experiments  # noqa: E402


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resamples", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=3)
    args = parser.parse_args(argv)
    bench = fit_experiments([synthetic(args.seed)])
    total = 0.0
    for fit in bench.fits:
        start = time.perf_counter()
        boot = bootstrap(fit, n=args.resamples, seed=0)
        seconds = time.perf_counter() - start
        total += seconds
        print(f"{fit.formula.id:18s} {seconds:6.2f} s  ({boot.n_failed} of {args.resamples} resamples failed)")
    print(f"total {total:.2f} s for {args.resamples} resamples x {len(bench.fits)} formulas")


if __name__ == "__main__":
    main()
