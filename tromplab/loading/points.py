"""Tromp points: measured partition to fines per size, one set per experiment.

File schema (CSV or Excel), one row per size class:

``experiment``
    optional; rows without the column form one experiment named after the file.
``size``
    representative particle size, > 0.  The unit may be given as a suffix
    (``size_um``, ``size_mm``; one of :data:`SIZE_UNITS`); otherwise it is the
    ``size_unit`` option (``--size-unit``), and a contradiction between the two is an
    error.  Sizes are used as given, never converted.
exactly one partition column
    ``partition_fine`` (0..1), ``partition_fine_pct`` (0..100), ``partition_coarse``
    (0..1) or ``partition_coarse_pct`` (0..100).
``weight``
    optional; relative weight of the point in the least-squares fit (> 0).
``used``
    optional yes/no; rows marked no are left out (``tromplab points`` writes it).
diagnostics written by ``tromplab points``
    ``size_lower``, ``size_upper`` (same unit suffix as ``size``), ``feed_share``,
    ``balance_residual``, ``flag``, ``component`` (``tromplab circuit``: the solids or a
    mineral): accepted and ignored, as are free-text ``note`` and ``comment`` columns.  Any other column is refused with its name (a typo such as
    ``partiton_fine`` or ``experimnet`` would otherwise be ignored silently).
"""

from __future__ import annotations

import contextlib
import os
import re
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import InputError
from ..validation import SIZE_LIMITS  # also offered here, beside MAX_SIZE_SPAN
from .tables import (
    DEFAULT_PIECE_ROWS,
    EXCEL_SUFFIXES,
    ExperimentIndex,
    Table,
    experiment_rows,  # noqa: F401 - also offered here (lab and density readers import it from points)
    read_table,
    read_table_in_pieces,
    table_from_frame,
)

SIZE_UNITS = ("nm", "um", "mm", "cm", "m")  # mesh numbers are not sizes (larger = finer)
_UNIT_SPELLINGS = {
    "µm": "um",
    "μm": "um",
    "micron": "um",
    "microns": "um",
    "micrometre": "um",
    "micrometer": "um",
    "millimetre": "mm",
    "millimeter": "mm",
}
POINTS_DIAGNOSTIC_COLUMNS = ("feed_share", "balance_residual", "flag", "component")

PARTITION_COLUMNS = {
    # column: (scale to a fraction, True if it is the partition to fines)
    "partition_fine": (1.0, True),
    "partition_fine_pct": (100.0, True),
    "partition_coarse": (1.0, False),
    "partition_coarse_pct": (100.0, False),
}


#: Measured partitions may leave 0..1 by this much through sampling noise (unclipped data
#: with a noise of 0.02 reach 5 sd); beyond it a value is an error, or a percentage.
PARTITION_SLACK = 0.1
#: Largest ratio of the largest size (or ``delta_max``) to the smallest in one experiment:
#: nine decades (1 nm to 1 m) hold any classifier test; more is a mistyped size or unit,
#: and a ratio near 1e300 overflowed the efficiency integrals (found by benchmarks/fuzz_cli.py).
MAX_SIZE_SPAN = 1e9


def _is_number(item) -> bool:
    try:
        float(item)
    except (TypeError, ValueError):
        return False
    return True


