"""Every column tromplab writes is documented in docs/columns.md with the unit the workbook
prints in its header (every reported number has a definition, a unit and a range)."""

import re

import pandas as pd
import pytest

from tromplab.cli import main
from tromplab.output.workbook import column_unit

from .conftest import DATASETS, ROOT

DOC = ROOT / "docs" / "columns.md"
# docs/columns.md unit words -> the unit column_unit gives (with the size unit "size unit")
UNIT_WORDS = {"size unit": "size unit", "0..1": "0..1", "-": "-", "count": "", "text": "", "true/false": ""}


def documented() -> dict[str, tuple[str, ...]]:
    """``{column name or pattern: units}`` from the tables of docs/columns.md."""
    found = {}
    for line in DOC.read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) != 4 or not cells[0].startswith("`"):
            continue
        names = re.findall(r"`([^`]+)`", cells[0])
        units = tuple(u.strip() for u in cells[2].split(","))
        for i, name in enumerate(names):
            found[name] = (units[min(i, len(units) - 1)],)
    return found


def _pattern(name: str) -> re.Pattern:
    return re.compile("^" + re.sub(r"<[a-z]+>", "[A-Za-z0-9_]+", re.escape(name).replace(r"\<", "<").replace(r"\>", ">")) + "$")


def _doc_entry(column: str, docs: dict) -> tuple[str, tuple[str, ...]]:
    if column in docs:
        return column, docs[column]
    for name, units in docs.items():
        if "<" in name and not name.startswith("<experiment>") and _pattern(name).match(column):
            return name, units
    raise AssertionError(f"column {column!r} is not documented in docs/columns.md")


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    out = tmp_path_factory.mktemp("columns")
    lab = str(DATASETS / "double_deck_screen_decks_lab.csv")
    assert main(["fit", lab, "-o", str(out / "fit"), "--size-unit", "mm", "--ci", "0.95", "--bootstrap", "4", "--extended",
                 "--water-recovery", "0.05", "--no-figures", "--quiet"]) in (0, 3)  # fmt: skip
    assert main(["points", lab, "-o", str(out / "points.csv"), "--water-recovery", "0.05", "--quiet"]) == 0
    tables = {name: pd.read_csv(out / "fit" / f"{name}.csv") for name in ("fits", "averages", "ranking")}
    tables["points"] = pd.read_csv(out / "points.csv", comment="#")
    return tables


@pytest.mark.slow
def test_every_written_column_is_documented_with_its_workbook_unit(written):
    docs = documented()
    assert len(docs) > 60
    experiments = set(written["fits"]["experiment"])
    for table, frame in written.items():
        for column in frame.columns:
            if table == "ranking" and column in experiments:
                column_doc = "<experiment>"
                units = docs[column_doc]
            else:
                column_doc, units = _doc_entry(column, docs)
            if "<quantity>" in column_doc or column_doc in ("value", "stderr", "low", "high"):
                continue  # the unit of the quantity the row or the stem names
            if re.match(r"size(_lower|_upper)?_", column):
                assert units == ("size unit",), column
                continue
            expected = column_unit(column, "size unit")
            assert UNIT_WORDS[units[0]] == expected, f"{table}.csv column {column}: docs say {units[0]!r}, workbook {expected!r}"


@pytest.mark.slow
def test_interval_columns_have_the_unit_of_their_quantity(written):
    fits = written["fits"]
    for column in fits.columns:
        for suffix in ("_boot_low", "_boot_high", "_low", "_high"):
            if column.endswith(suffix):
                stem = column[: -len(suffix)]
                assert stem in fits.columns, column
                assert column_unit(column, "mm") == column_unit(stem, "mm"), column
                break


def test_epsilon_is_not_labelled_a_share():
    # eps is an area in relative-size units, in [0, x_max - 1]; a "0..1" header would mislead
    assert column_unit("epsilon") == "-" and column_unit("epsilon_low") == "-"
    assert column_unit("x_break", "mm") == "-"  # a relative size
