"""Hostile inputs to the loaders: each ends in a clean InputError naming the file, row and
column (exit code 1 through the CLI, no traceback, nothing written), or in a result whose
invariants hold.  The cases are listed in docs/reliability.md ("Loading inputs")."""

import gzip
import os
import warnings

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from tromplab.classifiers.sieve import identify_from_table
from tromplab.cli import main
from tromplab.curves.ranking import read_f_table
from tromplab.errors import InputError
from tromplab.loading.lab import LabOptions, read_experiments, read_lab
from tromplab.loading.points import read_points
from tromplab.loading.tables import InputNote, read_table

from .conftest import LAB_CLASS_HEADER, LAB_CLASS_ROWS, ROOT
from .strategies import lab_tables, mutated, points_tables, write_frame

POINTS = "size,partition_fine\n10,0.95\n20,0.8\n40,0.5\n80,0.2\n160,0.05\n"
LAB_HEADER = LAB_CLASS_HEADER
LAB_ROWS = LAB_CLASS_ROWS


def lab(*replace, header=LAB_HEADER, extra=None):
    """The good lab table with rows replaced, another header, or ``extra = {column: [cell per row]}``."""
    lines = list(LAB_ROWS)
    for index, text in replace:
        lines[index] = text
    if extra:
        header = header.rstrip("\n") + "," + ",".join(extra) + "\n"
        lines = [line + "," + ",".join(cells[i] for cells in extra.values()) for i, line in enumerate(lines)]
    return header + "\n".join(lines) + "\n"


