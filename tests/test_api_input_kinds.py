"""The Python API takes the input kinds it documents and refuses the rest cleanly: a
``TypeError`` saying what is accepted, or an ``InputError`` naming the argument; never an
``AttributeError`` or numpy's own message."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import tromplab
from tromplab import TrompPoints, fit_experiments, read_experiments
from tromplab.errors import InputError

from .hostile_names import SIZES, partitions, points_rows

NAMES = ["002", "2", "NA"]
FLOWSHEET = Path(__file__).resolve().parent.parent / "datasets" / "circuit_example_flowsheet.csv"
FORMULAS = ["plitt", "lognormal"]


def _points(name: str, shift: int) -> TrompPoints:
    return TrompPoints(name, list(SIZES), partitions(shift))


def _frame() -> pd.DataFrame:
    return pd.DataFrame(points_rows(NAMES))


def _as_path(tmp_path: Path) -> Path:
    path = tmp_path / "points.csv"
    _frame().to_csv(path, index=False)
    return path


def _dask(tmp_path: Path):
    dataframe = pytest.importorskip("dask.dataframe")
    return dataframe.from_pandas(_frame(), npartitions=2)


INPUT_KINDS = {
    "path (str)": lambda tmp: str(_as_path(tmp)),
    "path (Path)": _as_path,
    "pandas DataFrame": lambda tmp: _frame(),
    "Dask DataFrame": _dask,
    "read_experiments": lambda tmp: read_experiments(_as_path(tmp)),
    "mapping of TrompPoints": lambda tmp: {name: _points("renamed", i) for i, name in enumerate(NAMES)},
    "mapping of DataFrames": lambda tmp: {
        name: pd.DataFrame({"size": SIZES, "partition_fine": partitions(i)}) for i, name in enumerate(NAMES)
    },
    "mapping of pairs": lambda tmp: {name: (list(SIZES), partitions(i)) for i, name in enumerate(NAMES)},
    "list of TrompPoints": lambda tmp: [_points(name, i) for i, name in enumerate(NAMES)],
    "tuple of TrompPoints": lambda tmp: tuple(_points(name, i) for i, name in enumerate(NAMES)),
    "generator of TrompPoints": lambda tmp: (_points(name, i) for i, name in enumerate(NAMES)),
}


@pytest.fixture(scope="module")
def reference():
    return fit_experiments([_points(name, i) for i, name in enumerate(NAMES)], formulas=FORMULAS).fits_table()


@pytest.mark.parametrize("kind", INPUT_KINDS)
def test_every_documented_input_kind_fits_the_same_experiments(tmp_path, kind, reference):
    bench = fit_experiments(INPUT_KINDS[kind](tmp_path), formulas=FORMULAS)
    assert bench.experiments == NAMES
    fits = bench.fits_table()
    np.testing.assert_allclose(fits["d_cut"].to_numpy(), reference["d_cut"].to_numpy(), rtol=1e-9)


@pytest.mark.parametrize(
    "experiments",
    [
        [_points("A", 0), _points("B", 1), _points("A", 2)],
        read_experiments(_frame())._replace(points=[_points("A", 0), _points("A", 1)]),
    ],
    ids=["list", "Experiments"],
)
def test_two_experiments_of_one_name_are_refused_naming_it(experiments):
    with pytest.raises(InputError, match="two experiments are named 'A'"):
        fit_experiments(experiments, formulas=FORMULAS)


@pytest.mark.parametrize("empty", [[], (), {}, (p for p in ()), read_experiments(_frame())._replace(points=[])])
def test_an_empty_input_is_refused(empty):
    with pytest.raises(InputError, match="no experiment to fit"):
        fit_experiments(empty, formulas=FORMULAS)


@pytest.mark.parametrize(
    "experiments, said",
    [
        (None, "got NoneType"),
        (3, "got int"),
        (2.5, "got float"),
        (b"points.csv", "got bytes"),
        (["a", "b"], r"experiments\[0\] is a str, not a TrompPoints"),
        ([[10, 20], [0.9]], r"experiments\[0\] is a list, not a TrompPoints"),
        ([_points("A", 0), {"size": [1]}], r"experiments\[1\] is a dict"),
        ({"A": 1.5}, r"experiments\['A'\] is a float"),
        ({"A": "points.csv"}, r"experiments\['A'\] is a str"),
        ({1: _points("A", 0)}, "names of a mapping of experiments are text"),
    ],
)
def test_anything_else_is_a_type_error_that_says_what_is_accepted(experiments, said):
    with pytest.raises(TypeError, match=said) as caught:
        fit_experiments(experiments, formulas=FORMULAS)
    assert "TrompPoints" in str(caught.value)


def test_a_mapping_with_bad_points_names_the_experiment():
    with pytest.raises(InputError, match=r"experiments\['A'\].*size.*flat sequence of numbers"):
        fit_experiments({"A": ([[1, 2], [3]], [0.5, 0.4])}, formulas=FORMULAS)


# --- every public entry point, given the wrong kind of argument --------------------------
BAD_ARGUMENTS = {
    "None": None,
    "strings": ["a", "b"],
    "ragged": [[1, 2], [3]],
    "dict of floats": {"a": 1.5},
    "number": 3,
    "empty list": [],
}
_POINTS = _points("run", 0)


def _fit():
    return tromplab.fit_formula(_POINTS, "plitt")


ENTRY_POINTS = {
    "read_points": lambda bad: tromplab.read_points(bad),
    "read_lab": lambda bad: tromplab.read_lab(bad),
    "read_experiments": lambda bad: tromplab.read_experiments(bad),
    "TrompPoints(size)": lambda bad: TrompPoints("x", bad, [0.5, 0.4]),
    "TrompPoints(partition_fine)": lambda bad: TrompPoints("x", [10, 20], bad),
    "TrompPoints(weight)": lambda bad: TrompPoints("x", [10, 20], [0.5, 0.4], weight=bad),
    "TrompPoints(experiment)": lambda bad: TrompPoints(bad, [10, 20], [0.5, 0.4]),
    "get_formula": lambda bad: tromplab.get_formula(bad),
    "fit_formula(points)": lambda bad: tromplab.fit_formula(bad, "plitt"),
    "fit_formula(formula)": lambda bad: tromplab.fit_formula(_POINTS, bad),
    "fit_experiments": lambda bad: fit_experiments(bad, formulas=FORMULAS),
    "curve_indices(d_cut)": lambda bad: tromplab.curve_indices("plitt", bad, 2.0, delta_max=500.0),
    "curve_indices(shape)": lambda bad: tromplab.curve_indices("plitt", 100.0, bad, delta_max=500.0),
    "rank_formulas": lambda bad: tromplab.rank_formulas(bad),
    "interval_table": lambda bad: tromplab.interval_table(bad),
    "bootstrap": lambda bad: tromplab.bootstrap(bad, n=3),
    "akaike_weights": lambda bad: tromplab.akaike_weights(bad),
    "model_average": lambda bad: tromplab.model_average(bad),
    "model_averages": lambda bad: tromplab.model_averages(bad),
    "shared_fit": lambda bad: tromplab.shared_fit(bad, "plitt"),
    "nested_f_test(reduced)": lambda bad: tromplab.nested_f_test(bad, _fit()),
    "nested_f_test(full)": lambda bad: tromplab.nested_f_test(_fit(), bad),
    "build_report": lambda bad: tromplab.build_report(bad, [], source="x"),
    "write_report": lambda bad: tromplab.write_report(bad, "report.html"),
    "load": lambda bad: tromplab.load(bad),
    "fit_density": lambda bad: tromplab.fit_density(bad),
    "predict_density": lambda bad: tromplab.predict_density(bad, rho50=1.5, ep=0.05),
    "reconcile_circuit(flowsheet)": lambda bad: tromplab.reconcile_circuit(bad, "survey.csv"),
    "reconcile_circuit(measurements)": lambda bad: tromplab.reconcile_circuit(FLOWSHEET, bad),
    "design_circuit": lambda bad: tromplab.design_circuit(bad),
    "monitor_surveys": lambda bad: tromplab.monitor_surveys(bad),
}
#: Arguments an entry point takes as they are: an empty list of criteria has no weights, no
#: weights is a weight of None, 3 is equation (3) and a size.
ACCEPTED = {
    ("akaike_weights", "empty list"),
    ("TrompPoints(weight)", "None"),
    ("get_formula", "number"),
    ("fit_formula(formula)", "number"),
    ("curve_indices(d_cut)", "number"),
    ("curve_indices(shape)", "number"),
}


@pytest.mark.parametrize("bad", BAD_ARGUMENTS)
@pytest.mark.parametrize("entry", ENTRY_POINTS)
def test_a_public_function_refuses_a_wrong_kind_cleanly(entry, bad, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    if (entry, bad) in ACCEPTED:
        ENTRY_POINTS[entry](BAD_ARGUMENTS[bad])
        return
    with pytest.raises((TypeError, InputError)) as caught:
        ENTRY_POINTS[entry](BAD_ARGUMENTS[bad])
    message = str(caught.value)
    assert message and "object has no attribute" not in message
    assert "could not convert" not in message and "inhomogeneous" not in message  # numpy's words
    assert not list(tmp_path.iterdir())  # nothing written


def test_every_public_function_taking_data_is_in_the_table():
    """A new public entry point must join the table above (or be listed here as taking no data)."""
    no_data = {"__version__", "FORMULAS", "ALL_FORMULAS", "Formula", "Parameter", "registry_table", "select_formulas"}
    no_data |= {"LabOptions", "MassBalance", "InputError", "CurveFit", "Workbench"}  # records, built by the functions above
    covered = {name.split("(")[0] for name in ENTRY_POINTS}
    assert set(tromplab.__all__) - no_data == covered
