"""How the report's tables and warnings read: numbers at a precision chosen per column, a note
repeated on every row of a table said once under it, warnings of one kind in one line.

Only the report's rendering uses these; the tables themselves (and the CSV files) keep full
precision.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from pathlib import Path

import numpy as np
import pandas as pd

from ..notices import NUMBER_IN_WORDS

#: Columns holding shares, partitions, efficiencies or weights (0..1): four decimals.
SHARE_COLUMNS = re.compile(
    r"^(feed|fine|coarse|partition_\w+|eta|epsilon|imperfection\w*|\w*_yield|akaike_\w+|weight|share|bypass|used_share)$"
)
#: Columns holding p-values: two significant digits.
P_VALUE_COLUMNS = re.compile(r"^(p|p_value|\w+_p)$")
#: Test statistics and information criteria: two decimals.
STATISTIC_COLUMNS = re.compile(r"^(F|F_crit|aic|aicc|bic|delta_aicc|chi2|t)$")
#: Residuals of a balance: two significant digits (their size, not their digits, matters).
RESIDUAL_COLUMNS = re.compile(r"^(balance_residual|residual\w*)$")
#: A text longer than this, repeated on two rows or more of a column, becomes a note under the table.
NOTE_LENGTH = 30


def column_format(column: str):
    """The formatter of one column's numbers (sizes and other values: four significant digits)."""
    name = str(column)
    if P_VALUE_COLUMNS.match(name):
        return lambda v: f"{v:.2g}"
    if RESIDUAL_COLUMNS.match(name):
        return lambda v: f"{v:.2g}"
    if SHARE_COLUMNS.match(name):
        return lambda v: f"{v:.4f}"
    if STATISTIC_COLUMNS.match(name):
        return lambda v: f"{v:,.2f}"
    return lambda v: f"{v:.4g}"


def display_table(table: pd.DataFrame) -> tuple[pd.DataFrame, list[str]]:
    """``table`` as text for reading: numbers formatted per column (:func:`column_format`),
    missing values as "-", and every long text that repeats in a column replaced by "see
    note k"; returns the text table and the notes (``"note k: text"``) to print under it."""
    columns: dict = {}
    notes: list[str] = []
    for column in table.columns:
        columns[column] = _column_text(table[column], column, notes)
    # made at once (a column inserted into a frame one by one costs pandas a new block each) and
    # of Python strings (pandas' Arrow strings are converted back to them cell by cell by
    # to_html and to_markdown): the same text, the report's tables in about half the time
    shown = pd.DataFrame(columns, index=table.index, dtype=object)
    return shown, [f"note {k}: {note}" for k, note in enumerate(notes, 1)]


def grouped_warnings(items: Iterable[tuple[str, str, str]]) -> list[str]:
    """Warnings of fits, ``(experiment, formula, warning)``, one line per kind of warning.

    Warnings that differ only in their numbers are of one kind: the line gives the warning
    once, with its numbers written as ``...``, then every fit it concerns with its numbers.
    Digits that are part of a name (``x50``, ``deck_2``) are not numbers: they stay in the
    line.  A kind met once keeps its own words.

    Examples
    --------
    >>> grouped_warnings([("a", "plitt", "residuals not normal (p = 0.003)"),
    ...                   ("a", "lynch", "residuals not normal (p = 0.02)"),
    ...                   ("b", "plitt", "bypass = 0.4 not determined")])  # doctest: +NORMALIZE_WHITESPACE
    ['residuals not normal (p = ...) (2 fits): a: plitt (0.003), lynch (0.02)', 'b, plitt: bypass = 0.4 not determined']
    """
    kinds: dict[str, list[tuple[str, str, str]]] = {}
    for experiment, formula, warning in items:
        kinds.setdefault(NUMBER_IN_WORDS.sub("...", warning), []).append((experiment, formula, warning))
    lines = []
    for kind, members in kinds.items():
        if len(members) == 1:
            experiment, formula, warning = members[0]
            lines.append(f"{experiment}, {formula}: {warning}")
            continue
        by_experiment: dict[str, list[str]] = {}
        for experiment, formula, warning in members:
            numbers = ", ".join(NUMBER_IN_WORDS.findall(warning))
            by_experiment.setdefault(experiment, []).append(f"{formula} ({numbers})" if numbers else formula)
        fits = "; ".join(f"{experiment}: {', '.join(named)}" for experiment, named in by_experiment.items())
        lines.append(f"{kind} ({len(members)} fits): {fits}")
    return lines


def input_names(source: str) -> str:
    """The input(s) of a report named by file name, not by the path on the user's machine."""
    return ", ".join(Path(part).name or part for part in str(source).split(", "))


def _column_text(values: pd.Series, column, notes: list[str]):
    """One column of :func:`display_table` as text; long repeated texts become ``see note k``,
    their text appended to ``notes``."""
    if pd.api.types.is_float_dtype(values):
        formatter = column_format(column)
        return [formatter(v) if np.isfinite(v) else "-" for v in values]
    text = values.map(lambda v: "-" if v is None or (isinstance(v, float) and np.isnan(v)) else str(v))
    if not any(len(t) > NOTE_LENGTH for t in text):  # no note possible: the counts are not needed
        return text
    counts = text.value_counts()
    for repeated in [t for t, count in counts.items() if count > 1 and len(t) > NOTE_LENGTH]:
        notes.append(repeated)
        text = text.where(text != repeated, f"see note {len(notes)}")
    return text
