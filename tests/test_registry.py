"""The registry documents itself and cannot drift: texts, functions, references and styles agree.

Reference: tests/reference/phi_reference.csv, made by tests/reference/make_phi_reference.py
from the registry's expression texts with mpmath at 40 digits.
"""

import re

import numpy as np
import pytest
from numpy.testing import assert_allclose

from tromplab.curves.formulas import (
    ALL_FORMULAS,
    EXPRESSION_FUNCTIONS,
    evaluate_expression,
    formula_table_markdown,
    get_formula,
    shuvalov_break,
    whiten_beta_star,
)
from tromplab.curves.measured import parameter_specs
from tromplab.curves.parameters import Parameter, d_cut_parameter
from tromplab.loading.points import TrompPoints
from tromplab.output.plotting import curve_styles

from .conftest import ROOT, reference

PHI = reference("phi_reference.csv")
all_formulas = pytest.mark.parametrize("formula", ALL_FORMULAS, ids=[f.id for f in ALL_FORMULAS])


def _rows(formula):
    return PHI[PHI["formula"] == formula.id]


def _values(formula, row):
    """Keyword values of one reference row: x, the shape, the extras and the derived variables."""
    values = {"x": float(row.x), formula.shape_name: float(row.shape)}
    values.update({extra.name: float(getattr(row, extra.name)) for extra in formula.extras})
    if "x_a" in formula.expression:
        values["x_a"] = shuvalov_break(float(row.shape), float(row.measured_efficiency))
    if "b_star" in formula.expression:
        values["b_star"] = whiten_beta_star(float(row.shape), values["fishhook"])
    return values


def _context(formula, row):
    return {"measured_efficiency": float(row.measured_efficiency)} if formula.context_from_efficiency else {}


@all_formulas
def test_every_formula_declares_every_field_reference_rows_and_a_figure_style(formula):
    for name in ("id", "title", "expression", "shape_name", "slope_expression", "citation", "shape_meaning"):
        assert getattr(formula, name), f"{formula.id} lacks {name}"
    assert "Shuvalov" in formula.citation or formula.family != "paper"
    assert re.search(r"\(\d{4}\)", formula.citation) or "not verified" in formula.citation, formula.citation
    for parameter in formula.parameters([1.0, 10.0]):
        assert isinstance(parameter, Parameter)
        assert parameter.unit and parameter.meaning and parameter.start_rule, parameter
        assert parameter.lower < parameter.upper
    assert len(_rows(formula)) >= 3 * 5, f"{formula.id} has no reference rows: run tests/reference/make_phi_reference.py"
    styles = curve_styles(len(ALL_FORMULAS))  # a batch draws the registry in order: one style per formula
    style = styles[ALL_FORMULAS.index(formula)]
    assert sum(s == style for s in styles) == 1, f"{formula.id} shares its figure style with another formula"
    assert formula.phi.__doc__, f"{formula.id}: its phi function has no docstring"


@all_formulas
def test_function_matches_the_high_precision_values_of_its_expression(formula):
    for row in _rows(formula).itertuples(index=False):
        extras = {extra.name: float(getattr(row, extra.name)) for extra in formula.extras}
        phi = formula.phi(float(row.x), float(row.shape), **_context(formula, row), **extras)
        assert_allclose(phi, row.phi, rtol=row.rtol, err_msg=f"{formula.id} at x = {row.x}, shape = {row.shape}")


@all_formulas
def test_expression_text_still_gives_the_reference_values(formula):
    """Catches an edited text whose reference rows were not regenerated."""
    names = set(re.findall(r"[A-Za-z_]\w*", formula.expression)) - set(EXPRESSION_FUNCTIONS)
    declared = {"x", formula.shape_name, *(e.name for e in formula.extras), "x_a", "b_star"}
    assert names <= declared, f"{formula.id}: undeclared names {names - declared} in its expression"
    for row in _rows(formula).itertuples(index=False):
        # atol: the printed forms cancel in double precision in the tails (Lynch's 1 - ...)
        assert_allclose(evaluate_expression(formula.expression, _values(formula, row)), row.phi, rtol=1e-9, atol=1e-13)


@all_formulas
def test_slope_text_matches_the_slope_function_and_the_curve(formula):
    zero_extras = {extra.name: 0.0 for extra in formula.extras}
    for shape in sorted(set(_rows(formula)["shape"].astype(float))):
        from_text = float(evaluate_expression(formula.slope_expression, {formula.shape_name: shape, **zero_extras}))
        assert_allclose(from_text, formula.slope_at_cut(shape), rtol=1e-12)
        h = 1e-6
        context = dict(formula.defaults)
        numeric = (formula.phi(1 + h, shape, **context, **zero_extras) - formula.phi(1 - h, shape, **context, **zero_extras)) / (
            2 * h
        )
        assert_allclose(numeric, from_text, rtol=1e-5, atol=1e-9)


@pytest.mark.parametrize("formula_id", ["plitt_bypass", "lognormal_bypass"])
def test_slope_text_holds_with_bypass(formula_id):
    formula = get_formula(formula_id)
    shape, bypass, h = 2.0, 0.2, 1e-6
    numeric = (formula.phi(1 + h, shape, bypass=bypass) - formula.phi(1 - h, shape, bypass=bypass)) / (2 * h)
    assert_allclose(
        evaluate_expression(formula.slope_expression, {formula.shape_name: shape, "bypass": bypass}), numeric, rtol=1e-6
    )


def test_derived_formulas_share_their_base_declaration():
    base = get_formula("rosin_rammler")
    for derived in ("luckie_austin", "shuvalov"):
        formula = get_formula(derived)
        assert (formula.shape_name, formula.shape_bounds, formula.slope_expression) == (
            base.shape_name,
            base.shape_bounds,
            base.slope_expression,
        )
        assert formula.expression == base.expression.replace("x^", f"max(x, {'1/2' if derived == 'luckie_austin' else 'x_a'})^")
    bypass = get_formula("plitt_bypass")
    assert bypass.shape_parameter == get_formula("plitt").shape_parameter


def test_one_parameter_record_serves_registry_fit_and_comparison():
    points = TrompPoints("run", np.array([1.0, 2.0, 4.0, 8.0]), np.array([0.9, 0.7, 0.3, 0.1]))
    formula = get_formula("whiten")
    specs = parameter_specs(formula, points)
    assert specs == list(formula.parameters(points.size))
    assert specs[0] == d_cut_parameter(points.size) and specs[0].bounds == (0.01, 800.0)
    assert [s.name for s in specs] == ["d_cut", "alpha", "bypass", "fishhook"]
    from tromplab.statistics.compare import _bounds

    assert _bounds(get_formula("plitt"), "d_cut", points.size) == specs[0].bounds
    assert _bounds(get_formula("plitt"), "ks", points.size) == get_formula("plitt").shape_bounds


def test_readme_formula_table_is_the_generated_one():
    readme = (ROOT / "README.md").read_text()
    assert formula_table_markdown() in readme, "README formula table differs: paste formula_table_markdown()"


def test_cli_formulas_prints_the_registry_texts(capsys):
    from tromplab.cli import main

    assert main(["formulas"]) == 0
    out = "".join(capsys.readouterr().out.split())  # textwrap breaks long texts at spaces
    for formula in ALL_FORMULAS:
        assert "".join(formula.expression.split()) in out and "".join(formula.slope_expression.split()) in out