@dataclass(frozen=True)
class TrompPoints:
    """Measured separation curve of one experiment, validated on construction.

    Attributes
    ----------
    experiment : str
        Name of the experiment.
    size : ndarray
        Representative sizes, > 0, finite, no size twice; stored in increasing order.
    partition_fine : ndarray
        Partition numbers to the fine product, fractions 0..1 (within 0.1 for noise).
    weight : ndarray or None
        Optional least-squares weights, > 0.
    delta_max : float or None
        Largest particle size in the feed when known (for the misplacement index);
        otherwise the largest size is used.
    source : str
        Where the points came from.
    size_unit : str
        Unit of the sizes (from the column suffix or the ``size_unit`` option), or "".
    resampled : bool
        True for bootstrap samples, whose sizes repeat and whose partitions may leave
        0..1 by noise; only finiteness and positive sizes are checked then.

    Raises
    ------
    InputError
        Naming the experiment, point and column: lengths that differ, NaN or inf,
        sizes <= 0 or repeated, partitions outside 0..1 (with a hint when they look
        like percentages), weights <= 0.

    Examples
    --------
    >>> TrompPoints("run1", [40, 10, 20], [0.7, 0.97, 0.9]).size
    array([10., 20., 40.])
    >>> TrompPoints("run1", [10, 20, 40], [97, 90, 70])
    Traceback (most recent call last):
    ...
    tromplab.errors.InputError: experiment 'run1', column 'partition_fine': partition 97 outside 0..1: these look like percentages; divide by 100 (or read a table with a partition_fine_pct column)
    """

    experiment: str
    size: np.ndarray
    partition_fine: np.ndarray
    weight: np.ndarray | None = None
    delta_max: float | None = None
    source: str = ""
    size_unit: str = ""
    meta: dict = field(default_factory=dict, compare=False)
    resampled: bool = field(default=False, repr=False, compare=False)

    def __post_init__(self):
        if not isinstance(self.experiment, str):
            raise TypeError(f"the experiment name must be text (str), got {type(self.experiment).__name__}")
        size, phi = self._real_array(self.size, "size"), self._real_array(self.partition_fine, "partition_fine")
        if size.ndim != 1 or phi.ndim != 1 or size.shape != phi.shape:
            raise self._error(f"size has {size.size} values and partition_fine {phi.size}: give one partition per size")
        if size.size == 0:  # numpy's own reductions would fail on it with their words
            raise self._error("no points: give the sizes and their partitions (at least 3 to fit a curve)", column="size")
        arrays = {"size": size, "partition_fine": phi}
        if self.weight is not None:
            arrays["weight"] = self._real_array(self.weight, "weight")
            if arrays["weight"].shape != size.shape:
                raise self._error(f"weight has {arrays['weight'].size} values for {size.size} sizes", column="weight")
        for column, values in arrays.items():
            bad = np.flatnonzero(~np.isfinite(values))
            if bad.size:
                raise self._error(f"value {values[bad[0]]} at point {bad[0] + 1} is not a finite number", column=column)
        bad = np.flatnonzero(size <= 0)
        if bad.size:
            raise self._error(f"size must be positive, got {size[bad[0]]:g} at point {bad[0] + 1}", column="size")
        if "weight" in arrays and np.any(arrays["weight"] <= 0):
            raise self._error("weights must be positive", column="weight")
        self._check_size_range(size)
        if not self.resampled:
            self._check_partitions(phi)
            repeated = size[np.flatnonzero(np.diff(np.sort(size)) == 0)]
            if repeated.size:
                raise self._error(f"duplicate size {repeated[0]:g}: each size once per experiment", column="size")
        order = np.argsort(size, kind="stable")
        object.__setattr__(self, "size", size[order])
        object.__setattr__(self, "partition_fine", phi[order])
        if self.weight is not None:
            object.__setattr__(self, "weight", arrays["weight"][order])

    def _real_array(self, values, column: str) -> np.ndarray:
        """``values`` as a flat array of floats, or an :class:`InputError` naming ``column``:
        complex numbers, nested (ragged) sequences and text are refused, not cast."""
        raw = values if isinstance(values, np.ndarray) else None
        try:
            raw = np.asarray(values) if raw is None else raw
        except ValueError:  # numpy refuses a ragged nesting
            raise self._error("takes one flat sequence of numbers, got a ragged nesting", column=column) from None
        if np.iscomplexobj(raw):  # numpy would drop the imaginary part with only a warning
            raise self._error("takes real numbers, got complex ones", column=column)
        if raw.dtype == object and any(isinstance(item, (list, tuple, np.ndarray)) for item in raw.ravel()):
            raise self._error("takes one flat sequence of numbers, got a ragged nesting", column=column)
        try:
            array = np.asarray(raw, dtype=float)
        except (TypeError, ValueError):
            first = next(item for item in np.atleast_1d(raw).ravel() if not _is_number(item))
            raise self._error(f"takes numbers, got {str(first)!r}", column=column) from None
        if array.ndim != 1:
            raise self._error(f"takes one flat sequence of numbers, got an array of shape {array.shape}", column=column)
        return array

    def _error(self, message: str, *, column: str | None = None) -> InputError:
        return InputError(message, source=self.source or f"experiment '{self.experiment}'", column=column)

    def _check_size_range(self, size: np.ndarray) -> None:
        lowest, highest = SIZE_LIMITS
        outside = np.flatnonzero((size < lowest) | (size > highest))
        if outside.size:
            raise self._error(
                f"experiment '{self.experiment}': size {size[outside[0]]:g} at point {outside[0] + 1} is outside {lowest:g}..{highest:g} (in any unit)",
                column="size",
            )
        largest = float(size.max())
        if self.delta_max is not None and np.isfinite(self.delta_max) and self.delta_max > largest:
            largest = float(self.delta_max)
        if largest / size.min() > MAX_SIZE_SPAN:
            raise self._error(
                f"experiment '{self.experiment}': the sizes span {size.min():g} to {largest:g}, more than {MAX_SIZE_SPAN:g} times; "
                "a size or unit is probably mistyped",
                column="size",
            )

    def _check_partitions(self, phi: np.ndarray) -> None:
        outside = np.flatnonzero((phi < -PARTITION_SLACK) | (phi > 1.0 + PARTITION_SLACK))
        if not outside.size:
            return
        value = phi[outside[0]]
        hint = ""
        if 1.5 < phi.max() <= 100.0 + PARTITION_SLACK and phi.min() >= 0:  # 0..100: percentages
            hint = ": these look like percentages; divide by 100 (or read a table with a partition_fine_pct column)"
        raise self._error(f"partition {value:.15g} outside 0..1{hint}", column="partition_fine")

    @property
    def n(self) -> int:
        return int(self.size.size)

    @property
    def largest_size(self) -> float:
        return float(self.delta_max) if self.delta_max is not None else float(self.size.max())

    def to_frame(self) -> pd.DataFrame:
        frame = pd.DataFrame({"experiment": self.experiment, "size": self.size, "partition_fine": self.partition_fine})
        if self.weight is not None:
            frame["weight"] = self.weight
        return frame


