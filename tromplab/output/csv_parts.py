"""A CSV table written from parts formatted elsewhere: the workers of a batch.

Formatting the tables of a large batch (``fits.csv`` of 10,000 experiments: 90,000 rows,
2.2 s of ``DataFrame.to_csv``) would be serial work in the main process after every worker
had finished.  Each worker formats the rows of its own chunk (:func:`csv_part`) and the
main process joins the texts (:func:`csv_from_parts`).  The text of a row depends on its
values, on its column's type and on the order of the columns only, so the joined text is
``table.to_csv(index=False)`` byte for byte when every part was formatted in the table's
columns and types; when one was not (a chunk without a column another chunk has, an
integer column that the failed experiments' empty cells turn into floats), the table is
formatted whole in the main process.

Every CSV file tromplab writes goes through :func:`write_csv` (or these parts): text that a
spreadsheet would read as a formula (a cell or column name beginning with ``=``, ``+``,
``-``, ``@``, a tab or a carriage return) gets a single quote in front
(:func:`defended_frame`, :func:`tromplab.loading.names.defended`), the usual defence against
spreadsheet formula injection; numbers are never touched.  tromplab's readers drop that
quote again in the name columns (:func:`tromplab.loading.names.undefended`).  A table
with a carriage return inside a text cell is written with every text cell quoted: the csv
module quotes a cell only for the characters of its line end (a line feed), and a reader
takes a bare carriage return for the end of a row.
"""

from __future__ import annotations

import csv
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import NamedTuple

import pandas as pd

from ..loading.names import FORMULA_STARTS, TEXT_MARK, defended

_MARKED_STARTS = (*FORMULA_STARTS, TEXT_MARK)


class CsvPart(NamedTuple):
    """Consecutive rows of a table as ``DataFrame.to_csv`` formats them (no header), with the
    layout they were formatted in."""

    text: str
    columns: tuple[str, ...]
    dtypes: tuple[str, ...]
    rows: int


def _layout(frame: pd.DataFrame) -> tuple[tuple[str, ...], tuple[str, ...]]:
    return tuple(frame.columns), tuple(str(dtype) for dtype in frame.dtypes)


def defended_frame(frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` with every text cell and column name that starts as a formula marked as text
    (:func:`tromplab.loading.names.defended`); ``frame`` itself when nothing needs the mark.

    Examples
    --------
    >>> defended_frame(pd.DataFrame({"experiment": ["=1+1", "run"], "shift": [-0.5, 1.0]})).values.tolist()
    [["'=1+1", -0.5], ['run', 1.0]]
    """
    columns = [defended(c) if isinstance(c, str) else c for c in frame.columns]
    marked = {}
    for position in _text_columns(frame):
        values = frame.iloc[:, position]
        try:
            starts = values.str.startswith(_MARKED_STARTS, na=False).to_numpy(dtype=bool)
        except AttributeError:  # no text in the column (booleans, numbers)
            continue
        if starts.any():
            cells = values.to_numpy(dtype=object, copy=True)
            cells[starts] = [defended(text) for text in cells[starts]]
            marked[position] = cells
    if not marked and columns == list(frame.columns):
        return frame
    frame = frame.copy()
    for position, cells in marked.items():
        frame.isetitem(position, pd.Series(cells, index=frame.index, dtype=frame.dtypes.iloc[position]))
    frame.columns = columns
    return frame


def write_csv(frame: pd.DataFrame, path, **options) -> None:
    """Write ``frame`` as CSV without its index, text that starts as a formula marked as text
    (:func:`defended_frame`), every text cell quoted when one holds a carriage return (module
    docstring); ``options`` go to ``DataFrame.to_csv``."""
    if holds_carriage_return(frame):
        options.setdefault("quoting", csv.QUOTE_NONNUMERIC)
    defended_frame(frame).to_csv(path, index=False, **options)


def file_writers(
    tables: Mapping[str, pd.DataFrame] | None = None,
    *,
    texts: Mapping[str, str] | None = None,
    pictures: Mapping[str, bytes] | None = None,
) -> dict[str, Callable[[Path], None]]:
    """File name -> writer of a results folder, for :func:`tromplab.output.outputs.replace_folder`:
    each of ``tables`` (stem -> DataFrame) as ``stem.csv`` (:func:`write_csv`), then ``texts``
    (file name -> text, UTF-8), then ``pictures`` (file name -> PNG bytes), in that order."""
    writers = {f"{name}.csv": (lambda path, table=table: write_csv(table, path)) for name, table in (tables or {}).items()}
    writers.update(
        {name: (lambda path, text=text: path.write_text(text, encoding="utf-8")) for name, text in (texts or {}).items()}
    )
    writers.update({name: (lambda path, png=png: path.write_bytes(png)) for name, png in (pictures or {}).items()})
    return writers


def holds_carriage_return(frame: pd.DataFrame) -> bool:
    """Whether a text cell or a column name of ``frame`` holds a carriage return."""
    if any(isinstance(c, str) and "\r" in c for c in frame.columns):
        return True
    for position in _text_columns(frame):
        try:
            if frame.iloc[:, position].str.contains("\r", regex=False, na=False).any():
                return True
        except AttributeError:  # no text in the column
            continue
    return False


def _text_columns(frame: pd.DataFrame) -> list[int]:
    """Positions of the columns of ``frame`` that may hold text (object or string dtype), found
    from the dtypes alone: a column taken out of a wide table (``ranking.csv`` has one per
    experiment) costs tens of microseconds, seconds for a batch of 100,000."""
    text = {dtype for dtype in set(frame.dtypes) if pd.api.types.is_object_dtype(dtype) or pd.api.types.is_string_dtype(dtype)}
    return [position for position, dtype in enumerate(frame.dtypes) if dtype in text]


def csv_part(frame: pd.DataFrame) -> CsvPart:
    """The rows of ``frame`` formatted as CSV (text marked as :func:`write_csv` marks it), for
    :func:`csv_from_parts`."""
    return CsvPart(defended_frame(frame).to_csv(index=False, header=False), *_layout(frame), len(frame))


def csv_from_parts(table: pd.DataFrame, parts) -> str | None:
    """The text :func:`write_csv` writes for ``table``, with its first rows taken from ``parts`` (in order), or
    None when a part was formatted in other columns or types than the table's, or when the
    parts hold more rows than the table."""
    pieces = csv_pieces(table, parts)
    return None if pieces is None else "".join(pieces)


def csv_pieces(table: pd.DataFrame, parts) -> list[str] | None:
    """The texts :func:`csv_from_parts` joins (header, the parts, the table's remaining rows),
    to be written one after another without a copy of the whole table's text."""
    if not parts:
        return None
    layout = _layout(table)
    covered = sum(part.rows for part in parts)
    if covered > len(table) or any((part.columns, part.dtypes) != layout for part in parts) or holds_carriage_return(table):
        return None
    rest = defended_frame(table.iloc[covered:]).to_csv(index=False, header=False) if covered < len(table) else ""
    return [defended_frame(table.iloc[:0]).to_csv(index=False), *(part.text for part in parts), rest]
