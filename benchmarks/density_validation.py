"""Validation of the density fits on simulated tracer tests: bias and 95 % interval coverage of rho50 and Ep.

Each cell of the design (density step x retrieval) simulates ``--tests`` tracer tests of a
separator with a known normal partition curve (rho50 1.55, Ep 0.04 by default; 30 tracers per
density, densities from rho50 - max(3 Ep, 2 step) to rho50 + max(3 Ep, 2 step); each tracer
recovered with the retrieval probability), reads each as a lab table through
``tromplab.density.read_density`` and fits the true curve twice: binomial maximum likelihood
on the counts and least squares on the shares (what a spreadsheet does), each with its
profile-likelihood intervals (``tromplab.density.simulation.tracer_study``).  Then, per step,
as many tests (retrieval 0.9) are fitted with the curve and its variant with limits, and the
rejection rate of the chi-bar-squared test of the limits at nominal 5 % is measured
(``limits_test_size``).  Last, float-sink analyses of the same kind of separator (rho50 1.55,
Ep 0.05, 14 fractions) with weighing errors on each analysis are fitted by weighted least
squares (``float_sink_study``), and overdispersed tracer tests are ranked by AIC and by QAIC
(``overdispersed_ranking_study``).  The tables are printed and written to
benchmarks/output/density_validation.csv, density_limits_test_size.csv and
density_float_sink_study.csv; docs/density_columns.md
records it.  The test suite runs a small version
(``test_tracer_study_small_binomial_coverage_near_nominal``).

    python benchmarks/density_validation.py --tests 1000
"""

import argparse
import time
from pathlib import Path

import pandas as pd

from tromplab.density.simulation import float_sink_study, limits_test_size, overdispersed_ranking_study, tracer_study

OUTPUT = Path(__file__).resolve().parent / "output"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tests", type=int, default=1000, help="simulated tests per step and retrieval")
    parser.add_argument("--rho50", type=float, default=1.55)
    parser.add_argument("--ep", type=float, default=0.04)
    parser.add_argument("--curve", default="normal")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--float-sink-only", action="store_true", help="run only the float-sink study")
    parser.add_argument("--ranking-only", action="store_true", help="run only the study of ranking overdispersed tests")
    parser.add_argument("--sharing", type=float, nargs="+", default=[4.0, 10.0], help="beta pseudo-tracers of the ranking study")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    if args.ranking_only:
        return _ranking(args, start)
    if args.float_sink_only:
        return _float_sink(args, start)
    table = tracer_study(rho50=args.rho50, ep=args.ep, curve=args.curve, tests=args.tests, seed=args.seed,
                         steps=(0.01, 0.02, 0.05), retrievals=(0.7, 0.85, 1.0))  # fmt: skip
    OUTPUT.mkdir(exist_ok=True)
    table.to_csv(OUTPUT / "density_validation.csv", index=False)
    with pd.option_context("display.width", 200, "display.max_columns", 20):
        print(table.to_string(index=False, float_format=lambda v: f"{v:.4f}"))
    sizes = pd.DataFrame(
        [{"step": step, **limits_test_size(rho50=args.rho50, ep=args.ep, curve=args.curve, step=step, tests=args.tests, seed=args.seed)}
         for step in (0.01, 0.02, 0.05)]
    )  # fmt: skip
    sizes.to_csv(OUTPUT / "density_limits_test_size.csv", index=False)
    print("\nThe test of the limits when the truth has none (nominal 5 %):")
    print(sizes.to_string(index=False, float_format=lambda v: f"{v:.4f}"))
    float_sink = _float_sink(args, start)
    return table, sizes, float_sink, _ranking(args, start)


def _ranking(args, start):
    OUTPUT.mkdir(exist_ok=True)
    ranking = pd.DataFrame(
        [{"sharing": sharing, **overdispersed_ranking_study(tests=args.tests, sharing=sharing, seed=args.seed)}
         for sharing in args.sharing]
    )  # fmt: skip
    name = "density_overdispersed_ranking" + ("_" + "_".join(f"{s:g}" for s in args.sharing) if args.ranking_only else "")
    ranking.to_csv(OUTPUT / f"{name}.csv", index=False)
    print("\nOverdispersed tracer tests of the normal curve: how often the curve with limits ranks first:")
    print(ranking.to_string(index=False, float_format=lambda v: f"{v:.4f}"))
    print(f"\n{time.perf_counter() - start:.0f} s")
    return ranking


def _float_sink(args, start):
    OUTPUT.mkdir(exist_ok=True)
    float_sink = pd.DataFrame(
        [{"relative_error": r, "absolute_error_pct": e, "method": method or "joint_least_squares",
          **float_sink_study(tests=args.tests, seed=args.seed, relative_error=r, absolute_error=e, method=method)}
         for method in (None, "least_squares") for r, e in ((0.01, 0.02), (0.03, 0.05))]
    )  # fmt: skip
    float_sink.to_csv(OUTPUT / "density_float_sink_study.csv", index=False)
    print("\nFloat-sink analyses with weighing errors, joint fit and least squares on the partitions (nominal 95 %):")
    print(float_sink.to_string(index=False, float_format=lambda v: f"{v:.4f}"))
    print(f"\nwrote {OUTPUT}/density_*.csv; {time.perf_counter() - start:.0f} s")
    return float_sink


if __name__ == "__main__":
    main()
