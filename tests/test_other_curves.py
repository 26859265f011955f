"""The curves of other tools (family "other"): declarations, reference values, round trips, name clashes."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from tromplab.cli import main
from tromplab.curves.curve_fit import fit_formula
from tromplab.curves.formulas import OTHER_FORMULAS, get_formula, select_formulas
from tromplab.curves.indices import curve_indices
from tromplab.loading.points import TrompPoints
from tromplab.workbench import fit_experiments

from .conftest import reference_rows, shapes_across_bounds

X = np.geomspace(1e-3, 1e2, 600)
SIZES = np.geomspace(20, 400, 14)
other_ids = pytest.mark.parametrize("formula", OTHER_FORMULAS, ids=[f.id for f in OTHER_FORMULAS])


def starts(formula):
    return {extra.name: extra.start for extra in formula.extras}


@other_ids
def test_other_curves_are_fully_declared(formula):
    assert formula.family == "other"
    assert formula.title and formula.expression and formula.citation and formula.slope_expression
    assert formula.shape_bounds[0] < formula.shape_bounds[1]
    for extra in formula.extras:
        assert extra.bounds[0] <= extra.start <= extra.bounds[1] and extra.meaning
    assert get_formula(formula.id) is formula and formula in select_formulas("other")


@other_ids
def test_half_at_the_cut_monotone_and_analytic_slope(formula):
    no_bypass = {**starts(formula), **({"bypass": 0.0} if "bypass" in starts(formula) else {})}
    for shape in shapes_across_bounds(formula):
        phi = formula.phi(X, shape, **no_bypass)
        assert_allclose(formula.phi(1.0, shape, **no_bypass), 0.5, atol=1e-12)
        assert np.all(np.isfinite(phi)) and np.all((phi >= 0) & (phi <= 1))
        assert np.all(np.diff(phi) <= 1e-15), shape
    shape = formula.shape_for_slope(-0.7)
    h = 1e-6
    numeric = (formula.phi(1 + h, shape, **no_bypass) - formula.phi(1 - h, shape, **no_bypass)) / (2 * h)
    assert_allclose(numeric, formula.slope_at_cut(shape), rtol=1e-6)
    assert_allclose(formula.slope_at_cut(shape), -0.7, rtol=1e-12)


def test_teipel_hennig_slope_at_the_cut_does_not_depend_on_alpha():
    formula = get_formula("teipel_hennig")
    h = 1e-6
    for alpha in (0.0, 1.0, 8.0, 40.0):
        slope = (formula.phi(1 + h, 4.0, th_alpha=alpha) - formula.phi(1 - h, 4.0, th_alpha=alpha)) / (2 * h)
        assert_allclose(slope, -0.75, rtol=1e-6)


@pytest.mark.parametrize("row", reference_rows("other_curves.csv"), ids=lambda r: f"{r.formula}-{r.x}-{r.parameters}")
def test_reference_values_computed_independently_with_mpmath(row):
    formula = get_formula(row.formula)
    values = {k: float(v) for k, v in (pair.split("=") for pair in row.parameters.split(";"))}
    shape = values.pop(formula.shape_name)
    assert_allclose(formula.phi(row.x, shape, **values), row.phi, atol=row.atol, rtol=1e-12)


def test_logistic_puts_d25_and_d75_one_imperfection_from_the_cut():
    indices = curve_indices("logistic", 100.0, 0.2, delta_max=500.0)
    assert_allclose([indices.d25, indices.d75, indices.ep, indices.imperfection], [80.0, 120.0, 20.0, 0.2], rtol=1e-9)


ROUND_TRIPS = [
    ("normal", 120.0, {"sigma_rel": 0.3}, 0.05),
    ("logistic", 90.0, {"imperfection": 0.25}, 0.05),
    ("teipel_hennig", 100.0, {"k": 3.0, "th_alpha": 2.0, "bypass": 0.12}, None),
    ("rosin_rammler_bypass", 110.0, {"kr": 2.2, "bypass": 0.2}, 0.05),
]


@pytest.mark.parametrize("formula_id, d_cut, params, shape_rtol", ROUND_TRIPS, ids=[r[0] for r in ROUND_TRIPS])
def test_round_trip_recovers_the_generating_curve(formula_id, d_cut, params, shape_rtol):
    formula = get_formula(formula_id)
    params = dict(params)
    shape = params.pop(formula.shape_name)
    rng = np.random.default_rng(14)
    truth = formula(SIZES, d_cut, shape, **params)
    points = TrompPoints(formula_id, SIZES, np.clip(truth + rng.normal(0, 0.005, SIZES.size), 0, 1))
    fit = fit_formula(points, formula)
    assert fit.success and fit.screen.adequate
    assert_allclose(fit.d_cut, d_cut, rtol=0.03)
    if shape_rtol is not None:  # alpha and beta of Teipel/Hennig trade off; the curve is what is identified
        assert_allclose(fit.shape, shape, rtol=shape_rtol)
    if "bypass" in params:
        assert_allclose(fit.extras["bypass"], params["bypass"], atol=0.02)
    assert_allclose(fit.predict(SIZES), truth, atol=0.01)


def test_other_curves_stay_out_of_the_ranking_unless_asked():
    rng = np.random.default_rng(5)
    points = TrompPoints("p", SIZES, np.clip(get_formula("plitt")(SIZES, 80, 2.5) + rng.normal(0, 0.01, SIZES.size), 0, 1))
    bench = fit_experiments([points], formulas="paper,other")
    assert {"normal", "teipel_hennig"} <= set(bench.fits_table()["formula"])
    assert "normal" not in set(bench.ranking_table()["formula"])
    row = bench.fits_table().set_index("formula").loc["teipel_hennig"]
    assert row["extras"].startswith("th_alpha=")
    assert "normal" in set(fit_experiments([points], formulas="paper,other", rank_extended=True).ranking_table()["formula"])


def test_formulas_command_lists_the_other_family_and_the_name_clashes(capsys):
    assert main(["formulas"]) == 0
    out = capsys.readouterr().out
    assert "teipel_hennig" in out and "(201) normal" in out
    assert "'Plitt'" in out and "rosin_rammler" in out and "'Whiten'" in out


def test_every_registered_curve_gets_its_own_figure_style():
    from tromplab.curves.formulas import ALL_FORMULAS
    from tromplab.output.plotting import curve_styles

    styles = [(s["color"], s["ls"]) for s in curve_styles(len(ALL_FORMULAS))]
    assert len(set(styles)) == len(ALL_FORMULAS) > 12
    assert all(a[1] != b[1] for a, b in zip(styles, styles[1:]))  # consecutive curves differ in line style
