"""Reading tidy input tables (CSV or Excel) with row numbers kept for error messages.

Rows are numbered as in the file: for CSV the line number (comment lines count, so the
number is where an editor shows the row); for Excel the sheet row; for a pandas DataFrame
its index label (messages say "DataFrame, row <label>").

Comments: lines (sheet rows) above the header whose first non-blank character is ``#`` are
comments, as are blank lines anywhere.  From the header on, every line that is not blank is
data, whatever it starts with, so a comment can never swallow a row (an experiment named
``#3`` is an experiment).

Names (``experiment``, ``survey``, ``stream`` and the other columns of
:data:`tromplab.loading.names.NAME_COLUMNS`, and class strings) are read as text exactly as
written (:mod:`tromplab.loading.names`): ``01`` and ``1`` are two names, and ``NA`` or
``None`` are names; only an empty cell is blank.  In other columns the words pandas reads as
missing (``NA``, ``nan``, ``null``, ...) are blanks, as before.  A DataFrame goes through the
same :class:`Table` checks as a file, so the Python API and the CLI refuse the same
input with the same words.

Before anything is parsed the path is checked (it exists, is a file, is readable, is not
empty) and the format is recognised from the suffix and the first bytes: CSV text
(``.csv``, ``.txt``, ``.tsv``) in UTF-8, or an Excel workbook (``.xlsx``, ``.xlsm``).
Legacy ``.xls``, OpenDocument ``.ods``, compressed and binary files are refused with
a message saying what to do.  Text that is not UTF-8 is refused with the line of the
first undecodable byte (no encoding is guessed: a wrong guess would silently change
names).

European CSV (semicolon separator, decimal comma) is read when declared (``sep=";"``,
``decimal=","``) or detected from the header and the cells; a detected layout is
reported as an :class:`InputNote`.  A comma-separated file with decimal commas shifts
its columns; rows with more fields than the header are refused with a hint.
"""

from __future__ import annotations

import csv
import datetime
import difflib
import io
import itertools
import logging
import math
import os
import pickle
import re
import tempfile
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import InputError, InputNote
from .names import MISSING_WORDS, cell_name, is_name_column, names_as_text
from .paths import check_input_file  # noqa: F401 - read from here by the loaders' callers

logger = logging.getLogger(__name__)

EXCEL_SUFFIXES = {".xlsx", ".xlsm"}
TEXT_SUFFIXES = {".csv", ".txt", ".tsv"}
_REFUSED_SUFFIXES = {
    ".xls": "legacy Excel .xls workbooks are not read: save the sheet as .xlsx (Excel workbook) or CSV UTF-8",
    ".ods": "OpenDocument .ods spreadsheets are not read: save the sheet as .xlsx or CSV UTF-8",
    ".gz": "compressed files are not read: decompress it first (gunzip) and give the CSV",
    ".zip": "zip archives are not read: extract the CSV or .xlsx first",
}
_MAGIC = (  # first bytes of formats that are not CSV text, and what to do about them
    (b"\x1f\x8b", "the file is gzip-compressed: decompress it first (gunzip) and give the CSV"),
    (
        b"PK\x03\x04",
        "the file is a zip archive (an .xlsx or .ods workbook under another name?): "
        "give a workbook the suffix .xlsx, or save the sheet as CSV UTF-8",
    ),
    (b"\xd0\xcf\x11\xe0", "the file is a legacy Excel (.xls) or other OLE document: save the sheet as .xlsx or CSV UTF-8"),
    (b"%PDF", "the file is a PDF document, not a table"),
    (b"\xff\xfe", "the file is UTF-16 text: save it as UTF-8 (in Excel: CSV UTF-8)"),
    (b"\xfe\xff", "the file is UTF-16 text: save it as UTF-8 (in Excel: CSV UTF-8)"),
)
_TRUTH = {"true": True, "1": True, "yes": True, "y": True, "false": False, "0": False, "no": False, "n": False}
_DECIMAL_COMMA = re.compile(r"^\s*[-+]?\d+,\d+(?:[eE][-+]?\d+)?\s*$")
NOTE_COLUMNS = ("note", "comment")  # free-text columns every loader accepts and ignores


