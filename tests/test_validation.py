"""One validation layer for the command line and the Python API: every numeric option states
its range, the API refuses what the parser refuses in the same words, and results that leave
their ranges are failures, not results."""

import argparse
from dataclasses import replace

import numpy as np
import pytest
from scipy import integrate

from tromplab import TrompPoints, fit_experiments
from tromplab.cli import build_parser, main
from tromplab.curves.curve_fit import as_failure_if_implausible, fit_formula, implausible_result
from tromplab.curves.formulas import plitt_efficiency
from tromplab.errors import InputError, OptionError
from tromplab.statistics.compare import shared_fit
from tromplab.validation import check_count, check_probability, check_range, check_size, cli_type, range_text

from .test_hostile_cli import CURVE, points_file

POINTS = [TrompPoints("run", [10, 20, 40, 80, 160], [0.98, 0.91, 0.62, 0.21, 0.04])]


def _options(parser, command=("tromplab",)):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _options(sub, (*command, name))
        elif action.option_strings:
            yield " ".join(command), action


def test_every_numeric_option_is_checked_and_states_its_range_in_its_help():
    seen = 0
    for command, action in _options(build_parser()):
        if action.type in (int, float):  # a bare conversion checks no range
            pytest.fail(f"{command} {action.option_strings[0]} converts without a range check")
        if getattr(action.type, "range", None):
            seen += 1
            assert f"(range {action.type.range})" in action.help or action.type.range in action.help, (
                command,
                action.option_strings,
            )
    assert seen >= 60  # fit, report, points, balance, sieve, rank, trend, layer, pulp, optimize, circuit


@pytest.mark.parametrize(
    "keywords, words",
    [
        ({"formulas": []}, "formulas names no formula"),
        ({"jobs": -3}, "jobs must be a whole number >= 0, got -3"),
        ({"jobs": 2.5}, "jobs takes a whole number, got 2.5"),
        ({"alpha": "0.05"}, "alpha takes a number, got the text '0.05'"),
        ({"alpha": True}, "alpha takes a number, got True"),
        ({"alpha": 0.05 + 0j}, "alpha takes a real number"),
        ({"seed": "1"}, "seed takes a whole number, got the text '1'"),
        ({"delta_max": 1e300}, "delta_max must lie in [1e-250, 1e+250], got 1e+300"),
        ({"delta_max": 1e200}, "delta_max of 1e+200 is more than 1e+09 times the smallest size of the data (10)"),
    ],
)
def test_the_api_refuses_bad_arguments_naming_them(keywords, words):
    with pytest.raises(OptionError) as caught:
        fit_experiments(POINTS, **keywords)
    assert words in str(caught.value)


def test_the_command_line_refuses_the_same_values_in_the_same_words(tmp_path, capsys):
    path = points_file(tmp_path, {"A": CURVE})
    assert main(["fit", str(path), "-o", str(tmp_path / "out"), "--jobs", "-3"]) == 2
    assert "argument --jobs: must be a whole number >= 0, got -3" in capsys.readouterr().err
    assert main(["fit", str(path), "-o", str(tmp_path / "out"), "--delta-max", "1e300"]) == 2
    assert "argument --delta-max: must lie in [1e-250, 1e+250], got 1e+300" in capsys.readouterr().err
    assert main(["fit", str(path), "-o", str(tmp_path / "out"), "--delta-max", "1e200"]) == 2  # after reading the sizes
    assert "--delta-max of 1e+200 is more than 1e+09 times the smallest size" in capsys.readouterr().err
    assert main(["fit", str(path), "-o", str(tmp_path / "out"), "--alpha", "x"]) == 2
    assert "argument --alpha: takes a number, got 'x'" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_cli_types_parse_text_the_checks_refuse_text():
    parse = cli_type(check_count, "--steps", maximum=10)
    assert parse("7") == 7 and parse("7.0") == 7
    with pytest.raises(argparse.ArgumentTypeError, match="is capped at 10"):
        parse("1e12")
    with pytest.raises(OptionError, match="got the text"):
        check_probability("0.5", "alpha")
    assert range_text(check_range, low=0.0, high=1e4, low_open=True, unit="1/s") == "(0, 10,000] 1/s"
    assert range_text(check_size) == "[1e-250, 1e+250]"


