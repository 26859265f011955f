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
"""

from __future__ import annotations

from typing import NamedTuple

import pandas as pd


class CsvPart(NamedTuple):
    """Consecutive rows of a table as ``DataFrame.to_csv`` formats them (no header), with the
    layout they were formatted in."""

    text: str
    columns: tuple[str, ...]
    dtypes: tuple[str, ...]
    rows: int


def _layout(frame: pd.DataFrame) -> tuple[tuple[str, ...], tuple[str, ...]]:
    return tuple(frame.columns), tuple(str(dtype) for dtype in frame.dtypes)


def csv_part(frame: pd.DataFrame) -> CsvPart:
    """The rows of ``frame`` formatted as CSV, for :func:`csv_from_parts`."""
    return CsvPart(frame.to_csv(index=False, header=False), *_layout(frame), len(frame))


def csv_from_parts(table: pd.DataFrame, parts) -> str | None:
    """``table.to_csv(index=False)`` with its first rows taken from ``parts`` (in order), or
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
    if covered > len(table) or any((part.columns, part.dtypes) != layout for part in parts):
        return None
    rest = table.iloc[covered:].to_csv(index=False, header=False) if covered < len(table) else ""
    return [table.iloc[:0].to_csv(index=False), *(part.text for part in parts), rest]
