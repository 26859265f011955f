"""The registry documents itself and cannot drift: texts, functions, references and styles agree.

Reference: tests/reference/phi_reference.csv, made by tests/reference/make_phi_reference.py
from the registry's expression texts with mpmath at 40 digits; each generated reference file
is regenerated here and compared with the committed one.
"""

import ast
import dataclasses
import inspect
import io
import re

import numpy as np
import pandas as pd
import pytest
from numpy.testing import assert_allclose

from tromplab.curves.formulas import (
    ALL_FORMULAS,
    EXPRESSION_FUNCTIONS,
    Formula,
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

from .conftest import REFERENCE, ROOT, reference
from .reference import make_other_curve_references, make_phi_reference

PHI = reference("phi_reference.csv")
OTHER_CURVES = reference("other_curves.csv")
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


# --- the registry is the one source: docstrings, generated references, the engine ----------------
NUMBER = r"-?\d+(?:\.\d+)?(?:e-?\d+)?"
#: A dated work in a citation: its authors ("Lynch A.J., Rao T.C.") and year.
DATED_WORK = re.compile(r"[A-Z][\w'-]+ [A-Z]\.(?:[A-Z]\.)*(?:, [A-Z][\w'-]+ [A-Z]\.(?:[A-Z]\.)*)* \(\d{4}\)")


def _documented_ranges(function) -> dict[str, tuple[float, float]]:
    """``{parameter: (low, high)}``: the first ``low..high`` of each entry of the Parameters section."""
    section = inspect.cleandoc(function.__doc__).split("Parameters\n----------\n", 1)[1].split("\n\n", 1)[0]
    ranges, name = {}, None
    for line in section.splitlines():
        entry = re.match(r"(\w+) : ", line)
        if entry:
            name = entry.group(1)
            continue
        found = re.search(rf"({NUMBER})\.\.({NUMBER})", line)
        if name and found and name not in ranges:
            ranges[name] = (float(found.group(1)), float(found.group(2)))
    return ranges


def _cited_works(citation: str):
    """Each dated work of a citation, from its authors to the next '; ', ' (' or the end."""
    for match in DATED_WORK.finditer(citation):
        rest = citation[match.end() :]
        end = min((i for i in (rest.find("; "), rest.find(" (")) if i >= 0), default=len(rest))
        yield (match.group() + rest[:end]).rstrip(".")


@all_formulas
def test_docstring_ranges_are_the_declared_bounds(formula):
    """The Parameters section of phi states the bounds the fits use (two said -1..60 for 0..60)."""
    shape_argument = list(inspect.signature(formula.phi).parameters)[1]
    declared = {shape_argument: formula.shape_bounds, **{extra.name: extra.bounds for extra in formula.extras}}
    documented = _documented_ranges(formula.phi)
    assert {name: documented.get(name) for name in declared} == declared, f"{formula.phi.__name__} docstring"


@all_formulas
def test_docstring_references_repeat_the_citation(formula):
    references = " ".join(inspect.cleandoc(formula.phi.__doc__).split("References\n----------\n", 1)[1].split())
    works = list(_cited_works(formula.citation))
    assert works or "not verified" in formula.citation or formula.id in ("lognormal", "teipel_hennig"), formula.citation
    for work in works:
        assert work in references, f"{formula.id}: the docstring does not cite {work!r}"


def test_citation_parsing_finds_every_work():
    plitt, bypass = get_formula("plitt"), get_formula("plitt_bypass")
    assert list(_cited_works(plitt.citation)) == [
        "Plitt L.R. (1971). The analysis of solid-solid separations in classifiers. CIM Bulletin 64(708), 42-47",
        "Shuvalov S.I., Novoseltseva S.S., Zhukov V.P. (2018). Justifying the choice of a dependence for the Tromp "
        "separation curve approximation. Vestnik IGEU 6, 15-23. doi:10.17588/2072-2672.2018.6.015-023",
    ]
    assert [DATED_WORK.match(work).group() for work in _cited_works(bypass.citation)] == [
        "Plitt L.R. (1976)",
        "Kelsall D.F. (1953)",
    ]
    assert _documented_ranges(get_formula("whiten").phi) == {"alpha": (1e-3, 60.0), "bypass": (0.0, 0.95), "fishhook": (0.0, 3.0)}


#: Each generated reference file and the function that writes its text.
GENERATED = {
    "phi_reference.csv": make_phi_reference.reference_text,
    "other_curves.csv": make_other_curve_references.reference_text,
}


@pytest.mark.parametrize("name", sorted(GENERATED))
def test_reference_file_is_what_its_generator_writes(name):
    """Regenerated in memory: provenance and text columns exact, numbers within each row's tolerance."""
    committed_text, generated_text = (REFERENCE / name).read_text(), GENERATED[name]()
    comments = [[line for line in text.splitlines() if line.startswith("#")] for text in (committed_text, generated_text)]
    assert comments[1] == comments[0]
    committed, generated = (pd.read_csv(io.StringIO(text), comment="#") for text in (committed_text, generated_text))
    assert list(generated.columns) == list(committed.columns) and len(generated) == len(committed)
    tolerance = "rtol" if "rtol" in committed else "atol"
    assert_allclose(generated[tolerance], committed[tolerance], rtol=0)
    for column in committed.columns.drop(tolerance):
        if not pd.api.types.is_numeric_dtype(committed[column]):
            assert generated[column].tolist() == committed[column].tolist(), f"{name}, column {column}"
            continue
        for value, rows in committed.groupby(tolerance).groups.items():
            assert_allclose(
                generated.loc[rows, column].to_numpy(float),
                committed.loc[rows, column].to_numpy(float),
                **{tolerance: value},
                err_msg=f"{name}, column {column}: rerun tests/reference/{GENERATED[name].__module__.split('.')[-1]}.py",
            )


def test_equal_sharpness_shapes_beyond_the_fit_bounds_keep_their_reference_rows():
    """Molerus-Hoffmann is fitted on km2 >= 0 but defined (and drawn) below: slope -0.3 is km2 = -0.4."""
    rows = _rows(get_formula("molerus_hoffmann"))
    assert sorted(set(rows["shape"])) == [-0.4, 1.0, 5.0]
    rising = rows[rows["shape"] == -0.4].set_index("x")["phi"]
    assert rising[4.0] > rising[2.0] > rising[1.3]  # risen again beyond the minimum at x = 1/sqrt(0.4)


@all_formulas
def test_every_formula_has_every_field_and_consistent_hooks(formula):
    """Completeness over the dataclass itself: a field added to Formula is checked here too."""
    for spec in dataclasses.fields(Formula):
        value = getattr(formula, spec.name)
        if spec.default is dataclasses.MISSING and spec.default_factory is dataclasses.MISSING:
            assert value is not None and value != "", f"{formula.id} lacks {spec.name}"
    for name in ("phi", "slope_at_cut", "shape_for_slope"):
        assert callable(getattr(formula, name)), f"{formula.id}: {name} is not callable"
    assert formula.shape_bounds[0] < formula.shape_bounds[1]
    assert formula.efficiency is None or callable(formula.efficiency)
    assert set(formula.defaults) <= ({"measured_efficiency"} if formula.context_from_efficiency else set())
    assert not formula.monotone or not formula.lower_bound_reason
    assert formula.nests is None or get_formula(formula.nests).family == "paper"
    moving = formula.moving_break
    if moving is not None:  # a moving break is a piecewise curve of the measured efficiency
        assert formula.piecewise and formula.context_from_efficiency
        for hook in dataclasses.fields(moving):
            assert getattr(moving, hook.name) is None or callable(getattr(moving, hook.name)), hook.name
    if formula.family == "other":
        assert (OTHER_CURVES["formula"] == formula.id).sum() >= 7, f"{formula.id} has no rows in other_curves.csv"


def test_a_moving_break_gives_the_curve_phi_gives():
    formula = get_formula("shuvalov")
    x, kr, efficiency = np.geomspace(0.05, 4.0, 9), 2.5, 0.8
    moving = formula.moving_break
    x_break = moving.at(kr, efficiency)
    assert_allclose(moving.on_arrays(np.array([kr]), np.array([efficiency])), [x_break], atol=1e-12)
    assert_allclose(moving.phi(x, kr, x_break), formula.phi(x, kr, measured_efficiency=efficiency), rtol=1e-14)
    kink = float(moving.kink(np.array([efficiency]), formula.shape_bounds)[0])
    assert moving.at(kink * 0.99, efficiency) == 0.0 < moving.at(kink * 1.01, efficiency)


@pytest.mark.parametrize("module", ["engine", "indices"])
def test_the_engine_and_the_indices_name_no_formula(module):
    """Behaviour special to a formula is declared on its record (piecewise, moving_break), not by id."""
    tree = ast.parse((ROOT / "tromplab" / "curves" / f"{module}.py").read_text())
    strings = {node.value for node in ast.walk(tree) if isinstance(node, ast.Constant) and isinstance(node.value, str)}
    assert not strings & {formula.id for formula in ALL_FORMULAS}