@dataclass(frozen=True)
class Table:
    """A data table with the file row number of each record."""

    frame: pd.DataFrame
    rows: np.ndarray
    source: str
    notes: tuple[str, ...] = ()

    def error(self, message: str, *, index: int | None = None, column: str | None = None) -> InputError:
        """An :class:`InputError` pointing at record ``index`` (0-based) and ``column``."""
        row = None if index is None else self.rows[index]
        row = int(row) if isinstance(row, (int, np.integer)) else row  # a DataFrame's index label may be text
        return InputError(message, source=self.source, row=row, column=column)

    def refuse_where(self, bad: np.ndarray, column: str | None, message: str | Callable[[int], str]) -> None:
        """Raise an :class:`InputError` naming the first record where ``bad`` (one boolean per
        record) is true and ``column``; ``message`` says what is wrong: the text, or a function of
        the record's index (0-based) that makes it, called only for the record refused."""
        refused = np.flatnonzero(bad)
        if refused.size:
            index = int(refused[0])
            raise self.error(message(index) if callable(message) else message, index=index, column=column)

    def refuse_outside(self, values: np.ndarray, column: str, low: float, high: float) -> None:
        """Raise an :class:`InputError` naming the first record of ``values`` (the numbers of
        ``column``) outside ``[low, high]``."""
        self.refuse_where((values < low) | (values > high), column, lambda i: f"{values[i]:g} is outside [{low:g}, {high:g}]")

    def require(self, *columns: str) -> None:
        missing = [c for c in columns if c not in self.frame.columns]
        if missing:
            have = ", ".join(map(str, self.frame.columns))
            raise InputError(f"missing column(s) {', '.join(missing)} (columns present: {have})", source=self.source)

    def unknown_columns(self, known) -> str:
        """The columns not in ``known`` (nor a free-text note column), each with a close
        known name when there is one; "" when every column is known."""
        known = list(dict.fromkeys(known))
        described = []
        for column in self.frame.columns:
            if column in known or column.lower() in NOTE_COLUMNS:
                continue
            close = difflib.get_close_matches(column, known, n=1, cutoff=0.75)
            described.append(f"'{column}'" + (f" (did you mean '{close[0]}'?)" if close else ""))
        return ", ".join(described)

    def refuse_unknown(self, known, *, what: str = "table") -> None:
        """Refuse columns that are not in ``known`` (nor a free-text note column), listing them.

        A close known name is suggested for each, so typos (``partiton_fine``,
        ``experimnet``) are caught rather than ignored.
        """
        described = self.unknown_columns(known)
        if described:
            first = described.split("'")[1]
            raise InputError(
                f"unknown column(s) {described} in a {what}; rename them (--rename OLD=NEW) or name free text "
                "'note' or 'comment'",
                source=self.source,
                column=first,
            )

    def numeric(self, column: str, *, allow_blank: bool = False) -> np.ndarray:
        """Column as finite floats; text, dates, inf and (unless allowed) blanks raise naming the first bad row."""
        raw = self.frame[column]
        if pd.api.types.is_float_dtype(raw.dtype) or (
            pd.api.types.is_integer_dtype(raw.dtype) and not pd.api.types.is_bool_dtype(raw.dtype)
        ):
            return self._checked_numbers(
                raw, raw.to_numpy(dtype=float, na_value=np.nan), column, allow_blank
            )  # parsed: no text, no dates
        dates = _date_cells(raw)
        if dates.any():
            i = int(np.flatnonzero(dates)[0])
            raise self.error(f"'{raw.iloc[i]}' is a date, not a number (a cell formatted as a date?)", index=i, column=column)
        values = _as_floats(raw)
        text = raw.notna().to_numpy() & np.isnan(values)
        if text.any():
            i = int(np.flatnonzero(text)[0])
            hint = (
                " (a decimal comma? declare it: --decimal ',', Python decimal=',')"
                if _DECIMAL_COMMA.match(str(raw.iloc[i]))
                else ""
            )
            raise self.error(f"'{raw.iloc[i]}' is not a number{hint}", index=i, column=column)
        return self._checked_numbers(raw, values, column, allow_blank)

    def _checked_numbers(self, raw: pd.Series, values: np.ndarray, column: str, allow_blank: bool) -> np.ndarray:
        infinite = np.isinf(values)
        if infinite.any():
            i = int(np.flatnonzero(infinite)[0])
            raise self.error(f"'{_shortened(raw.iloc[i])}' is not a finite number", index=i, column=column)
        if not allow_blank and np.isnan(values).any():
            i = int(np.flatnonzero(np.isnan(values))[0])
            raise self.error("value is missing (blank or NaN)", index=i, column=column)
        return values

    def boolean(self, column: str) -> np.ndarray:
        """Column of yes/no marks (true/false, 1/0, yes/no, y/n; any case)."""
        values = self.frame[column]
        if values.dtype == bool:  # parsed from True/False by the reader: every cell is a mark
            return values.to_numpy(dtype=bool, copy=True)
        marks = []
        for i, value in enumerate(values):
            text = str(value).strip().lower()
            text = text[:-2] if text.endswith(".0") else text
            if text not in _TRUTH:
                raise self.error(f"'{value}' is not a yes/no mark", index=i, column=column)
            marks.append(_TRUTH[text])
        return np.asarray(marks, dtype=bool)

    def names(self, column: str, *, what: str | None = None) -> np.ndarray:
        """A name column as text (read so by :func:`read_table`); with ``what``, a blank cell
        is refused ("{what} name is blank"), else it is ""."""
        names = [value if isinstance(value, str) else cell_name(value) for value in self.frame[column].tolist()]
        blank = np.fromiter((not name for name in names), dtype=bool, count=len(names))
        if what is not None:
            self.refuse_where(blank, column, f"{what} name is blank")
        return np.asarray([name or "" for name in names], dtype=object)

    def experiment_labels(self) -> np.ndarray:
        """The ``experiment`` column as names; the file's name when there is no such column."""
        if "experiment" not in self.frame.columns:
            return np.full(len(self.frame), Path(self.source).stem, dtype=object)
        return self.names("experiment", what="experiment")

    def subset(self, selection) -> Table:
        """The records selected by a boolean mask or by integer positions (in that order)."""
        selection = np.asarray(selection)
        if selection.dtype != bool:
            selection = selection.astype(int)
        return Table(self.frame.iloc[selection].reset_index(drop=True), self.rows[selection], self.source, self.notes)


def _as_floats(raw: pd.Series) -> np.ndarray:
    """The cells as floats, NaN where a cell is not a number.  An integer too large for a
    float (400 digits) is infinite, as ``float`` reads it, so that it is refused as such:
    pandas raises an ``OverflowError`` on the whole column instead."""
    try:
        return pd.to_numeric(raw, errors="coerce").to_numpy(dtype=float)
    except OverflowError:
        return np.array([_cell_float(value) for value in raw.tolist()], dtype=float)


def _cell_float(value) -> float:
    try:
        return float(str(value).strip())
    except (TypeError, ValueError):
        return math.nan


def _shortened(value, width: int = 40) -> str:
    """A cell as text for a message, long numbers cut in the middle (``1000...0000 (400 digits)``)."""
    text = str(value)
    return text if len(text) <= width else f"{text[:12]}...{text[-8:]} ({len(text)} characters)"


