"""Coverage of the transformed 95 % intervals (issue 10): d_cut (log), Ep (log), eta (logit)
and epsilon (logit of eps / (x_max - 1)) cover the true value of seeded synthetic curves
90-99 % of the time.  The full study is benchmarks/coverage.py (numbers in
docs/uncertainty.md); this is a smaller seeded run of the same code."""

import numpy as np
import pytest

from tromplab._coverage import CASES, COVERED, coverage_run, coverage_table, true_values


@pytest.mark.slow
def test_transformed_intervals_cover_the_truth_90_to_99_percent_of_the_time():
    runs = {case.label: coverage_run(case, 50, seed=100 + i) for i, case in enumerate(CASES)}
    table = coverage_table(runs)
    assert (table["replicates"] >= 48).all()  # fits and intervals are made on nearly every replicate
    for quantity in COVERED:
        rows = table[table["quantity"] == quantity]
        pooled = np.average(rows["coverage"], weights=rows["replicates"])  # 200 replicates: binomial sd 1.5 %
        assert 0.90 <= pooled <= 0.99, (quantity, pooled)
        assert (rows["coverage"] >= 0.84).all(), rows  # no formula far below the nominal level
        # misses fall on both sides: a transform or gradient bias would push them to one
        assert rows["missed_low"].sum() > 0 and rows["missed_high"].sum() > 0, rows


def test_true_values_are_the_generating_curve_indices():
    truth = true_values(CASES[0])
    assert truth["d_cut"] == CASES[0].d_cut
    assert 0 < truth["eta"] < 1 and truth["ep"] > 0
    x_max = CASES[0].sizes.max() / CASES[0].d_cut
    assert 0 < truth["epsilon"] < x_max - 1
