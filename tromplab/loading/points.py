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

import re
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..errors import InputError
from ..validation import SIZE_LIMITS  # also offered here, beside MAX_SIZE_SPAN
from .tables import Table, read_table, table_from_frame

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
        raise self._error(f"partition {value:g} outside 0..1{hint}", column="partition_fine")

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
    tromplab.errors.InputError: DataFrame, row 0, column 'partition_fine': partition 98 outside 0..1
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
    size_columns = [c for c in table.frame.columns if size_column_unit(c)[0]]
    if len(size_columns) > 1:
        raise InputError(
            f"several size columns ({', '.join(size_columns)}): give exactly one", source=table.source, column=size_columns[1]
        )
    size_column = size_columns[0] if size_columns else "size"
    unit = resolve_size_unit(table, size_column_unit(size_column)[1], size_unit, size_column)
    known = _known_points_columns(size_column)
    if "used" in table.frame.columns:
        table = table.subset(table.boolean("used"))
        if table.frame.empty:
            raise InputError("no row is marked as used", source=table.source, column="used")
    table.require(size_column)
    given = [c for c in PARTITION_COLUMNS if c in table.frame.columns]
    if not given:
        unknown = table.unknown_columns(known)
        raise InputError(
            f"no partition column: give exactly one of {', '.join(PARTITION_COLUMNS)}"
            + (f"; unknown column(s) {unknown}" if unknown else ""),
            source=table.source,
        )
    if len(given) > 1:
        raise InputError(
            f"several partition columns ({', '.join(given)}): give exactly one", source=table.source, column=given[1]
        )
    table.refuse_unknown(known, what="Tromp-points file")
    column = given[0]
    scale, to_fines = PARTITION_COLUMNS[column]
    size = table.numeric(size_column)
    partition = table.numeric(column)
    upper = scale
    bad = np.flatnonzero((partition < 0) | (partition > upper))
    if bad.size:
        i = int(bad[0])
        raise table.error(f"partition {partition[i]:g} outside 0..{upper:g}", index=i, column=column)
    bad = np.flatnonzero(size <= 0)
    if bad.size:
        raise table.error(f"size must be positive, got {size[bad[0]]:g}", index=int(bad[0]), column=size_column)
    weight = None
    if "weight" in table.frame.columns:
        weight = table.numeric("weight")
        bad = np.flatnonzero(weight <= 0)
        if bad.size:
            raise table.error("weight must be positive", index=int(bad[0]), column="weight")
    phi = partition / scale
    if not to_fines:
        phi = 1.0 - phi
    experiments = table.experiment_labels()
    result = []
    for name, rows in experiment_rows(experiments).items():
        _check_unique_sizes(table, rows, size, size_column)
        result.append(
            TrompPoints(
                experiment=name,
                size=size[rows],
                partition_fine=phi[rows],
                weight=None if weight is None else weight[rows],
                source=table.source,
                size_unit=unit,
            )
        )
    return result


def experiment_rows(labels) -> dict:
    """Positions of each experiment's rows, experiments in order of first appearance (one
    pass over the labels: a file of 10,000 experiments is not scanned 10,000 times)."""
    groups = pd.Series(np.arange(len(labels))).groupby(pd.Series(labels, dtype=object), sort=False).indices
    return {name: np.asarray(groups[name]) for name in dict.fromkeys(labels)}


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


def _check_unique_sizes(table: Table, rows: np.ndarray, size: np.ndarray, column: str = "size") -> None:
    seen = {}
    for i in rows:
        if size[i] in seen:
            raise table.error(
                f"duplicate size {size[i]:g} in the same experiment (also at row {table.rows[seen[size[i]]]})",
                index=int(i),
                column=column,
            )
        seen[size[i]] = i


def points_from_frame(frame: pd.DataFrame, *, source: str = "data frame") -> list[TrompPoints]:
    """Tromp points from a data frame in the file schema (same checks and messages as a file;
    rows are numbered from 1)."""
    frame = frame.reset_index(drop=True)
    frame.index = frame.index + 1
    return points_from_table(table_from_frame(frame, source=source))
