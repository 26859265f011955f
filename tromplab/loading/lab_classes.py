"""The size classes of a lab table: where the sizes are, the class bounds, each stream's share per class.

Three layouts (schema: :mod:`tromplab.loading.lab`): class bounds ``size_lower`` and
``size_upper``, class-range strings ``size_class``, or sieve apertures ``size`` (per-class
shares retained on each sieve, or cumulative data turned into classes by differences).  The
representative size of a class is the geometric mean of its bounds; the open top class and the
pan continue the geometric progression of their neighbour unless ``top_size`` or
``pan_lower_size`` is given.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..errors import InputError
from .lab_options import LabOptions
from .lab_streams import CUMULATIVE_KINDS, SIZE_STEMS
from .size_classes import class_string_bounds, size_columns
from .tables import Table

#: Largest amount (mass) of one class: sums over any number of classes stay finite.
MAX_AMOUNT = 1e250


@dataclass(frozen=True)
class SizeLayout:
    """Where the sizes are: sieve apertures in one column, class bounds in two, or
    class-range strings ("+1168", "-1168+589", "-74") in one; optionally a column of
    representative sizes; and their unit ("" when not known)."""

    sieve_sizes: bool
    columns: tuple[str, ...]
    class_strings: bool = False
    representative: str | None = None
    unit: str = ""
    unit_suffix: str = ""


def read_size_layout(table: Table, options: LabOptions | None = None) -> SizeLayout:
    found, unit, suffix = size_columns(table, SIZE_STEMS, options.size_unit if options else None)
    layouts = [
        name
        for name, present in (
            ("size_class", "size_class" in found),
            ("size_lower/size_upper", "size_lower" in found or "size_upper" in found),
            ("size", "size" in found),
        )
        if present
    ]
    if len(layouts) > 1:
        raise InputError(
            f"the sizes are given twice ({' and '.join(layouts)}): keep one layout (a representative size per class goes "
            "in 'size_representative')",
            source=table.source,
        )
    representative = found.get("size_representative")
    if "size_lower" in found or "size_upper" in found:
        if not ("size_lower" in found and "size_upper" in found):
            missing = "size_upper" if "size_lower" in found else "size_lower"
            raise InputError(f"class bounds need both size_lower and size_upper; {missing} is missing", source=table.source)
        return SizeLayout(
            False, (found["size_lower"], found["size_upper"]), representative=representative, unit=unit, unit_suffix=suffix
        )
    if "size_class" in found:
        return SizeLayout(
            False, (found["size_class"],), class_strings=True, representative=representative, unit=unit, unit_suffix=suffix
        )
    if "size" in found:
        if representative:
            raise InputError(
                "a representative size column needs class bounds or size classes, not sieve sizes",
                source=table.source,
                column=representative,
            )
        return SizeLayout(True, (found["size"],), unit=unit, unit_suffix=suffix)
    raise InputError(
        "give class bounds 'size_lower' and 'size_upper', size classes 'size_class' (\"+1168\", \"-1168+589\", \"-74\"), "
        "or sieve sizes 'size'",
        source=table.source,
    )


class _ClassShares(NamedTuple):
    """The size classes of one experiment and each stream's share per class, as read."""

    lower: np.ndarray
    upper: np.ndarray
    shares: dict  # stream -> share per class (summing to 1)
    totals: dict  # stream -> the column's total (per-class columns only)
    notes: list
    rows: list  # the file row of each class (None: a class spans two sieve rows)


def class_shares(table: Table, streams, layout: SizeLayout, options: LabOptions) -> _ClassShares:
    """The class bounds of the table's size layout and the shares of every stream column."""
    if any(kind in CUMULATIVE_KINDS for _, kind in streams.values()):
        if not layout.sieve_sizes:
            raise InputError(
                "cumulative stream columns need sieve sizes in a 'size' column, not class bounds", source=table.source
            )
        lower, upper, shares, notes = _classes_from_cumulative(table, layout.columns[0], streams)
        return _ClassShares(lower, upper, shares, {}, notes, [None] * lower.size)
    if layout.sieve_sizes:
        lower, upper = _retained_on_sieves(table, layout.columns[0])
    elif layout.class_strings:
        lower, upper = _checked_bounds(
            table, *class_string_bounds(table, layout.columns[0]), layout.columns[0], layout.columns[0]
        )
    else:
        lower, upper = _class_bounds(table, *layout.columns)
    shares, totals, notes = {}, {}, []
    for stream, (column, kind) in streams.items():
        shares[stream], totals[stream], note = per_class_shares(table, column, kind, options)
        notes += [note] if note else []
    return _ClassShares(lower, upper, shares, totals, notes, list(table.rows))


