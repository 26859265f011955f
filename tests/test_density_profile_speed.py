"""The shortcuts of the density profiles and covariances against the arithmetic they replace:
analytic derivatives against central differences, Newton's roots against regula falsi's, the
profiles of several curves searched together against each curve alone, the covariance of every
fit at once against index_covariance fit by fit, the remembered interval rule against the rule."""

import dataclasses

import numpy as np
import pandas as pd
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from tromplab.curves.likelihood import Bracket, newton_in_bracket, regula_falsi, step_out
from tromplab.density import read_density
from tromplab.density.batch import partition_at
from tromplab.density.covariance import covariance_table, index_covariance
from tromplab.density.dispersion import PooledDispersion, _interval_rule, interval_rule
from tromplab.density.fitting import _profile_requests, fit_data, fit_density_curves
from tromplab.density.profiles import (
    MAX_ROOT_ITERATIONS,
    ROOT_RELATIVE_TOLERANCE,
    ROOT_STEP_TOLERANCE,
    _Profiles,
    _RowForms,
    _smooth_brackets,
    curve_of_indices,
    held_derivative,
    index_derivatives,
    profile_limits,
)
from tromplab.density.registry import DENSITY_CURVES, LIMIT_CURVES, PLAIN_CURVES
from tromplab.density.simulation import beta_binomial_tracer_test, simulate_tracer_test

ROWS = 8
DENSITY = np.tile(np.linspace(1.3, 1.9, 12), (ROWS, 1))


