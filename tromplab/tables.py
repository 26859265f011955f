"""Reading tidy input tables (CSV or Excel) with row numbers kept for error messages.

Rows are numbered as in the file: for CSV the line number (comment lines starting with
``#`` count, so the number is where an editor shows the row); for Excel the sheet row
(header = row 1); for a pandas DataFrame its index label (messages say "DataFrame, row
<label>").  A DataFrame goes through the same :class:`Table` checks as a file, so the
Python API and the CLI refuse the same input with the same words.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from .errors import InputError

EXCEL_SUFFIXES = {".xlsx", ".xlsm", ".xls"}
_TRUTH = {"true": True, "1": True, "yes": True, "y": True, "false": False, "0": False, "no": False, "n": False}


@dataclass(frozen=True)
class Table:
    """A data table with the file row number of each record."""

    frame: pd.DataFrame
    rows: np.ndarray
    source: str

    def error(self, message: str, *, index: int | None = None, column: str | None = None) -> InputError:
        """An :class:`InputError` pointing at record ``index`` (0-based) and ``column``."""
        row = None if index is None else self.rows[index]
        row = int(row) if isinstance(row, (int, np.integer)) else row  # a DataFrame's index label may be text
        return InputError(message, source=self.source, row=row, column=column)

    def require(self, *columns: str) -> None:
        missing = [c for c in columns if c not in self.frame.columns]
        if missing:
            have = ", ".join(map(str, self.frame.columns))
            raise InputError(f"missing column(s) {', '.join(missing)} (columns present: {have})", source=self.source)

    def numeric(self, column: str, *, allow_blank: bool = False) -> np.ndarray:
        """Column as floats; text or (unless allowed) blanks raise naming the first bad row."""
        raw = self.frame[column]
        values = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=float)
        text = raw.notna().to_numpy() & np.isnan(values)
        if text.any():
            i = int(np.flatnonzero(text)[0])
            raise self.error(f"'{raw.iloc[i]}' is not a number", index=i, column=column)
        if not allow_blank and np.isnan(values).any():
            i = int(np.flatnonzero(np.isnan(values))[0])
            raise self.error("value is missing (blank or NaN)", index=i, column=column)
        return values

    def boolean(self, column: str) -> np.ndarray:
        """Column of yes/no marks (true/false, 1/0, yes/no, y/n; any case)."""
        marks = []
        for i, value in enumerate(self.frame[column]):
            text = str(value).strip().lower()
            text = text[:-2] if text.endswith(".0") else text
            if text not in _TRUTH:
                raise self.error(f"'{value}' is not a yes/no mark", index=i, column=column)
            marks.append(_TRUTH[text])
        return np.asarray(marks, dtype=bool)

    def experiment_labels(self) -> np.ndarray:
        """The ``experiment`` column as stripped text; the file's name when there is no such column."""
        if "experiment" not in self.frame.columns:
            return np.full(len(self.frame), Path(self.source).stem, dtype=object)
        labels = self.frame["experiment"]
        blank = labels.isna().to_numpy()
        if blank.any():
            raise self.error("experiment name is blank", index=int(np.flatnonzero(blank)[0]), column="experiment")
        return labels.astype(str).str.strip().to_numpy(dtype=object)

    def subset(self, mask) -> Table:
        mask = np.asarray(mask, dtype=bool)
        return Table(self.frame.loc[mask].reset_index(drop=True), self.rows[mask], self.source)


def read_table(path, *, sheet: str | int | None = None) -> Table:
    """Read a CSV (``#`` comments allowed) or Excel file, or take a DataFrame, into a :class:`Table`.

    Parameters
    ----------
    path : str, path-like or pandas.DataFrame
        The file, or a DataFrame already in memory (see :func:`table_from_frame`).
    sheet : str or int, optional
        Excel sheet (name or 0-based position); the first sheet by default.

    Raises
    ------
    InputError
        When the file is missing, empty, has no data rows, or the sheet does not exist.
    """
    if isinstance(path, pd.DataFrame):
        if sheet is not None:
            raise InputError(f"a sheet ({sheet!r}) was given with a DataFrame", source=DATAFRAME_SOURCE)
        return table_from_frame(path)
    path = Path(path)
    source = str(path)
    if not path.exists():
        raise InputError("file not found", source=source)
    if path.stat().st_size == 0:
        raise InputError("the file is empty", source=source)
    if path.suffix.lower() in EXCEL_SUFFIXES:
        frame, rows = _read_excel(path, sheet)
    else:
        if sheet is not None:
            raise InputError(f"a sheet ({sheet!r}) was given but the file is not an Excel workbook", source=source)
        frame, rows = _read_csv(path)
    frame.columns = [str(c).strip() for c in frame.columns]
    if frame.empty:
        raise InputError("the table has a header but no data rows", source=source)
    return Table(frame.reset_index(drop=True), rows, source)


DATAFRAME_SOURCE = "DataFrame"


def table_from_frame(frame: pd.DataFrame, *, source: str = DATAFRAME_SOURCE) -> Table:
    """A :class:`Table` from a DataFrame; rows are named by the frame's index labels.

    Column names are stripped of spaces and rows that are blank throughout are dropped, as
    for a file; the frame itself is not changed.

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
    keep = ~frame.isna().all(axis=1).to_numpy()
    rows = np.asarray(frame.index[keep], dtype=object)
    frame = frame.loc[keep].reset_index(drop=True)
    if frame.empty:
        raise InputError("the table has no data rows", source=source)
    return Table(frame, rows, source)


def _read_csv(path: Path):
    lines = path.read_text(encoding="utf-8-sig").splitlines()
    content = [i + 1 for i, line in enumerate(lines) if line.strip() and not line.lstrip().startswith("#")]
    if not content:
        raise InputError("the file has no header and no data (only comments or blank lines)", source=str(path))
    try:
        frame = pd.read_csv(path, comment="#", skip_blank_lines=True, skipinitialspace=True, encoding="utf-8-sig")
    except pd.errors.ParserError as error:
        raise InputError(f"cannot parse as CSV: {error}", source=str(path)) from None
    rows = np.asarray(content[1:], dtype=int)
    if rows.size != len(frame):  # quoted fields spanning lines: fall back to record numbers
        rows = np.arange(len(frame)) + 2
    keep = ~frame.isna().all(axis=1).to_numpy()
    return frame.loc[keep], rows[keep]


def _read_excel(path: Path, sheet):
    try:
        workbook = pd.ExcelFile(path)
    except Exception as error:  # openpyxl raises several unrelated types for a bad workbook
        raise InputError(f"cannot open as an Excel workbook: {error}", source=str(path)) from None
    if sheet is None:
        sheet = workbook.sheet_names[0]
    elif isinstance(sheet, str) and sheet not in workbook.sheet_names:
        raise InputError(f"no sheet named '{sheet}' (sheets: {', '.join(workbook.sheet_names)})", source=str(path))
    frame = pd.read_excel(workbook, sheet_name=sheet)
    keep = ~frame.isna().all(axis=1).to_numpy()
    rows = (np.arange(len(frame)) + 2)[keep]
    return frame.loc[keep], rows
