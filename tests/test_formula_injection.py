"""No formula from data: a name that starts as a spreadsheet formula (``=1+1``, ``+1``, ``-1``,
``@SUM(A1)``, a tab, a carriage return) is a text cell in every workbook tromplab writes, is
marked as text in every CSV it writes (a single quote in front), comes back unmarked when
tromplab reads its own outputs, survives Parquet as it is, and is escaped in the HTML and
Markdown reports.  The names come from tests/hostile_names.py."""

import csv
import re
from pathlib import Path

import openpyxl
import pandas as pd
import pytest

import tromplab
from tromplab import TrompPoints, fit_experiments, read_experiments
from tromplab.cli import main
from tromplab.loading.names import FORMULA_STARTS
from tromplab.loading.tables import read_table
from tromplab.output.csv_parts import defended_frame, write_csv
from tromplab.output.report import markdown_table, markdown_text

from .hostile_names import FORMULA_LIKE, NAMES, as_read, distinct_as_read, partitions, points_rows

FORMULAS = ["plitt", "lognormal"]
#: The names a file can carry and get back whole (surrounding white space is trimmed on reading).
FILE_NAMES = distinct_as_read(NAMES)


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _unescaped(text: str) -> str:
    """A workbook string with its ``_xHHHH_`` escapes decoded, as Excel shows it (openpyxl
    reads them as written)."""
    return re.sub(r"_x([0-9A-F]{4})_", lambda found: chr(int(found.group(1), 16)), text)


def assert_no_formula_cell_in_csv(path: Path) -> None:
    """No cell of the CSV (header included) starts as a formula, unless it is a number."""
    with open(path, newline="", encoding="utf-8") as handle:
        for line, row in enumerate(csv.reader(handle), start=1):
            for cell in row:
                assert not cell.startswith(FORMULA_STARTS) or _is_number(cell), (path.name, line, cell)


def assert_no_formula_cell_in_workbook(path: Path) -> list:
    """No cell of any sheet is a formula; returns every text value of the workbook."""
    book = openpyxl.load_workbook(path)
    texts = []
    for sheet in book.worksheets:
        for row in sheet.iter_rows():
            for cell in row:
                assert cell.data_type != "f", (sheet.title, cell.coordinate, cell.value)
                if isinstance(cell.value, str):
                    texts.append(cell.value)
                    if cell.value.startswith(FORMULA_STARTS):
                        assert cell.quotePrefix, (sheet.title, cell.coordinate, cell.value)
    return texts


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    """``tromplab fit --excel`` of a points file whose experiments carry every catalogue name."""
    folder = tmp_path_factory.mktemp("hostile")
    source = folder / "points.csv"
    pd.DataFrame(points_rows(FILE_NAMES)).to_csv(source, index=False)
    out = folder / "out"
    assert main(["fit", str(source), "-o", str(out), "--formulas", ",".join(FORMULAS), "--excel", "--figures", "all", "-q"]) == 0
    return source, out


@pytest.mark.slow
def test_the_acceptance_workbook_of_a_formula_name_holds_no_formula_cell(tmp_path):
    source = tmp_path / "points.csv"
    pd.DataFrame(points_rows(["=1+1", "plain"])).to_csv(source, index=False)
    workbook = tmp_path / "results.xlsx"
    assert main(["fit", str(source), "-o", str(workbook), "--formulas", "plitt", "-q"]) == 0
    assert "=1+1" in assert_no_formula_cell_in_workbook(workbook)
    fits = openpyxl.load_workbook(workbook)["fits"]
    assert [row[0] for row in fits.iter_rows(min_row=2, values_only=True)] == ["=1+1", "plain"]


@pytest.mark.slow
def test_every_table_of_the_workbook_holds_the_names_as_text(fitted):
    _, out = fitted
    texts = assert_no_formula_cell_in_workbook(out / "results.xlsx")
    book = openpyxl.load_workbook(out / "results.xlsx")
    for sheet in ("fits", "points", "averages"):
        names = list(dict.fromkeys(row[0] for row in book[sheet].iter_rows(min_row=2, values_only=True)))
        assert names == [as_read(name) for name in FILE_NAMES], sheet
    ranking_header = [cell.value for cell in book["ranking"][1]]
    assert ranking_header[2 : 2 + len(FILE_NAMES)] == [as_read(name) for name in FILE_NAMES]
    assert set(FORMULA_LIKE) - {"\tx", "\rx"} <= set(texts)


