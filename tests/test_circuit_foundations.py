"""The circuit on the library's foundations: the lab reader's class strings and size units, the
registry's curves, the defaults of tromplab.options, figures without pyplot state, and the
command line's defaults and ranges from the same declarations as the Python API."""

import numpy as np
import pandas as pd
import pytest

from tromplab import options
from tromplab.circuit import ErrorModel, read_flowsheet, read_survey, reconcile, reconcile_circuit
from tromplab.circuit.simulation import plitt_partition_to_fines
from tromplab.cli import build_parser
from tromplab.curves.formulas import get_formula
from tromplab.errors import InputError
from tromplab.loading.lab import read_lab

from .conftest import write

CYCLONE = "stream,from,to,product\nfeed,,cyclone,\noverflow,cyclone,,fine\nunderflow,cyclone,,coarse\n"
CLASSES = ["+100", "-100+50", "-50+0"]
SHARES = {"feed": [20, 30, 50], "fine": [5, 25, 70], "coarse": [35, 35, 30]}


def test_survey_and_lab_tables_read_class_strings_and_units_alike(tmp_path):
    """The same class strings (the pan written "-50+0") and the same size_unit column give the
    same classes through the lab reader and the survey reader."""
    lab = pd.DataFrame({"size_class": CLASSES, "size_unit": "um", **{f"{k}_pct": v for k, v in SHARES.items()}})
    lab_classes = read_lab(lab)[0].classes
    survey = pd.concat(
        [pd.DataFrame({"stream": name, "size_class": CLASSES, "size_unit": "um", "retained_pct": SHARES[key]})
         for name, key in (("feed", "feed"), ("overflow", "fine"), ("underflow", "coarse"))], ignore_index=True,
    )  # fmt: skip
    read = read_survey(survey, read_flowsheet(write(tmp_path, CYCLONE, "sheet.csv")))
    np.testing.assert_array_equal(read.classes["size_lower"], lab_classes["size_lower"])
    np.testing.assert_array_equal(read.classes["size_upper"], lab_classes["size_upper"])
    assert read.size_unit == "um"
    lone = survey.assign(size_class=survey["size_class"].replace({"-50+0": "+0"}))
    with pytest.raises(InputError, match="neither a lower nor an upper bound"):  # the lab reader's words
        read_survey(lone, read_flowsheet(write(tmp_path, CYCLONE, "sheet.csv")))
    with pytest.raises(InputError, match="contradicts"):  # a unit column against the --size-unit option
        read_survey(survey, read_flowsheet(write(tmp_path, CYCLONE, "sheet.csv")), size_unit="mm")


def test_the_simulated_separators_follow_the_registry_curve_of_plitt_1976():
    size = np.geomspace(10.0, 1000.0, 25)
    expected = (1.0 - 0.2) * np.exp(-np.log(2.0) * (size / 110.0) ** 2.5)  # Plitt (1976) corrected curve, bypass 0.2
    np.testing.assert_allclose(plitt_partition_to_fines(size, 110.0, 2.5, bypass=0.2), expected, rtol=1e-14)
    assert "Plitt" in get_formula("rosin_rammler_bypass").citation


def test_the_error_model_and_the_command_line_take_their_defaults_from_options():
    model = ErrorModel()
    assert (model.relative_error, model.absolute_error) == (options.DEFAULT_RELATIVE_ERROR, options.DEFAULT_ABSOLUTE_ERROR)
    assert (model.flow_relative_error, model.pct_solids_sd) == (
        options.DEFAULT_FLOW_RELATIVE_ERROR,
        options.DEFAULT_PCT_SOLIDS_SD,
    )
    args = build_parser().parse_args(["circuit", "sheet.csv", "survey.csv"])
    assert (args.relative_error, args.absolute_error, args.flow_relative_error, args.pct_solids_sd, args.alpha) == (
        model.relative_error, model.absolute_error, model.flow_relative_error, model.pct_solids_sd, options.DEFAULT_ALPHA
    )  # fmt: skip


@pytest.mark.parametrize(
    "flag, value", [("--flow-relative-error", "0"), ("--flow-relative-error", "2"), ("--pct-solids-sd", "1e3"), ("--alpha", "1")]
)
def test_out_of_range_error_model_options_are_usage_errors(flag, value, capsys):
    with pytest.raises(SystemExit) as stop:
        build_parser().parse_args(["circuit", "sheet.csv", "survey.csv", flag, value])
    assert stop.value.code == 2 and flag in capsys.readouterr().err


@pytest.mark.slow
def test_the_figures_are_drawn_without_pyplot_state(tmp_path):
    import matplotlib.pyplot as plt

    before = plt.get_fignums()
    table = pd.concat(
        [pd.DataFrame({"stream": name, "size_class_um": CLASSES, "retained_pct": SHARES[key]})
         for name, key in (("feed", "feed"), ("overflow", "fine"), ("underflow", "coarse"))], ignore_index=True,
    )  # fmt: skip
    table.to_csv(tmp_path / "survey.csv", index=False)
    run = reconcile_circuit(write(tmp_path, CYCLONE, "sheet.csv"), tmp_path / "survey.csv")
    run.save(tmp_path / "out")
    assert plt.get_fignums() == before
    assert {"flowsheet.png", "adjustments.png", "distributions.png"} <= {p.name for p in (tmp_path / "out").iterdir()}
    assert run.balance.dof == 1


def test_one_rank_decision_serves_the_redundancy_the_covariance_and_the_tests(tmp_path):
    table = pd.concat(
        [pd.DataFrame({"stream": name, "size_class_um": CLASSES, "retained_pct": SHARES[key]})
         for name, key in (("feed", "feed"), ("overflow", "fine"), ("underflow", "coarse"))], ignore_index=True,
    )  # fmt: skip
    balance = reconcile(read_flowsheet(write(tmp_path, CYCLONE, "sheet.csv")), table)
    decomposition = balance.decomposition
    assert balance.dof == balance.problem.W.shape[0] - decomposition.rank
    z_covariance = balance.problem.N.T @ balance.covariance @ balance.problem.N
    assert np.linalg.matrix_rank(z_covariance, tol=1e-9 * np.abs(z_covariance).max()) == decomposition.rank
