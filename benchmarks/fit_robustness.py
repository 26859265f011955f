"""Benchmark: tromplab's fit (data-driven start + profiled grid + lmfit) against a bare
lmfit fit from a fixed, generic start, on the same synthetic experiments in one run.

For each of the nine formulas and each seeded synthetic experiment (curves of every
formula at several slopes, 8-12 points, noise 0.01-0.03) both fits are run; reported per
formula: how often the bare fit ends more than 1e-5 (relative) above tromplab's sum of
squares or fails, how often it ends more than 1e-5 below it (differences smaller than that
are solver tolerance: formula (11) is only piecewise smooth in kr), and the median time of
each.

Usage: ``python benchmarks/fit_robustness.py [--experiments 30]`` (not part of the test suite).
"""

import argparse
import time

import lmfit
import numpy as np
import pandas as pd

from tromplab._synthetic import synthetic as shared_synthetic
from tromplab.curves.curve_fit import fit_formula
from tromplab.curves.formulas import FORMULAS

TOLERANCE = 1e-5


def synthetic(seed):
    """The shared unweighted synthetic curve of ``tromplab._synthetic`` for this seed."""
    return shared_synthetic(seed, weighted=False)


def bare_lmfit(points, formula, context):
    params = lmfit.Parameters()
    params.add("d_cut", value=float(np.median(points.size)), min=points.size.min() / 100, max=points.size.max() * 100)
    low, high = formula.shape_bounds
    params.add("shape", value=float(np.clip(1.0, low, high)), min=low, max=high)

    def residual(p):
        return formula(points.size, p["d_cut"].value, p["shape"].value, **context) - points.partition_fine

    try:
        result = lmfit.minimize(residual, params, method="least_squares")
        return float(np.sum(result.residual**2)) if result.success else np.inf
    except ValueError:
        return np.inf


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--experiments", type=int, default=30)
    args = parser.parse_args(argv)
    rows = []
    for seed in range(args.experiments):
        points = synthetic(seed)
        for formula in FORMULAS:
            start = time.perf_counter()
            ours = fit_formula(points, formula)
            ours_time = time.perf_counter() - start
            start = time.perf_counter()
            bare = bare_lmfit(points, formula, ours.context)
            bare_time = time.perf_counter() - start
            worse = not np.isfinite(bare) or bare > ours.fit.ssr * (1 + TOLERANCE) + 1e-15
            better = np.isfinite(bare) and bare < ours.fit.ssr * (1 - TOLERANCE) - 1e-15
            rows.append(
                {"formula": formula.id, "bare_worse": worse, "bare_better": better, "tromplab_s": ours_time, "bare_s": bare_time}
            )
    table = (
        pd.DataFrame(rows)
        .groupby("formula", sort=False)
        .agg(
            bare_missed_optimum=("bare_worse", "mean"),
            bare_beat_tromplab=("bare_better", "mean"),
            tromplab_ms=("tromplab_s", lambda t: 1000 * np.median(t)),
            bare_ms=("bare_s", lambda t: 1000 * np.median(t)),
        )
    )
    print(f"{args.experiments} synthetic experiments x {len(FORMULAS)} formulas")
    print(table.to_string(float_format=lambda v: f"{v:.3g}"))
    total = pd.DataFrame(rows)
    print(
        f"\nbare lmfit missed the optimum in {100 * total['bare_worse'].mean():.1f} % of fits, beat tromplab in "
        f"{100 * total['bare_better'].mean():.1f} %; median time {1000 * total['tromplab_s'].median():.1f} ms (tromplab) vs "
        f"{1000 * total['bare_s'].median():.1f} ms (bare)"
    )


if __name__ == "__main__":
    main()
