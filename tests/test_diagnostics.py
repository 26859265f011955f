"""Residual diagnostics: the batched tests give the values of the one-by-one tests."""

import numpy as np
import pytest
from statsmodels.sandbox.stats.runs import runstest_1samp

from tromplab._synthetic import synthetic
from tromplab.curves.diagnostics import batch_residual_diagnostics, residual_diagnostics
from tromplab.workbench import fit_chunk


def _residual_vectors():
    rng = np.random.default_rng(11)
    vectors = [rng.normal(0, 0.02, n) for n in rng.integers(3, 14, 200)]
    vectors += [np.sort(rng.normal(0, 0.02, 10)), np.abs(rng.normal(0, 0.02, 8)), -np.abs(rng.normal(0, 0.02, 5))]
    vectors += [np.array([0.01, 0.0, -0.02, 0.0, 0.03]), np.array([0.01, -0.01]), np.array([]), np.zeros(6)]
    vectors += [np.array([1e-15, -2e-16, 3e-16, 5e-16, -1e-16]), np.full(7, 0.01), rng.normal(0, 0.02, 60)]
    vectors += [np.tile([0.01, 0.01, -0.01, -0.01], 15)]  # 60 points: statsmodels' uncorrected branch
    return vectors


@pytest.mark.parametrize("alpha", [0.05, 0.01])
def test_batched_diagnostics_equal_the_single_ones(alpha):
    vectors = _residual_vectors()
    batched = batch_residual_diagnostics(vectors, alpha=alpha)
    single = [residual_diagnostics(vector, alpha=alpha) for vector in vectors]
    assert len(batched) == len(single)
    for one, other in zip(batched, single):
        assert (one.n_runs, one.alpha, one.exact, one.verdict) == (other.n_runs, other.alpha, other.exact, other.verdict)
        np.testing.assert_array_equal([one.runs_p, one.normality_p], [other.runs_p, other.normality_p])  # bit for bit
    assert sum(np.isfinite(d.runs_p) for d in batched) > 150 and sum(d.exact for d in batched) == 2


def test_batched_runs_test_is_statsmodels_runs_test():
    vectors = [v for v in _residual_vectors() if np.count_nonzero(v > 0) and np.count_nonzero(v < 0) and v.size >= 3]
    found = batch_residual_diagnostics(vectors)
    assert sum(d.exact for d in found) == 1
    for vector, diagnostics in zip(vectors, found):
        if diagnostics.exact:  # residuals at rounding level are not tested
            continue
        signs = np.sign(vector[vector != 0])
        assert diagnostics.runs_p == runstest_1samp(signs, cutoff=0, correction=True)[1]


def test_a_chunk_caches_the_diagnostics_the_lazy_property_would_compute():
    fits = fit_chunk([synthetic(seed) for seed in range(6)], formulas=("plitt", "shuvalov"), alpha=0.05, delta_max=None)
    for fit in fits:
        assert "diagnostics" in fit.__dict__
        assert fit.diagnostics == residual_diagnostics(fit.fit.residual, alpha=fit.options.alpha)


def test_residuals_at_rounding_level_do_not_change_the_runs_test():
    # a partition of 1e-274 against a curve of 1e-300: the sign is rounding, and it moved the
    # runs test's p-value from 1.0 to 0.91 when the sizes were given in another unit
    base = [0.1, -0.1, 0.2, 0.0, 0.0, -0.1, 0.1, -0.05]
    variants = [base, [0.1, -0.1, 0.2, 1e-274, -1e-300, -0.1, 0.1, -0.05], [0.1, -0.1, 0.2, -1e-9, 3e-8, -0.1, 0.1, -0.05]]
    found = [residual_diagnostics(v) for v in variants]
    assert len({(d.runs_p, d.n_runs) for d in found}) == 1
    assert [(d.runs_p, d.n_runs) for d in batch_residual_diagnostics(variants)] == [(d.runs_p, d.n_runs) for d in found]
    assert residual_diagnostics([0.1, -0.1, 0.2, 2e-7, -0.1]).n_runs == 4  # above the floor: counted
