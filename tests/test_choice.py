"""Multi-criteria choice engine and the sieve worked example."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from tromplab.classifiers.choice import Constraint, Criterion, Problem, Variable, choose, sieve_speed_problem


def toy():
    """Maximise x and 1 - x^2 on [0, 1] with x <= 0.9: the compromise has equal normalised criteria."""
    return Problem(
        variables=(Variable("x", 0.0, 1.0),),
        criteria=(Criterion("f", lambda x: x), Criterion("g", lambda x: 1 - x**2)),
        constraints=(Constraint("cap", lambda x: 0.9 - x),),
    )


def test_toy_problem_against_its_analytic_solution():
    result = choose(toy())
    assert_allclose(result.best_first.point["x"], 0.9, atol=1e-6)
    assert_allclose(result.best_second.point["x"], 0.0, atol=1e-6)
    assert_allclose(result.ranges["f"], (0.0, 0.9), atol=1e-6)
    assert_allclose(result.ranges["g"], (0.19, 1.0), atol=1e-6)
    # normalised f = x / 0.9 equals normalised g = (1 - x^2 - 0.19) / 0.81
    x = np.roots([1 / 0.81, 1 / 0.9, -1])[1]
    assert_allclose(result.compromise.point["x"], x, atol=1e-5)
    assert result.pareto["x"].is_monotonic_increasing


def test_constrained_single_criterion_optima():
    result = choose(toy(), floor_second=0.64, share_of_first=0.5)
    assert_allclose(result.best_first.point["x"], 0.6, atol=1e-6)  # g >= 0.64 caps x at 0.6
    assert_allclose(result.best_second.point["x"], 0.3, atol=1e-6)  # f >= 0.5 * 0.6


@pytest.mark.slow
def test_sieve_example_reproduces_the_corrected_compromise_check():
    result = choose(sieve_speed_problem(), floor_second=80.0, share_of_first=0.8)
    best = result.best_first.point
    assert_allclose(best["V"], 0.0805, atol=2e-4)
    assert_allclose(best["E"], 89.64, atol=0.01)
    gamma_next = np.exp(-0.127 * 1.6 / best["V"])
    assert_allclose(gamma_next, 0.08, atol=1e-5)  # at the purity limit
    assert result.best_second.point["Q"] == pytest.approx(0.8 * best["Q"], rel=1e-4)
    compromise = result.compromise.point
    assert best["V"] > compromise["V"] > result.best_second.point["V"]
