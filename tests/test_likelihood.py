"""The profile-likelihood search every curve shares (tromplab.curves.likelihood): the bracket, the
root, the Hessian and the on-bound check, against scipy and closed forms."""

import math

import numpy as np
import pytest
import scipy.optimize
from numpy.testing import assert_allclose

from tromplab.curves.likelihood import (
    MAX_DOUBLINGS,
    Bracket,
    central_hessian,
    newton_in_bracket,
    on_bound,
    regula_falsi,
    step_out,
)

#: Monotone excesses with a known root in [0.1, 5] (the shape of a profile's rise less its threshold).
EXCESSES = [
    (lambda x: x**2 - 2.0, math.sqrt(2.0)),
    (lambda x: np.expm1(x) - 3.0, math.log(4.0)),
    (lambda x: np.sqrt(x) - 1.5, 2.25),
    (lambda x: np.tanh(x - 1.0) + 0.5, 1.0 - math.atanh(0.5)),
]


def test_every_row_finds_its_root_as_brentq_does():
    functions = [f for f, _ in EXCESSES]
    centre, direction = np.full(4, 0.1), np.ones(4)

    def excess(rows, values):
        return np.array([functions[r](v) for r, v in zip(rows, values)])

    bracket = Bracket(np.zeros(4), np.full(4, 4.9), excess(np.arange(4), centre), excess(np.arange(4), centre + 4.9))
    distance = regula_falsi(excess, centre, direction, bracket, np.full(4, 1e-14))
    assert_allclose(centre + distance, [root for _, root in EXCESSES], rtol=1e-12)
    assert_allclose(centre + distance, [scipy.optimize.brentq(f, 0.1, 5.0, xtol=1e-14) for f in functions], rtol=1e-12)


def test_a_root_below_the_estimate_is_searched_downwards():
    # 1 - x^2 from the estimate 1.5 downwards: -1.25 there, 0.75 at 1.5 - 2, the root at 1
    bracket = Bracket(np.array([0.0]), np.array([2.0]), np.array([-1.25]), np.array([0.75]))
    distance = regula_falsi(lambda rows, x: 1.0 - x**2, np.array([1.5]), np.array([-1.0]), bracket, np.array([1e-14]))
    assert 1.5 - distance[0] == pytest.approx(1.0, abs=1e-13)


def test_an_excess_within_its_tolerance_ends_the_search_early():
    calls = []

    def excess(rows, values):
        calls.append(len(rows))
        return values - 1.0

    bracket = Bracket(np.array([0.0]), np.array([3.0]), np.array([-1.0]), np.array([2.0]))
    loose = regula_falsi(excess, [0.0], [1.0], bracket, [1e-15], excess_tolerance=0.2)
    assert abs(loose[0] - 1.0) <= 0.2 and len(calls) < 3
    tight = regula_falsi(excess, [0.0], [1.0], bracket, [1e-15])
    assert tight[0] == pytest.approx(1.0, abs=1e-14)


def test_an_unclosed_row_gives_its_better_end_and_an_open_bracket_none():
    bracket = Bracket(np.array([0.0, 0.0]), np.array([3.0, np.nan]), np.array([-1.0, -1.0]), np.array([2.0, np.nan]))
    distance = regula_falsi(lambda rows, x: x - 1.0, [0.0, 0.0], [1.0, 1.0], bracket, [0.0, 0.0], max_iterations=1)
    assert distance[0] == 1.0 and np.isnan(distance[1])  # the secant through (0, -1) and (3, 2) hits the root


def test_the_step_out_doubles_until_the_excess_is_positive():
    tried = []

    def excess(rows, values):
        tried.extend(values)
        return values - 2.5  # root 2.5 above a centre 1: steps 0.25, 0.5, 1, 2 reach 1.25, 1.5, 2, 3

    bracket = step_out(excess, [1.0], [1.0], [10.0], [0.25], [-1.5])
    assert tried == [1.25, 1.5, 2.0, 3.0]
    assert (bracket.inner[0], bracket.outer[0]) == (1.0, 2.0)  # distances from the centre
    assert (bracket.inner_excess[0], bracket.outer_excess[0]) == (-0.5, 0.5)
    assert bracket.closed.tolist() == [True]


def test_each_side_steps_its_own_way_and_stops_at_the_end_of_its_range():
    tried = []

    def excess(rows, values):
        tried.extend(zip(rows.tolist(), values.tolist()))
        return -np.ones_like(values)

    bracket = step_out(excess, [1.0, 1.0], [1.0, -1.0], [0.25, 0.1], [0.2, 0.01], [-1.0, -1.0])
    assert [value for row, value in tried if row == 0] == [1.2, 1.25]  # the step 0.4 is cut to the range's 0.25
    assert [value for row, value in tried if row == 1] == [0.99, 0.98, 0.96, 0.92, 0.9]
    assert bracket.closed.tolist() == [False, False] and bracket.inner.tolist() == [0.25, 0.1]


def test_a_nan_excess_ends_a_side_without_a_bracket():
    bracket = step_out(lambda rows, x: np.where(x > 2.0, np.nan, -1.0), [1.0], [1.0], [100.0], [0.5], [-1.0])
    assert not bracket.closed[0] and bracket.inner[0] == 1.0


def test_a_side_is_given_up_after_its_doublings():
    calls = []

    def excess(rows, values):
        calls.append(1)
        return -np.ones_like(values)

    bracket = step_out(excess, [0.0], [1.0], [np.inf], [1.0], [-1.0])
    assert not bracket.closed[0] and len(calls) == MAX_DOUBLINGS


def test_the_hessian_of_a_quadratic_form_is_its_matrix():
    matrix = np.array([[4.0, 1.0, 0.5], [1.0, 3.0, -0.2], [0.5, -0.2, 2.0]])
    hessian = central_hessian(lambda v: 0.5 * v @ matrix @ v + v.sum(), np.array([0.3, -1.0, 2.0]), np.full(3, 1e-3))
    assert_allclose(hessian, matrix, rtol=1e-9)


def test_on_bound_is_relative_absolute_at_zero_or_absolute_when_asked():
    assert on_bound(1e-9, 0.0) and not on_bound(1e-6, 0.0)
    assert on_bound(1e6 * (1 + 1e-6), 1e6) and not on_bound(7.3e-10, 7.07e-12)
    assert on_bound(0.5 + 9e-7, 0.5, atol=1e-6) and not on_bound(0.5 + 2e-6, 0.5, atol=1e-6)


def test_size_and_density_curves_search_their_profiles_with_it():
    # the one implementation: neither the size curves' batched search nor the density profiles define their own
    from tromplab.curves import batched
    from tromplab.density import fitting, profiles

    assert batched.step_out is step_out and batched.regula_falsi is regula_falsi
    assert profiles.step_out is step_out and profiles.newton_in_bracket is newton_in_bracket
    assert fitting.step_out is step_out and fitting.central_hessian is central_hessian
    for module in (batched, profiles, fitting):
        assert not any(name in vars(module) for name in ("_chandrupatla", "_step_out", "_regula_falsi", "_bracket", "_hessian"))
