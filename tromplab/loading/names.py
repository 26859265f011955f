"""Names in tables: the columns that hold names, how a cell becomes a name, and the mark that
keeps a name from turning into a spreadsheet formula.

A name is text exactly as written: ``01`` and ``1`` are two experiments, ``007`` stays
``007``, ``4E2`` stays ``4E2``, ``TRUE`` stays ``TRUE``, and ``NA``, ``None``, ``null`` or
``N/A`` are names; only an empty cell is blank.  The readers (:func:`tromplab.loading.tables.read_table`)
read the columns :func:`is_name_column` selects as text and pass every cell through
:func:`cell_name`: surrounding white space is trimmed, and a single quote in front of a
character that starts a formula (``'=1+1``) is dropped, as a spreadsheet drops it (the quote
marks a cell as text).  That quote is what tromplab's own CSV files carry in front of such
text (:func:`defended`, the usual defence against spreadsheet formula injection), so reading
them back gives the names as they were.

Class strings (``size_class``: ``+1168``, ``-150+75``) are read as text too, so that ``+1168``
stays a class and does not become the number 1168.
"""

from __future__ import annotations

import datetime
import math
import re

import numpy as np
import pandas as pd

#: Columns read as text by every table reader (names of experiments, surveys, streams, nodes,
#: sieves, size fractions and the equations of a ``rank`` table).
NAME_COLUMNS = ("experiment", "survey", "stream", "from", "to", "sieve", "fraction", "equation", "test")
_CLASS_COLUMN = re.compile(r"size_class(?:_[A-Za-z]+)?")
#: First characters that make a spreadsheet read a cell as a formula (OWASP, "CSV injection").
FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")
#: The mark a spreadsheet reads as "this cell is text": a single quote in front.
TEXT_MARK = "'"
#: What pandas reads as missing by default; tromplab keeps it for columns of numbers only.
MISSING_WORDS = (
    "",
    "#N/A",
    "#N/A N/A",
    "#NA",
    "-1.#IND",
    "-1.#QNAN",
    "-NaN",
    "-nan",
    "1.#IND",
    "1.#QNAN",
    "<NA>",
    "N/A",
    "NA",
    "NULL",
    "NaN",
    "None",
    "n/a",
    "nan",
    "null",
)


def is_name_column(column: str, extra=()) -> bool:
    """Whether a column (its name trimmed) is read as text: a name column, a class-string
    column (``size_class``, ``size_class_um``) or one of ``extra``.

    Examples
    --------
    >>> is_name_column("experiment"), is_name_column("size_class_um"), is_name_column("size")
    (True, True, False)
    """
    column = str(column).strip()
    return column in NAME_COLUMNS or column in extra or bool(_CLASS_COLUMN.fullmatch(column))


def renamed_to_names(rename) -> tuple[str, ...]:
    """The columns that a rename (``{old: new}``) turns into name columns: read them as text too."""
    return tuple(old for old, new in (rename or {}).items() if is_name_column(new))


def defended(text: str) -> str:
    """``text`` with :data:`TEXT_MARK` in front when it starts as a formula would (or with the
    mark before such a start, so that :func:`undefended` gives it back whole); else unchanged.

    Examples
    --------
    >>> defended("=1+1"), defended("-150+75"), defended("'=x"), defended("run 1")
    ("'=1+1", "'-150+75", "''=x", 'run 1')
    """
    return TEXT_MARK + text if _starts_as_formula(text) else text


def undefended(text: str) -> str:
    """``text`` without the :data:`TEXT_MARK` that :func:`defended` puts in front (only before
    a character that starts a formula; any other quote is part of the name).

    Examples
    --------
    >>> undefended("'=1+1"), undefended("'quoted'")
    ('=1+1', "'quoted'")
    """
    return text[1:] if text.startswith(TEXT_MARK) and _starts_as_formula(text[1:]) else text


def _starts_as_formula(text: str) -> bool:
    """Whether ``text``, after any marks in front, starts as a formula would."""
    return text.lstrip(TEXT_MARK).startswith(FORMULA_STARTS)


def cell_name(value) -> str | None:
    """The name a cell holds, or None for a blank cell.

    Text is trimmed of surrounding white space and loses the mark of :func:`undefended`;
    ``True``/``False`` (a spreadsheet's boolean cell) read ``TRUE``/``FALSE``, a date cell at
    midnight its ISO date, any other value its ``str``.  An empty text is blank.
    """
    if value is None or value is pd.NA or value is pd.NaT:
        return None
    if isinstance(value, (float, np.floating)) and math.isnan(value):
        return None
    if isinstance(value, (bool, np.bool_)):
        return "TRUE" if value else "FALSE"
    if isinstance(value, datetime.datetime) and value == datetime.datetime.combine(value.date(), datetime.time()):
        return value.date().isoformat()
    text = undefended(str(value).strip())
    return text or None


def names_as_text(values: pd.Series) -> pd.Series:
    """A column of cells as names (:func:`cell_name`), blanks as NaN, in an object column."""
    if pd.api.types.infer_dtype(values, skipna=True) in ("string", "empty"):  # text only: at once
        names = values.str.strip()  # vectorised for a string column (pyarrow), a loop for objects
        marked = names.str.startswith(TEXT_MARK, na=False).to_numpy()
        names = names.to_numpy(dtype=object, na_value=np.nan, copy=True)
        if marked.any():
            names[marked] = [undefended(name) for name in names[marked]]
        names[names == ""] = np.nan
        return pd.Series(names, index=values.index, dtype=object)
    names = [cell_name(value) for value in values.tolist()]
    return pd.Series([np.nan if name is None else name for name in names], index=values.index, dtype=object)