def read_points(
    path, *, sheet=None, size_unit: str | None = None, sep: str | None = None, decimal: str | None = None
) -> list[TrompPoints]:
    """Read and validate Tromp points (schema in the module docstring).

    Parameters
    ----------
    path : str, path-like or pandas.DataFrame
        CSV or Excel file, or a DataFrame with the same columns; the same checks and
        messages as ``tromplab fit`` (for a DataFrame the row is its index label).
    sheet : str or int, optional
        Excel sheet.
    size_unit : str, optional
        Unit of the sizes when the size column has no unit suffix (a contradiction with
        the suffix is an error).
    sep, decimal : str, optional
        CSV separator and decimal mark (detected when not given).

    Returns
    -------
    list of TrompPoints
        One per experiment, in order of first appearance.

    Raises
    ------
    InputError
        Naming file, row and column: missing or duplicated partition columns, unknown
        columns, text, blanks, dates or inf in numeric columns, partitions out of range,
        non-positive or duplicate sizes within an experiment.

    Examples
    --------
    >>> frame = pd.DataFrame({"size": [10, 20, 40, 80, 160], "partition_fine_pct": [98, 91, 62, 21, 4]})
    >>> points = read_points(frame)
    >>> points[0].experiment, points[0].partition_fine.tolist()
    ('DataFrame', [0.98, 0.91, 0.62, 0.21, 0.04])
    >>> read_points(frame.rename(columns={"partition_fine_pct": "partition_fine"}))
    Traceback (most recent call last):
    ...
    tromplab.errors.InputError: DataFrame, row 0, column 'partition_fine': partition 98 outside 0..1: these look like percentages; name the column partition_fine_pct (0..100) or divide by 100
    """
    table = read_table(path, sheet=sheet, sep=sep, decimal=decimal)
    return points_from_table(table, size_unit=size_unit)


