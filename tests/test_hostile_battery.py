"""The hostile-input battery: every case of tests/hostile_catalogue.py over every command and
API entry point ends in the outcome the catalogue states, and only in the documented ones.

For the command line: an exit code of 0, 1, 2 or 3 (130 and 143 for the signals), the one
expected; no traceback; a refusal (1, 2) names what is wrong and writes nothing; a result
(0, 3) has every index inside its range (docs/columns.md) and prints no nan as a number of a
model command.  For the API: the expected exception, naming the argument, or a result.
"""

import argparse
import math
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pandas as pd
import pytest

from tromplab.cli import main
from tromplab.curves.formulas import get_formula

from .hostile_catalogue import FIT, catalogue, option_boundaries, points_text

CASES = catalogue()
CLI_CASES = [c for c in CASES if c.call is None]
API_CASES = [c for c in CASES if c.call is not None]
DOCUMENTED_EXITS = {0, 1, 2, 3, 130, 143}
#: Slack of the range checks on written numbers (CSV rounding of a value on its bound).
SLACK = 1e-9


def _ids(cases):
    return [f"{c.family}: {c.id}" for c in cases]


def _marks(c):
    marks = [pytest.mark.slow] if c.slow else []
    if c.known:
        marks.append(pytest.mark.xfail(reason=c.known, strict=True))
    return pytest.param(c, marks=marks)


def _write_inputs(case, folder) -> dict[str, str]:
    paths = {}
    for name, content in case.files.items():
        path = folder / name
        if callable(content):
            content(path)
        elif isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content, encoding="utf-8")
        paths[name] = str(path)
    return paths


def _argv(case, folder, paths) -> list[str]:
    argv = []
    for part in case.argv:
        for name, path in paths.items():
            part = part.replace("{" + name + "}", path)
        argv.append(part.replace("{tmp}", str(folder)))
    return argv


def _files_under(folder) -> set:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


def _inside(values, low, high, what):
    values = pd.to_numeric(values, errors="coerce").dropna().to_numpy(dtype=float)
    assert np.isfinite(values).all(), f"{what}: not finite {values[~np.isfinite(values)][:3]}"
    outside = values[(values < low - SLACK) | (values > high + SLACK)]
    assert outside.size == 0, f"{what}: {outside[:3]} outside [{low}, {high}]"


#: Ranges of the quantities whose intervals fits.csv holds (docs/columns.md, docs/uncertainty.md).
INTERVAL_RANGES = {
    "d_cut": (0.0, math.inf),
    "d50": (0.0, math.inf),
    "d50c": (0.0, math.inf),
    "ep": (0.0, math.inf),
    "eta": (0.0, 1.0),
    "epsilon": (0.0, math.inf),
    "bypass": (0.0, 1.0),
}


def check_fits_table(path) -> None:
    """Every number of a fits.csv inside the range docs/columns.md gives it."""
    fits = pd.read_csv(path, keep_default_na=False, na_values=[""])
    done = fits[fits["success"].astype(str).str.lower() == "true"]
    for column in ("d_cut", "d50", "d50c", "d25", "d75", "ep", "ep_c", "imperfection"):
        if column in done:
            _inside(done[column], 0.0, math.inf, column)
            assert (pd.to_numeric(done[column], errors="coerce").dropna() > 0).all(), column
    for column in ("eta", "runs_p", "normality_p", "nested_p", "bypass"):
        if column in done:
            _inside(done[column], 0.0, 1.0, column)
    for column in ("epsilon", "ssr", "F_crit", "d_cut_stderr", "shape_stderr"):
        if column in done:
            _inside(done[column], 0.0, math.inf, column)
    # inf where documented: F of a curve through every point, AICc of too few points
    for column, why in (("F", done["F"]), ("delta_aicc", done["aicc"])):
        infinite = pd.to_numeric(why, errors="coerce") == math.inf
        _inside(done.loc[~infinite, column], 0.0, math.inf, column)
    _inside(done["slope"], -math.inf, 0.0, "slope")
    for row in done.itertuples(index=False):
        low, high = get_formula(row.formula).shape_bounds
        assert low - SLACK <= float(row.shape) <= high + SLACK, (row.formula, row.shape)
    ranked = pd.to_numeric(fits["rank"], errors="coerce").dropna()
    per_experiment = fits.groupby("experiment")["formula"].nunique().max()
    _inside(ranked, 1.0, float(per_experiment), "rank")
    for quantity, (low, high) in INTERVAL_RANGES.items():  # intervals stay in the quantity's range
        for column in [c for c in fits.columns if c.startswith(quantity + "_") and c.endswith(("_low", "_high"))]:
            _inside(fits[column], low, high, column)
    for column in [c for c in fits.columns if c.endswith("_low")]:
        quantity, high = column[: -len("_low")], column[: -len("_low")] + "_high"
        if high in fits and quantity in fits:
            rows = fits[[column, quantity, high]].apply(pd.to_numeric, errors="coerce").dropna()
            assert (rows[column] <= rows[quantity] * (1 + 1e-9) + SLACK).all(), column
            assert (rows[quantity] <= rows[high] * (1 + 1e-9) + SLACK).all(), high


def check_averages_table(path) -> None:
    averages = pd.read_csv(path)
    for quantity, (low, high) in {"eta": (0.0, 1.0), "d50": (0.0, math.inf), "d50c": (0.0, math.inf)}.items():
        rows = averages[averages["quantity"] == quantity]
        for column in ("value", "low", "high"):
            _inside(rows[column], low, high, f"averages {quantity} {column}")
    _inside(averages["akaike_share"], 0.0, 1.0, "akaike_share")