def read_table(
    path,
    *,
    sheet: str | int | None = None,
    sep: str | None = None,
    decimal: str | None = None,
    columns=None,
    text_columns=(),
) -> Table:
    """Read a CSV (``#`` comments allowed) or Excel file, or take a DataFrame, into a :class:`Table`.

    Parameters
    ----------
    path : str, path-like or pandas.DataFrame
        The file (format from the suffix, checked against the content), or a DataFrame
        already in memory (see :func:`table_from_frame`).
    sheet : str or int, optional
        Excel sheet (name or 0-based position); the first sheet by default.
    sep, decimal : str, optional
        CSV field separator and decimal mark; detected when not given (comma and point
        unless the header is split by semicolons and the cells use decimal commas).
    columns : collection of str, optional
        Keep only these columns of a CSV (the others are checked as the header is, but not
        parsed: a large table read for a few of its columns needs a fraction of the memory).
    text_columns : collection of str, optional
        Columns read as names besides :data:`~tromplab.loading.names.NAME_COLUMNS` (the
        columns a rename will turn into name columns).

    Raises
    ------
    InputError
        When the file is missing, not a file, unreadable, empty, of an unknown or
        unsupported format, not UTF-8, has duplicate or unnamed columns, rows with more
        fields than the header, no data rows, or the sheet does not exist.
    """
    if isinstance(path, pd.DataFrame):
        _refuse_file_options_with_a_frame(sheet, sep, decimal)
        return table_from_frame(path, text_columns=text_columns)
    path, sep = _checked_file_request(path, sep, decimal)
    source = str(path)
    _check_path(path)
    suffix = path.suffix.lower()
    if suffix in EXCEL_SUFFIXES:
        if sep is not None or decimal is not None:
            raise InputError("sep and decimal apply to CSV files, not to an Excel workbook", source=source)
        frame, rows, header = _read_excel(path, sheet, text_columns)
        notes = ()
    else:
        if sheet is not None:
            raise InputError(f"a sheet ({sheet!r}) was given but the file is not an Excel workbook", source=source)
        frame, rows, header, notes = _read_csv(path, sep=sep, decimal=decimal, columns=columns, text_columns=text_columns)
    frame = _named_columns(frame, header, columns, source, text_columns)
    if frame.empty:
        raise InputError("the table has a header but no data rows", source=source)
    for note in notes:
        warnings.warn(f"{source}: {note}", InputNote, stacklevel=2)
    logger.info("read %s: %d data rows, columns %s", source, len(frame), ", ".join(map(str, frame.columns)))
    return Table(frame.reset_index(drop=True), rows, source, tuple(notes))


def _refuse_file_options_with_a_frame(sheet, sep, decimal) -> None:
    if sheet is not None:
        raise InputError(f"a sheet ({sheet!r}) was given with a DataFrame", source=DATAFRAME_SOURCE)
    if sep is not None or decimal is not None:
        raise InputError("sep and decimal apply to CSV files, not to a DataFrame", source=DATAFRAME_SOURCE)


def _checked_file_request(path, sep: str | None, decimal: str | None) -> tuple[Path, str | None]:
    """The path of a table file and its separator (a tab spelled out as ``\\t`` or ``tab``), or
    an error for another kind of argument or a separator or decimal mark that is not one character."""
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"a table is read from a file path (str or path-like) or a pandas DataFrame, got {type(path).__name__}")
    path = Path(path)
    sep = {"\\t": "\t", "tab": "\t"}.get(sep, sep)  # a tab is hard to type on a command line
    for name, value in (("separator (--sep)", sep), ("decimal mark (--decimal)", decimal)):
        if value is not None and (len(value) != 1 or value in '"\n\r' or value.isalnum()):
            raise InputError(f"the {name} must be one character such as ';' or ',', got {value!r}", source=str(path))
    return path, sep


def _named_columns(frame: pd.DataFrame, header, columns, source: str, text_columns) -> pd.DataFrame:
    """``frame`` with the header's names (trimmed, checked), empty unnamed columns dropped and
    name columns as text."""
    _check_header(header, source)
    frame.columns = [str(c).strip() for c in (header if columns is None else frame.columns)]
    return _with_names_as_text(_drop_empty_unnamed(frame, source), text_columns)


#: Records per piece of :func:`read_table_in_pieces` (a piece of 10,000 points takes about 2 MB).
DEFAULT_PIECE_ROWS = 10_000


def read_table_in_pieces(
    path, *, piece_rows: int = DEFAULT_PIECE_ROWS, sep=None, decimal=None, columns=None, text_columns=(), warn: bool = True
) -> Iterator[Table]:
    """Read a CSV table in pieces of at most ``piece_rows`` records, each a :class:`Table`.

    The memory is bounded by the piece, not the file: lines are read one after another and
    each piece is parsed by pandas as :func:`read_table` parses the whole file (same values,
    row numbers, notes and errors; the layout detected from the header and the first 49 data
    lines).  An Excel workbook or a DataFrame is not read in pieces: it comes whole.

    Parameters
    ----------
    path : str, path-like or pandas.DataFrame
        The file, as for :func:`read_table`.
    piece_rows : int
        Most records per piece (at least 1); a record with quoted line breaks is never cut.
    sep, decimal, columns, text_columns
        As for :func:`read_table`.
    warn : bool
        Warn of the layout detected (:class:`~tromplab.errors.InputNote`), as :func:`read_table`
        does; False for a second reading of the same file.

    Yields
    ------
    Table
        Consecutive records of the file, with their line numbers; a piece whose lines are
        all blank cells is left out.

    Raises
    ------
    InputError
        As :func:`read_table`, when the piece with the fault is read.  Where a quoted field
        spans lines, rows are numbered by their first line (the whole-file reader numbers
        such a table's records instead).
    """
    if isinstance(path, pd.DataFrame) or (isinstance(path, (str, os.PathLike)) and Path(path).suffix.lower() in EXCEL_SUFFIXES):
        yield read_table(path, sep=sep, decimal=decimal, columns=columns, text_columns=text_columns)
        return
    if int(piece_rows) < 1:
        raise ValueError(f"piece_rows must be at least 1, got {piece_rows}")
    path, sep = _checked_file_request(path, sep, decimal)
    _check_path(path)
    source = str(path)
    blocks = _content_blocks(path, min(1 << 20, 64 * int(piece_rows)))  # characters: about a piece's lines
    numbers, lines = _first_lines_of(blocks, 50)
    if not lines:
        raise InputError("the file has no header and no data (only comments or blank lines)", source=source)
    header_number, header_line = numbers[0], lines[0]
    sep, decimal, notes = csv_layout(header_line, lines[1:50], sep, decimal, path.suffix.lower(), source)
    header = _checked_header_line(header_line, sep, source, notes if warn else ())
    count = lines_before = 0
    for piece_numbers, piece in _pieces(itertools.chain([(numbers[1:], lines[1:])], blocks), int(piece_rows)):
        body = "\n".join([header_line, *piece])
        frame, rows = parse_csv_body(body, [header_number, *piece_numbers], header, header_line, sep=sep,
                                     decimal=decimal, columns=columns, text_columns=text_columns, source=source,
                                     records_before=lines_before)  # fmt: skip
        lines_before += len(piece)
        frame = _named_columns(frame, header[: frame.shape[1]] if columns is None else header, columns, source, text_columns)
        if not frame.empty:
            count += len(frame)
            yield Table(frame.reset_index(drop=True), rows, source, tuple(notes))
    if not count:
        raise InputError("the table has a header but no data rows", source=source)
    logger.info("read %s in pieces of %d records: %d data rows", source, piece_rows, count)