def normal_unit(unit: str | None) -> str:
    """A unit as the loaders spell it (``µm`` and ``micron`` become ``um``); "" for none."""
    text = (unit or "").strip()
    return _UNIT_SPELLINGS.get(text.lower(), text)


def size_column_unit(column: str, stem: str = "size") -> tuple[bool, str]:
    """Whether ``column`` is ``stem`` with an optional unit suffix, and that unit.

    Examples
    --------
    >>> size_column_unit("size_lower_um", "size_lower"), size_column_unit("size_mesh")
    ((True, 'um'), (False, ''))
    """
    match = re.fullmatch(re.escape(stem) + r"(?:_(" + "|".join(SIZE_UNITS) + r"))?", column)
    return (True, match.group(1) or "") if match else (False, "")


def resolve_size_unit(
    table: Table, suffix_unit: str, option_unit: str | None, column: str, given_as: str = "as an option (--size-unit)"
) -> str:
    """The unit of the sizes: the column suffix, else the option; a contradiction is an error."""
    option = normal_unit(option_unit)
    if suffix_unit and option and option != suffix_unit:
        raise InputError(
            f"the size unit '{option_unit}' given {given_as} contradicts the column name '{column}' "
            f"(unit '{suffix_unit}'); sizes are never converted: drop one or fix the column name",
            source=table.source,
            column=column,
        )
    return suffix_unit or option


def points_from_table(table: Table, *, size_unit: str | None = None) -> list[TrompPoints]:
    """Tromp points from a table; rows with ``used`` false (written by ``tromplab points``) are skipped."""
    columns = points_columns(table, size_unit)
    table, values = checked_values(table, columns)
    return [
        experiment_points(name, table.rows[rows], values.take(rows), source=table.source, columns=columns)
        for name, rows in experiment_rows(values.labels).items()
    ]


@dataclass(frozen=True)
class PointsColumns:
    """The columns of a Tromp-points table: the size column, the unit of its sizes and every
    column the table may hold."""

    size: str
    unit: str
    known: tuple[str, ...]


@dataclass(frozen=True)
class PointsValues:
    """The checked values of the rows of a Tromp-points table: experiment names, sizes,
    partitions to fines and weights (or None)."""

    labels: np.ndarray
    size: np.ndarray
    partition_fine: np.ndarray
    weight: np.ndarray | None

    def take(self, rows) -> PointsValues:
        weight = None if self.weight is None else self.weight[rows]
        return PointsValues(self.labels[rows], self.size[rows], self.partition_fine[rows], weight)


def points_columns(table: Table, size_unit: str | None) -> PointsColumns:
    """The size column (exactly one, with its unit) and the known columns of a points table."""
    size_columns = [c for c in table.frame.columns if size_column_unit(c)[0]]
    if len(size_columns) > 1:
        raise InputError(
            f"several size columns ({', '.join(size_columns)}): give exactly one", source=table.source, column=size_columns[1]
        )
    size_column = size_columns[0] if size_columns else "size"
    unit = resolve_size_unit(table, size_column_unit(size_column)[1], size_unit, size_column)
    return PointsColumns(size_column, unit, tuple(_known_points_columns(size_column)))


#: The checks of :func:`checked_values` in the order they are made (``check`` receives them).
USED_MARKS, NO_ROW_USED, COLUMNS, SIZES, PARTITIONS, PARTITION_RANGE, POSITIVE_SIZES, WEIGHTS, POSITIVE_WEIGHTS, NAMES = range(10)


