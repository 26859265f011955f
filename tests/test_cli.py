"""The command line: outputs of fit and rank, and bad input that stops with a clear message."""

import pandas as pd
import pytest

from tromplab.cli import main
from tromplab.curves.curve_fit import FIT_COLUMNS

from .conftest import DATASETS, TWO_EXPERIMENT_POINTS, write

GOOD = TWO_EXPERIMENT_POINTS


@pytest.mark.slow
def test_fit_writes_tables_and_figures(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["fit", str(write(tmp_path, GOOD)), "-o", str(out)]) == 0
    fits = pd.read_csv(out / "fits.csv")
    assert tuple(fits.columns) == FIT_COLUMNS
    assert len(fits) == 18 and fits["success"].all()
    ranking = pd.read_csv(out / "ranking.csv")
    assert list(ranking.columns) == ["equation", "formula", "A", "B", "points", "place"]
    assert (out / "curves_A.png").stat().st_size > 10_000
    printed = capsys.readouterr().out
    assert "Experiment A (n = 6)" in printed and str(out / "fits.csv") in printed
    assert max(len(line) for line in printed.splitlines() if not line.startswith("  /")) <= 100


def test_fit_accepts_percent_coarse_partitions_and_a_formula_subset(tmp_path):
    text = "size,partition_coarse_pct\n10,3\n20,10\n40,30\n80,65\n160,90\n"
    out = tmp_path / "out"
    assert main(["fit", str(write(tmp_path, text)), "-o", str(out), "--formulas", "plitt,9", "--no-figures"]) == 0
    fits = pd.read_csv(out / "fits.csv")
    assert list(fits["formula"]) == ["plitt", "lognormal"]
    assert set(fits["experiment"]) == {"points"}


def test_fit_reads_excel(tmp_path):
    frame = pd.read_csv(write(tmp_path, GOOD))
    path = tmp_path / "points.xlsx"
    frame.to_excel(path, sheet_name="lab", index=False)
    assert main(["fit", str(path), "--sheet", "lab", "-o", str(tmp_path / "o"), "--no-figures"]) == 0
    assert main(["fit", str(path), "--sheet", "nope", "-o", str(tmp_path / "o2")]) == 1


BAD_INPUTS = [
    ("size,other\n1,2\n2,3\n3,4\n", "no partition column"),
    ("partition_fine\n0.5\n0.4\n0.3\n", "missing column(s) size"),
    ("size,partition_fine,partition_coarse\n1,0.9,0.1\n2,0.5,0.5\n3,0.1,0.9\n", "several partition columns"),
    ("size,partition_fine\n1,0.9\n2,1.5\n3,0.1\n", "row 3, column 'partition_fine': partition 1.5 outside 0..1"),
    ("size,partition_fine_pct\n1,90\n2,-5\n3,10\n", "row 3, column 'partition_fine_pct': partition -5 outside 0..100"),
    ("size,partition_fine\n1,0.9\n0,0.5\n3,0.1\n", "row 3, column 'size': size must be positive"),
    ("size,partition_fine\n1,0.9\n3,0.5\n3,0.1\n", "row 4, column 'size': duplicate size 3"),
    ("size,partition_fine\n1,0.9\n2,\n3,0.1\n", "row 3, column 'partition_fine': value is missing"),
    ("size,partition_fine\n1,0.9\n2,NaN\n3,0.1\n", "row 3, column 'partition_fine': value is missing"),
    ("size,partition_fine\n1,0.9\n2,abc\n3,0.1\n", "row 3, column 'partition_fine': 'abc' is not a number"),
    ("# comment line\nsize,partition_fine\n1,0.9\n2,0.5\n-3,0.1\n", "row 5, column 'size'"),
    ("", "the file is empty"),
    ("size,partition_fine\n", "no data rows"),
]


@pytest.mark.parametrize("text, expected", BAD_INPUTS, ids=[e for _, e in BAD_INPUTS])
def test_bad_input_stops_with_file_row_column_and_writes_nothing(tmp_path, capsys, text, expected):
    path = write(tmp_path, text)
    out = tmp_path / "out"
    assert main(["fit", str(path), "-o", str(out)]) == 1
    error = capsys.readouterr().err
    assert expected in error and str(path) in error
    assert not out.exists() or not any(out.iterdir())


def test_unknown_formula_is_named(tmp_path, capsys):
    # a bad option value is a usage error (exit 2), named by its option
    assert main(["fit", str(write(tmp_path, GOOD)), "--formulas", "plitt,banana", "-o", str(tmp_path / "o")]) == 2
    error = capsys.readouterr().err
    assert "--formulas" in error and "unknown formula 'banana'" in error
    assert not (tmp_path / "o").exists()