# (file text, extra CLI options, expected message fragment); row numbers are file lines
TEXT_CASES = [
    # non-finite values where a number is required
    ("size,partition_fine\n10,0.95\ninf,0.8\n40,0.5\n", [], "row 3, column 'size': 'inf' is not a finite number"),
    ("size,partition_fine\n10,0.95\n20,-inf\n40,0.5\n", [], "row 3, column 'partition_fine': '-inf' is not a finite number"),
    ("size,partition_fine\n10,0.95\n1e999,0.8\n40,0.5\n", [], "row 3, column 'size': 'inf' is not a finite number"),
    ("size,partition_fine,weight\n10,0.95,1\n20,0.8,Infinity\n40,0.5,1\n", [], "row 3, column 'weight': 'inf' is not a finite"),
    ("size,partition_fine\n10,0.95\nnan,0.8\n40,0.5\n", [], "row 3, column 'size': value is missing"),
    # sizes out of range (found by benchmarks/fuzz_cli.py: 1e308 among sizes near 100 overflowed the indices)
    (
        "size,partition_fine\n10,0.95\n20,0.8\n1e308,0.5\n",
        [],
        "column 'size': experiment 'input': size 1e+308 at point 3 is outside",
    ),
    (
        "size,partition_fine\n1e-6,0.95\n20,0.8\n40000,0.5\n",
        [],
        "the sizes span 1e-06 to 40000, more than 1e+09 times; a size or unit is probably mistyped",
    ),
    (lab((2, "200,400,inf,16.3,35.4")), [], "row 4, column 'feed_pct': 'inf' is not a finite number"),
    (
        "size_lower,size_upper,feed_mass,fine_mass\n400,,5,1\n200,400,inf,2\n,200,4,3\n",
        ["--fine-yield", "0.3"],
        "row 3, column 'feed_mass': 'inf' is not a finite number",
    ),
    (lab((1, "400,inf,15,1,25.3")), [], "row 3, column 'size_upper': 'inf' is not a finite number"),
    (
        lab(extra={"fine_yield": ["0.5", "-inf", "0.5", "0.5", "0.5", "0.5"]}),
        [],
        "row 3, column 'fine_yield': '-inf' is not a finite",
    ),
    # unknown, duplicate and ambiguous columns
    ("size,partiton_fine\n10,0.9\n20,0.5\n40,0.1\n", [], "no partition column: give exactly one of partition_fine"),
    ("size,partiton_fine\n10,0.9\n20,0.5\n40,0.1\n", [], "'partiton_fine' (did you mean 'partition_fine'?)"),
    ("experimnet,size,partition_fine\nA,10,0.9\nB,20,0.5\nA,40,0.1\n", [], "'experimnet' (did you mean 'experiment'?)"),
    ("size,partition_fine,wieght\n10,0.9,1\n20,0.5,1\n40,0.1,1\n", [], "'wieght' (did you mean 'weight'?)"),
    ("size,size,partition_fine\n10,11,0.9\n20,21,0.5\n40,41,0.1\n", [], "column 'size': duplicate column 'size'"),
    ("size,size_um,partition_fine\n10,11,0.9\n20,21,0.5\n40,41,0.1\n", [], "several size columns (size, size_um)"),
    ("size,partition_fine,\n10,0.9,1\n20,0.5,2\n40,0.1,3\n", [], "column 3 holds values but has no header"),
    (lab(header=LAB_HEADER.replace("coarse_pct", "coarse_pctt")), [], "'coarse_pctt' (did you mean 'coarse_pct'?)"),
    (
        lab(header=LAB_HEADER.replace("coarse_pct", "overflow_pct")),
        [],
        "two columns for the fine stream (fine_pct, overflow_pct)",
    ),
    (lab(extra={"fine_yield": ["0.5"] * 6, "overflow_yield": ["0.5"] * 6}), [], "two yield columns for the fine product"),
    (
        "size_class,size_lower,size_upper,feed_pct,fine_pct\n+400,400,,50,10\n-400+200,200,400,30,30\n-200,,200,20,60\n",
        ["--fine-yield", "0.4"],
        "the sizes are given twice (size_class and size_lower/size_upper)",
    ),
    ("size_lower,feed_pct,fine_pct\n400,50,10\n200,30,30\n100,20,60\n", ["--fine-yield", "0.4"], "size_upper is missing"),
    (lab(), ["--rename", "coarse_pct=fine_pct"], "after renaming, column(s) fine_pct appear twice"),
    # shifted columns, European CSV declared wrongly, dates
    ("size,partition_fine\n10,0,95\n20,0,8\n40,0,5\n", [], "row 2: the row has 3 fields but the header has 2; decimal commas"),
    (
        "size;partition_fine\n10;0,95\n20;0,8\n40;0,5\n",
        ["--sep", ";", "--decimal", "."],
        "row 2, column 'partition_fine': '0,95' is not a number (a decimal comma?",
    ),
    (POINTS, ["--sep", ",", "--decimal", ","], "the separator and the decimal mark are both ','"),
    (POINTS, ["--sep", ";;"], "the separator (--sep) must be one character such as ';' or ',', got ';;'"),
    # size classes, units and yields
    (
        "size_class,feed_pct,fine_pct\n+400,50,10\n-400+200,30,30\nabc,20,60\n",
        ["--fine-yield", "0.4"],
        "row 4, column 'size_class': 'abc' is not a size class",
    ),
    (
        "size_class,feed_pct,fine_pct\n+400,50,10\n+400+200,30,30\n-200,20,60\n",
        ["--fine-yield", "0.4"],
        "row 3, column 'size_class': '+400+200' is not a size class",
    ),
    (
        "size_um,partition_fine\n10,0.9\n20,0.5\n40,0.1\n",
        ["--size-unit", "mm"],
        "column 'size_um': the size unit 'mm' given as an option (--size-unit) contradicts the column name",
    ),
    (
        lab(header=LAB_HEADER.replace("size_lower,size_upper", "size_lower_um,size_upper_um"), extra={"size_unit": ["mm"] * 6}),
        [],
        "the size unit 'mm' given in column 'size_unit' contradicts the column name 'size_lower_um'",
    ),
    (
        lab(extra={"size_representative": ["", "900", "", "", "", ""]}),
        [],
        "row 3, column 'size_representative': representative size 900",
    ),
    ("size_lower,size_upper,feed_pct,fine_pct,coarse_pct\n400,,100,100,100\n", [], "has 1 size class(es); at least 3 are needed"),
    (
        "size_lower,size_upper,feed_pct,fine_pct,coarse_pct\n400,,30,30,30\n200,400,30,30,30\n,200,40,40,40\n",
        [],
        "the fine and coarse distributions are identical",
    ),
    (lab((2, ",,30,16.3,35.4")), [], "row 4, column 'size_lower': the class has neither a lower nor an upper bound"),
    (lab((1, "400,800,15,-1,25.3")), [], "row 3, column 'fine_pct': negative amount -1"),
    (
        "experiment,size,partition_fine\nA,10,0.9\n  ,20,0.5\nA,40,0.1\n",
        [],
        "row 3, column 'experiment': experiment name is blank",
    ),
]


