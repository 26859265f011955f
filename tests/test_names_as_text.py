"""Names are text exactly as written, in every reader: ``01`` and ``1`` are two experiments,
``4E2`` stays ``4E2``, ``NA`` is a name; only an empty cell is blank.  Comments are lines above
the header only.  The names come from the catalogue in tests/hostile_names.py."""

import numpy as np
import openpyxl
import pandas as pd
import pytest

from tromplab import fit_experiments, read_experiments, read_points
from tromplab.circuit import read_flowsheet
from tromplab.cli import main
from tromplab.curves.ranking import read_f_table
from tromplab.errors import InputError
from tromplab.loading.lab import read_lab
from tromplab.loading.names import cell_name, undefended
from tromplab.loading.surveys import split_survey_columns
from tromplab.loading.tables import read_table
from tromplab.trend import read_surveys

from .hostile_names import NAMES, as_read, distinct_as_read, points_rows

READ_NAMES = distinct_as_read(NAMES)


def _write_xlsx(path, rows: list[list]):
    """A workbook whose cells hold the given values, every text cell stored as text."""
    book = openpyxl.Workbook()
    sheet = book.active
    for row in rows:
        sheet.append(row)
    for row in sheet.iter_rows():
        for cell in row:
            if isinstance(cell.value, str):
                cell.data_type = "s"
    book.save(path)
    return path


@pytest.mark.filterwarnings("ignore::tromplab.errors.InputNote")  # the detected semicolon dialect
@pytest.mark.parametrize("form", ["csv", "semicolon csv", "xlsx", "DataFrame"])
def test_every_catalogue_name_is_read_as_written(tmp_path, form):
    frame = pd.DataFrame(points_rows(READ_NAMES))
    if form == "csv":
        source = tmp_path / "points.csv"
        frame.to_csv(source, index=False)
    elif form == "semicolon csv":
        source = tmp_path / "points.csv"
        frame.to_csv(source, index=False, sep=";", decimal=",")
    elif form == "xlsx":
        source = _write_xlsx(tmp_path / "points.xlsx", [list(frame.columns), *frame.values.tolist()])
    else:
        source = frame
    points = read_points(source)
    assert [p.experiment for p in points] == [as_read(name) for name in READ_NAMES]
    assert all(p.n == 5 for p in points)


@pytest.mark.parametrize(
    "cells, names",
    [
        (["1", "01"], ["1", "01"]),  # two experiments, not one with ten points
        (["1e3", "1000"], ["1e3", "1000"]),
        (["4E2", "400"], ["4E2", "400"]),
        (["TRUE", "True"], ["TRUE", "True"]),
        (["NA", "None"], ["NA", "None"]),
        (["null", "N/A"], ["null", "N/A"]),
        (["#3", "3"], ["#3", "3"]),  # below the header a '#' line is data
    ],
)
def test_names_that_look_alike_are_different_experiments(tmp_path, cells, names):
    source = tmp_path / "points.csv"
    pd.DataFrame(points_rows(cells)).to_csv(source, index=False)
    assert [p.experiment for p in read_points(source)] == names


def test_the_acceptance_file_fits_three_experiments_through_the_cli_and_the_api(tmp_path):
    source = tmp_path / "points.csv"
    pd.DataFrame(points_rows(["002", "2", "NA"])).to_csv(source, index=False)
    out = tmp_path / "out"
    assert main(["fit", str(source), "-o", str(out), "--formulas", "plitt,lognormal", "--figures", "none", "-q"]) == 0
    fits = pd.read_csv(out / "fits.csv", dtype={"experiment": str}, keep_default_na=False)
    assert list(dict.fromkeys(fits["experiment"])) == ["002", "2", "NA"]
    assert (fits.groupby("experiment")["n"].max() == 5).all()  # five points each, none merged
    bench = fit_experiments(read_experiments(source), formulas=["plitt", "lognormal"])
    assert bench.experiments == ["002", "2", "NA"]
    assert list(bench.ranking_table().columns[2:5]) == ["002", "2", "NA"]


def test_only_an_empty_cell_is_blank(tmp_path):
    source = tmp_path / "points.csv"
    source.write_text("experiment,size,partition_fine\nNA,10,0.9\n,20,0.5\n")
    with pytest.raises(InputError, match="row 3, column 'experiment': experiment name is blank"):
        read_points(source)
    source.write_text('experiment,size,partition_fine\nNA,10,0.9\n"  ",20,0.5\n')
    with pytest.raises(InputError, match="row 3, column 'experiment': experiment name is blank"):
        read_points(source)


def test_numbers_keep_pandas_words_for_missing(tmp_path):
    """Outside the name columns NA, nan and null still mean a blank cell (a blank a column may allow)."""
    source = tmp_path / "table.csv"
    source.write_text("experiment,value\nNA,NA\nnull,nan\nN/A,null\nx,\n")
    table = read_table(source)
    assert table.names("experiment").tolist() == ["NA", "null", "N/A", "x"]
    assert np.isnan(table.numeric("value", allow_blank=True)).all()


@pytest.mark.parametrize(
    "text, rows, names",
    [
        ("# a comment\n\nexperiment,size,partition_fine\nA,10,0.9\n", [4], ["A"]),
        ("  # indented comment\nexperiment,size,partition_fine\nA,10,0.9\n\n#B,20,0.5\n", [3, 5], ["A", "#B"]),
        ("experiment,size,partition_fine\n#A,10,0.9\n# B,20,0.5\n", [2, 3], ["#A", "# B"]),
        ("experiment,size,partition_fine\r\n#A,10,0.9\r\n\r\nB,20,0.5\r\n", [2, 4], ["#A", "B"]),
    ],
)
def test_comments_are_lines_above_the_header_only(tmp_path, text, rows, names):
    source = tmp_path / "points.csv"
    source.write_text(text)
    table = read_table(source)
    assert table.rows.tolist() == rows
    assert table.experiment_labels().tolist() == names