def test_every_csv_of_the_results_folder_is_marked_and_reads_back_as_written(fitted):
    _, out = fitted
    written = sorted(out.glob("*.csv"))
    assert {p.name for p in written} >= {"fits.csv", "ranking.csv", "averages.csv", "figures.csv"}
    for path in written:
        assert_no_formula_cell_in_csv(path)
    expected = [as_read(name) for name in FILE_NAMES]
    for name in ("fits.csv", "averages.csv", "figures.csv"):
        assert list(dict.fromkeys(read_table(out / name).experiment_labels())) == expected, name
    fits_text = (out / "fits.csv").read_text(encoding="utf-8")
    assert "\n'=1+1," in fits_text and "\n'-150+75," in fits_text and "\n'@SUM(A1)," in fits_text


def test_export_reads_the_names_back_as_written(fitted, tmp_path):
    _, out = fitted
    exported = tmp_path / "export.csv"
    assert main(["export", str(out), "--to", "csv-long", "-o", str(exported)]) == 0
    assert_no_formula_cell_in_csv(exported)
    names = read_table(exported).experiment_labels()
    assert list(dict.fromkeys(names)) == [as_read(name) for name in FILE_NAMES]
    plain = pd.read_csv(exported, dtype={"experiment": str}, keep_default_na=False)
    assert "'=1+1" in set(plain["experiment"])  # the file itself carries the mark


@pytest.mark.slow
def test_a_reloadable_folder_refits_and_reports_the_same_names(tmp_path):
    names = [name for name in FILE_NAMES if name in ("007", "=1+1", "-150+75", "NA", "01", "1")]
    bench = fit_experiments(read_experiments(pd.DataFrame(points_rows(names))), formulas=["plitt"])
    out = tmp_path / "out"
    bench.save(out, figures="none", reloadable=True)
    assert_no_formula_cell_in_csv(out / "points.csv")
    again = read_experiments(out / "points.csv").points
    assert [p.experiment for p in again] == names
    assert tromplab.load(out).experiments == names
    report = tmp_path / "report.html"
    assert main(["report", str(out / "points.csv"), "-o", str(report), "--formulas", "plitt"]) == 0
    for path in report.parent.glob("report*.csv"):
        assert_no_formula_cell_in_csv(path)
    markdown = report.with_suffix(".md").read_text(encoding="utf-8")
    assert "### Experiment 007" in markdown and "### Experiment =1+1" in markdown


@pytest.mark.slow
def test_api_names_survive_csv_parquet_and_excel_whole(tmp_path):
    """Names given to the API (not trimmed) come back whole from every format."""
    names = [name for name in NAMES if name.strip() == name or name in FORMULA_LIKE]
    points = [TrompPoints(name, [10, 20, 40, 80, 160], partitions(i)) for i, name in enumerate(names)]
    bench = fit_experiments(points, formulas=["plitt"])
    bench.save(tmp_path / "csv", figures="none", excel=True, reloadable=True)
    bench.save(tmp_path / "parquet", figures="none", format="parquet")
    parquet = pd.read_parquet(tmp_path / "parquet" / "fits.parquet")
    assert list(dict.fromkeys(parquet["experiment"])) == names  # typed: no mark needed, none added
    assert list(dict.fromkeys(read_table(tmp_path / "csv" / "fits.csv").experiment_labels())) == names
    assert [p.experiment for p in read_experiments(tmp_path / "csv" / "points.csv").points] == names
    book = openpyxl.load_workbook(tmp_path / "csv" / "results.xlsx")
    in_book = [_unescaped(row[0]) for row in book["fits"].iter_rows(min_row=2, values_only=True)]
    assert list(dict.fromkeys(in_book)) == names
    assert_no_formula_cell_in_workbook(tmp_path / "csv" / "results.xlsx")


