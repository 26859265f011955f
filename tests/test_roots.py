"""Brent's root search side by side (tromplab.curves.roots) against scipy.optimize.brentq one by one,
and the joint fits of formula (11) that use it (tromplab.trend.joint_fit): the same numbers to the
last bit, since each search takes brentq's steps on the same values of the function."""

import math

import numpy as np
import pytest
import scipy.optimize

from tromplab.curves.formulas import get_formula
from tromplab.curves.formulas.paper import _break_or_edge_uncached, rosin_rammler_area, shuvalov_breaks_of_shape
from tromplab.curves.measured import measured_efficiency
from tromplab.curves.roots import brent_roots
from tromplab.trend import _joint_curves, joint_fit, read_surveys

from .conftest import DATASETS


def _cubics(count: int, seed: int):
    """Coefficients of ``count`` increasing cubics with a root in [-2, 3] (some flat, some steep near it)."""
    rng = np.random.default_rng(seed)
    roots = rng.uniform(-1.5, 2.5, count)
    scales = 10.0 ** rng.uniform(-6, 3, count)
    shifts = rng.uniform(0.0, 0.5, count)  # increasing: one root, a change of sign across [-2, 3]
    return roots, scales, shifts


def test_each_root_is_the_one_brentq_finds_to_the_last_bit():
    roots, scales, shifts = _cubics(400, seed=3)

    def cubic(x, rows):
        return scales[rows] * (x - roots[rows]) ** 3 + shifts[rows] * (x - roots[rows])

    low, high = np.full(roots.size, -2.0), np.full(roots.size, 3.0)
    for xtol in (2e-12, 1e-14, 1e-4):
        found_roots, found = brent_roots(cubic, low, high, xtol=xtol)
        assert found.all()
        for i in range(roots.size):
            one = scipy.optimize.brentq(lambda x, i=i: cubic(np.array([x]), np.array([i]))[0], -2.0, 3.0, xtol=xtol)
            assert found_roots[i] == one, (i, xtol)


def test_brackets_brentq_would_refuse_are_left_to_the_caller():
    """Same sign at both ends, a zero at an end, a nan on the way or too few steps: not found (nan)."""
    targets = np.array([2.0, -1.0, 0.0, 4.0, 8.0])

    def gap(x, rows):
        values = x * x - targets[rows]
        return np.where((rows == 3) & (abs(x - 2.0) < 0.5), np.nan, values)  # the fourth turns nan inside its bracket

    roots, found = brent_roots(gap, np.zeros(5), np.full(5, 3.0))
    assert found.tolist() == [True, False, False, False, True]
    assert roots[0] == scipy.optimize.brentq(lambda x: x * x - 2.0, 0.0, 3.0) and math.isnan(roots[1])
    _, found = brent_roots(lambda x, rows: x * x - targets[rows], np.zeros(5), np.full(5, 3.0), maxiter=3)
    assert not found[0]  # brentq would raise: not converged in 3 steps


def test_the_break_points_of_one_shape_are_those_of_formula_11_one_by_one():
    """Inside [1/2, eta_5(kr)] from the side-by-side search, at and beyond its ends the edges:
    every one the number formula (11) itself uses."""
    rng = np.random.default_rng(11)
    for _ in range(300):
        kr = float(np.exp(rng.uniform(np.log(0.05), np.log(40.0))))
        eta = float(rosin_rammler_area(0.0, 1.0, kr))
        efficiencies = [*rng.uniform(0.45, min(eta + 0.05, 1.0), 8).tolist(), 0.5, eta, float("nan")]
        found = shuvalov_breaks_of_shape(kr, efficiencies)
        expected = tuple(_break_or_edge_uncached(kr, e) for e in efficiencies)
        assert found == expected, kr


@pytest.fixture(scope="module")
def series():
    return [survey.points for survey in read_surveys(DATASETS / "classifier_trend_surveys.csv")]


def test_a_joint_fit_of_formula_11_evaluates_the_curves_of_each_survey_as_before(series):
    """The joint fit's curves with the breaks found side by side: bit for bit those of the formula
    called survey by survey with each survey's measured efficiency (as joint_fit did before)."""
    formula = get_formula("shuvalov")
    groups = series[:9]
    contexts = [{"measured_efficiency": measured_efficiency(g)} for g in groups]
    curves = _joint_curves(formula, groups, contexts)
    rng = np.random.default_rng(5)
    for _ in range(50):
        values = {"d_cut": float(rng.uniform(60.0, 300.0)), "kr": float(np.exp(rng.uniform(np.log(0.3), np.log(15.0))))}
        expected = [formula(g.size, values["d_cut"], values["kr"], **c) for g, c in zip(groups, contexts)]
        for found, before in zip(curves(values), expected):
            assert np.array_equal(found, before)


def test_joint_fits_of_other_formulas_take_each_survey_as_before(series):
    formula = get_formula("plitt_bypass")
    groups = series[:3]
    values = {"d_cut": 150.0, formula.shape_name: 2.0, "bypass": 0.1}
    found = _joint_curves(formula, groups, [{}, {}, {}])(values)
    for curve, g in zip(found, groups):
        assert np.array_equal(curve, formula(g.size, 150.0, 2.0, bypass=0.1))
    fit = joint_fit(groups, formula, [])
    assert fit.success and fit.n_points == sum(g.n for g in groups)
