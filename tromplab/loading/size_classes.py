"""Size columns as lab and survey tables write them: which columns hold the sizes, their unit,
and the grammar of class-range strings.

One implementation for every reader of size classes (the lab tables of
:mod:`tromplab.loading.lab` and the survey tables of :mod:`tromplab.circuit.measurements`),
so that a table means the same to both.
"""

from __future__ import annotations

import re
from typing import NamedTuple

import numpy as np
import pandas as pd

from ..errors import InputError
from .points import normal_unit, resolve_size_unit, size_column_unit
from .tables import Table

#: A class-range string: "+1168" (retained on 1168: the open top class), "-1168+589" (through
#: 1168, on 589), "-74" (through 74: the pan); a lower bound "+0" is the pan's.
CLASS_STRING = re.compile(r"([+-])(\d+(?:\.\d*)?(?:[eE][-+]?\d+)?)(?:([+-])(\d+(?:\.\d*)?(?:[eE][-+]?\d+)?))?")


class SizeColumns(NamedTuple):
    """The size columns of a table: ``found`` maps each stem present to its column, ``unit``
    is the unit of the sizes ("" when unknown) and ``suffix`` the unit the column names carry."""

    found: dict
    unit: str
    suffix: str


def size_columns(table: Table, stems, option_unit: str | None = None) -> SizeColumns:
    """Find the columns of ``stems`` (with an optional unit suffix) and the unit of the sizes.

    The unit is the columns' suffix, else a ``size_unit`` column, else ``option_unit``; two
    of them that disagree are an error, as are two columns of one stem or mixed suffixes.

    Raises
    ------
    InputError
        Naming the table and the columns at fault.
    """
    found = {}  # stem -> (column, unit suffix)
    for column in table.frame.columns:
        for stem in stems:
            matched, unit = size_column_unit(column, stem)
            if matched:
                if stem in found:
                    raise InputError(
                        f"two {stem} columns ({found[stem][0]}, {column}): give one", source=table.source, column=column
                    )
                found[stem] = (column, unit)
    units = {unit for _, unit in found.values()}
    if len(units) > 1:
        described = ", ".join(f"{column} ({unit or 'no unit'})" for column, unit in found.values())
        raise InputError(f"mixed units in the size columns: {described}; use one unit", source=table.source)
    suffix = units.pop() if units else ""
    unit = suffix
    first = next(iter(found.values()))[0] if found else None
    if "size_unit" in table.frame.columns:
        given = table.frame["size_unit"].dropna().astype(str).str.strip().unique()
        if len(given) > 1:
            raise InputError(f"mixed units in column 'size_unit': {', '.join(given)}", source=table.source, column="size_unit")
        if len(given) == 1:
            unit = resolve_size_unit(table, suffix, given[0], first or "size_unit", given_as="in column 'size_unit'")
    if unit and not suffix and option_unit and unit != normal_unit(option_unit):
        raise InputError(
            f"the size unit '{option_unit}' given as an option (--size-unit) contradicts column 'size_unit' ({unit})",
            source=table.source,
            column="size_unit",
        )
    unit = resolve_size_unit(table, unit, option_unit, first or "size")
    return SizeColumns({stem: column for stem, (column, _) in found.items()}, unit, suffix)


def class_string_bounds(table: Table, column: str, *, blank_allowed: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Class bounds ``(lower, upper)`` from class-range strings (:data:`CLASS_STRING`).

    A missing bound is NaN (the open top's upper, the pan's lower); a lower bound written
    "+0" is returned as 0 (the pan: the callers' bound checks read 0 as the pan).  With
    ``blank_allowed`` a blank cell is a row without a class (both NaN).

    Examples
    --------
    >>> table = Table(pd.DataFrame({"size_class": ["+1168", "-1168+589", "-589+0"]}), np.arange(2, 5), "lab.csv")
    >>> [bounds.tolist() for bounds in class_string_bounds(table, "size_class")]
    [[1168.0, 589.0, 0.0], [nan, 1168.0, 589.0]]
    """
    lower = np.full(len(table.frame), np.nan)
    upper = np.full(len(table.frame), np.nan)
    for i, value in enumerate(table.frame[column]):
        text = "" if pd.isna(value) else str(value).strip().replace("\u2212", "-").replace(" ", "")
        if blank_allowed and not text:
            continue
        parts = CLASS_STRING.fullmatch(text)
        if not parts or parts.group(1) == parts.group(3):
            raise table.error(
                f"'{value}' is not a size class: write '+1168' (retained on 1168), '-1168+589' (through 1168, on 589) "
                "or '-74' (through 74)",
                index=i,
                column=column,
            )
        for sign, number in ((parts.group(1), parts.group(2)), (parts.group(3), parts.group(4))):
            if sign == "+":
                lower[i] = float(number)
            elif sign == "-":
                upper[i] = float(number)
    return lower, upper


def class_label(lower: float, upper: float, unit: str = "") -> str:
    """How a class reads in a message: ``4.1-5.3``, with ``pan`` and ``top`` for the open ends
    (NaN bounds) and the unit after it when given.

    Examples
    --------
    >>> class_label(np.nan, 38.0, "um"), class_label(300.0, np.nan)
    ('pan-38 um', '300-top')
    """
    low = "pan" if not np.isfinite(lower) else f"{lower:g}"
    high = "top" if not np.isfinite(upper) else f"{upper:g}"
    return f"{low}-{high}{f' {unit}' if unit else ''}"