@pytest.mark.parametrize("name", NAMES)
def test_write_csv_marks_only_text_that_starts_as_a_formula(tmp_path, name):
    frame = pd.DataFrame({"experiment": [name], "shift": [-0.5], "label": [name]})
    write_csv(frame, tmp_path / "t.csv")
    assert_no_formula_cell_in_csv(tmp_path / "t.csv")
    with open(tmp_path / "t.csv", newline="", encoding="utf-8") as handle:
        rows = list(csv.reader(handle))
    marked = "'" + name if name in FORMULA_LIKE else name
    assert rows[1] == [marked, "-0.5", marked]  # the number is not touched
    assert read_table(tmp_path / "t.csv").names("experiment").tolist() == [as_read(name) if name not in FORMULA_LIKE else name]


def test_numbers_and_booleans_are_never_marked():
    frame = pd.DataFrame({"shift": [-0.5, 1.0], "n": [-1, 2], "ok": [True, False], "mixed": [-1.5, "-x"]})
    defended = defended_frame(frame)
    assert defended["shift"].tolist() == [-0.5, 1.0] and defended["n"].tolist() == [-1, 2]
    assert defended["mixed"].tolist() == [-1.5, "'-x"]
    unmarked = frame.drop(columns="mixed")
    assert defended_frame(unmarked) is unmarked  # nothing to mark: the frame itself


def test_size_class_strings_load_and_are_not_echoed_as_text(tmp_path):
    """Class strings are input only: the outputs give the classes as numeric bounds, so no mark is needed."""
    lab = tmp_path / "lab.csv"
    lab.write_text(
        "experiment,size_class,feed_pct,fine_pct,coarse_pct\n"
        + "".join(
            f"-150+75,{c},{f},{o},{u}\n"
            for c, f, o, u in (("+400", 10, 0, 20), ("-400+200", 30, 10, 50), ("-200+100", 40, 50, 25), ("-100", 20, 40, 5))
        )
    )
    out = tmp_path / "points.csv"
    assert main(["points", str(lab), "-o", str(out), "--fine-yield", "0.4"]) == 0
    assert_no_formula_cell_in_csv(out)
    table = read_table(out)
    assert set(table.experiment_labels()) == {"-150+75"}
    assert table.numeric("size_lower", allow_blank=True).dtype == float


# --- reports ------------------------------------------------------------------------------
HOSTILE_TEXT = ["<script>alert(1)</script>", "a|b", "`code`", "=1+1", "# heading", "- item", "1. first", "x\ny", "*bold*"]


@pytest.mark.parametrize("text", HOSTILE_TEXT)
def test_markdown_text_is_literal(text):
    escaped = markdown_text(text)
    assert "\n" not in escaped
    assert not re.search(r"(?<!\\)[|`<>*]", escaped)  # every mark escaped
    assert not escaped.startswith(("=", "#", "-", "+")) and not re.match(r"\d+\.", escaped)
    assert re.sub(r"\\(.)", r"\1", escaped) == text.replace("\n", " ")  # nothing lost but the line break


def test_markdown_table_keeps_names_as_written_and_rows_whole():
    table = pd.DataFrame({"experiment": ["01", "1e3", "a|b", "=1+1"], "d_cut": [1.23456, -0.5, 2.0, 3.0]})
    lines = markdown_table(table).splitlines()
    assert all(len(re.findall(r"(?<!\\)\|", line)) == 3 for line in lines)  # two columns in every row
    assert "| 01 " in lines[2] and "| 1e3 " in lines[3] and "a\\|b" in lines[4] and "\\=1+1" in lines[5]
    assert "1.235" in lines[2] and "-0.5" in lines[3]  # numbers as before: 4 significant digits


@pytest.mark.slow
def test_the_html_and_markdown_reports_escape_the_same_names(tmp_path):
    names = ["<script>alert(1)</script>", "a|b`c`", "=1+1", "-150+75"]
    points = [TrompPoints(name, [10, 20, 40, 80, 160], partitions(i)) for i, name in enumerate(names)]
    bench = fit_experiments(points, formulas=["plitt"])
    written = bench.write_report(tmp_path / "report.html")
    html = written["report.html"].read_text(encoding="utf-8")
    markdown = written["report.md"].read_text(encoding="utf-8")
    assert "<script>" not in html and "&lt;script&gt;alert(1)&lt;/script&gt;" in html
    assert "<script>" not in markdown and "\\<script\\>alert(1)\\</script\\>" in markdown
    assert "a\\|b\\`c\\`" in markdown and "### Experiment =1+1" in markdown  # '=' inside a heading line is text
    assert "<td>=1+1</td>" in html and "<td>-150+75</td>" in html
    for block in markdown.split("\n\n"):
        rows = [line for line in block.splitlines() if line.startswith("|")]
        if rows:
            assert len({len(re.findall(r"(?<!\\)\|", row)) for row in rows}) == 1, block