def run_cli(tmp_path, capsys, path, options=()):
    out = tmp_path / "out"
    code = main(["fit", str(path), "-o", str(out), "--no-figures", *options])
    captured = capsys.readouterr()
    return code, captured, out


def assert_refused(code, captured, out, expected, source):
    assert code == 1
    assert expected in captured.err, captured.err
    assert str(source) in captured.err
    assert "Traceback" not in captured.err
    assert not out.exists() or not any(out.iterdir())


@pytest.mark.parametrize("text, options, expected", TEXT_CASES, ids=[e[:70] for _, _, e in TEXT_CASES])
def test_hostile_text_tables_are_refused_by_the_cli(tmp_path, capsys, text, options, expected):
    path = tmp_path / "input.csv"
    path.write_text(text)
    code, captured, out = run_cli(tmp_path, capsys, path, options)
    assert_refused(code, captured, out, expected, path)


def _xlsx_with_dates(path):
    frame = pd.DataFrame({"size": [10.0, 20.0, 40.0], "partition_fine": [0.9, 0.5, 0.1]}).astype(object)
    frame.loc[1, "size"] = pd.Timestamp("2024-03-05")
    frame.to_excel(path, index=False)


def _xlsx_with_duplicate_header(path):
    frame = pd.DataFrame([[10.0, 0.9, 11.0], [20.0, 0.5, 21.0], [40.0, 0.1, 41.0]], columns=["size", "partition_fine", "size "])
    frame.to_excel(path, index=False)


