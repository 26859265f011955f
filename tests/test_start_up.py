"""The start-up of the commands: what each imports, and the pieces that let ``circuit design``
run on numpy and pandas alone (docs/performance.md, "Start-up").

The times are measured by ``benchmarks/import_time.py`` and ``benchmarks/circuit_speed.py``;
these tests check what the times rest on, in fresh interpreters: the modules a command has
loaded when it has finished, and that the numpy replacements of the scipy functions give
scipy's numbers.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg
import scipy.optimize

from tromplab import cli
from tromplab.circuit import linear_algebra
from tromplab.circuit.problem import _bounded_least_squares
from tromplab.classifiers.pulp import COEFFICIENT_RANGES, PulpScreen
from tromplab.cli.startup import cli_words, words_of
from tromplab.loading.node_balance import estimate_fine_yield
from tromplab.options import PULP_COEFFICIENT_RANGES, PULP_SCREEN_DEFAULTS

ROOT = Path(__file__).resolve().parents[1]
DATASETS = ROOT / "datasets"
ASSAYED = Path(__file__).parent / "data" / "circuit_reference" / "inputs" / "assay_class.csv"

#: A command run through the console script's entry point in this interpreter, then the
#: modules it loaded (every module stays in sys.modules once imported).
_COMMAND = """
import json, sys
from tromplab._launch import main
sys.argv = ["tromplab", *{argv!r}]
try:
    code = main()
except SystemExit as stop:  # --version and -h leave through argparse
    code = stop.code