def _checked_header_line(header_line: str, sep: str, source: str, notes) -> list[str]:
    """The checked names of a header line; the notes on the layout are warned of."""
    header = header_cells(header_line, sep)
    _check_header(header, source)
    for note in notes:
        warnings.warn(f"{source}: {note}", InputNote, stacklevel=3)
    return header


def _content_blocks(path: Path, block: int = 1 << 20) -> Iterator[tuple[list[int], list[str]]]:
    """``(numbers, lines)`` of the header line and the data lines of a CSV file, a block of
    about ``block`` characters at a time (line breaks ``\\r\\n``, ``\\r`` or ``\\n``): comments
    and blank lines above the header are skipped, below it blank lines only, as
    :func:`_content_lines` does."""
    count, header_seen = 0, False
    newline = None if _bare_carriage_returns(path) else ""
    try:
        with path.open(encoding="utf-8-sig", newline=newline) as stream:
            for text in _line_blocks(stream, block):
                lines = text.split("\n")
                if "\r" in text:  # CRLF line ends; a carriage return inside a quoted name stays (as read whole)
                    lines = [line[:-1] if line.endswith("\r") else line for line in lines]
                numbers = range(count + 1, count + 1 + len(lines))
                count += len(lines)
                if not header_seen:
                    first = next((i for i, line in enumerate(lines) if not is_comment_or_blank(line)), None)
                    if first is None:
                        continue
                    header_seen = True
                    lines, numbers = lines[first:], numbers[first:]
                if any(not line.strip(" \t") for line in lines):
                    keep = [i for i, line in enumerate(lines) if line.strip(" \t")]
                    lines, numbers = [lines[i] for i in keep], [numbers[i] for i in keep]
                if lines:
                    yield list(numbers), lines
    except UnicodeDecodeError:
        raise _first_undecodable(path) from None


def _bare_carriage_returns(path: Path) -> bool:
    """Whether the file's lines end in a bare carriage return (old Mac line ends): read with
    universal newlines then; other files keep a carriage return inside a quoted name."""
    with path.open("rb") as stream:
        head = stream.read(1 << 16)
    first_return, first_feed = head.find(b"\r"), head.find(b"\n")
    return first_return >= 0 and (first_feed < 0 or first_return < first_feed - 1)


def _line_blocks(stream, block: int) -> Iterator[str]:
    """The text of ``stream`` in blocks of whole lines, each without its last line break."""
    carry = ""
    while text := stream.read(block):
        text = carry + text
        cut = text.rfind("\n")
        if cut < 0:
            carry = text
            continue
        carry = text[cut + 1 :]
        yield text[:cut]
    if carry:
        yield carry


def _first_lines_of(blocks, count: int) -> tuple[list[int], list[str]]:
    """At least ``count`` content lines from ``blocks`` (all there are when fewer), with their numbers."""
    numbers, lines = [], []
    while len(lines) < count:
        found = next(blocks, None)
        if found is None:
            break
        numbers += found[0]
        lines += found[1]
    return numbers, lines


def _first_undecodable(path: Path, block: int = 1 << 20) -> InputError:
    """The error :func:`_decoded_text` gives for the first byte of ``path`` that is not UTF-8,
    found block by block."""
    lines, carry = 0, b""
    with path.open("rb") as stream:
        for data in iter(lambda: stream.read(block), b""):
            data = carry + data
            try:
                data.decode("utf-8")
                carry = b""
            except UnicodeDecodeError as error:
                if error.reason != "unexpected end of data":  # not a character cut by the block's end
                    return not_utf8(str(path), data[error.start], lines + data[: error.start].count(b"\n") + 1)
                carry = data[error.start :]
                data = data[: error.start]
            lines += data.count(b"\n")
    return not_utf8(str(path), carry[0], lines + 1)


def _pieces(blocks, piece_rows: int) -> Iterator[tuple[list[int], list[str]]]:
    """``(numbers, lines)`` of consecutive pieces of at most ``piece_rows`` lines of ``blocks``,
    longer only to end outside double quotes (a quoted field may hold a line break)."""
    numbers, lines = [], []
    for more_numbers, more_lines in blocks:
        numbers += more_numbers
        lines += more_lines
        start = 0
        while len(lines) - start >= piece_rows:
            end = _end_outside_quotes(lines, start, start + piece_rows)
            if end is None:
                break
            yield numbers[start:end], lines[start:end]
            start = end
        numbers, lines = numbers[start:], lines[start:]
    if lines:
        yield numbers, lines


def _end_outside_quotes(lines: list[str], start: int, end: int) -> int | None:
    """The first end at or after ``end`` where ``lines[start:end]`` hold an even number of
    double quotes; None when the lines run out first."""
    quotes = "".join(lines[start:end]).count('"')
    while quotes % 2 and end < len(lines):
        quotes += lines[end].count('"')
        end += 1
    return None if quotes % 2 else end


#: Most temporary files among which the rows of a table whose experiments are not consecutive
#: are sorted (experiments in order of first appearance, a run of them per file).
MAX_SORT_FILES = 256