def _class_bounds(table: Table, lower_column: str, upper_column: str):
    lower = table.numeric(lower_column, allow_blank=True)
    upper = table.numeric(upper_column, allow_blank=True)
    return _checked_bounds(table, lower, upper, lower_column, upper_column)


def _checked_bounds(table: Table, lower, upper, lower_column: str, upper_column: str):
    """Class bounds checked: positive (a lower bound of 0 = the pan), ordered, one open top, one pan, no overlap."""
    zero_lower = lower == 0
    lower = np.where(zero_lower, np.nan, lower)  # the pan written with a lower bound of 0
    for values, column in ((lower, lower_column), (upper, upper_column)):
        table.refuse_where(values <= 0, column, "class bounds must be positive (a pan's lower bound may be 0 or blank)")
    both = np.isfinite(lower) & np.isfinite(upper)
    table.refuse_where(
        both & (lower >= upper), lower_column, lambda i: f"lower bound {lower[i]:g} is not below the upper bound {upper[i]:g}"
    )
    table.refuse_where(np.isnan(lower) & np.isnan(upper), lower_column, "the class has neither a lower nor an upper bound")
    open_top = np.flatnonzero(np.isnan(upper))
    pan = np.flatnonzero(np.isnan(lower))
    for rows, column, what in ((open_top, upper_column, "open top class"), (pan, lower_column, "pan")):
        if rows.size > 1:
            raise table.error(f"only one {what} (blank {column}) is allowed", index=int(rows[1]), column=column)
    _refuse_open_inside(table, lower, upper, zero_lower, lower_column, upper_column)
    key = np.where(np.isfinite(lower), lower, 0.0)
    step = np.diff(key)
    if not (np.all(step < 0) or np.all(step > 0)):
        i = int(np.flatnonzero(step <= 0)[0] if step[0] > 0 else np.flatnonzero(step >= 0)[0]) + 1
        raise table.error(
            "class bounds are not sorted (give classes from coarse to fine or from fine to coarse)", index=i, column=lower_column
        )
    order = np.argsort(key)[::-1]  # coarse to fine
    for coarser, finer in zip(order[:-1], order[1:]):
        if np.isfinite(upper[finer]) and np.isfinite(lower[coarser]) and upper[finer] > lower[coarser] * (1 + 1e-9):
            raise table.error(
                f"class {lower[finer]:g}-{upper[finer]:g} overlaps the class starting at {lower[coarser]:g}",
                index=int(finer),
                column=upper_column,
            )
    return lower, upper


def _refuse_open_inside(table: Table, lower, upper, zero_lower, lower_column: str, upper_column: str) -> None:
    """A blank lower bound belongs to the finest class (the pan) and a blank upper bound to the
    coarsest; elsewhere it is a bound left out, named as blank (not as classes out of order)."""
    for i in np.flatnonzero(np.isnan(lower)):
        if np.any(upper[np.arange(upper.size) != i] < upper[i]):
            given = "0" if zero_lower[i] else "blank"
            raise table.error(
                f"the lower bound is {given} but the class (upper bound {upper[i]:g}) is not the finest: only the pan may "
                "have a blank or 0 lower bound; fill in the bound",
                index=int(i),
                column=lower_column,
            )
    for i in np.flatnonzero(np.isnan(upper)):
        if np.any(lower[np.arange(lower.size) != i] > lower[i]):
            raise table.error(
                f"the upper bound is blank but the class (lower bound {lower[i]:g}) is not the coarsest: only the top class "
                "may be open; fill in the bound",
                index=int(i),
                column=upper_column,
            )


def _retained_on_sieves(table: Table, size_column: str):
    """Class bounds when per-class shares are given as retained on each sieve: a class runs
    from its sieve up to the next coarser one; the coarsest class is open at the top."""
    size = _sorted_sieves(table, size_column)
    upper = np.full(size.size, np.nan)
    order = np.argsort(size)
    upper[order[:-1]] = size[order[1:]]
    return size, upper