@pytest.mark.parametrize("ks", [1.001, 1.5, 3.0, 30.0, 60.0])
@pytest.mark.parametrize("x_max", [10.0, 1e6, 1e11, 1e100])
def test_plitt_misplacement_stays_right_where_x_to_the_ks_overflows(ks, x_max):
    """eps of (7) against quadrature in ln x (a power x^ks above 1e308 gave eps = -eta)."""
    _, eps = plitt_efficiency(np.array([ks]), np.array([x_max]))

    def integrand(t):
        return np.exp(t) / (1 + np.exp(min(ks * t, 700.0)))

    reference, _ = integrate.quad(integrand, 0.0, np.log(x_max), limit=2000, epsabs=1e-15, epsrel=1e-13)
    assert float(eps[0]) == pytest.approx(reference, rel=1e-11)


def test_a_result_outside_its_range_turns_the_fit_into_a_failure():
    fit = fit_formula(POINTS[0], "plitt")
    assert implausible_result(fit) == ""
    fit.__dict__["indices"] = replace(fit.indices, epsilon=-0.5)  # what an overflowing integral gave
    assert "epsilon = -0.5 is outside its range" in implausible_result(fit)
    failed = as_failure_if_implausible(fit)
    assert not failed.success and "epsilon = -0.5" in failed.message
    fit.__dict__["indices"] = replace(fit.indices, epsilon=0.3, eta=float("nan"))
    assert "eta = nan" in implausible_result(fit)


def test_compare_refuses_an_experiment_named_twice(tmp_path, capsys):
    path = points_file(tmp_path, {"A": CURVE, "B": CURVE})
    assert main(["compare", str(path), "--experiments", "A,A"]) == 2
    assert "--experiments names A more than once" in capsys.readouterr().err
    with pytest.raises(InputError, match="'run' given more than once"):
        shared_fit([POINTS[0], POINTS[0]], "plitt")


@pytest.mark.parametrize(
    "argv, code, words",
    [
        (["trend", "x.csv", "--alpha", "2"], 2, "argument --alpha: must lie strictly between 0 and 1, got 2"),
        (["pulp", "optimum", "--frequency", "1e300"], 2, "argument --frequency: must lie in [0.001, 10,000] 1/s"),
        (["pulp", "optimum", "--frequency", "10", "--tau", "1e300"], 2, "argument --tau: must lie in (0, 5]"),
        (["pulp", "optimum", "--applied", "0"], 2, "--applied 0 with --phi 0 leaves no pressure drop"),
        (["sieve", "pg", "--hole", "1e300", "--length", "1", "--width", "1", "--cell-width", "3"], 2, "--hole: must lie in"),
        (["sieve", "bin", "--decks", "1", "--length", "1", "--recovery", "0.999999999999999"], 3, "normal: the bin position"),
        (["optimize", "--bulk-density", "1e300"], 2, "argument --bulk-density: must lie in [1, 25,000] kg/m^3"),
        (["layer", "simulate", "--step-seconds", "1e308"], 2, "argument --step-seconds: must lie in [1e-06, 3,600] s"),
    ],
)
def test_model_commands_refuse_values_the_arithmetic_cannot_carry(capsys, argv, code, words):
    assert main(argv) == code
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err and "nan" not in err


@pytest.mark.parametrize(
    "arrays, words",
    [
        (([10, 20, 30], [0.9 + 1j, 0.5, 0.1]), "column 'partition_fine': takes real numbers, got complex ones"),
        (([[10, 20], [30]], [0.9, 0.5, 0.1]), "column 'size': takes one flat sequence of numbers, got a ragged nesting"),
        (([[10, 20], [30, 40]], [0.9, 0.5]), "column 'size': takes one flat sequence of numbers, got an array of shape (2, 2)"),
        (([10, 20, 30], ["a", 0.5, 0.1]), "column 'partition_fine': takes numbers, got 'a'"),
        (([10, 20, 30], [0.9, float("nan"), 0.1]), "column 'partition_fine': value nan at point 2 is not a finite number"),
    ],
)
def test_points_refuse_complex_ragged_and_text_arrays_naming_the_column(arrays, words):
    with pytest.raises(InputError) as caught:
        TrompPoints("r", *arrays)
    assert words in str(caught.value)