@dataclass
class ExperimentIndex:
    """What a first pass over the pieces of a table finds: the number of rows of each
    experiment in order of first appearance, and whether each experiment's rows are
    consecutive (one entry per experiment in memory).  ``columns`` is for the caller (the
    columns its checks found)."""

    counts: dict = field(default_factory=dict)
    consecutive: bool = True
    last: str | None = None
    columns: object = None

    def add(self, labels: np.ndarray) -> None:
        """Count the rows of a piece, ``labels`` naming the experiment of each."""
        if not labels.size:
            return
        runs = labels[np.flatnonzero(np.r_[True, labels[1:] != labels[:-1]])]
        fresh = runs[1:] if runs[0] == self.last else runs
        if len(set(fresh)) < fresh.size or any(name in self.counts for name in fresh):
            self.consecutive = False
        self.last = runs[-1]
        names, first, counts = np.unique(labels, return_index=True, return_counts=True)
        for at in np.argsort(first, kind="stable"):
            self.counts[names[at]] = self.counts.get(names[at], 0) + int(counts[at])

    def runs(self, rows_per_run: int) -> tuple[dict, int]:
        """The position of each experiment and how many consecutive experiments share one of
        at most :data:`MAX_SORT_FILES` runs of about ``rows_per_run`` rows."""
        rows_per_experiment = sum(self.counts.values()) / len(self.counts)
        per_run = max(1, int(rows_per_run / rows_per_experiment), -(-len(self.counts) // MAX_SORT_FILES))
        return {name: i for i, name in enumerate(self.counts)}, per_run


def iter_experiment_tables(
    path, *, piece_rows: int = DEFAULT_PIECE_ROWS, sep=None, decimal=None, text_columns=(), warn: bool = True
) -> Iterator[Table]:
    """The rows of each experiment of a CSV table as a :class:`Table`, the file read in pieces.

    For readers that work experiment by experiment (a lab table's mass balances): the tables
    come in order of first appearance, each with the file's row numbers, after a first pass
    that counts each experiment's rows (and makes the checks of :func:`read_table`, and the
    blank-name check of :meth:`Table.experiment_labels`).  Rows of one experiment spread over
    the file are sorted on disk (at most :data:`MAX_SORT_FILES` temporary files).  Without an
    ``experiment`` column the whole table is one experiment, and comes whole.

    Parameters
    ----------
    path : str or path-like
        The file (a workbook or DataFrame is read whole, see :func:`read_table_in_pieces`).
    piece_rows : int
        Records per piece.
    sep, decimal, text_columns
        As for :func:`read_table`.
    warn : bool
        Warn of the layout detected, as :func:`read_table` does; False for a second reading.

    Yields
    ------
    Table
        The rows of one experiment.
    """

    def pieces(warn: bool):
        return read_table_in_pieces(path, piece_rows=piece_rows, sep=sep, decimal=decimal, text_columns=text_columns, warn=warn)

    index = ExperimentIndex()
    for table in pieces(warn):
        index.add(table.experiment_labels())
    if index.consecutive:
        yield from _consecutive_experiment_tables(pieces(False), index.counts)
        return
    position, per_run = index.runs(piece_rows)
    with tempfile.TemporaryDirectory(prefix="tromplab-sort-") as folder:
        for table in pieces(False):
            run = (
                np.fromiter((position[name] for name in table.experiment_labels()), dtype=int, count=len(table.frame)) // per_run
            )
            for number in np.unique(run):
                with open(Path(folder) / f"{number}.pickle", "ab") as stream:  # our own file, read back below
                    pickle.dump(table.subset(run == number), stream)
        for number in range(-(-len(position) // per_run)):
            with open(Path(folder) / f"{number}.pickle", "rb") as stream:
                parts = list(_pickled(stream))
            yield from _consecutive_experiment_tables([_joined_tables(parts)], None)


def _pickled(stream):
    while True:
        try:
            yield pickle.load(stream)  # noqa: S301 - a temporary file this module wrote
        except EOFError:
            return


def _consecutive_experiment_tables(pieces, counts: dict | None) -> Iterator[Table]:
    """The table of each experiment of ``pieces``, yielded when its ``counts`` rows are read
    (``counts`` None: every experiment of the pieces, at their end)."""
    pending: dict[str, list[Table]] = {}
    order = iter(counts.items()) if counts is not None else None
    waiting, expected = next(order, (None, 0)) if order is not None else (None, 0)
    for table in pieces:
        for name, rows in experiment_rows(table.experiment_labels()).items():
            pending.setdefault(name, []).append(table.subset(rows))
        while waiting is not None and sum(len(part.frame) for part in pending.get(waiting, ())) == expected:
            yield _joined_tables(pending.pop(waiting))
            waiting, expected = next(order, (None, 0))
    for parts in pending.values():  # counts None: all at the end, in order of first appearance
        yield _joined_tables(parts)


def experiment_rows(labels) -> dict:
    """Positions of each experiment's rows, experiments in order of first appearance (one
    pass over the labels: a file of 10,000 experiments is not scanned 10,000 times)."""
    groups = pd.Series(np.arange(len(labels))).groupby(pd.Series(labels, dtype=object), sort=False).indices
    return {name: np.asarray(groups[name]) for name in dict.fromkeys(labels)}


def _joined_tables(parts: list[Table]) -> Table:
    if len(parts) == 1:
        return parts[0]
    frame = pd.concat([part.frame for part in parts], ignore_index=True)
    return Table(frame, np.concatenate([part.rows for part in parts]), parts[0].source, parts[0].notes)


DATAFRAME_SOURCE = "DataFrame"


def table_from_frame(frame: pd.DataFrame, *, source: str = DATAFRAME_SOURCE, text_columns=()) -> Table:
    """A :class:`Table` from a DataFrame; rows are named by the frame's index labels.

    Column names are stripped of spaces, name columns (and ``text_columns``) become text as
    a file's do (a number ``1`` the name ``"1"``; a missing value stays blank) and rows that
    are blank throughout are dropped, as for a file; the frame itself is not changed.

    Examples
    --------
    >>> frame = pd.DataFrame({"size": [10, "ten"]}, index=["a", "b"])
    >>> table_from_frame(frame).numeric("size")
    Traceback (most recent call last):
    ...
    tromplab.errors.InputError: DataFrame, row b, column 'size': 'ten' is not a number
    """
    if not isinstance(frame, pd.DataFrame):
        raise InputError(f"expected a pandas DataFrame, got {type(frame).__name__}", source=source)
    frame = frame.copy()
    frame.columns = [str(c).strip() for c in frame.columns]
    if len(set(frame.columns)) != len(frame.columns):
        twice = sorted({c for c in frame.columns if list(frame.columns).count(c) > 1})
        raise InputError(f"column(s) {', '.join(twice)} appear more than once", source=source)
    frame = _with_names_as_text(frame, text_columns)
    keep = ~frame.isna().all(axis=1).to_numpy()
    rows = np.asarray(frame.index[keep], dtype=object)
    frame = frame.loc[keep].reset_index(drop=True)
    if frame.empty:
        raise InputError("the table has no data rows", source=source)
    return Table(frame, rows, source)


def _with_names_as_text(frame: pd.DataFrame, text_columns=()) -> pd.DataFrame:
    """``frame`` with its name columns as text (:func:`~tromplab.loading.names.names_as_text`)."""
    named = [position for position, column in enumerate(frame.columns) if is_name_column(column, text_columns)]
    if not named:
        return frame
    frame = frame.copy()
    for position in named:
        frame[frame.columns[position]] = names_as_text(frame.iloc[:, position])
    return frame


def _check_path(path: Path) -> None:
    source = str(path)
    if not path.exists():
        raise InputError("file not found", source=source)
    if path.is_dir():
        raise InputError("is a directory, not a file", source=source)
    if not path.is_file():
        raise InputError("is not a regular file", source=source)
    if not os.access(path, os.R_OK):
        raise InputError("the file is not readable (permission denied)", source=source)
    if path.stat().st_size == 0:
        raise InputError("the file is empty", source=source)
    suffix = path.suffix.lower()
    if suffix in _REFUSED_SUFFIXES:
        raise InputError(_REFUSED_SUFFIXES[suffix], source=source)
    if suffix not in EXCEL_SUFFIXES | TEXT_SUFFIXES:
        raise InputError(
            f"unknown format '{path.suffix}': give a CSV file (.csv, .txt, .tsv) or an Excel workbook (.xlsx, .xlsm)",
            source=source,
        )
    try:
        with path.open("rb") as handle:
            head = handle.read(8192)
    except OSError as error:
        raise InputError(f"cannot read the file: {error.strerror}", source=source) from None
    if suffix in EXCEL_SUFFIXES:
        if not head.startswith(b"PK\x03\x04"):
            raise InputError("the file has an Excel suffix but is not an .xlsx workbook (a CSV or .xls renamed?)", source=source)
        return
    for magic, message in _MAGIC:
        if head.startswith(magic):
            raise InputError(message, source=source)
    if b"\x00" in head:
        raise InputError("the file is binary (it contains NUL bytes), not a CSV text table", source=source)


#: A comment line (first non-blank character '#') or a blank line (spaces and tabs only), its
#: line break removed.
_COMMENT_OR_BLANK_LINE = re.compile(r"[ \t]*(?:#|\Z)")
#: The first line as a comment or blank, and a blank line after a line break: searched by the
#: literal line break, which the regex engine finds a block at a time (the ``^`` of MULTILINE is
#: tried at every character: 0.2 s on 52 MB)
_FIRST_LINE_COMMENT_OR_BLANK = re.compile(r"[ \t]*(?:#|\r?(?:\n|\Z))")
_LATER_BLANK_LINE = re.compile(r"\n[ \t]*\r?(?:\n|\Z)")
_LINE_BREAK = re.compile(r"\r\n|\r|\n")


def is_comment_or_blank(line: str) -> bool:
    """Whether a line above the header is a comment (first non-blank character ``#``) or blank.

    Below the header only a blank line is skipped: a line starting with ``#`` there is data.
    The CSV reader and the Excel reader (for the first non-empty cell of a row) both ask this.
    """
    return bool(_COMMENT_OR_BLANK_LINE.match(line))


def _lines_to_skip(text: str, end: int) -> bool:
    """Whether ``text[:end]`` has a line the reader skips: a comment or blank first line, or a
    blank line anywhere (else pandas reads the file as it is)."""
    return bool(_FIRST_LINE_COMMENT_OR_BLANK.match(text, 0, end) or _LATER_BLANK_LINE.search(text, 0, end))


def _content_lines(lines: list[str]) -> list[int]:
    """Numbers (1-based) of the header line and the data lines: comments and blank lines
    above the header are skipped, below it blank lines only."""
    header = next((i for i, line in enumerate(lines) if not is_comment_or_blank(line)), None)
    if header is None:
        return []
    return [header + 1] + [i + 1 for i in range(header + 1, len(lines)) if lines[i].strip(" \t")]


def _read_csv(path: Path, *, sep, decimal, columns=None, text_columns=()):
    source = str(path)
    text = _decoded_text(path)
    lines, content, body = _csv_content(path, text)
    if not content:
        raise InputError("the file has no header and no data (only comments or blank lines)", source=source)
    header_line = lines[content[0] - 1]
    first_rows = [lines[i - 1] for i in content[1:50]]
    del lines, text
    sep, decimal, notes = csv_layout(header_line, first_rows, sep, decimal, path.suffix.lower(), source)
    header = header_cells(header_line, sep)
    frame, rows = parse_csv_body(body, content, header, header_line, sep=sep, decimal=decimal, columns=columns,
                                 text_columns=text_columns, source=source)  # fmt: skip
    return frame, rows, (header[: frame.shape[1]] if columns is None else header), notes


def _decoded_text(path: Path) -> str:
    """The file as text, or an error naming the line of the first byte that is not UTF-8."""
    raw = path.read_bytes()
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        raise not_utf8(str(path), raw[error.start], raw[: error.start].count(b"\n") + 1) from None


def not_utf8(source: str, byte: int, line: int) -> InputError:
    """The error for a byte that cannot be decoded as UTF-8 on ``line`` (1-based)."""
    return InputError(
        f"the text is not UTF-8 (byte 0x{byte:02x} cannot be decoded): save the file as UTF-8 (in Excel: CSV UTF-8)",
        source=source,
        row=line,
    )


def _csv_content(path: Path, text: str) -> tuple[list[str], list[int], str | Path]:
    """``(lines, content, body)``: lines enough for the header and the layout's detection, the
    numbers (1-based) of the header line and the data lines, and what pandas parses (the file
    itself when every line is content, else the content lines joined)."""
    end = len(text)
    while end and text[end - 1] in "\r\n \t":
        end -= 1
    first_break = text.find("\n")
    plain_breaks = first_break > 0 and "\r" not in text[: first_break - 1]  # not old Mac line ends (a bare CR)
    if plain_breaks and not _lines_to_skip(text, end):  # the usual table: every line is content
        content = list(range(1, text.count("\n", 0, end) + 2))
        lines = [line.rstrip("\r") for line in _first_lines(text, 51)]  # enough for the header and decimal marks
        # pandas reads the file itself (a StringIO of a large text would hold four bytes per character)
        return lines, content, (path if text[end:] in ("", "\n", "\r\n") else text[:end])
    lines = _LINE_BREAK.split(text[:end])  # line breaks only: a name may hold a form feed or U+2028
    content = _content_lines(lines)
    return lines, content, "\n".join(lines[i - 1] for i in content)


def csv_layout(header_line: str, first_rows, sep, decimal, suffix: str, source: str) -> tuple[str, str, list[str]]:
    """``(sep, decimal, notes)``: the separator and decimal mark given, or detected from the
    header line and the first data lines (``first_rows``, up to 49), with a note for each found."""
    notes = []
    if sep is None:
        sep = _detect_separator(header_line, suffix)
        if sep != ",":
            notes.append(
                f"read as {'semicolon' if sep == ';' else 'tab'}-separated (detected from the header; declare it with --sep)"
            )
    if decimal is None:
        decimal = "."
        if sep != "," and any(_DECIMAL_COMMA.match(cell) for line in first_rows for cell in line.split(sep)):
            decimal = ","
            notes.append("decimal commas detected and read as decimal marks (declare them with --decimal ',')")
    if sep == decimal:
        raise InputError(f"the separator and the decimal mark are both '{sep}'", source=source)
    return sep, decimal, notes


def header_cells(header_line: str, sep: str) -> list[str]:
    """The column names of a header line, trimmed."""
    return [cell.strip() for cell in next(csv.reader([header_line], delimiter=sep, skipinitialspace=True))]


def parse_csv_body(body, content, header, header_line, *, sep, decimal, columns, text_columns, source, records_before=0):
    """``(frame, rows)``: the records of ``body`` (CSV text from the header line on, or a file
    of it) read as :func:`read_table` reads them, rows blank throughout dropped, and the line
    number of each record (``content``: the numbers of the header and data lines in ``body``);
    a record with more fields than the header is refused naming its line.  Where quoted fields
    span lines, records are numbered instead (from 2, after ``records_before`` records)."""
    wanted = None if columns is None else {str(c) for c in columns}
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", pd.errors.ParserWarning)
            frame = pd.read_csv(
                body if isinstance(body, Path) else io.StringIO(body),
                encoding="utf-8-sig",
                sep=sep,
                decimal=decimal,
                skip_blank_lines=False,
                skipinitialspace=True,
                index_col=False,
                header=0,
                usecols=None if wanted is None else (lambda name: str(name).strip() in wanted),
                **_value_options(header_line, sep, text_columns),
            )
        too_many = any(issubclass(w.category, pd.errors.ParserWarning) for w in caught)
    except (pd.errors.ParserError, ValueError) as error:
        _check_field_counts_of(body, content, len(header), sep, source)  # says which row, in words
        raise InputError(f"cannot parse as CSV: {error}", source=source) from None
    # pandas drops the extra fields of a row with a warning, or silently for the columns it does not
    # read: refuse them, naming the row
    if too_many or (wanted is not None and _has_long_records(body, sep, len(header))):
        _check_field_counts_of(body, content, len(header), sep, source)
    rows = np.asarray(content[1:], dtype=int)
    if rows.size != len(frame):  # quoted fields spanning lines: fall back to record numbers
        rows = np.arange(len(frame)) + 2 + records_before
    keep = ~frame.isna().all(axis=1).to_numpy()
    return frame.loc[keep], rows[keep]


def _value_options(header_line: str, sep: str, text_columns) -> dict:
    """The ``read_csv`` options that read name columns as text with only an empty cell blank,
    and every other column with pandas' words for missing (keyed by the labels pandas gives the
    header's cells)."""
    labels = pd.read_csv(io.StringIO(header_line), sep=sep, skipinitialspace=True, index_col=False, nrows=0).columns
    named = [label for label in labels if is_name_column(label, text_columns)]
    return {
        "dtype": dict.fromkeys(named, str),
        "keep_default_na": False,
        "na_values": {label: ([""] if label in named else list(MISSING_WORDS)) for label in labels},
    }


def _first_lines(text: str, count: int) -> list[str]:
    """``text.split("\n", count)[:count]`` without the copy of the rest of the text (52 MB for
    a large table) that the split makes as its last piece."""
    end = -1
    for _ in range(count):
        end = text.find("\n", end + 1)
        if end < 0:
            return text.split("\n")
    return text[:end].split("\n")


def _detect_separator(header: str, suffix: str) -> str:
    if suffix == ".tsv" or ("\t" in header and "," not in header and ";" not in header):
        return "\t"
    if header.count(";") > header.count(","):
        return ";"
    return ","


def _has_long_records(body: str | Path, sep: str, expected: int, block: int = 1 << 20) -> bool:
    """Whether a record after the header has more than ``expected`` fields, separators and line
    breaks inside double quotes not counted: one pass over the bytes in blocks of ``block``,
    without the Python strings of a full parse (trailing empty fields count here; the full
    check that follows forgives them)."""
    if isinstance(body, Path):
        with body.open("rb") as stream:
            blocks = iter(lambda: stream.read(block), b"")
            return _long_records_in(blocks, sep, expected)
    return _long_records_in([body.encode()], sep, expected)


def _long_records_in(blocks, sep: str, expected: int) -> bool:
    quote, separator, newline = ord('"'), ord(sep), ord("\n")
    parity, pending, header_seen = 0, 0, False
    for data in blocks:
        data = np.frombuffer(data, dtype=np.uint8)
        if not data.size:
            continue
        outside = _outside_quotes(data == quote, parity)
        parity = int(not outside[-1])
        # separators and record ends outside quotes, by position: the separators of a record
        # are those before its end (searchsorted), without a running count over the block
        separators = np.flatnonzero((data == separator) & outside)
        ends = np.flatnonzero((data == newline) & outside)
        if ends.size:
            per_record = np.diff(np.searchsorted(separators, ends), prepend=0)
            per_record[0] += pending
            if not header_seen:
                per_record, header_seen = per_record[1:], True
            if np.any(per_record + 1 > expected):
                return True
            pending = int(separators.size - np.searchsorted(separators, ends[-1]))
        else:
            pending += int(separators.size)
    return header_seen and pending + 1 > expected


def _outside_quotes(quotes: np.ndarray, parity: int) -> np.ndarray:
    """Which bytes of a block lie outside double quotes, given whether it starts inside them
    (``parity``): the runs between quotes lie alternately outside and inside (each quote counts
    with the run it starts), spread by np.repeat, a twentieth of the time of a running count."""
    runs = np.diff(np.flatnonzero(quotes), prepend=0, append=quotes.size)
    return np.repeat((np.arange(runs.size) + parity) % 2 == 0, runs)


def _check_field_counts_of(body: str | Path, line_numbers, expected: int, sep: str, source: str) -> None:
    """Refuse the first row with more fields than the header (the full parse, only for a table
    pandas could not read as it is; ``body`` the text without comments, or the file that has none)."""
    text = body.read_text(encoding="utf-8-sig") if isinstance(body, Path) else body
    records = list(csv.reader(io.StringIO(text), delimiter=sep, skipinitialspace=True))
    if len(records) != len(line_numbers):  # quoted fields spanning lines: name the record (as the rows of the table do)
        line_numbers = list(range(1, len(records) + 1))
    _check_field_counts(records, line_numbers, expected, sep, source)


def _check_field_counts(records, line_numbers, expected: int, sep: str, source: str) -> None:
    for record, line in zip(records[1:], line_numbers[1:]):
        while len(record) > expected and record[-1].strip() == "":
            record = record[:-1]  # trailing separators add nothing
        if len(record) > expected:
            hint = ""
            if sep == "," and re.search(r"\d,\d", ",".join(record)):
                hint = (
                    "; decimal commas in a comma-separated file shift the columns: use decimal points, or "
                    "semicolons between fields with --sep ';' --decimal ','"
                )
            raise InputError(f"the row has {len(record)} fields but the header has {expected}{hint}", source=source, row=line)


def _check_header(header, source: str) -> None:
    names = [str(c).strip() for c in header]
    seen = set()
    for name in names:
        if name == "":
            continue  # columns without a header: dropped when empty, refused otherwise (_drop_empty_unnamed)
        if name in seen:
            raise InputError(f"duplicate column '{name}': each column name may appear once", source=source, column=name)
        seen.add(name)


def _drop_empty_unnamed(frame: pd.DataFrame, source: str) -> pd.DataFrame:
    """Columns without a header: dropped when empty (trailing separators), refused otherwise."""
    keep = []
    for position, name in enumerate(frame.columns):
        if name == "" or name.startswith("Unnamed: ") or name == "nan":
            if frame.iloc[:, position].notna().any():
                raise InputError(f"column {position + 1} holds values but has no header", source=source)
            continue
        keep.append(position)
    return frame.iloc[:, keep]


def _date_cells(values: pd.Series) -> np.ndarray:
    if pd.api.types.is_datetime64_any_dtype(values) or pd.api.types.is_timedelta64_dtype(values):
        return values.notna().to_numpy()
    if values.dtype != object:
        return np.zeros(len(values), dtype=bool)
    kinds = (datetime.date, datetime.time, datetime.timedelta, np.datetime64)
    return np.fromiter((isinstance(v, kinds) for v in values), dtype=bool, count=len(values))


def _read_excel(path: Path, sheet, text_columns=()):
    try:
        workbook = pd.ExcelFile(path)
    except Exception as error:  # openpyxl raises several unrelated types for a bad workbook
        raise InputError(f"cannot open as an Excel workbook: {error}", source=str(path)) from None
    if sheet is None:
        sheet = workbook.sheet_names[0]
    elif isinstance(sheet, str) and sheet not in workbook.sheet_names:
        raise InputError(f"no sheet named '{sheet}' (sheets: {', '.join(workbook.sheet_names)})", source=str(path))
    # every cell as the sheet holds it (an empty one as ""): names keep "NA" and "01" as text
    frame = pd.read_excel(workbook, sheet_name=sheet, header=None, dtype=object, keep_default_na=False)
    at = next((i for i, row in enumerate(frame.itertuples(index=False)) if not is_comment_or_blank(_first_text(row))), None)
    if at is None:
        raise InputError(f"sheet '{sheet}' is empty (or holds only comments)", source=str(path))
    header = [str(v) for v in frame.iloc[at]]
    frame = frame.iloc[at + 1 :]
    frame.columns = range(frame.shape[1])
    for position, name in enumerate(header):
        cells = frame[position]
        if is_name_column(name, text_columns):
            frame[position] = cells.where(cells != "", np.nan)
        else:
            frame[position] = cells.where(~cells.map(_missing_word), np.nan)
    frame = frame.infer_objects()
    keep = ~frame.isna().all(axis=1).to_numpy()
    rows = (np.arange(len(frame)) + at + 2)[keep]
    return frame.loc[keep], rows, header


def _missing_word(value) -> bool:
    return isinstance(value, str) and value in MISSING_WORDS


def _first_text(row) -> str:
    """The first cell of a sheet row that is not empty, as text ("" for an empty row)."""
    return next((text for text in (str(v) for v in row) if text.strip()), "")


# --- checks before any work -------------------------------------------------------------