def _sorted_sieves(table: Table, size_column: str) -> np.ndarray:
    size = table.numeric(size_column)
    table.refuse_where(size <= 0, size_column, "sieve size must be positive")
    step = np.diff(size)
    if not (np.all(step < 0) or np.all(step > 0)):
        direction = np.sign(step[0]) if step[0] != 0 else 1.0
        i = int(np.flatnonzero(step * direction <= 0)[0]) + 1
        raise table.error("sieve sizes are not strictly sorted", index=i, column=size_column)
    return size


def per_class_shares(table: Table, column: str, kind: str, options: LabOptions):
    """Shares of one stream per class (summing to 1), the column's total, and a note on blank cells."""
    values = table.numeric(column, allow_blank=True)
    blank = np.flatnonzero(np.isnan(values))
    note = f"column '{column}': blank cell(s) at {_rows_text(table.rows[blank])} read as no material" if blank.size else ""
    values = np.where(np.isnan(values), 0.0, values)
    table.refuse_where(values < 0, column, lambda i: f"negative amount {values[i]:g}")
    largest = {"pct": 100.0 + options.sum_tolerance_pct, "frac": 1.0 + options.sum_tolerance_pct / 100.0}.get(kind, MAX_AMOUNT)
    # a share above the whole, or a mass whose sum would overflow
    table.refuse_where(
        values > largest, column, lambda i: f"amount {values[i]:g} is above {largest:g}, more than the whole stream"
    )
    total = values.sum()
    if total <= 0:
        raise InputError(f"column '{column}' holds no material", source=table.source, column=column)
    if kind in ("pct", "frac"):
        full = 100.0 if kind == "pct" else 1.0
        off_by = 100.0 * (total - full) / full
        if abs(off_by) > options.sum_tolerance_pct:
            raise InputError(
                f"the per-class shares sum to {100 * total / full:.2f} % instead of 100 % "
                f"({'over' if off_by > 0 else 'short'} by {abs(off_by):.2f} percentage points; "
                f"tolerance {options.sum_tolerance_pct:g})"
                + (f"; blank or NaN at {_rows_text(table.rows[blank])}, read as no material" if blank.size else ""),
                source=table.source,
                row=_single_row(table.rows[blank]),
                column=column,
            )
    return values / total, float(total), note


def _single_row(rows):
    """The one row of ``rows`` as a message names it (a file line), or None."""
    if len(rows) != 1:
        return None
    return int(rows[0]) if isinstance(rows[0], (int, np.integer)) else rows[0]


def _rows_text(rows) -> str:
    rows = [str(r) for r in rows]  # file lines, or a DataFrame's index labels
    return ("row " if len(rows) == 1 else "rows ") + ", ".join(rows[:8]) + (", ..." if len(rows) > 8 else "")


def _classes_from_cumulative(table: Table, size_column: str, streams):
    size = _sorted_sieves(table, size_column)
    order = np.argsort(size)[::-1]  # coarse to fine
    sieves = size[order]
    shares = {}
    notes = []
    for stream, (column, kind) in streams.items():
        retained, note = _cumulative_retained(table, column, kind, order)
        shares[stream] = np.diff(np.concatenate(([0.0], retained, [1.0])))
        notes += [note] if note else []
    lower = np.concatenate((sieves, [np.nan]))
    upper = np.concatenate(([np.nan], sieves))
    return lower, upper, shares, notes