def checked_values(
    table: Table, columns: PointsColumns, check=contextlib.nullcontext, *, require_used: bool = True
) -> tuple[Table, PointsValues]:
    """The used rows of a points table and their checked values.

    ``check(step)`` is entered around each check (the steps numbered as above), so that a
    reader in pieces can tell which fault the whole-table reader would name first;
    ``require_used`` False lets a piece have no used row (the reader counts them).
    """
    if "used" in table.frame.columns:
        with check(USED_MARKS):
            table = table.subset(table.boolean("used"))
        if require_used and table.frame.empty:
            raise InputError("no row is marked as used", source=table.source, column="used")
    with check(COLUMNS):
        column = _partition_column(table, columns)
    scale, to_fines = PARTITION_COLUMNS[column]
    with check(SIZES):
        size = table.numeric(columns.size)
    with check(PARTITIONS):
        partition = table.numeric(column)
    with check(PARTITION_RANGE):
        table.refuse_where(
            (partition < 0) | (partition > scale),
            column,
            lambda i: f"partition {partition[i]:.15g} outside 0..{scale:g}{_percent_hint(partition[: i + 1], column, scale)}",
        )
    with check(POSITIVE_SIZES):
        table.refuse_where(size <= 0, columns.size, lambda i: f"size must be positive, got {size[i]:g}")
    weight = None
    if "weight" in table.frame.columns:
        with check(WEIGHTS):
            weight = table.numeric("weight")
        with check(POSITIVE_WEIGHTS):
            table.refuse_where(weight <= 0, "weight", "weight must be positive")
    phi = partition / scale
    with check(NAMES):
        labels = table.experiment_labels()
    return table, PointsValues(labels, size, phi if to_fines else 1.0 - phi, weight)


def _percent_hint(partition: np.ndarray, column: str, scale: float) -> str:
    """The hint for shares given in per cent in a column of shares: name the per cent column.
    ``partition``: the values up to the first out of range, which a reader of the file in pieces
    has seen too (the rows before it in earlier pieces lie in 0..1: they cannot change the
    decision), so both readers give one message."""
    if scale == 1.0 and 1.5 < partition.max() <= 100.0 + PARTITION_SLACK and partition.min() >= 0:
        return f": these look like percentages; name the column {column}_pct (0..100) or divide by 100"
    return ""


def _partition_column(table: Table, columns: PointsColumns) -> str:
    """The one partition column of a points table; the size column must be there and no
    column unknown."""
    table.require(columns.size)
    given = [c for c in PARTITION_COLUMNS if c in table.frame.columns]
    if not given:
        unknown = table.unknown_columns(columns.known)
        raise InputError(
            f"no partition column: give exactly one of {', '.join(PARTITION_COLUMNS)}"
            + (f"; unknown column(s) {unknown}" if unknown else ""),
            source=table.source,
        )
    if len(given) > 1:
        raise InputError(
            f"several partition columns ({', '.join(given)}): give exactly one", source=table.source, column=given[1]
        )
    table.refuse_unknown(columns.known, what="Tromp-points file")
    return given[0]


def experiment_points(name: str, rows: np.ndarray, values: PointsValues, *, source: str, columns: PointsColumns) -> TrompPoints:
    """The points of experiment ``name`` from its rows (``rows``: their numbers in the file)."""
    _check_unique_sizes(source, rows, values.size, columns.size)
    return TrompPoints(
        experiment=name,
        size=values.size,
        partition_fine=values.partition_fine,
        weight=values.weight,
        source=source,
        size_unit=columns.unit,
    )


def _known_points_columns(size_column: str) -> list[str]:
    suffix = size_column[len("size") :]
    return [
        "experiment",
        size_column,
        *PARTITION_COLUMNS,
        "weight",
        "used",
        f"size_lower{suffix}",
        f"size_upper{suffix}",
        *POINTS_DIAGNOSTIC_COLUMNS,
    ]


def _check_unique_sizes(source: str, rows: np.ndarray, size: np.ndarray, column: str = "size") -> None:
    seen = {}
    for row, value in zip(rows, size):
        if value in seen:
            raise InputError(
                f"duplicate size {value:g} in the same experiment (also at row {seen[value]})",
                source=source,
                row=int(row) if isinstance(row, (int, np.integer)) else row,  # a DataFrame's index label may be text
                column=column,
            )
        seen[value] = row