def test_a_workbook_skips_comment_and_blank_rows_above_its_header_only(tmp_path):
    source = _write_xlsx(
        tmp_path / "points.xlsx",
        [[None], ["# measured 2024"], ["experiment", "size", "partition_fine"], ["#1", 10, 0.9], ["NA", 20, 0.5]],
    )
    table = read_table(source)
    assert table.experiment_labels().tolist() == ["#1", "NA"]
    assert table.rows.tolist() == [4, 5]  # sheet rows
    with pytest.raises(InputError, match="row 5, column 'partition_fine': 'x' is not a number"):
        read_table(
            _write_xlsx(source, [["# note"], ["experiment", "partition_fine"], ["A", 0.9], ["B", 0.5], ["C", "x"]])
        ).numeric("partition_fine")


@pytest.mark.parametrize(
    "value, name",
    [
        (1, "1"),
        (1.5, "1.5"),
        (True, "TRUE"),
        (False, "FALSE"),
        (pd.Timestamp("2024-03-05"), "2024-03-05"),
        ("  007 ", "007"),
        ("'=1+1", "=1+1"),
        ("'-150+75", "-150+75"),
        ("'quoted'", "'quoted'"),
        ("''=x", "'=x"),
        ("", None),
        (" ", None),
        (None, None),
        (np.nan, None),
        (pd.NA, None),
    ],
)
def test_a_cell_becomes_a_name(value, name):
    assert cell_name(value) == name


def test_the_text_mark_is_dropped_only_before_a_formula_start():
    for name in NAMES:
        assert undefended("'" + name) == (name if name.startswith(("=", "+", "-", "@", "\t", "\r")) else "'" + name)


def test_excel_numbers_and_booleans_in_a_name_column_read_as_the_sheet_shows_them(tmp_path):
    source = _write_xlsx(
        tmp_path / "points.xlsx",
        [["experiment", "size", "partition_fine"], [1, 10, 0.9], [1, 20, 0.5], ["01", 10, 0.9], ["01", 20, 0.5], [True, 10, 0.8]],
    )
    assert read_table(source).experiment_labels().tolist() == ["1", "1", "01", "01", "TRUE"]


def test_a_dataframe_with_numbers_as_names_reads_them_as_text():
    frame = pd.DataFrame(points_rows([1, 2]))
    assert [p.experiment for p in read_points(frame)] == ["1", "2"]


def test_lab_table_experiments_01_and_1_are_two(tmp_path):
    rows = "400,,10,0,20\n200,400,30,10,50\n100,200,40,50,25\n0,100,20,40,5\n"
    text = "experiment,size_lower,size_upper,feed_pct,fine_pct,coarse_pct\n" + "".join(
        f"{name},{line}\n" for name in ("01", "1") for line in rows.strip().split("\n")
    )
    source = tmp_path / "lab.csv"
    source.write_text(text)
    balances = read_lab(source, fine_yield=0.4)
    assert [b.experiment for b in balances] == ["01", "1"]


def test_a_column_renamed_to_experiment_is_read_as_text(tmp_path):
    source = tmp_path / "points.csv"
    frame = pd.DataFrame(points_rows(["01", "1"])).rename(columns={"experiment": "run"})
    frame.to_csv(source, index=False)
    points = read_experiments(source, rename={"run": "experiment"}).points
    assert [p.experiment for p in points] == ["01", "1"]


def test_survey_names_are_text_in_fit_and_trend(tmp_path):
    rows = []
    for day, name in enumerate(["01", "1", "NA", "1e3"]):
        for row in points_rows([name]):
            rows.append({"survey": name, "date": f"2024-01-0{day + 1}", **row})
    frame = pd.DataFrame(rows).drop(columns="experiment")
    source = tmp_path / "surveys.csv"
    frame.to_csv(source, index=False)
    table, found = split_survey_columns(read_table(source))
    assert list(found) == ["01", "1", "NA", "1e3"]
    assert [s.name for s in read_surveys(source)] == ["01", "1", "NA", "1e3"]
    assert [p.experiment for p in read_experiments(source).points] == ["01", "1", "NA", "1e3"]


def test_flowsheet_streams_are_text(tmp_path):
    source = tmp_path / "flowsheet.csv"
    source.write_text("stream,from,to,product\n01,,007,\n1,007,,fine\nNA,007,,coarse\n")
    sheet = read_flowsheet(source)
    assert sheet.stream_names == ("01", "1", "NA") or list(sheet.stream_names) == ["01", "1", "NA"]


def test_rank_table_experiments_and_equations_are_text(tmp_path):
    source = tmp_path / "ranks.csv"
    source.write_text("experiment,equation,F,F_crit\n007,01,5,3\n007,1,4,3\n7,01,6,3\n7,1,2,3\n")
    table = read_f_table(source)
    assert table["experiment"].tolist() == ["007", "007", "7", "7"]
    assert table["equation"].tolist() == ["01", "1", "01", "1"]


@pytest.mark.parametrize("name", [*NAMES, "'=x", "''=x", "'", "="])
def test_the_text_mark_round_trips_every_name(name):
    from tromplab.loading.names import defended

    assert undefended(defended(name)) == name


def test_the_words_for_missing_are_pandas_own():
    """Numbers keep exactly the blanks pandas gave them before names were read as text."""
    parsers = pytest.importorskip("pandas._libs.parsers")
    from tromplab.loading.names import MISSING_WORDS

    assert set(MISSING_WORDS) == set(parsers.STR_NA_VALUES)
