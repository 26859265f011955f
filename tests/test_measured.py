"""The measured quantities on arrays equal those of one point set at a time (tromplab.curves.measured)."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from tromplab.curves.formulas import get_formula
from tromplab.curves.measured import (
    formula_context,
    formula_contexts,
    measured_cut_size,
    measured_efficiencies,
    measured_efficiency,
    measured_slope,
    measured_starts,
)
from tromplab.loading.points import TrompPoints


def _point_sets(seed: int, sets: int = 40):
    """Noisy partitions of one size grid: some rows cross 1/2 several times, some never, some
    have fewer than two points between 0.1 and 0.9 (the rules' other branches)."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(3, 16))
    size = np.sort(rng.choice(np.arange(1, 500), n, replace=False)).astype(float)
    cut = rng.uniform(size[0] / 2, size[-1] * 2)
    base = 1.0 / (1.0 + (size / cut) ** rng.uniform(1.0, 8.0))
    return size, np.clip(base + rng.normal(0.0, rng.choice([0.005, 0.2]), (sets, n)), -0.05, 1.05)


@pytest.mark.parametrize("seed", range(25))
def test_cut_and_slope_on_arrays_equal_one_set_at_a_time(seed):
    size, partitions = _point_sets(seed)
    cuts, slopes = measured_starts(size, partitions)
    for row, partition in enumerate(partitions):
        points = TrompPoints("x", size, partition, resampled=True)
        cut = measured_cut_size(points)
        assert cuts[row] == cut  # the same arithmetic, element by element
        assert_allclose(slopes[row], measured_slope(points, cut), rtol=1e-12, atol=1e-15)  # closed form vs polyfit


@pytest.mark.parametrize("seed", range(25))
def test_measured_efficiency_on_arrays_equals_one_set_at_a_time(seed):
    size, partitions = _point_sets(seed)
    found = measured_efficiencies(size, partitions)
    contexts = formula_contexts(get_formula("shuvalov"), size, partitions)["measured_efficiency"]
    assert_allclose(contexts, found, rtol=0, atol=0)
    for row, partition in enumerate(partitions):
        points = TrompPoints("x", size, partition, resampled=True)
        assert_allclose(found[row], measured_efficiency(points), rtol=1e-14, atol=1e-16)
        assert_allclose(found[row], formula_context(get_formula("shuvalov"), points)["measured_efficiency"], rtol=1e-14)
    assert formula_contexts(get_formula("plitt"), size, partitions) == {}
