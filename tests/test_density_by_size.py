"""Density partition by size fraction and the trend of Ep with size (tromplab.density.by_size)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from tromplab.density.by_size import (
    BY_SIZE_COLUMNS,
    EP_TREND_COLUMNS,
    by_size_outputs,
    by_size_table,
    common_curve,
    fit_ep_trend,
    representative_sizes,
)
from tromplab.density.fitting import fit_density_curve
from tromplab.density.readers import read_density

from .conftest import DATASETS

TRACERS = DATASETS / "density_tracers_dmc_by_size_synthetic.csv"
# the truth of that file (analysis/make_density_tracer_example.py): Ep = 0.05 d^-0.35, rho50 = 1.52 + 0.04 d^-0.5
TRUE_A, TRUE_B = 0.05, 0.35


def _independent_wls(size, ep, sd, ci):
    """Weighted least squares of ln Ep on ln d by numpy alone: estimates and t intervals."""
    x = np.column_stack([np.ones_like(size), np.log(size)])
    w = 1.0 / sd**2
    xtw = x.T * w
    beta = np.linalg.solve(xtw @ x, xtw @ np.log(ep))
    residual = np.log(ep) - x @ beta
    scale = np.sum(w * residual**2) / (len(ep) - 2)
    se = np.sqrt(np.diag(np.linalg.inv(xtw @ x)) * scale)
    t = stats.t.ppf(0.5 + ci / 2, len(ep) - 2)
    return beta, beta - t * se, beta + t * se


def test_the_trend_is_the_weighted_least_squares_line_of_an_independent_computation():
    rng = np.random.default_rng(7)
    size = np.array([0.75, 1.5, 3.0, 6.0, 12.0, 24.0])
    sd = np.array([0.25, 0.2, 0.15, 0.12, 0.1, 0.1])  # the sd of ln Ep the intervals state
    ep = 0.06 * size**-0.4 * np.exp(rng.normal(0, sd))
    z = stats.norm.ppf(0.975)
    trend = fit_ep_trend(size, ep, ep * np.exp(-z * sd), ep * np.exp(z * sd), ci=0.95)
    beta, low, high = _independent_wls(size, ep, sd, 0.95)
    np.testing.assert_allclose([np.log(trend.a), -trend.b], beta, rtol=0, atol=1e-10)
    np.testing.assert_allclose(np.log(trend.a_interval), [low[0], high[0]], rtol=0, atol=1e-10)
    np.testing.assert_allclose(trend.b_interval, [-high[1], -low[1]], rtol=0, atol=1e-10)
    assert trend.weighted and trend.n_sizes == 6 and trend.note == ""
    np.testing.assert_allclose(trend.ep_at(size), trend.a * size ** (-trend.b), rtol=1e-14)


@pytest.mark.slow
def test_the_trend_interval_of_b_covers_the_truth_at_the_nominal_rate():
    # ln Ep drawn about the power law with the sd each fraction's interval states: 5,000 trends
    rng = np.random.default_rng(123)
    size = np.array([2.8, 5.7, 11.3, 22.6])
    sd = np.array([0.2, 0.17, 0.15, 0.14])
    z = stats.norm.ppf(0.975)
    covered = 0
    for _ in range(5000):
        ep = TRUE_A * size**-TRUE_B * np.exp(rng.normal(0, sd))
        trend = fit_ep_trend(size, ep, ep * np.exp(-z * sd), ep * np.exp(z * sd))
        covered += trend.b_interval[0] <= TRUE_B <= trend.b_interval[1]
    # binomial sd of the rate at 5,000 trends is 0.0031: 0.95 +/- 4 sd (10,000 trends gave 0.9488)
    assert abs(covered / 5000 - 0.95) < 0.0125


def test_too_few_fractions_or_intervals_are_said_in_words():
    two = fit_ep_trend([2.0, 8.0], [0.04, 0.02])
    assert two.b == pytest.approx(0.5) and np.isnan(two.b_interval[0]) and "no interval" in two.note
    one = fit_ep_trend([2.0, 8.0], [0.04, np.nan])
    assert np.isnan(one.a) and "no trend: 1 size fraction" in one.note
    partly = fit_ep_trend(
        [2.0, 4.0, 8.0, 16.0], [0.04, 0.03, 0.02, 0.015], [0.03, np.nan, 0.015, 0.01], [0.05, np.nan, 0.027, 0.02]
    )
    assert partly.n_sizes == 3 and "1 size fraction(s) without an Ep interval left out" in partly.note


def test_representative_sizes_extend_open_fractions_by_their_neighbour_s_ratio():
    sizes = representative_sizes([np.nan, 0.5, 2.0, 8.0], [0.5, 2.0, 8.0, np.nan])
    np.testing.assert_allclose(sizes, [0.25, 1.0, 4.0, 16.0], rtol=1e-12)


def _exact_partition_table():
    """Partitions read off normal curves whose Ep follows 0.05 d^-0.35 exactly, four size fractions."""
    density = np.round(np.arange(1.40, 1.70, 0.02), 2)
    frames = []
    for lower, upper in ((2.0, 4.0), (4.0, 8.0), (8.0, 16.0), (16.0, 32.0)):
        size = np.sqrt(lower * upper)
        ep, rho50 = TRUE_A * size**-TRUE_B, 1.52 + 0.04 * size**-0.5
        partition = stats.norm.cdf((density - rho50) / (ep / stats.norm.ppf(0.75)))
        frames.append(pd.DataFrame({"test": "exact", "size_lower_mm": lower, "size_upper_mm": upper, "density": density,
                                    "partition_sinks": partition}))  # fmt: skip
    return pd.concat(frames, ignore_index=True)


def test_exact_partitions_give_back_the_power_law_of_their_curves():
    samples = read_density(_exact_partition_table())
    fits = [fit_density_curve(sample, "normal") for sample in samples]
    by_size, trends = by_size_table(fits)
    sizes = np.sqrt([8.0, 32.0, 128.0, 512.0])
    np.testing.assert_allclose(by_size["size"], sizes, rtol=1e-12)
    np.testing.assert_allclose(by_size["ep"], TRUE_A * sizes**-TRUE_B, rtol=1e-5)
    np.testing.assert_allclose(by_size["rho50"], 1.52 + 0.04 * sizes**-0.5, rtol=0, atol=1e-6)
    (trend,) = trends.itertuples()
    assert trend.a == pytest.approx(TRUE_A, rel=1e-5) and trend.b == pytest.approx(TRUE_B, rel=1e-4)
    assert not trend.weighted and trend.n_sizes == 4  # no intervals asked: every fraction weighs the same


def test_the_tracer_example_gives_indices_per_size_and_a_trend_covering_the_truth():
    samples = read_density(TRACERS)
    fits = [fit_density_curve(sample, curve, ci=0.95) for sample in samples for curve in ("normal", "logistic")]
    by_size, trends = by_size_table(fits)
    assert list(by_size.columns) == list(BY_SIZE_COLUMNS) and list(trends.columns) == list(EP_TREND_COLUMNS)
    assert len(by_size) == 8 and set(by_size["size_unit"]) == {"mm"}
    np.testing.assert_allclose(by_size["imperfection"], by_size["ep"] / (by_size["rho50"] - 1), rtol=1e-12)
    for low, value, high in ("rho50_low", "rho50", "rho50_high"), ("ep_low", "ep", "ep_high"):
        assert (by_size[low] < by_size[value]).all() and (by_size[value] < by_size[high]).all()
    normal = trends.set_index("curve").loc["normal"]
    assert normal.weighted and normal.n_sizes == 4
    assert normal.b_low < TRUE_B < normal.b_high and normal.a_low < TRUE_A < normal.a_high
    assert normal.b_low > 0  # the finer tracers separate less sharply, and the data say so
    truth = 1.52 + 0.04 * by_size.loc[by_size.curve == "normal", "size"] ** -0.5
    rows = by_size[by_size.curve == "normal"]
    assert ((rows.rho50_low < truth) & (truth < rows.rho50_high)).all()
    assert common_curve(by_size, "dmc_tracers") in {"normal", "logistic"}


def test_the_outputs_are_the_tables_and_one_figure_per_test(tmp_path):
    samples = read_density(TRACERS)
    fits = [fit_density_curve(sample, "normal", ci=0.95) for sample in samples]
    outputs = by_size_outputs(fits)
    assert set(outputs) == {"by_size.csv", "ep_trend.csv", "by_size_dmc_tracers.png"}
    for name, writer in outputs.items():
        writer(tmp_path / name)
    assert (tmp_path / "by_size_dmc_tracers.png").read_bytes()[:4] == b"\x89PNG"
    assert len(pd.read_csv(tmp_path / "by_size.csv")) == 4
    no_sizes = read_density(pd.DataFrame({"density": [1.4, 1.5, 1.6, 1.7], "partition_sinks": [0.05, 0.3, 0.8, 0.97]}))
    assert by_size_outputs([fit_density_curve(no_sizes[0], "normal")]) == {}


@pytest.mark.slow
def test_density_fit_writes_the_size_tables_the_python_api_writes(tmp_path, capsys):
    from tromplab.cli import main
    from tromplab.density import fit_density

    assert main(["density", "fit", str(TRACERS), "-o", str(tmp_path / "cli"), "--ci", "0.9", "--curves", "normal"]) == 0
    fit_density(TRACERS, ci=0.9, curves="normal").save(tmp_path / "api")
    for name in ("by_size.csv", "ep_trend.csv"):
        assert (tmp_path / "cli" / name).read_bytes() == (tmp_path / "api" / name).read_bytes()
    assert (tmp_path / "cli" / "by_size_dmc_tracers.png").exists()
    by_size = pd.read_csv(tmp_path / "cli" / "by_size.csv")
    fits = pd.read_csv(tmp_path / "cli" / "fits.csv")
    # the per-size indices are those of fits.csv
    np.testing.assert_allclose(np.sort(by_size["ep"]), np.sort(fits["ep"]), rtol=1e-12)
    assert by_size["ep_low"].notna().all()