def check_points_table(path) -> None:
    points = pd.read_csv(path, comment="#")
    size = next(c for c in points.columns if c.startswith("size"))
    partition = next(c for c in points.columns if c.startswith("partition_"))
    _inside(points[size], 0.0, math.inf, "size")
    _inside(points[partition], 0.0, 1.0, "partition")


def check_trend_table(path) -> None:
    trend = pd.read_csv(path)
    for quantity, (low, high) in {
        "eta": (0.0, 1.0),
        "bypass": (0.0, 1.0),
        "d_cut": (0.0, math.inf),
        "ep": (0.0, math.inf),
    }.items():
        rows = trend[trend["quantity"] == quantity]
        for column in ("value", "low", "high"):
            _inside(rows[column], low, high, f"trend {quantity} {column}")
    for column in ("p_previous", "p_baseline"):
        _inside(trend[column], 0.0, 1.0, f"trend {column}")


def check_circuit_tables(folder) -> None:
    """Reconciled flows and water not negative; partitions written as measured inside 0..1."""
    flows = pd.read_csv(folder / "flows.csv")
    _inside(flows["reconciled"], 0.0, math.inf, "reconciled solids flow")
    if (folder / "water.csv").is_file():
        water = pd.read_csv(folder / "water.csv")
        for column in [c for c in ("water_flow", "pct_solids") if c in water]:
            _inside(water[column], 0.0, math.inf if column == "water_flow" else 100.0, f"water {column}")
    partition = pd.read_csv(folder / "partition.csv")
    if not partition.empty:
        used = partition[partition["used"].astype(str).str.lower() == "true"]
        _inside(used["partition_fine"], 0.0, 1.0, "circuit partition")


def check_results(folder) -> None:
    for path in folder.rglob("flows.csv"):
        check_circuit_tables(path.parent)
    for path in folder.rglob("fits.csv"):
        check_fits_table(path)
    for path in folder.rglob("averages.csv"):
        check_averages_table(path)
    for path in folder.rglob("trend.csv"):
        check_trend_table(path)
    for path in list(folder.glob("pts.csv")) + list(folder.glob("sub/pts.csv")):
        check_points_table(path)


@pytest.mark.parametrize("case", [_marks(c) for c in CLI_CASES], ids=_ids(CLI_CASES))
@pytest.mark.slow
def test_every_hostile_command_line_ends_in_its_documented_outcome(case, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    paths = _write_inputs(case, tmp_path)
    before = _files_under(tmp_path)
    code = main(_argv(case, tmp_path, paths))
    captured = capsys.readouterr()
    assert code in DOCUMENTED_EXITS
    assert code in case.expect, f"exit {code}, expected {sorted(case.expect)}: {captured.err[-600:]}"
    assert "Traceback" not in captured.err and "internal error" not in captured.err
    if code in (1, 2):
        assert _files_under(tmp_path) == before, "a refused run wrote files"
        assert case.words in captured.err, captured.err
        assert "error" in captured.err
    else:
        check_results(tmp_path)
        if case.check is not None:
            case.check(tmp_path)
        if case.family == "model corners":
            assert "nan" not in captured.out.lower(), captured.out


@pytest.mark.parametrize("case", API_CASES, ids=_ids(API_CASES))
def test_every_hostile_api_call_ends_in_its_documented_outcome(case, tmp_path):
    try:
        case.call(tmp_path)
    except Exception as error:  # the outcome is the exception's class
        outcome, message = type(error).__name__, str(error)
    else:
        outcome, message = "ok", ""
    assert outcome in case.expect, f"{outcome}: {message}"
    assert case.words in message
    assert "Traceback" not in message and "np.str_" not in message


def test_every_value_inside_an_options_range_is_taken_by_the_parser():
    taken = 0
    for command, action, text in option_boundaries():
        value = action.type(text)
        assert not isinstance(value, str) and math.isfinite(float(value)), (command, action.option_strings, text)
        taken += 1
    assert taken >= 200


def test_the_battery_holds_at_least_300_cases_over_every_command():
    assert len(CASES) >= 300
    commands = {c.argv[0] for c in CLI_CASES}
    assert commands >= {
        "fit",
        "report",
        "compare",
        "trend",
        "points",
        "balance",
        "rank",
        "sieve",
        "layer",
        "pulp",
        "optimize",
        "circuit",
    }


# --- signals: a real process, a real signal ---------------------------------------------
def _as_in_a_terminal():
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.slow
@pytest.mark.parametrize("signum, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_signal_during_a_hostile_run_ends_in_its_exit_code_with_one_line(tmp_path, signum, code):
    points = tmp_path / "points.csv"
    points.write_text(points_text({f"E{k}": (0.97, 0.9, 0.7, 0.35, 0.1, 0.02) for k in range(30)}))
    argv = [part.replace("{points.csv}", str(points)).replace("{tmp}", str(tmp_path)) for part in FIT]
    script = "import sys; from tromplab._launch import main; sys.exit(main())"
    env = {**os.environ, "PYTHONPATH": str(os.path.dirname(os.path.dirname(__file__)))}
    process = subprocess.Popen(
        [sys.executable, "-c", script, *argv, "--bootstrap", "40"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        preexec_fn=_as_in_a_terminal,
    )
    time.sleep(1.0)
    process.send_signal(signum)
    assert process.wait(timeout=120) in (code, 0)
    err = process.stderr.read()
    assert "Traceback" not in err and len(err.strip().splitlines()) <= 1, err
    assert not list(tmp_path.glob(".out.tmp-*"))


def test_option_boundaries_are_probed_for_every_numeric_option():
    probed = {(command, action.option_strings[-1]) for command, action, _ in option_boundaries()}
    assert len(probed) >= 60
    assert all(isinstance(action, argparse.Action) for _, action, _ in option_boundaries())
