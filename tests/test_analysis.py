"""Each analysis script runs on its default input and writes what it says."""

import subprocess
import sys

import pandas as pd
import pytest

from tromplab.reproduce import compare_printed, printed_unit, sieve_checks

from .conftest import ROOT

SCRIPTS = {
    "sieve_published_checks.py": ["sieve_published_checks.csv"],
    "shuvalov2018_table3.py": ["table3_printed_marks.csv"],
    "sieve_operating_point.py": ["sieve_pareto.csv", "sieve_pareto.png"],
    "shuvalov2018_figures.py": [
        "fig1_equal_slope_-0.5.png",
        "fig2_equal_slope_-0.4.png",
        "fig3_ks_kf.png",
        "table2_F_heatmap.png",
        "table3_ranking.png",
    ],
    "sieve_figures.py": ["sieve_pg_family.png", "sieve_residue_efficiency.png", "sieve_distance_densities.png"],
}


@pytest.mark.parametrize("script", sorted(SCRIPTS))
@pytest.mark.slow
def test_script_runs_and_writes_its_tables(tmp_path, script):
    done = subprocess.run(
        [sys.executable, str(ROOT / "analysis" / script), "--outdir", str(tmp_path)], capture_output=True, text=True, check=True
    )
    for name in SCRIPTS[script]:
        assert (tmp_path / name).exists()
        assert str(tmp_path / name) in done.stdout


@pytest.mark.slow
def test_table3_script_marks_exactly_the_known_differences(tmp_path):
    subprocess.run(
        [sys.executable, str(ROOT / "analysis" / "shuvalov2018_table3.py"), "--outdir", str(tmp_path)],
        check=True,
        capture_output=True,
    )
    table = pd.read_csv(tmp_path / "table3_printed_marks.csv", keep_default_na=False).set_index("equation")
    marked = {eq: text for eq, text in table["differences"].items() if text}
    assert marked == {8: "rank in exp. 6; points", 10: "points", 11: "points"}


def test_sieve_checks_reproduce_what_the_spec_says():
    checks = sieve_checks().set_index("quantity")
    verdicts = checks.groupby("agreement").groups
    assert set(verdicts["agrees"]) == {
        "P_v fraction 1 at Va = 0.287 m/s",
        "P_v fraction 2 at Va = 0.287 m/s",
        "gamma_1^1 at the corrected speed",
        "C, 1/m^2",
        "x1, normal approximation, m",
    }
    assert set(verdicts["last digit"]) == {
        "P_g (D 2, cell 3.2 x 3.2 mm, d/l 0.5, l 2.2 mm)",
        "E at the corrected speed, %",
        "Q at the corrected speed, kg/h",
        "x1, exact, m",
    }
    assert checks.loc["E at the corrected speed, %", "computed"] == pytest.approx(89.64, abs=0.01)
    assert checks.loc["E = g (1 - S), %", "computed"] == pytest.approx(80.64)


@pytest.mark.parametrize(
    "printed, unit",
    [
        ("0.150", 1e-3),
        ("0.15", 1e-2),
        ("2.8e-2", 1e-3),
        ("1340", 10.0),
        ("1500", 100.0),
        ("81.5", 0.1),
        ("7", 1.0),
        ("120.", 1.0),
    ],
)
def test_printed_unit_is_read_from_the_printed_digits(printed, unit):
    assert printed_unit(printed) == pytest.approx(unit)


@pytest.mark.parametrize(
    "printed, computed, verdict",
    [
        ("0.150", 0.15049, "agrees"),
        ("0.150", 0.1511, "last digit"),
        ("0.15", 0.1511, "agrees"),
        ("0.150", 0.1516, "differs"),
        ("1340", 1332.3, "last digit"),
        ("1490", 1471.8, "differs"),
        ("0.00321", 0.0032103, "agrees"),
    ],
)
def test_compare_printed_rounds_to_the_printed_digits(printed, computed, verdict):
    assert compare_printed(printed, computed)[0] == verdict