def indices_and_holds(curve, seed: int):
    """Index vectors of ``curve`` (rho50, Ep or I[, l, h]), which rows hold rho50 (0) or the second index (1)."""
    rng = np.random.default_rng(seed)
    q = np.column_stack([rng.uniform(1.4, 1.7, ROWS), rng.uniform(0.02, 0.08, ROWS), rng.uniform(0.0, 0.2, ROWS),
                         rng.uniform(0.8, 1.0, ROWS)])[:, : len(curve.parameters)]  # fmt: skip
    imperfection = np.arange(ROWS) % 2 == 0
    q[imperfection, 1] /= q[imperfection, 0] - 1.0
    return q, imperfection, (np.arange(ROWS) // 2) % 2


@pytest.mark.parametrize("curve", DENSITY_CURVES, ids=lambda c: c.id)
def test_index_derivatives_are_the_central_differences_of_the_partitions(curve):
    q, imperfection, held = indices_and_holds(curve, 3)
    forms = _RowForms([curve], np.zeros(ROWS, dtype=int))
    first, second = index_derivatives(forms, DENSITY, q, imperfection, held)
    size = q.shape[1]
    column = np.tile(np.arange(size), (ROWS, 1))  # the minimiser's column k is the index column[:, k]
    column[held == 1, 0], column[held == 1, 1] = 1, 0

    def partitions(moved):
        return partition_at(curve, DENSITY, curve_of_indices(curve, moved, imperfection))

    def unit(k, h):
        step = np.zeros((ROWS, size))
        step[np.arange(ROWS), column[:, k]] = h
        return step

    h = 1e-5  # errors of the differences about h**2 times the third derivatives: 1e-7 of these scales
    assert set(first) == set(range(1, size))
    for i in range(1, size):
        difference = (partitions(q + unit(i, h)) - partitions(q - unit(i, h))) / (2 * h)
        assert_allclose(first[i], difference, rtol=0, atol=1e-5 * max(1.0, np.abs(difference).max()))
        for j in range(i, size):
            a, b = unit(i, h), unit(j, h)
            difference = (partitions(q + a + b) - partitions(q + a - b) - partitions(q - a + b) + partitions(q - a - b)) / (
                4 * h * h
            )
            assert_allclose(second[i, j], difference, rtol=0, atol=1e-5 * max(1.0, np.abs(difference).max()))
    step = unit(0, h)
    difference = (partitions(q + step) - partitions(q - step)) / (2 * h)
    assert_allclose(held_derivative(forms, DENSITY, q, imperfection, held), difference, rtol=0,
                    atol=1e-5 * max(1.0, np.abs(difference).max()))  # fmt: skip


def excess_functions():
    """Increasing functions with a root in (0, 2): convex, concave and with an inflexion, each with its slope."""
    return {
        "convex": (lambda t: t**3 + t - 3.0, lambda t: 3 * t**2 + 1.0),
        "concave": (lambda t: np.log1p(t) - 0.8, lambda t: 1.0 / (1.0 + t)),
        "inflexion": (lambda t: np.tanh(4.0 * (t - 1.3)) + 0.2, lambda t: 4.0 / np.cosh(4.0 * (t - 1.3)) ** 2),
        "quadratic profile": (lambda t: (t + 0.5) ** 2 - 3.84, lambda t: 2.0 * (t + 0.5)),
    }


@pytest.mark.parametrize("name", list(excess_functions()))
def test_newton_in_the_bracket_finds_the_root_regula_falsi_finds(name):
    value, slope = excess_functions()[name]
    inner, outer = np.array([0.0, 0.5, 0.0]), np.array([2.0, 2.0, 3.0])
    bracket = Bracket(inner, outer, value(inner), value(outer))
    centre, direction = np.zeros(3), np.ones(3)
    width = np.full(3, 1e-13)
    calls = []

    def excess_and_slope(rows, t):
        calls.append(len(rows))
        return value(t), slope(t)

    newton = newton_in_bracket(excess_and_slope, centre, direction, bracket, width)
    falsi = regula_falsi(lambda rows, t: value(t), centre, direction, bracket, width)
    assert_allclose(newton, falsi, rtol=1e-12)
    assert_allclose(value(newton), 0.0, atol=1e-12)
    assert len(calls) <= 12


def test_newton_in_the_bracket_searches_the_lower_side_as_the_upper():
    # a profile's lower side: the value v = 2 - t falls with the distance t, the excess (2 - v)**2 - 3.84 rises
    bracket = Bracket(np.array([0.0]), np.array([2.5]), np.array([-3.84]), np.array([2.41]))

    def excess_and_slope(rows, v):
        return (2.0 - v) ** 2 - 3.84, -2.0 * (2.0 - v)

    t = newton_in_bracket(excess_and_slope, np.array([2.0]), np.array([-1.0]), bracket, np.array([1e-14]))
    assert_allclose(t, np.sqrt(3.84), rtol=1e-14)


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    """Ten simulated tracer tests, read through the CSV reader, and every curve fitted without intervals."""
    rng = np.random.default_rng(11)
    frames = []
    for number in range(10):
        rho50, ep = rng.uniform(1.45, 1.75), rng.uniform(0.02, 0.08)
        densities = np.round(np.linspace(rho50 - 3 * ep, rho50 + 3 * ep, 12), 3)
        frames.append(simulate_tracer_test("normal", {"rho50": rho50, "ep": ep}, densities, placed=30, retrieval=0.95,
                                           rng=rng, test=f"t{number}"))  # fmt: skip
    path = tmp_path_factory.mktemp("campaign") / "tracers.csv"
    pd.concat(frames, ignore_index=True).to_csv(path, index=False)
    samples = read_density(path)
    return samples, fit_density_curves(samples, DENSITY_CURVES, ci=0.95)


@pytest.mark.parametrize("curves", [PLAIN_CURVES, LIMIT_CURVES], ids=["plain", "limits"])
def test_profiles_of_several_curves_are_each_curve_alone_to_the_last_bit(campaign, curves):
    samples, fits = campaign
    chosen = [(fit, quantity, fit_data(fit.sample, fit.method)) for fit in fits if fit.curve in curves and fit.success
              for quantity in ("rho50", "ep", "imperfection")]  # fmt: skip
    number = {curve.id: i for i, curve in enumerate(curves)}
    requests = _profile_requests(chosen, 0.95)
    which = np.array([number[fit.curve.id] for fit, _, _ in chosen])
    together = profile_limits(list(curves), dataclasses.replace(requests, curve=which))
    for curve in curves:
        rows = [i for i, (fit, _, _) in enumerate(chosen) if fit.curve is curve]
        low, high, notes = profile_limits(curve, _profile_requests([chosen[i] for i in rows], 0.95))
        assert_array_equal(together[0][rows], low)
        assert_array_equal(together[1][rows], high)
        assert [together[2][i] for i in rows] == notes


def test_the_profile_slope_is_the_derivative_of_the_excess(campaign):
    _, fits = campaign
    chosen = [(fit, quantity, fit_data(fit.sample, fit.method)) for fit in fits[:12] if not fit.curve.has_limits
              for quantity in ("rho50", "ep", "imperfection")]  # fmt: skip
    requests = _profile_requests(chosen, 0.95)
    sides = np.arange(len(chosen))  # the lower sides
    value = requests.centre[sides, requests.position[sides]] - requests.step[sides]
    _, slope = _Profiles([chosen[0][0].curve], requests).excess_and_slope(sides, value)
    h = 1e-6 * requests.step[sides]
    up = _Profiles([chosen[0][0].curve], requests).excess(sides, value + h)
    down = _Profiles([chosen[0][0].curve], requests).excess(sides, value - h)
    assert_allclose(slope, (up - down) / (2 * h), rtol=1e-5)


def test_the_covariance_of_every_fit_at_once_is_index_covariance_fit_by_fit(campaign):
    _, fits = campaign
    table = covariance_table(fits, sizes=False)
    expected = []
    for fit in fits:
        covariance = index_covariance(fit)
        if covariance is not None:
            expected += [(fit.sample.test, fit.curve.id, *line) for line in covariance]
    assert len(expected) == len(table) > 0
    assert_array_equal(table[["rho50", "ep"]].to_numpy(), np.array([row[2:] for row in expected]))
    assert list(zip(table["test"], table["curve"])) == [row[:2] for row in expected]


@pytest.mark.parametrize("dispersion, df_resid, pooled", [(0.6, 5, None), (2.5, 9, None), (0.6, 5, PooledDispersion(3.0, 50, 10)),
                                                          (5.0, 5, PooledDispersion(3.0, 50, 10))])  # fmt: skip
def test_the_remembered_interval_rule_is_the_rule(dispersion, df_resid, pooled):
    for _ in range(2):  # the second time from memory
        assert interval_rule(dispersion, df_resid, 0.95, pooled) == _interval_rule(dispersion, df_resid, 0.95, pooled)
    rule = interval_rule(np.array(2.5), 9, 0.95)  # an array argument is not remembered: the rule itself
    assert rule.scale == _interval_rule(2.5, 9, 0.95, None).scale


def falsi_limits(curves, requests):
    """The limits as the profiles of the curves with limits were searched before their smooth
    brackets were closed by Newton's steps (main at e005dd4): the step out, then regula falsi in
    every bracket, each value re-optimised from the side's last optimum and from the estimate."""
    profiles = _Profiles(list(curves), requests)
    request, position = profiles.request, requests.position[profiles.request]
    centre = requests.centre[request, position]
    edge = np.where(profiles.direction > 0, requests.upper[request, position], requests.lower[request, position])
    step = requests.step[request]
    bracket = step_out(profiles.excess, centre, profiles.direction, np.abs(edge - centre), step, -requests.threshold[request])
    limits = np.full(len(request), np.nan)
    closed = np.flatnonzero(bracket.closed)
    width = 2.0 * (ROOT_STEP_TOLERANCE * step[closed] + 2.0 * ROOT_RELATIVE_TOLERANCE * np.abs(centre[closed]))
    distance = regula_falsi(lambda rows, values: profiles.excess(closed[rows], values), centre[closed],
                            profiles.direction[closed], bracket.take(closed), width, max_iterations=MAX_ROOT_ITERATIONS)  # fmt: skip
    limits[closed] = centre[closed] + profiles.direction[closed] * distance
    at_edge = np.flatnonzero(np.abs(limits - edge) <= 1e-6 * step)
    if at_edge.size:
        limits[at_edge[profiles.excess(at_edge, edge[at_edge]) <= 0]] = np.nan
    count = len(requests.best)
    return limits[:count], limits[count:]


def limits_requests(fits):
    """The profiles of rho50, Ep and I of every fit of a curve with limits, searched together."""
    chosen = [(fit, quantity, fit_data(fit.sample, fit.method)) for fit in fits if fit.curve in LIMIT_CURVES
              and fit.success for quantity in ("rho50", "ep", "imperfection")]  # fmt: skip
    number = {curve.id: i for i, curve in enumerate(LIMIT_CURVES)}
    which = np.array([number[fit.curve.id] for fit, _, _ in chosen])
    return dataclasses.replace(_profile_requests(chosen, 0.95), curve=which)


@pytest.fixture(scope="module")
def overdispersed(tmp_path_factory):
    """Six beta-binomial tracer tests (precision 4; density_folders_digest.py's overdispersed
    input), whose profiles of the curves with limits hold several local minima, every curve fitted."""
    rng = np.random.default_rng(44)
    densities = np.round(np.linspace(1.35, 1.75, 9), 3)
    frames = [beta_binomial_tracer_test("normal", {"rho50": 1.55, "ep": 0.05}, densities, precision=4.0, rng=rng,
                                        test=f"od{i}") for i in range(6)]  # fmt: skip
    path = tmp_path_factory.mktemp("overdispersed") / "tracers.csv"
    pd.concat(frames, ignore_index=True).to_csv(path, index=False)
    return fit_density_curves(read_density(path), DENSITY_CURVES)


@pytest.mark.parametrize("data", ["campaign", "overdispersed"])
def test_the_limits_curves_profiles_are_regula_falsis_limits(data, request):
    # Newton's steps in the smooth brackets, the starts made once and the estimate's start followed
    # near the root: every limit as regula falsi found it, to its tolerance (measured: 3e-13)
    found = request.getfixturevalue(data)
    requests = limits_requests(found[1] if data == "campaign" else found)
    low, high, _ = profile_limits(list(LIMIT_CURVES), requests)
    old_low, old_high = falsi_limits(LIMIT_CURVES, requests)
    assert np.isfinite(np.concatenate([low, high])).mean() > 0.6
    assert_allclose(low, old_low, rtol=1e-11, equal_nan=True)
    assert_allclose(high, old_high, rtol=1e-11, equal_nan=True)


def test_a_profile_that_is_not_smooth_in_its_bracket_keeps_regula_falsis_limit_bit_for_bit(overdispersed):
    requests = limits_requests(overdispersed)
    profiles = _Profiles(list(LIMIT_CURVES), requests)
    request, position = profiles.request, requests.position[profiles.request]
    centre = requests.centre[request, position]
    edge = np.where(profiles.direction > 0, requests.upper[request, position], requests.lower[request, position])
    bracket = step_out(profiles.stepping_excess, centre, profiles.direction, np.abs(edge - centre),
                       requests.step[request], -requests.threshold[request])  # fmt: skip
    closed = np.flatnonzero(bracket.closed)
    rough = closed[~_smooth_brackets(profiles, bracket, closed)]
    assert rough.size  # the local minima of these profiles make some brackets rough
    low, high, _ = profile_limits(list(LIMIT_CURVES), requests)
    old = np.concatenate(falsi_limits(LIMIT_CURVES, requests))
    assert_array_equal(np.concatenate([low, high])[rough], old[rough])


def test_a_bracket_is_smooth_where_the_profile_rises_through_it_evenly():
    # rows: an even rise; a chord far steeper than both ends (a jump to another local minimum);
    # falling at the outer end; flat at the outer end
    class Slopes:
        direction = np.array([1.0, 1.0, -1.0, 1.0])
        inner_slope = np.array([2.0, 2.0, -2.0, 2.0])  # in the value: the lower side's profile falls with it
        outer_slope = np.array([3.0, 3.0, 1.0, 0.0])

    bracket = Bracket(np.zeros(4), np.ones(4), np.full(4, -1.0), np.array([1.5, 40.0, 1.5, 1.5]))
    assert _smooth_brackets(Slopes(), bracket, np.arange(4)).tolist() == [True, False, False, False]
