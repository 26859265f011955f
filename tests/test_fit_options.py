"""The options travel with the fit; failed fits of any formula are nan, never KeyError."""

import pickle

import numpy as np
import pandas as pd
import pytest
from numpy.testing import assert_allclose

from tromplab.cli import main
from tromplab.curves.curve_fit import CurveFit, FitOptions, failed_fit, fit_formula
from tromplab.curves.formulas import ALL_FORMULAS
from tromplab.curves.indices import curve_indices
from tromplab.loading.points import TrompPoints
from tromplab.statistics.uncertainty import bootstrap, interval_table, model_average
from tromplab.workbench import fit_experiments

from .conftest import DATASETS

SIZES = np.array([1.0, 2, 4, 8, 16, 32, 64])
PHI = np.array([0.97, 0.9, 0.7, 0.45, 0.2, 0.07, 0.02])


def test_fit_records_its_options_and_derives_screen_and_indices_from_them():
    points = TrompPoints("run", SIZES, PHI, weight=np.arange(1.0, 8.0))
    fit = fit_formula(points, "plitt", alpha=0.01, delta_max=500.0, size_unit="um")
    assert fit.options.alpha == 0.01 and fit.options.delta_max == 500.0 and fit.options.size_unit == "um"
    assert_allclose(fit.options.weights.mean(), 1.0)
    assert_allclose(fit.options.weights, np.arange(1.0, 8.0) / 4.0)
    assert fit.screen.alpha == 0.01
    expected = curve_indices("plitt", fit.d_cut, fit.shape, delta_max=500.0)
    assert_allclose(fit.indices.epsilon, expected.epsilon, rtol=1e-12)
    default = fit_formula(points, "plitt")
    assert default.options.delta_max == 64.0 and default.indices.epsilon < fit.indices.epsilon


def test_intervals_bootstrap_and_averages_use_the_fits_delta_max():
    points = TrompPoints("run", SIZES, PHI)
    fits = [fit_formula(points, f, delta_max=2000.0) for f in ("plitt", "lognormal", "rosin_rammler")]
    table = interval_table(fits[0], level=0.95).set_index("quantity")
    epsilon = table.loc["epsilon"]
    assert_allclose(epsilon["value"], fits[0].indices.epsilon, rtol=1e-12)
    assert epsilon["low"] <= epsilon["value"] <= epsilon["high"]
    boot = bootstrap(fits[0], n=20, seed=1).intervals(0.95).set_index("quantity")
    assert boot.loc["epsilon", "low"] <= fits[0].indices.epsilon <= boot.loc["epsilon", "high"]
    averaged = model_average(fits, quantities=("epsilon",)).set_index("quantity")
    shares = [f.indices.epsilon for f in fits]
    assert min(shares) <= averaged.loc["epsilon", "value"] <= max(shares)


def test_cli_delta_max_reaches_the_intervals(tmp_path):
    # --delta-max 2000 --ci 0.95 wrote epsilon 0.677 with the interval [0.518, 0.604]
    source = DATASETS / "double_deck_screen_decks_lab.csv"
    assert (
        main(
            [
                "fit",
                str(source),
                "--size-unit",
                "mm",
                "--delta-max",
                "2000",
                "--ci",
                "0.95",
                "--formulas",
                "plitt,lognormal",
                "-o",
                str(tmp_path),
                "--no-figures",
            ]
        )
        == 0
    )
    fits = pd.read_csv(tmp_path / "fits.csv")
    inside = (fits["epsilon_low"] <= fits["epsilon"]) & (fits["epsilon"] <= fits["epsilon_high"])
    assert inside.all(), fits[["experiment", "formula", "epsilon", "epsilon_low", "epsilon_high"]]


@pytest.mark.parametrize("formula", ALL_FORMULAS, ids=lambda f: f.id)
def test_a_failed_fit_of_any_formula_is_nan_and_predicts_nan(formula):
    points = TrompPoints("three", np.array([1.0, 2.0, 4.0]), np.array([0.9, 0.5, 0.1]))
    bench = fit_experiments([points], formulas=[formula.id])
    fit = bench.fits[0]
    if formula.n_params < 3:
        fit = failed_fit(points, formula, "made to fail")
    assert not fit.success
    assert np.isnan(fit.d_cut) and np.isnan(fit.shape)
    assert set(fit.extras) == {extra.name for extra in formula.extras}
    assert all(np.isnan(v) for v in fit.extras.values())
    assert set(fit.fit.values) == {"d_cut", formula.shape_name, *fit.extras}
    assert np.isnan(fit.predict(points.size)).all() and fit.predict(points.size).shape == (3,)
    assert fit.screen is None and fit.indices is None and fit.warnings == ()
    row = fit.row()
    assert not row["success"] and np.isnan(row["d_cut"])


def test_whiten_on_three_points_is_reported_not_raised():
    points = TrompPoints("three", np.array([1.0, 2.0, 4.0]), np.array([0.9, 0.5, 0.1]))
    bench = fit_experiments([points], formulas=["plitt", "whiten"])
    whiten = next(f for f in bench.fits if f.formula.id == "whiten")
    assert not whiten.success and "points cannot be screened" in whiten.message
    assert np.isnan(whiten.extras["fishhook"]) and np.isnan(whiten.predict(1.0))
    assert bench.fits_table().set_index("formula").loc["whiten", "success"] == False  # noqa: E712


def test_derived_results_survive_pickling_and_hand_built_results_get_default_options():
    points = TrompPoints("run", SIZES, PHI)
    fit = fit_formula(points, "plitt_bypass", delta_max=100.0)
    _ = fit.indices, fit.warnings  # cached before pickling
    copy = pickle.loads(pickle.dumps(fit))
    assert copy.options.delta_max == 100.0
    assert_allclose(copy.indices.epsilon, fit.indices.epsilon)
    assert copy.screen.F == fit.screen.F
    bare = CurveFit(formula=fit.formula, points=points, fit=fit.fit, context=fit.context)
    assert bare.options.delta_max == points.largest_size and bare.options.alpha == 0.05
    with pytest.raises(ValueError, match="alpha"):
        FitOptions.for_points(points, alpha=1.5)
