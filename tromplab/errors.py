"""Errors raised for bad input: each names the file, row and column at fault."""

from __future__ import annotations


class InputError(ValueError):
    """Bad input data.

    The message names the file, the row (as a spreadsheet user counts it: the header is
    row 1 of the data table, so the first data row is row 2) and the column, then says
    what is wrong.
    """

    def __init__(self, message: str, *, source: str | None = None, row: int | None = None, column: str | None = None):
        self.source = source
        self.row = row
        self.column = column
        self.reason = message
        where = []
        if source:
            where.append(str(source))
        if row is not None:
            where.append(f"row {row}")
        if column:
            where.append(f"column '{column}'")
        super().__init__(f"{', '.join(where)}: {message}" if where else message)