# --- the other commands' CSV files ----------------------------------------------------------
DATASETS = Path(__file__).resolve().parent.parent / "datasets"


def _renamed_dataset(name: str, column: str, rename, tmp_path: Path, *, columns=None) -> Path:
    """A bundled data set with the names in ``column`` (and ``columns``) passed through ``rename``."""
    frame = pd.read_csv(DATASETS / name, comment="#", dtype=str, keep_default_na=False)
    for each in [column, *(columns or ())]:
        frame[each] = [rename(v) if v else v for v in frame[each]]
    path = tmp_path / name
    frame.to_csv(path, index=False)
    return path


def _all_csv_marked_and_named(folder: Path, column: str, expected: set) -> None:
    for path in folder.glob("*.csv"):
        assert_no_formula_cell_in_csv(path)
    found = set()
    for path in folder.glob("*.csv"):
        if len(path.read_text(encoding="utf-8").splitlines()) < 2:
            continue  # a header without rows (no gross error found, say)
        table = read_table(path)
        if column in table.frame.columns:
            found |= set(table.names(column)) - {""}
    assert found and found <= expected, (found, expected)


@pytest.mark.slow
def test_trend_files_mark_and_keep_formula_like_survey_names(tmp_path):
    source = _renamed_dataset("classifier_trend_surveys.csv", "survey", lambda s: "=" + s, tmp_path)
    out = tmp_path / "trend"
    assert main(["trend", str(source), "-o", str(out), "--no-figures"]) == 0
    surveys = set(pd.read_csv(source, dtype=str)["survey"])
    _all_csv_marked_and_named(out, "survey", surveys)
    markdown = (out / "trend_report.md").read_text(encoding="utf-8")
    assert "| =S01" not in markdown


@pytest.mark.slow
def test_circuit_files_mark_and_keep_formula_like_stream_and_node_names(tmp_path):
    def rename(name):
        return "-" + name

    flowsheet = _renamed_dataset("circuit_example_flowsheet.csv", "stream", rename, tmp_path, columns=("from", "to"))
    survey = _renamed_dataset("circuit_example_survey.csv", "stream", rename, tmp_path)
    out = tmp_path / "circuit"
    assert main(["circuit", str(flowsheet), str(survey), "-o", str(out), "--no-figures", "-q"]) == 0
    streams = set(pd.read_csv(flowsheet, dtype=str)["stream"])
    _all_csv_marked_and_named(out, "stream", streams)
    assert read_flowsheet_names(out / "flowsheet.csv") == list(pd.read_csv(flowsheet, dtype=str)["stream"])


def read_flowsheet_names(path: Path) -> list:
    from tromplab.circuit import read_flowsheet

    return [stream.name for stream in read_flowsheet(path).streams]


def test_rank_and_sieve_files_mark_formula_like_names(tmp_path):
    ranks = tmp_path / "ranks.csv"
    ranks.write_text("experiment,equation,F,F_crit\n=1+1,3,5,3\n=1+1,7,4,3\n+2,3,6,3\n+2,7,2,3\n")
    assert main(["rank", str(ranks), "-o", str(tmp_path / "rank")]) == 0
    assert_no_formula_cell_in_csv(tmp_path / "rank" / "ranking.csv")
    header = (tmp_path / "rank" / "ranking.csv").read_text(encoding="utf-8").splitlines()[0]
    assert "'=1+1" in header and "'+2" in header
    residues = _renamed_dataset(
        "sieve_identify_residues_example.csv", "sieve", lambda s: "@" + s, tmp_path, columns=("fraction",)
    )
    laws = tmp_path / "laws.csv"
    assert main(["sieve", "identify", str(residues), "-o", str(laws)]) == 0
    assert_no_formula_cell_in_csv(laws)
    table = read_table(laws)
    assert set(table.names("sieve")) == {"@1"} and all(name.startswith("@") for name in table.names("fraction"))