def points_from_frame(frame: pd.DataFrame, *, source: str = "data frame") -> list[TrompPoints]:
    """Tromp points from a data frame in the file schema (same checks and messages as a file;
    rows are numbered from 1)."""
    frame = frame.reset_index(drop=True)
    frame.index = frame.index + 1
    return points_from_table(table_from_frame(frame, source=source))


# --- a points file read in pieces ----------------------------------------------------------------
def iter_experiments(
    path, *, piece_rows: int = DEFAULT_PIECE_ROWS, size_unit: str | None = None, sep=None, decimal=None, sheet=None,
    warn: bool = True,
) -> Iterator[TrompPoints]:  # fmt: skip
    """The experiments of a Tromp-points file one at a time, the file read in pieces.

    The same points, checks and messages as :func:`read_points` (file, row, column), in the
    same order (that of first appearance), with the memory of a piece of ``piece_rows``
    records and of the experiments not yet complete, however large the file.  Two passes
    over the file: the first makes every check of :func:`read_points` and counts the rows of
    each experiment (one entry per experiment in memory); the second reads the pieces again
    and yields each experiment as soon as all its rows are read.  When the rows of every
    experiment are consecutive (the usual file) an experiment is yielded at the end of the
    piece that completes it; rows of an experiment spread over the file are kept until its
    last row is read, so for such a file the memory grows with the span of the experiments
    (sort the file by experiment to avoid it).  An Excel workbook or a DataFrame is read whole.

    Parameters
    ----------
    path : str, path-like or pandas.DataFrame
        A points file, as for :func:`read_points`.
    piece_rows : int
        Records per piece (:func:`~tromplab.loading.tables.read_table_in_pieces`).
    size_unit, sep, decimal, sheet
        As for :func:`read_points`.
    warn : bool
        Warn of the layout detected, as :func:`read_points` does; False for a second reading.

    Yields
    ------
    TrompPoints
        One per experiment, in order of first appearance.

    Raises
    ------
    InputError
        As :func:`read_points`: every fault of a row is found by the first pass, before any
        experiment is yielded, and named as :func:`read_points` names it; a size repeated
        within an experiment, or points that :class:`TrompPoints` refuses, when that
        experiment is reached in the second pass (after the experiments before it).

    Notes
    -----
    For a batch of any size: take the experiments in chunks as they come
    (``itertools.islice(experiments, 1024)`` until it is empty) and fit each chunk before the
    next is read; nothing of a chunk need stay once its results are written.  Reading the
    file is done by the consumer's process, in order; the iterator is not thread-safe.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (folder / "points.csv").write_text("experiment,size,partition_fine\\na,10,0.9\\nb,10,0.8\\na,20,0.4\\nb,20,0.3\\n")
    >>> [(p.experiment, p.n) for p in iter_experiments(folder / "points.csv", piece_rows=2)]
    [('a', 2), ('b', 2)]
    """
    if sheet is not None or not isinstance(path, (str, os.PathLike)) or Path(path).suffix.lower() in EXCEL_SUFFIXES:
        yield from read_points(path, sheet=sheet, size_unit=size_unit, sep=sep, decimal=decimal)
        return

    def pieces(warn: bool):
        return read_table_in_pieces(path, piece_rows=piece_rows, sep=sep, decimal=decimal, warn=warn)

    index = _index_experiments(pieces(warn=warn), size_unit)
    if index.consecutive:
        yield from _experiments_of_pieces(pieces(warn=False), index.columns, index.counts)
    else:
        yield from _experiments_sorted_on_disk(pieces(warn=False), index, piece_rows)


class _FaultAt(Exception):
    """An :class:`InputError` met at step ``step`` of :func:`checked_values`."""

    def __init__(self, step: int, error: InputError):
        super().__init__(step, error)
        self.step, self.error = step, error


@contextlib.contextmanager
def _numbered_check(step: int):
    try:
        yield
    except InputError as error:
        raise _FaultAt(step, error) from None