@pytest.mark.parametrize(
    "arguments, words",
    [
        (([0.5, 0.5], [0.6, 0.4], [0.4, 0.6], 1.5), "fine_yield must lie strictly between 0 and 1, got 1.5"),
        (([0.5, float("nan")], [0.6, 0.4], [0.4, 0.6], 0.5), "feed takes finite shares >= 0, got nan in class 2"),
        (([0.5, 0.5], [0.6, 0.4 + 1j], [0.4, 0.6], 0.5), "fine takes one real share per class"),
        (([0.5, 0.5], [0.6], [0.4, 0.6], 0.5), "feed, fine and coarse take one share per class each, got 2, 1, 2"),
    ],
)
def test_reconciliation_and_partition_refuse_implausible_shares_and_yields(arguments, words):
    from tromplab.loading.lab import partition_to_fines, reconcile

    for function in (reconcile, partition_to_fines):
        with pytest.raises(OptionError) as caught:
            function(*arguments)
        assert words in str(caught.value)


def test_public_functions_say_what_they_take():
    from tromplab import model_averages, rank_formulas, write_report

    for call, words in [
        (lambda: rank_formulas("abc"), "table must be a pandas DataFrame"),
        (lambda: write_report(None, "x.html"), "report must be a Report"),
        (lambda: model_averages(None), "bench must be a Workbench"),
    ]:
        with pytest.raises(TypeError, match=words):
            call()


def _with_cell(tmp_path, dataset, column, value, name):
    from .conftest import DATASETS

    lines = [line for line in (DATASETS / dataset).read_text().splitlines() if not line.startswith("#")]
    header = lines[0].split(",")
    cells = lines[1].split(",")
    cells[header.index(column)] = value
    path = tmp_path / name
    path.write_text("\n".join([lines[0], ",".join(cells), *lines[2:]]) + "\n")
    return path


@pytest.mark.parametrize(
    "command, dataset, column, value, words",
    [
        (["sieve", "identify"], "sieve_identify_residues_example.csv", "relative_speed", "-0.5", "relative_speed -0.5 must lie in (0, 1000]"),
        (["sieve", "identify"], "sieve_identify_residues_example.csv", "relative_speed", "1e308", "relative_speed 1e+308 must lie"),
        (["pulp", "fit"], "pulp_screen_productivity_example.csv", "productivity", "1e308", "productivity 1e+308 must lie in (0, 1e+09]"),
        (["pulp", "fit"], "pulp_screen_productivity_example.csv", "frequency", "1e300", "frequency 1e+300 must lie in [0.001, 10000]"),
    ],
)  # fmt: skip
def test_implausible_model_data_are_refused_naming_row_and_column(tmp_path, capsys, command, dataset, column, value, words):
    path = _with_cell(tmp_path, dataset, column, value, "data.csv")
    out = tmp_path / "out.csv"
    assert main([*command, str(path), "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert f"row 2, column '{column}': {words}" in err and f"tromplab {' '.join(command)}: error" in err
    assert not out.exists()


@pytest.mark.parametrize("rows", [1, 2, 3])
def test_a_layer_table_of_too_few_rows_is_bad_input(tmp_path, capsys, rows):
    path = tmp_path / "layer.csv"
    path.write_text("step,extraction\n" + "".join(f"{50 * (i + 1)},{0.3 + 0.1 * i}\n" for i in range(rows)))
    assert main(["layer", "fit", str(path)]) == 1
    assert f"{rows} point(s): the layer fit needs at least four" in capsys.readouterr().err