# (file name, how to write it, expected fragment) for files that are not CSV text
FILE_CASES = [
    (
        "latin1.csv",
        lambda p: p.write_bytes("experiment,size,partition_fine\nProbe é,10,0.9\n".encode("latin-1")),
        "row 2: the text is not UTF-8 (byte 0xe9 cannot be decoded)",
    ),
    ("utf16.csv", lambda p: p.write_text(POINTS, encoding="utf-16"), "the file is UTF-16 text"),
    ("packed.csv", lambda p: p.write_bytes(gzip.compress(POINTS.encode())), "the file is gzip-compressed"),
    ("points.csv.gz", lambda p: p.write_bytes(gzip.compress(POINTS.encode())), "compressed files are not read"),
    ("sheet.ods", lambda p: p.write_bytes(b"PK\x03\x04 OpenDocument"), "OpenDocument .ods spreadsheets are not read"),
    ("sheet.xls", lambda p: p.write_bytes(b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1" + bytes(100)), "save the sheet as .xlsx"),
    ("binary.csv", lambda p: p.write_bytes(b"size,partition_fine\n\x00\x01\x02\x03"), "the file is binary"),
    ("renamed.csv", lambda p: p.write_bytes(b"PK\x03\x04" + bytes(64)), "the file is a zip archive"),
    ("points.json", lambda p: p.write_text('{"size": [1, 2]}'), "unknown format '.json'"),
    ("text.xlsx", lambda p: p.write_text(POINTS), "is not an .xlsx workbook"),
    ("dates.xlsx", _xlsx_with_dates, "row 3, column 'size': '2024-03-05 00:00:00' is a date, not a number"),
    ("duplicate.xlsx", _xlsx_with_duplicate_header, "column 'size': duplicate column 'size'"),
    ("empty.csv", lambda p: p.write_text(""), "the file is empty"),
    ("comments.csv", lambda p: p.write_text("# only a comment\n\n"), "only comments or blank lines"),
    ("folder.csv", lambda p: p.mkdir(), "is a folder; the input must be a file"),
    ("missing.csv", lambda p: None, "file not found"),
]


@pytest.mark.parametrize("name, make, expected", FILE_CASES, ids=[c[0] for c in FILE_CASES])
def test_files_that_are_not_csv_text_are_refused_by_the_cli(tmp_path, capsys, name, make, expected):
    path = tmp_path / name
    make(path)
    code, captured, out = run_cli(tmp_path, capsys, path)
    assert_refused(code, captured, out, expected, path)


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="permissions do not bind root")
def test_an_unreadable_file_is_refused(tmp_path):
    path = tmp_path / "locked.csv"
    path.write_text(POINTS)
    path.chmod(0)
    with pytest.raises(InputError, match="not readable"):
        read_points(path)


def test_empty_columns_without_a_header_are_dropped(tmp_path):
    """Trailing separators in a CSV, or formatted but empty columns in a sheet, are not data."""
    path = tmp_path / "trailing.csv"
    path.write_text("size,partition_fine,,\n10,0.9,,\n20,0.5,,\n40,0.1,,\n")
    (points,) = read_points(path)
    assert_allclose(points.size, [10, 20, 40])
    sheet = tmp_path / "gaps.xlsx"
    pd.DataFrame(
        [[10, 0.9, None, None, "x"], [20, 0.5, None, None, None], [40, 0.1, None, None, None]],
        columns=["size", "partition_fine", "", " ", "note"],
    ).to_excel(sheet, index=False)
    (points,) = read_points(sheet)
    assert_allclose(points.partition_fine, [0.9, 0.5, 0.1])


def test_the_sieve_and_rank_tables_refuse_non_finite_values(tmp_path):
    sieve = tmp_path / "residues.csv"
    sieve.write_text(
        "sieve,fraction,relative_speed,residue,sieve_length,cell_pitch,P_g\ns1,f1,1.0,0.5,1,0.1,0.4\ns1,f1,2.0,inf,1,0.1,0.4\n"
    )
    with pytest.raises(InputError, match=r"row 3, column 'residue': 'inf' is not a finite number"):
        identify_from_table(read_table(sieve))
    sieve.write_text("sieve,fraction,relative_speed,residue,sieve_length,cell_pitch,P_g,cell_pich\n1,a,1,0.5,1,0.1,0.4,0.1\n")
    with pytest.raises(InputError, match=r"unknown column\(s\) 'cell_pich' \(did you mean 'cell_pitch'\?\) in a residue table"):
        identify_from_table(read_table(sieve))
    ranks = tmp_path / "f.csv"
    ranks.write_text("experiment,equation,F,n\n1,3,5.3,5\n1,4,-inf,5\n")
    with pytest.raises(InputError, match=r"row 3, column 'F': '-inf' is not a finite number"):
        read_f_table(ranks)
    ranks.write_text("experiment,equation,F,F\n1,3,5.3,5\n")
    with pytest.raises(InputError, match="duplicate column 'F'"):
        read_f_table(ranks)


# --- layouts that load ---------------------------------------------------------
DATA = os.path.join(os.path.dirname(__file__), "data")
CLASS_PARTITIONS = [0.02, 0.10, 0.35, 0.70, 0.92, 0.99]  # the curve the three layout files were built from


@pytest.mark.parametrize(
    "text",
    [
        "a,b,c\n1,2,x\n3,4,y\n",  # no comment or blank line: pandas reads the file itself
        "# a comment\na,b,c\n1,2,x\n\n3,4,y\n",  # comments and blank lines stripped first
        "a,b,c\r\n1,2,x\r\n3,4,y\r\n\r\n\r\n",  # CRLF and trailing blank lines
        "a,b,c\r1,2,x\r3,4,y\r",  # old Mac line ends: read line by line
    ],
)
def test_a_table_read_for_some_columns_keeps_the_file_rows(tmp_path, text):
    path = tmp_path / "t.csv"
    path.write_bytes(text.encode())
    whole, some = read_table(path), read_table(path, columns=("a", "c"))
    assert list(some.frame.columns) == ["a", "c"]
    assert some.frame.equals(whole.frame[["a", "c"]]) and list(some.rows) == list(whole.rows)
    assert f"row {whole.rows[1]}, column 'a'" in str(some.error("bad", index=1, column="a"))


def test_extra_fields_are_refused_by_row_on_the_fast_path_too(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("a,b\n1,2\n3,4,5\n6,7\n")
    with pytest.raises(InputError, match="row 3: the row has 3 fields but the header has 2"):
        read_table(path)
    for text, row in (("a,b\n1,2,5\n3,4\n", 2), ('a,b\n1,"2,x"\n3,"4\n5",6\n', 3)):  # pandas warns, or is silent
        path.write_text(text)
        with pytest.raises(InputError, match=f"row {row}: the row has 3 fields but the header has 2"):
            read_table(path, columns=("a",))
    path.write_text('a,b\n1,"2,x"\n3,"4\n5"\n7,8,\n')  # quoted separators and line breaks, a trailing empty field
    assert read_table(path, columns=("a",)).frame["a"].tolist() == [1, 3, 7]


def test_semicolon_and_decimal_comma_are_detected_with_a_note():
    path = os.path.join(DATA, "european_semicolon_decimal_comma.csv")
    with pytest.warns(InputNote) as caught:
        (balance,) = read_lab(path, LabOptions(fine_yield=0.6156))
    messages = " ".join(str(w.message) for w in caught)
    assert "read as semicolon-separated" in messages and "decimal commas detected" in messages
    assert_allclose(balance.classes["partition_fine"], CLASS_PARTITIONS, atol=1e-6)
    with warnings.catch_warnings():
        warnings.simplefilter("error", InputNote)  # declared: no note
        (declared,) = read_lab(path, LabOptions(fine_yield=0.6156, sep=";", decimal=","))
    assert_allclose(declared.classes["partition_fine"], CLASS_PARTITIONS, atol=1e-6)


def test_a_detected_dialect_is_printed_as_a_note_by_the_cli(capsys):
    assert main(["balance", os.path.join(DATA, "european_semicolon_decimal_comma.csv"), "--fine-yield", "0.6156"]) == 0
    err = capsys.readouterr().err.replace("\n", " ")
    assert "note: " in err and "read as semicolon-separated" in err and "Traceback" not in err


# --- properties: either a clean InputError or invariants that hold -------------------------
PROPERTY_SETTINGS = settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def _load_lab(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            return read_lab(path)
        except InputError:
            return None


@PROPERTY_SETTINGS
@given(case=lab_tables(), scale=st.sampled_from([1e-300, 1e-9, 1e-3, 25.4, 1e6, 1e300]))
@pytest.mark.slow
def test_lab_tables_row_order_unit_scale_and_stream_swap(tmp_path_factory, case, scale):
    """Reversed rows change nothing, scaled sizes scale the sizes, swapped fine/coarse give 1 - partition."""
    directory = tmp_path_factory.mktemp("lab")
    loaded = _load_lab(write_frame(case.frame, directory / "table.csv"))
    if loaded is None:
        return  # a clean refusal is an allowed outcome
    reference = pd.concat([b.classes for b in loaded]).sort_values(["experiment", "size"], kind="stable")
    reversed_ = _load_lab(write_frame(case.frame.iloc[::-1], directory / "reversed.csv"))
    assert reversed_ is not None
    by_size = pd.concat([b.classes for b in reversed_]).sort_values(["experiment", "size"], kind="stable")
    assert_allclose(by_size["partition_fine"], reference["partition_fine"], rtol=1e-9, atol=1e-12)
    scaled_frame = case.frame.copy()
    for column in case.size_columns:
        scaled_frame[column] = scaled_frame[column] * scale
    scaled = _load_lab(write_frame(scaled_frame, directory / "scaled.csv"))
    if scaled is not None:  # extreme scales may overflow to inf or underflow to 0: refused cleanly
        by_size = pd.concat([b.classes for b in scaled]).sort_values(["experiment", "size"], kind="stable")
        assert_allclose(by_size["size"], reference["size"] * scale, rtol=1e-9)
        assert_allclose(by_size["partition_fine"], reference["partition_fine"], rtol=1e-9, atol=1e-12)
    swap = {column: column.replace("fine", "@").replace("coarse", "fine").replace("@", "coarse") for column in case.frame.columns}
    swapped = _load_lab(write_frame(case.frame.rename(columns=swap), directory / "swapped.csv"))
    assert swapped is not None
    by_size = pd.concat([b.classes for b in swapped]).sort_values(["experiment", "size"], kind="stable")
    used = reference["used"].to_numpy() & by_size["used"].to_numpy()
    assert_allclose(by_size["partition_fine"][used], 1 - reference["partition_fine"][used], atol=1e-9)


@PROPERTY_SETTINGS
@given(case=lab_tables(), mutation=mutated())
def test_mutated_lab_tables_load_or_fail_cleanly(tmp_path_factory, case, mutation):
    path = write_frame(mutation(case.frame, case), tmp_path_factory.mktemp("mut") / "table.csv")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            points, balances = read_experiments(path)
    except InputError as error:
        assert str(path) in str(error)
        return
    for experiment in points:
        assert np.all(np.isfinite(experiment.size)) and np.all(experiment.size > 0)
        assert np.all((experiment.partition_fine >= 0) & (experiment.partition_fine <= 1))
        assert np.all(np.diff(experiment.size) > 0)


@PROPERTY_SETTINGS
@given(case=points_tables(), mutation=mutated(), scale=st.sampled_from([1e-300, 1e-6, 1.0, 1e3, 1e300]))
def test_points_files_load_or_fail_cleanly_and_keep_their_invariants(tmp_path_factory, case, mutation, scale):
    directory = tmp_path_factory.mktemp("pts")
    frame = mutation(case.frame, case)
    path = write_frame(frame, directory / "points.csv")
    other = tmp_path_factory.mktemp("pts")  # same file name: an experiment without a name column is named after it
    try:
        loaded = read_points(path)
    except InputError as error:
        assert str(path) in str(error)
        return
    for experiment in loaded:
        assert np.all(np.isfinite(experiment.size)) and np.all(np.diff(experiment.size) > 0)
        assert np.all((experiment.partition_fine >= 0) & (experiment.partition_fine <= 1))
    shuffled = read_points(write_frame(frame.sample(frac=1.0, random_state=1), other / "points.csv"))
    shuffled = {p.experiment: p for p in shuffled}  # experiments come in order of first appearance
    for a in loaded:
        b = shuffled[a.experiment]
        assert_allclose(a.size, b.size)
        assert_allclose(a.partition_fine, b.partition_fine)
    scaled_frame = frame.assign(**{case.size_columns[0]: pd.to_numeric(frame[case.size_columns[0]], errors="coerce") * scale})
    try:
        scaled = read_points(write_frame(scaled_frame, other / "points.csv"))
    except InputError:
        return  # overflow to inf, underflow to 0 or to duplicate sizes: refused
    for a, b in zip(loaded, scaled):
        assert_allclose(b.size, a.size * scale, rtol=1e-9)
        assert_allclose(b.partition_fine, a.partition_fine)


def test_the_reliability_table_lists_every_loading_case():
    """docs/reliability.md ("Loading inputs") stays in step with the cases above."""
    text = (ROOT / "docs" / "reliability.md").read_text(encoding="utf-8")
    section = text[text.index("## Loading inputs") :]
    missing = [expected for _, _, expected in TEXT_CASES + FILE_CASES if f"`{expected}`" not in section]
    assert not missing, missing