print(json.dumps({{"code": code, "modules": sorted(sys.modules)}}))
"""
#: What ``circuit design`` used to import and no longer needs (0.1 to 0.25 s of its 0.6 s).
NOT_FOR_A_DESIGN = ("scipy.linalg", "scipy.optimize", "scipy.sparse", "scipy.special", "scipy.stats", "lmfit",
                    "matplotlib", "statsmodels", "networkx", "tromplab.workbench", "tromplab.classifiers.pulp")  # fmt: skip


def _loaded_by(tmp_path: Path, *argv: str) -> set[str]:
    done = subprocess.run(
        [sys.executable, "-c", _COMMAND.format(argv=list(argv))],
        capture_output=True, text=True, timeout=300, cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(ROOT)},
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout.splitlines()[-1])
    assert result["code"] == 0, done.stderr
    return set(result["modules"])


def _heavy(loaded: set[str], names) -> list[str]:
    return sorted(name for name in loaded if name in names)


@pytest.mark.slow
@pytest.mark.parametrize("survey", [[], [str(DATASETS / "circuit_example_survey.csv")]], ids=["simulated survey", "given survey"])
def test_a_design_runs_on_numpy_and_pandas_without_scipys_numerical_modules(tmp_path, survey):
    argv = ["circuit", "design", str(DATASETS / "circuit_example_flowsheet.csv"), *survey, "-o", str(tmp_path / "d"), "-q"]
    loaded = _loaded_by(tmp_path, *argv)
    assert (tmp_path / "d" / "design.csv").is_file()
    assert {"numpy", "pandas", "tromplab.circuit.design", "tromplab.circuit.linear_algebra"} <= loaded
    assert _heavy(loaded, NOT_FOR_A_DESIGN) == []


@pytest.mark.slow
def test_a_survey_with_assays_imports_the_tests_distributions_but_not_scipys_solvers(tmp_path):
    argv = ["circuit", str(DATASETS / "circuit_example_flowsheet.csv"), str(ASSAYED), "-o", str(tmp_path / "c"),
            "--no-figures", "-q"]  # fmt: skip
    loaded = _loaded_by(tmp_path, *argv)
    assert (tmp_path / "c" / "adjustments.csv").is_file()
    assert "scipy.special" in loaded  # the measurement tests' normal and chi-square tails
    assert _heavy(loaded, ("scipy.linalg", "scipy.optimize", "scipy.sparse", "scipy.stats", "lmfit", "matplotlib")) == []


#: The modules of the CLI that register commands (tromplab.cli.COMMANDS).
COMMAND_MODULES = ("app", "circuit", "density", "density_predict", "fit", "formulas", "models", "plant", "points", "rank",
                   "report", "sieve", "trend")  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize(
    "argv, built",
    [
        (["--version"], COMMAND_MODULES),
        (["-h"], COMMAND_MODULES),
        (["-q", "-h", "fit"], COMMAND_MODULES),  # tromplab's help, which lists every command
        (["circuit", "design", "-h"], ("circuit",)),
        (["pulp", "optimum", "-h"], ("models",)),
        (["-qv", "density", "fit", "-h"], ("density", "density_predict")),
    ],
)
def test_the_parser_is_built_without_numpy_or_any_commands_implementation(tmp_path, argv, built):
    loaded = _loaded_by(tmp_path, *argv)
    # a command named on the command line builds its own parser and imports no other command's module
    assert sorted(name for name in COMMAND_MODULES if f"tromplab.cli.{name}" in loaded) == sorted(built)
    implementations = ("tromplab.circuit", "tromplab.classifiers", "tromplab.curves", "tromplab.density", "tromplab.plant",
                       "tromplab.loading.tables", "tromplab.workbench")  # fmt: skip
    assert sorted(name for name in loaded if name.split(".")[0] in ("numpy", "pandas", "scipy")) == []
    assert sorted(name for name in loaded if name.startswith(implementations)) == []


@pytest.mark.slow
def test_a_tracer_file_is_read_without_the_size_lab_tables_balance(tmp_path):
    # tromplab.loading.lab and the ten modules under it are the float-sink tables' mass balance
    table = tmp_path / "tracers.csv"
    table.write_text("test,density,placed,sinks,floats\n" + "".join(
        f"{test},{density:.2f},30,{sinks},{30 - sinks}\n"
        for test, shift in (("A", 0), ("B", 1)) for density, sinks in zip((1.3, 1.4, 1.5, 1.6, 1.7, 1.8), (0, 2, 9 + shift, 22, 29, 30))
    ), encoding="utf-8")  # fmt: skip
    loaded = _loaded_by(
        tmp_path, "density", "fit", str(table), "--ci", "0.95", "--figures", "none", "-o", str(tmp_path / "d"), "-q"
    )
    assert (tmp_path / "d" / "fits.csv").is_file()
    lab = ("tromplab.loading.lab", "tromplab.loading.lab_classes", "tromplab.loading.node_balance", "tromplab.loading.kelsall")
    assert _heavy(loaded, (*lab, "statsmodels", "scipy.optimize", "scipy.stats", "lmfit", "matplotlib")) == []
    assert sorted(name for name in COMMAND_MODULES if f"tromplab.cli.{name}" in loaded) == ["density", "density_predict"]


def _command_paths(parser, path=()):
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _command_paths(sub, (*path, name))


@pytest.mark.parametrize("names", [names for names, *_ in cli.COMMANDS], ids=lambda names: names[0])
def test_a_commands_own_parser_is_the_whole_parsers_to_the_word(names):
    whole = dict(_command_paths(cli.build_parser()))
    for name in names:
        own = dict(_command_paths(cli.build_parser(name)))
        assert {path for path in own if path} == {path for path in whole if path and path[0] in names}
        for path, parser in own.items():
            if path:  # each sub-command's help (usage, options, ranges), its options and defaults as in the whole parser
                assert parser.format_help() == whole[path].format_help(), path
                assert _options(parser) == _options(whole[path]), path
                assert _values(parser._defaults) == _values(whole[path]._defaults), path


def _options(parser) -> list:
    fields = ("option_strings", "dest", "nargs", "const", "default", "required", "help", "metavar")
    return [
        [*(getattr(action, name) for name in fields), getattr(action.type, "range", None), getattr(action.type, "__name__", None),
         sorted(action.choices) if action.choices is not None else None]
        for action in parser._actions
    ]  # fmt: skip


def _values(defaults: dict) -> dict:
    # a command group's run is a function made for its parser (print its usage): compared by name
    return {key: getattr(value, "__qualname__", value) for key, value in defaults.items()}


@pytest.mark.parametrize(
    "argv, named",
    [
        (["density", "fit", "x.csv"], "density"),
        (["-q", "--debug", "-vv", "circuit", "design", "x.csv"], "circuit"),
        (["--quiet", "--verbose", "pulp", "optimum"], "pulp"),
        (["-h", "fit"], None),  # tromplab -h: every command listed
        (["--he", "fit"], None),  # an abbreviation of --help
        (["-qh", "fit"], None),
        (["--version", "fit"], None),
        (["-5", "fit"], None),  # argparse reads -5 as the command (and refuses it among every choice)
        (["--", "fit"], None),
        (["fi", "x.csv"], None),  # not a command: the choices are listed
        ([], None),
    ],
)
def test_only_a_command_named_before_any_other_option_is_built_alone(argv, named):
    assert cli._command_named(argv) == named


def test_the_option_words_of_the_whole_parser_are_built_only_for_a_message_that_may_name_one():
    built = []

    def whole():
        built.append(1)
        return cli.build_parser()

    with words_of(whole):
        assert cli_words("7 of 40 tests: the counts are overdispersed (Pearson chi2/df > 1)") == (
            "7 of 40 tests: the counts are overdispersed (Pearson chi2/df > 1)"
        )
        assert built == []
        worded = cli_words("the fine_yield of the sum_tolerance_pct and kind='pct'")
    assert len(built) == 1
    with words_of(cli.build_parser()):
        assert worded == cli_words("the fine_yield of the sum_tolerance_pct and kind='pct'")
    assert worded == "the --fine-yield of the --sum-tolerance and --kind pct"


def test_the_pulp_options_are_the_screens_fields_and_ranges():
    assert PULP_SCREEN_DEFAULTS == {item.name: item.default for item in fields(PulpScreen)}
    assert list(PULP_SCREEN_DEFAULTS) == [item.name for item in fields(PulpScreen)]  # the options' order in -h
    assert COEFFICIENT_RANGES is PULP_COEFFICIENT_RANGES


def _constraint_matrices():
    """Balances-like matrices: a random incidence pattern with repeated rows (rank deficient)."""
    rng = np.random.default_rng(40)
    for rows, columns in ((34, 88), (12, 30), (5, 5), (1, 7)):
        A = np.zeros((rows, columns))
        for row in A:
            picked = rng.choice(columns, size=min(3, columns), replace=False)
            row[picked] = rng.choice([-1.0, 1.0, 0.3], size=picked.size)
        if rows > 2:
            A[-1] = A[0] + A[1]  # a dependent row: the null space is wider than columns - rows
        yield A


@pytest.mark.parametrize("A", list(_constraint_matrices()), ids=lambda A: f"{A.shape[0]}x{A.shape[1]}")
def test_the_null_space_is_scipys_to_the_bit_and_in_its_memory_order(A):
    expected = scipy.linalg.null_space(A, rcond=1e-10)
    basis = linear_algebra.null_space(A, rcond=1e-10)
    np.testing.assert_array_equal(basis, expected)
    # rows in memory order as scipy's (a view of LAPACK's Fortran array): the layout decides the
    # BLAS path of the products with the basis, and a column-major one moved an assayed survey's
    # adjustments by 2e-5 relative
    assert basis.shape[1] == 1 or basis.strides[1] == expected.strides[1] == basis.itemsize
    np.testing.assert_array_equal(linear_algebra.null_space(A), scipy.linalg.null_space(A))


@pytest.mark.parametrize("size", [1, 3, 10])
def test_the_cholesky_solves_equal_scipys_to_rounding(size):
    rng = np.random.default_rng(size)
    E = rng.normal(size=(size, 40)) * 10.0 ** rng.uniform(-3, 3, size=(size, 1))  # rows of very different weights
    inner = np.eye(size) + E @ E.T  # a design candidate's I + E C E^T: eigenvalues 1 or more
    right = rng.normal(size=(size, 25))
    expected = scipy.linalg.cho_solve(scipy.linalg.cho_factor(inner), right)
    solved = linear_algebra.cho_solve(linear_algebra.cho_factor(inner), right)
    np.testing.assert_allclose(solved, expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())
    np.testing.assert_allclose(inner @ solved, right, rtol=0, atol=1e-9 * np.abs(right).max())
    vector = linear_algebra.cho_solve(linear_algebra.cho_factor(inner), right[:, 0])
    np.testing.assert_allclose(vector, expected[:, 0], rtol=1e-12, atol=1e-12 * np.abs(expected).max())


def test_a_matrix_that_is_not_positive_definite_is_refused_as_scipy_refuses_it():
    with pytest.raises(np.linalg.LinAlgError):
        linear_algebra.cho_factor(np.array([[1.0, 2.0], [2.0, 1.0]]))
    assert np.linalg.LinAlgError is scipy.linalg.LinAlgError


def test_every_other_name_is_scipys_function():
    assert linear_algebra.qr is scipy.linalg.qr
    with pytest.raises(AttributeError):
        linear_algebra.no_such_function  # noqa: B018


@pytest.mark.parametrize(
    "A, b, lower",
    [
        (np.array([[10.0, -10.0, 0.0], [0.0, 10.0, -10.0], [10.0, 0.0, 0.0]]), np.array([0.0, 0.0, 1000.0]), 0.1),
        (np.array([[1.0, 1.0], [1.0, -1.0], [0.0, 1.0]]), np.array([1.0, 3.0, -2.0]), 0.0),  # the bound binds
        (np.array([[1.0, 1.0, 0.0], [0.0, 1.0, 1.0]]), np.array([2.0, 2.0]), 0.0),  # underdetermined: minimum norm
    ],
    ids=["within the bounds", "at a bound", "underdetermined"],
)
def test_the_starts_bounded_least_squares_is_lsq_linear_to_the_bit(A, b, lower):
    # the start's bits reach the outputs (what no measurement sees keeps its starting value)
    np.testing.assert_array_equal(_bounded_least_squares(A, b, lower), scipy.optimize.lsq_linear(A, b, bounds=(lower, np.inf)).x)


@pytest.mark.parametrize("classes", [1, 2, 3, 8, 40])
def test_the_fine_yield_is_statsmodels_ols_to_the_bit(classes):
    sm = pytest.importorskip("statsmodels.api")
    rng = np.random.default_rng(classes)
    for _ in range(20):
        fine, coarse = rng.dirichlet(np.ones(classes)), rng.dirichlet(np.ones(classes))
        if classes == 1:  # one class: shares that are not closed (else fine equals coarse)
            fine, coarse = rng.uniform(size=1), rng.uniform(size=1)
        feed = 0.37 * fine + 0.63 * coarse + rng.normal(scale=0.01, size=classes)  # a balance with sampling error
        estimate = estimate_fine_yield(feed, fine, coarse)
        model = sm.OLS(feed - coarse, fine - coarse).fit()
        assert estimate.value == float(model.params[0])
        np.testing.assert_array_equal(estimate.residuals, model.resid)
        if classes > 1:
            assert estimate.stderr == float(model.bse[0])
        else:
            assert np.isnan(estimate.stderr)


@pytest.mark.slow
def test_a_lab_table_is_read_without_statsmodels(tmp_path):
    # the three streams of each experiment give its fine yield by least squares (before: statsmodels' OLS)
    table = DATASETS / "air_classifier_lab_synthetic.csv"
    loaded = _loaded_by(tmp_path, "points", str(table), "-o", str(tmp_path / "points.csv"))
    assert (tmp_path / "points.csv").is_file()
    assert "tromplab.loading.node_balance" in loaded
    assert _heavy(loaded, ("statsmodels", "statsmodels.api", "lmfit", "matplotlib")) == []


def test_scipy_sparse_is_imported_on_the_first_use_of_one_of_its_names():
    import scipy.sparse

    assert linear_algebra.sparse.csr_matrix is scipy.sparse.csr_matrix


def test_the_module_answers_pythons_own_questions_without_importing_scipy():
    done = subprocess.run(
        [sys.executable, "-c", "import sys, tromplab.circuit.linear_algebra as m; "
         "print(hasattr(m, '__path__'), hasattr(m.sparse, '__deepcopy__'), 'scipy.linalg' in sys.modules, 'scipy.sparse' in sys.modules)"],
        capture_output=True, text=True, check=True, env={**os.environ, "PYTHONPATH": str(ROOT)},
    )  # fmt: skip
    assert done.stdout.split() == ["False", "False", "False", "False"]