def _cumulative_retained(table: Table, column: str, kind: str, order: np.ndarray) -> np.ndarray:
    """Cumulative fraction retained, coarse to fine, checked: 0..1 and non-decreasing.

    A blank at the coarse end counts as nothing retained; a blank at the fine end counts
    as everything retained only when the last given value is already 100 %.  Both are
    reported in the returned note; a blank between given values is refused.
    """
    full = 100.0 if kind.endswith("pct") else 1.0
    values = table.numeric(column, allow_blank=True)[order]
    rows = np.asarray(order)
    given = np.flatnonzero(np.isfinite(values))
    if given.size == 0:
        raise InputError(f"column '{column}' is empty", source=table.source, column=column)
    inner_blank = [i for i in range(given[0], given[-1]) if np.isnan(values[i])]
    if inner_blank:
        raise table.error("blank between given cumulative values", index=int(rows[inner_blank[0]]), column=column)
    for i in range(values.size):
        value = values[i]
        if np.isfinite(value) and not -1e-9 * full <= value <= full * (1 + 1e-9):
            raise table.error(f"cumulative value {value:g} outside 0..{full:g}", index=int(rows[i]), column=column)
    filled = []
    if given[0] > 0:
        values[: given[0]] = 0.0 if not kind.startswith("passing") else full
        filled.append(f"{_rows_text(table.rows[rows[: given[0]]])} (coarse end) read as {values[0]:g}")
    if given[-1] < values.size - 1:
        last = values[given[-1]]
        complete = full if kind.startswith("retained") else 0.0
        if not np.isclose(last, complete):
            raise table.error(
                "blank at the fine end after an incomplete cumulative value", index=int(rows[given[-1] + 1]), column=column
            )
        values[given[-1] + 1 :] = complete
        filled.append(f"{_rows_text(table.rows[rows[given[-1] + 1 :]])} (fine end) read as {complete:g}")
    note = f"column '{column}': blank cell(s) at {' and '.join(filled)}" if filled else ""
    retained = values / full if kind.startswith("retained") else 1.0 - values / full
    drops = np.flatnonzero(np.diff(retained) < -1e-12)
    if drops.size:
        what = "retained share falls" if kind.startswith("retained") else "passing share rises"
        raise table.error(
            f"cumulative data are not monotone: the {what} towards finer sieves", index=int(rows[drops[0] + 1]), column=column
        )
    return np.clip(retained, 0.0, 1.0), note


def representative_class_sizes(table: Table, lower, upper, options: LabOptions, representative_column: str | None = None):
    lower, upper = lower.astype(float).copy(), upper.astype(float).copy()
    order = np.argsort(np.where(np.isfinite(lower), lower, 0.0))[::-1]
    top, pan = order[0], order[-1]
    if np.isnan(upper[top]):
        if options.top_size is not None:
            upper[top] = options.top_size
        else:
            neighbour = order[1]
            upper[top] = lower[top] * _ratio(table, lower[neighbour], upper[neighbour])
    if np.isnan(lower[pan]):
        if options.pan_lower_size:  # 0, like a lower bound of 0 in the table, means "the pan": extend the progression
            lower[pan] = options.pan_lower_size
        else:
            neighbour = order[-2]
            lower[pan] = upper[pan] / _ratio(table, lower[neighbour], upper[neighbour])
    if not upper[top] > lower[top] or not upper[pan] > lower[pan]:
        raise InputError(
            "top_size must exceed the top class's lower bound and pan_lower_size must be below the pan's upper bound",
            source=table.source,
        )
    size = np.sqrt(lower) * np.sqrt(upper)  # not sqrt(lower * upper): the product under- or overflows at extreme sizes
    if representative_column:  # measured or stated sizes replace the geometric-mean rule where given
        given = table.numeric(representative_column, allow_blank=True)
        table.refuse_where(
            np.isfinite(given) & ((given <= lower * (1 - 1e-9)) | (given >= upper * (1 + 1e-9))),
            representative_column,
            lambda i: f"representative size {given[i]:g} outside its class {lower[i]:g}-{upper[i]:g}",
        )
        size = np.where(np.isfinite(given), given, size)
    bad = np.flatnonzero(~(np.isfinite(size) & (size > 0)) | ~(upper[top] < np.inf))
    if bad.size:  # e.g. a pan below 5e-324 or a top class above 1e308 once extended by the class ratio
        i = int(bad[0])
        raise InputError(
            f"class {lower[i]:g}-{upper[i]:g} has the representative size {size[i]:g}: its bounds are too extreme to "
            "compute with (give the sizes in another unit)",
            source=table.source,
        )
    return float(upper[top]), size


def _ratio(table, lower, upper) -> float:
    if not (np.isfinite(lower) and np.isfinite(upper)):
        raise InputError(
            "the open top class and the pan need a closed neighbour class to extend; give top_size / pan_lower_size",
            source=table.source,
        )
    return upper / lower