def _index_experiments(pieces, size_unit: str | None) -> ExperimentIndex:
    """The first pass: every check of a points table on every piece, and the rows of each
    experiment counted.  Raises the fault the whole-table reader would name: the one of the
    earliest check, the first in the file among them."""
    index, fault, used = ExperimentIndex(), None, 0
    for table in pieces:
        index.columns = index.columns or points_columns(table, size_unit)
        used += _used_rows(table)
        try:
            table, values = checked_values(table, index.columns, _numbered_check, require_used=False)
        except _FaultAt as found:
            fault = found if fault is None or found.step < fault.step else fault
            continue
        index.add(values.labels)
    if not used and (fault is None or fault.step > USED_MARKS):
        raise InputError("no row is marked as used", source=str(table.source), column="used")
    if fault is not None:
        raise fault.error
    return index


def _used_rows(table: Table) -> int:
    """How many rows of a piece are marked as used (all without a ``used`` column; none where
    a mark is not yes or no, a fault the checks report)."""
    if "used" not in table.frame.columns:
        return len(table.frame)
    try:
        return int(table.boolean("used").sum())
    except InputError:
        return 0


def _experiments_of_pieces(pieces, columns: PointsColumns, counts: dict[str, int]) -> Iterator[TrompPoints]:
    """The second pass: the rows of each experiment gathered from the pieces, each experiment
    yielded (in order of first appearance) as soon as its last row is read."""
    order = iter(counts.items())
    waiting, gathered = next(order, (None, 0))
    pending: dict[str, list] = {}
    for table in pieces:
        table, values = checked_values(table, columns, require_used=False)
        for name, rows in experiment_rows(values.labels).items():
            pending.setdefault(name, []).append((table.rows[rows], values.take(rows)))
        while waiting is not None and sum(len(rows) for rows, _ in pending.get(waiting, ())) == gathered:
            parts = pending.pop(waiting)
            rows = np.concatenate([rows for rows, _ in parts])
            yield experiment_points(waiting, rows, _joined([part for _, part in parts]), source=table.source, columns=columns)
            waiting, gathered = next(order, (None, 0))


def _joined(parts: list[PointsValues]) -> PointsValues:
    if len(parts) == 1:
        return parts[0]
    weight = None if parts[0].weight is None else np.concatenate([p.weight for p in parts])
    return PointsValues(
        *(np.concatenate([getattr(p, name) for p in parts]) for name in ("labels", "size", "partition_fine")), weight
    )


def _experiments_sorted_on_disk(pieces, index: ExperimentIndex, piece_rows: int) -> Iterator[TrompPoints]:
    """The second pass for experiments whose rows are spread over the file: an external sort.
    The checked rows of each piece (experiment, row number, size, partition, weight) go to
    temporary binary files, each holding a run of consecutive experiments (about ``piece_rows``
    rows, or a 256th of the file); each file is then read, sorted and cut into experiments."""
    names = list(index.counts)
    position, per_file = index.runs(piece_rows)
    weighted, source = False, ""
    with tempfile.TemporaryDirectory(prefix="tromplab-sort-") as folder:
        for table in pieces:
            table, values = checked_values(table, index.columns, require_used=False)
            number = np.fromiter((position[name] for name in values.labels), dtype=float, count=values.labels.size)
            weighted, source = values.weight is not None, table.source
            weight = values.weight if weighted else np.ones(number.size)
            records = np.column_stack([number, table.rows.astype(float), values.size, values.partition_fine, weight])
            run = number.astype(int) // per_file
            for file in np.unique(run):
                with open(Path(folder) / f"{file}.bin", "ab") as stream:
                    records[run == file].tofile(stream)
        for file in range(-(-len(names) // per_file)):
            records = np.fromfile(Path(folder) / f"{file}.bin").reshape(-1, 5)
            records = records[np.argsort(records[:, 0], kind="stable")]  # file order within an experiment
            for part in np.split(records, np.flatnonzero(np.diff(records[:, 0])) + 1):
                values = PointsValues(None, part[:, 2], part[:, 3], part[:, 4] if weighted else None)
                name = names[int(part[0, 0])]
                yield experiment_points(name, part[:, 1].astype(int), values, source=source, columns=index.columns)
