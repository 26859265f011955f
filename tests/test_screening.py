"""Fisher screen (spec section 4; Shuvalov et al. 2018, Table 2)."""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy import stats

from tromplab.curves.screening import critical_f, fisher_screen

from .conftest import dataset, reference_rows


@pytest.mark.parametrize("row", reference_rows("critical_f.csv"), ids=lambda r: f"n={r.n}")
def test_critical_values_of_table_2(row):
    assert_allclose(critical_f(int(row.n)), row.F_crit, atol=row.atol)


def test_table_2_stars_are_exactly_the_cells_below_the_critical_value():
    table = dataset("shuvalov2018_table2_F.csv")
    computed = [fisher_crit_below(f, n) for f, n in zip(table.F, table.n)]
    assert computed == list(table.star_table2)


def fisher_crit_below(f_value, n):
    return bool(f_value < critical_f(int(n)))


def test_screen_statistics_follow_the_definitions():
    observed = np.array([0.95, 0.8, 0.52, 0.2, 0.05, 0.01])
    screen = fisher_screen(observed, ssr=0.004, alpha=0.1)
    s0 = (np.sum(observed**2) - observed.sum() ** 2 / 6) / 5
    assert_allclose(screen.s0_sq, s0)
    assert_allclose(screen.s_res_sq, 0.004 / 4)
    assert_allclose(screen.F, s0 / 0.001)
    assert_allclose(screen.F_crit, stats.f.ppf(0.9, 5, 4))
    assert screen.adequate


def test_a_poor_fit_is_inadequate():
    assert not fisher_screen([0.9, 0.6, 0.4, 0.1, 0.0], ssr=0.5).adequate


@pytest.mark.parametrize("n", [0, 1, 2])
def test_two_points_or_fewer_are_refused(n):
    with pytest.raises(ValueError, match="cannot be screened"):
        fisher_screen(np.linspace(1, 0, n), ssr=0.0)


def test_alpha_must_be_a_probability():
    with pytest.raises(ValueError, match="alpha"):
        critical_f(5, alpha=1.5)