def test_rank_reproduces_table_3_places(tmp_path, capsys):
    out = tmp_path / "r"
    assert main(["rank", str(DATASETS / "shuvalov2018_table2_F.csv"), "-o", str(out)]) == 0
    ranking = pd.read_csv(out / "ranking.csv")
    assert list(ranking["place"]) == [9, 8, 3, 5, 1, 4, 2, 7, 6]
    assert main(["rank", str(DATASETS / "shuvalov2018_table2_F.csv"), "-o", str(out), "--computed-adequacy"]) == 0
    assert list(pd.read_csv(out / "ranking.csv")["points"])[:4] == [114, 80, 48, 55]


def test_formulas_lists_the_registry(capsys):
    assert main(["formulas"]) == 0
    printed = capsys.readouterr().out
    assert all(name in printed for name in ("(4) molerus_hoffmann", "-ks/4", "erfc(ln(x)/kf)/2", "(106) whiten"))
    assert max(len(line) for line in printed.splitlines()) <= 100


def test_rising_partition_and_extrapolated_cut_are_warned(tmp_path, capsys):
    rising = "size,partition_fine\n10,0.03\n20,0.1\n40,0.3\n80,0.65\n160,0.9\n320,0.98\n"
    assert main(["fit", str(write(tmp_path, rising)), "-o", str(tmp_path / "o"), "--no-figures", "--formulas", "plitt"]) == 0
    assert "rises with size" in capsys.readouterr().err
    above = "size,partition_fine\n10,0.99\n20,0.95\n40,0.9\n80,0.8\n160,0.7\n"
    assert main(["fit", str(write(tmp_path, above)), "-o", str(tmp_path / "p"), "--no-figures", "--formulas", "plitt"]) == 0
    said = capsys.readouterr().err.replace("\n", " ")
    assert "every measured partition lies above 1/2" in said and "extrapolated beyond the measured sizes" in said


def test_indistinguishable_fits_and_non_normal_residuals_are_said_in_the_console(tmp_path, capsys):
    """On deck_65mesh the nine formulas reach one sum of squares, yet got ranks 1..9, all
    "adequate" while every normality p-value is about 0.0003, and nothing warned."""
    out = tmp_path / "out"
    lab = DATASETS / "double_deck_screen_decks_lab.csv"
    assert main(["fit", str(lab), "--size-unit", "mm", "-o", str(out), "--no-figures"]) == 0
    fits = pd.read_csv(out / "fits.csv")
    deck = fits[fits["experiment"] == "deck_65mesh"].set_index("formula")
    tied = deck.drop(index="shuvalov")
    assert (tied["rank"] == 4.5).all() and deck.loc["shuvalov", "rank"] == 9
    assert (deck["delta_aicc"] < 2).all()
    assert (deck["residuals"] == "not normal").all() and (deck["normality_p"] < 0.001).all()
    assert deck["extrapolated"].str.contains("eta").all()
    printed = capsys.readouterr().out
    block = printed[printed.index("Experiment deck_65mesh") : printed.index("Ranking across")]
    assert "The data cannot tell the 9 formulas apart" in block
    assert "Shared rank 4.5: molerus, molerus_hoffmann" in block
    assert "Adequate by F, but the residuals are not normal: all 9 formulas" in block
    assert "Extrapolated beyond the measured sizes (0.06242 to 3.954): eta of all 9 formulas" in block
    rows = [line for line in block.splitlines() if line.strip().startswith("4.5")]
    assert len(rows) == 8 and all("yes*" in row and "NOT NORMAL" in row for row in rows)
    assert max(len(line) for line in printed.splitlines() if not line.startswith("  /")) <= 100


@pytest.mark.parametrize(
    ("argv", "flag"),
    [
        (["fit", "x.csv", "--jobs", "-3"], "--jobs"),
        (["fit", "x.csv", "--bootstrap", "many"], "--bootstrap"),
        (["fit", "x.csv", "--alpha", "2"], "--alpha"),
        (["layer", "simulate", "--diffusion", "1.5"], "--diffusion"),
    ],
)
def test_an_option_error_is_one_line_and_a_pointer_to_the_help(capsys, argv, flag):
    assert main(argv) == 2
    said = capsys.readouterr().err.strip().splitlines()
    command = " ".join(["tromplab", *argv[:2]]) if argv[0] == "layer" else f"tromplab {argv[0]}"
    assert len(said) == 2 and flag in said[0] and "usage:" not in said[0]
    assert said[1] == f"  see '{command} -h' for the options"
