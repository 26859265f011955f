"""Density inputs read as the lab writes them: tracer counts, float-sink analyses, or a partition.

Three layouts, told apart by their columns (:func:`density_layout`):

tracer tests
    ``test, density, placed, sinks, floats``: per tracer density, the tracers put into the
    feed (``placed``, optional) and those recovered in the sinks and in the floats (whole
    numbers >= 0).  The recovered ``n = sinks + floats`` are the binomial trials; the lost
    ``placed - sinks - floats`` are reported, not counted.  A density with no tracer
    recovered is left out with a note.
float-sink analyses of the products
    ``test, density_lower, density_upper, feed_pct, floats_pct, sinks_pct``: mass per cent
    of each stream in each density fraction (``feed_pct`` optional), optionally
    ``floats_yield`` (mass share of the feed to the floats, 0..1, constant within a test),
    ``density_mean`` (the measured mean density of a fraction) and the ash per stream and
    fraction ``feed_ash_pct, floats_ash_pct, sinks_ash_pct`` (carried, not used by the fit).
    The mass balance is the size lab tables' (:mod:`tromplab.loading.lab`) with the sinks as
    the "fine" product: the sinks yield is estimated by least squares from the three
    analyses (:func:`~tromplab.loading.lab.estimate_fine_yield`) when no yield is given, a
    stated yield is compared with it (:func:`~tromplab.loading.lab.yield_contradiction`),
    and the partition to sinks is ``(1 - Y) s / ((1 - Y) s + Y f)`` from both products
    (:func:`~tromplab.loading.lab.partition_to_fines`).
a partition given directly
    ``test, density, partition_sinks`` (0..1).

``test`` is optional (all rows one test, named after the file).  Any layout may add
``size_lower_<unit>`` and ``size_upper_<unit>`` (tracers or fractions of several sizes;
blank ``size_upper`` = the open top size, blank or 0 ``size_lower`` = the finest): each
test and size fraction is then one curve.  Rows of one test and size fraction are given
in increasing density.

Open density fractions: a blank (or 0) ``density_lower`` is the float below the lightest
liquid, a blank ``density_upper`` the sink above the heaviest; each is given the width of
its neighbouring fraction (as an open size class continues its neighbour's progression,
here on the linear density axis), and its partition is plotted and fitted at the
midpoint of that extended fraction unless ``density_mean`` is given.  Closed fractions sit
at their midpoint, or at ``density_mean``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ..errors import InputError
from ..loading.points import experiment_rows, size_column_unit
from ..loading.tables import Table, read_table
from ..options import DEFAULT_SUM_TOLERANCE_PCT
from ..validation import YIELD_MARGIN, check_optional, check_yield
from .fractions import densities, density_fractions

# The size lab tables' mass balance (tromplab.loading.lab and the ten modules under it) is imported
# where a float-sink table needs it: a file of tracer counts or of partitions does not.
if TYPE_CHECKING:
    from ..loading.lab import LabOptions, YieldEstimate

LAYOUTS = ("tracers", "float-sink", "partition")
TRACER_COLUMNS = ("density", "sinks", "floats")
FLOAT_SINK_COLUMNS = ("density_lower", "density_upper", "floats_pct", "sinks_pct")
PARTITION_COLUMNS = ("density", "partition_sinks")
ASH_COLUMNS = ("feed_ash_pct", "floats_ash_pct", "sinks_ash_pct")
#: Most tracers of one density: a tracer test places tens to a few thousand; a larger count is a
#: mistyped value (and above 2**53 a count is no longer a whole number in floating point).
MAX_TRACERS = 1_000_000_000
#: A partition to sinks that falls by more than this from the lightest density to the heaviest
#: is the partition to floats (or the products swapped): sinks take the heavy particles.
FALLING_PARTITION = 0.5


@dataclass(frozen=True)
class DensitySample:
    """The measured partition to sinks of one test (and size fraction).

    Attributes
    ----------
    test : str
        Name of the test.
    layout : str
        ``"tracers"``, ``"float-sink"`` or ``"partition"``.
    points : pandas.DataFrame
        One row per density (tracers, partition) or density fraction (float-sink), in
        increasing density: ``density`` (g/cm3, where the partition is plotted and
        fitted), ``partition_sinks`` (0..1), ``row`` (file row), ``used``; tracers add
        ``placed, sinks, floats, recovered, lost``; float-sink adds ``density_lower,
        density_upper, feed, floats, sinks`` (shares 0..1; ``feed`` as the products
        recombine), ``feed_measured`` (when given), ``balance_residual``, ``weight`` (the
        fraction's feed share, the least-squares weight) and the ash columns when given.
    size_lower, size_upper : float
        Bounds of the particle size fraction (NaN when not given or open).
    size_unit : str
        Unit of the size bounds ("" when none).
    floats_yield : float or None
        Mass share of the feed to the floats (float-sink only).
    yield_source : str
        Where ``floats_yield`` came from.
    yield_estimate : YieldEstimate or None
        The least-squares estimate of the sinks yield from three analyses.
    notes : tuple of str
        What was inferred or left out, in words.
    source : str
        The file (or ``DataFrame``).
    """

    test: str
    layout: str
    points: pd.DataFrame
    size_lower: float = math.nan
    size_upper: float = math.nan
    size_unit: str = ""
    floats_yield: float | None = None
    yield_source: str = ""
    yield_estimate: YieldEstimate | None = field(default=None, repr=False)
    notes: tuple[str, ...] = ()
    source: str = ""

    @property
    def has_size(self) -> bool:
        """True when the test gives a particle size fraction."""
        return not (math.isnan(self.size_lower) and math.isnan(self.size_upper))

    @property
    def size_fraction(self) -> str:
        """The size fraction as text (``"8-16 mm"``, ``"+16 mm"``, ``"-0.5 mm"``); "" when none."""
        if not self.has_size:
            return ""
        unit = f" {self.size_unit}" if self.size_unit else ""
        if math.isnan(self.size_upper):
            return f"+{self.size_lower:g}{unit}"
        if math.isnan(self.size_lower):
            return f"-{self.size_upper:g}{unit}"
        return f"{self.size_lower:g}-{self.size_upper:g}{unit}"

    @property
    def label(self) -> str:
        """The test and its size fraction, for messages and figure titles."""
        return f"{self.test} ({self.size_fraction})" if self.has_size else self.test

    @cached_property
    def used(self) -> pd.DataFrame:
        """The points the fits use (made once, on first use: read it as :attr:`points` is read, not
        to be changed in place)."""
        # the fits, the tables and the summary ask for it a dozen times per test: a boolean row
        # selection of pandas each time was a fifth of the writing of fits.csv
        return self.points[self.points["used"]].reset_index(drop=True)


def density_layout(columns) -> str | None:
    """Which density layout the columns are (``"tracers"``, ``"float-sink"``, ``"partition"``), or None.

    Examples
    --------
    >>> density_layout(["test", "density", "placed", "sinks", "floats"])
    'tracers'
    >>> density_layout(["density_lower", "density_upper", "floats_pct", "sinks_pct"])
    'float-sink'
    """
    names = {str(column).strip() for column in columns}
    if set(TRACER_COLUMNS) <= names:
        return "tracers"
    if set(FLOAT_SINK_COLUMNS) <= names:
        return "float-sink"
    if set(PARTITION_COLUMNS) <= names:
        return "partition"
    return None


def read_density(
    path,
    *,
    sheet=None,
    sep: str | None = None,
    decimal: str | None = None,
    floats_yield: float | None = None,
    sum_tolerance_pct: float = DEFAULT_SUM_TOLERANCE_PCT,
) -> list[DensitySample]:
    """Read tracer counts, float-sink analyses or a partition into one sample per test and size fraction.

    Parameters
    ----------
    path : str, path-like or pandas.DataFrame
        CSV or Excel file, or a DataFrame with the same columns (rows named by index label).
    sheet, sep, decimal : optional
        As for the size lab tables (:func:`tromplab.loading.tables.read_table`).
    floats_yield : float, optional
        Mass share of the feed reporting to the floats (float-sink only); overrides a
        ``floats_yield`` column.
    sum_tolerance_pct : float
        Allowed deviation of each analysis from 100 % (percentage points).

    Returns
    -------
    list of DensitySample

    Raises
    ------
    InputError
        For bad input, naming the file, row and column: negative or fractional counts,
        sinks + floats above placed, densities not increasing, overlapping fractions,
        analyses that do not sum to 100 %, shares outside 0..1.

    Examples
    --------
    >>> tracers = pd.DataFrame({"density": [1.3, 1.4, 1.5], "placed": [30, 30, 30],
    ...                         "sinks": [1, 14, 29], "floats": [28, 15, 1]})
    >>> sample = read_density(tracers)[0]
    >>> sample.points["lost"].tolist(), sample.points["partition_sinks"].round(3).tolist()
    ([1, 1, 0], [0.034, 0.483, 0.967])
    """
    table = density_table(path, sheet=sheet, sep=sep, decimal=decimal, floats_yield=floats_yield,
                          sum_tolerance_pct=sum_tolerance_pct)  # fmt: skip
    return list(table.samples())


def density_table(
    path,
    *,
    sheet=None,
    sep: str | None = None,
    decimal: str | None = None,
    floats_yield: float | None = None,
    sum_tolerance_pct: float = DEFAULT_SUM_TOLERANCE_PCT,
) -> DensityTable:
    """Read a density table and check it as a whole (:func:`read_density`'s checks of the file and
    its columns); its samples are made when :meth:`DensityTable.samples` is iterated.

    Parameters are those of :func:`read_density`.

    Returns
    -------
    DensityTable
    """
    floats_yield = check_optional(check_yield, floats_yield, "floats_yield")
    table = read_table(path, sheet=sheet, sep=sep, decimal=decimal)
    layout = density_layout(table.frame.columns)
    if layout is None:
        have = ", ".join(map(str, table.frame.columns))
        raise InputError(
            "not a density table: give tracer counts (density, placed, sinks, floats), float-sink analyses "
            f"(density_lower, density_upper, feed_pct, floats_pct, sinks_pct) or a partition (density, partition_sinks); "
            f"columns present: {have}",
            source=table.source,
        )
    size_columns, size_unit = _size_columns(table)
    known = {"tracers": TRACER_COLUMNS + ("placed",), "partition": PARTITION_COLUMNS}.get(
        layout, FLOAT_SINK_COLUMNS + ("feed_pct", "floats_yield", "density_mean") + ASH_COLUMNS
    )
    table.refuse_unknown(["test", *known, *size_columns], what=f"{layout} table")
    labels = _test_labels(table)
    sizes = _size_bounds(table, size_columns)
    group_keys = [f"{label}\x00{lower!r}\x00{upper!r}" for label, lower, upper in zip(labels, *sizes)]
    groups = tuple(experiment_rows(group_keys).values())
    return DensityTable(table, layout, groups, labels, sizes, size_unit, floats_yield, sum_tolerance_pct)


@dataclass(frozen=True)
class DensityTable:
    """A density table read and checked as a whole, its rows grouped by test and size fraction:
    the samples are made from it one at a time (:meth:`samples`), so that a large campaign need
    not hold every sample at once (``tromplab density fit`` streaming its results).

    Attributes
    ----------
    table : Table
        The rows as read.
    layout : str
        ``"tracers"``, ``"float-sink"`` or ``"partition"``.
    groups : tuple of numpy.ndarray
        The row positions of each test and size fraction, in the order they first appear.
    labels : numpy.ndarray
        The test of each row.
    sizes : tuple of numpy.ndarray
        The lower and upper size bound of each row (NaN when not given).
    size_unit : str
        Unit of the size bounds ("" when none).
    floats_yield : float or None
        The floats yield asked for (float-sink tables).
    sum_tolerance_pct : float
        Allowed deviation of each analysis from 100 %.
    """

    table: Table
    layout: str
    groups: tuple
    labels: np.ndarray = field(repr=False)
    sizes: tuple = field(repr=False)
    size_unit: str = ""
    floats_yield: float | None = None
    sum_tolerance_pct: float = DEFAULT_SUM_TOLERANCE_PCT

    def __len__(self) -> int:
        return len(self.groups)

    @property
    def has_size(self) -> bool:
        """True when a test gives a particle size fraction."""
        return bool(np.isfinite(self.sizes[0]).any() or np.isfinite(self.sizes[1]).any())

    def samples(self):
        """The :class:`DensitySample` of each test and size fraction, in order, made as they are
        taken (an :class:`~tromplab.errors.InputError` when one cannot be made)."""
        for rows in self.groups:
            yield self._sample(rows)

    def _sample(self, rows) -> DensitySample:
        part = self.table.subset(rows)
        lower, upper = float(self.sizes[0][rows[0]]), float(self.sizes[1][rows[0]])
        context = {"test": str(self.labels[rows[0]]), "size_lower": lower, "size_upper": upper, "size_unit": self.size_unit}
        if self.layout == "tracers":
            return _tracer_sample(part, context)
        if self.layout == "partition":
            return _partition_sample(part, context)
        from ..loading.lab import LabOptions

        options = LabOptions(sum_tolerance_pct=self.sum_tolerance_pct)
        return _float_sink_sample(part, context, options, self.floats_yield)


def _test_labels(table: Table) -> np.ndarray:
    if "test" not in table.frame.columns:
        return np.full(len(table.frame), Path(table.source).stem, dtype=object)
    labels = table.frame["test"]
    blank = labels.isna().to_numpy() | (labels.astype(str).str.strip() == "").to_numpy()
    table.refuse_where(blank, "test", "test name is blank")
    return labels.astype(str).str.strip().to_numpy(dtype=object)


def _size_columns(table: Table) -> tuple[tuple[str, ...], str]:
    found = {}
    for column in table.frame.columns:
        for stem in ("size_lower", "size_upper"):
            matched, unit = size_column_unit(column, stem)
            if matched:
                found[stem] = (column, unit)
    if not found:
        return (), ""
    if len(found) == 1:
        missing = "size_upper" if "size_lower" in found else "size_lower"
        raise InputError(f"size fractions need both size_lower and size_upper; {missing} is missing", source=table.source)
    if found["size_lower"][1] != found["size_upper"][1]:
        raise InputError("the two size columns carry different units; use one unit", source=table.source)
    return (found["size_lower"][0], found["size_upper"][0]), found["size_lower"][1]


def _size_bounds(table: Table, columns: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray]:
    count = len(table.frame)
    if not columns:
        return np.full(count, np.nan), np.full(count, np.nan)
    lower = table.numeric(columns[0], allow_blank=True)
    upper = table.numeric(columns[1], allow_blank=True)
    lower = np.where(lower == 0, np.nan, lower)
    for values, column in ((lower, columns[0]), (upper, columns[1])):
        table.refuse_where(
            values < 0, column, "a size bound must be positive (a finest fraction's lower bound may be 0 or blank)"
        )
    table.refuse_where(
        np.isfinite(lower) & np.isfinite(upper) & (lower >= upper),
        columns[0],
        lambda i: f"size_lower {lower[i]:g} is not below size_upper {upper[i]:g}",
    )
    return lower, upper


def _check_increasing(table: Table, values: np.ndarray, column: str) -> None:
    step = np.diff(values)
    bad = np.flatnonzero(~(step > 0))
    if bad.size:
        i = int(bad[0]) + 1
        raise table.error(
            f"densities not increasing: {values[i]:g} follows {values[i - 1]:g} (give the rows of a test in increasing density, "
            "each density once)",
            index=i,
            column=column,
        )


def _counts(table: Table, column: str) -> np.ndarray:
    values = table.numeric(column)
    table.refuse_where(values < 0, column, lambda i: f"negative count {values[i]:g}")
    table.refuse_where(
        values > MAX_TRACERS, column, lambda i: f"count {values[i]:.6g} is more than {MAX_TRACERS:,} tracers: a mistyped value?"
    )
    table.refuse_where(values != np.round(values), column, lambda i: f"count {values[i]:g} is not a whole number of tracers")
    return values.astype(np.int64)


def _base_sample(table: Table, context: dict, layout: str, points: pd.DataFrame, notes: list[str], **extra) -> DensitySample:
    used = int(points["used"].sum())
    if used < 2:
        label = context["test"]
        raise InputError(f"test '{label}' has {used} usable densities; at least 2 are needed to fit a curve", source=table.source)
    if layout == "partition":  # counts and analyses carry sampling noise: a few tracers may fall by chance
        _refuse_falling(table, context["test"], points[points["used"]])
    return DensitySample(layout=layout, points=points, notes=tuple(notes), source=table.source, **context, **extra)


def _refuse_falling(table: Table, test: str, used: pd.DataFrame) -> None:
    """Refuse a partition to sinks given directly that falls from the lightest density to the heaviest.

    Sinks take the heavy particles, so a partition to sinks rises with density; fitted as
    given, a falling one ends with Ep at its bound and a negative rho25 reported as a success.
    """
    share = used["partition_sinks"].to_numpy(dtype=float)
    drop = share[0] - share[-1]
    if drop > FALLING_PARTITION:
        raise InputError(
            f"test '{test}': the partition to sinks falls with density, from {share[0]:.3g} at {used['density'].iloc[0]:g} "
            f"to {share[-1]:.3g} at {used['density'].iloc[-1]:g} g/cm3; the sinks take the heavy particles, so it looks "
            "like the partition to floats: give partition_sinks = 1 - the partition to floats",
            source=table.source,
            column="partition_sinks",
        )


def _tracer_sample(table: Table, context: dict) -> DensitySample:
    density = densities(table, "density")
    _check_increasing(table, density, "density")
    sinks, floats = _counts(table, "sinks"), _counts(table, "floats")
    recovered = sinks + floats
    notes = []
    if "placed" in table.frame.columns:
        placed = _counts(table, "placed")
        table.refuse_where(
            recovered > placed, "placed", lambda i: f"sinks + floats = {recovered[i]} is more than the {placed[i]} tracers placed"
        )
        lost = placed - recovered
        if lost.sum():
            notes.append(
                f"{int(lost.sum())} of {int(placed.sum())} tracers lost ({100 * lost.sum() / placed.sum():.1f} %), not counted"
            )
    else:
        placed = lost = np.full(density.size, -1, dtype=np.int64)  # replaced by NA below
    empty = recovered == 0
    if empty.any():
        notes.append(f"no tracer recovered at density {', '.join(f'{d:g}' for d in density[empty])}: left out")
    with np.errstate(invalid="ignore", divide="ignore"):
        share = np.where(empty, np.nan, sinks / np.maximum(recovered, 1))
    points = pd.DataFrame(
        {
            "density": density,
            "partition_sinks": share,
            "placed": pd.array(placed, dtype="Int64"),
            "sinks": sinks,
            "floats": floats,
            "recovered": recovered,
            "lost": pd.array(lost, dtype="Int64"),
            "row": table.rows,
            "used": ~empty,
        }
    )
    if "placed" not in table.frame.columns:
        points[["placed", "lost"]] = pd.NA
    return _base_sample(table, context, "tracers", points, notes)


def _partition_sample(table: Table, context: dict) -> DensitySample:
    density = densities(table, "density")
    _check_increasing(table, density, "density")
    share = table.numeric("partition_sinks")
    bad = np.flatnonzero((share < 0) | (share > 1))
    if bad.size:
        hint = ": give it as a share 0..1, not per cent" if share.max() > 1.5 else ""
        raise table.error(f"partition {share[bad[0]]:g} outside 0..1{hint}", index=int(bad[0]), column="partition_sinks")
    points = pd.DataFrame({"density": density, "partition_sinks": share, "row": table.rows, "used": True})
    return _base_sample(table, context, "partition", points, ["partition given directly: fitted by unweighted least squares"])


def _float_sink_sample(table: Table, context: dict, options: LabOptions, floats_yield: float | None) -> DensitySample:
    from ..loading.lab import partition_to_fines, per_class_shares

    fractions = density_fractions(table, minimum=3)
    lower, upper, density, notes = fractions.lower, fractions.upper, fractions.density, list(fractions.notes)
    shares = {}
    for stream, column in (("feed", "feed_pct"), ("sinks", "sinks_pct"), ("floats", "floats_pct")):
        if column in table.frame.columns:
            shares[stream], _, note = per_class_shares(table, column, "pct", options)
            notes += [note] if note else []
    sinks_yield, yield_source, estimate = _sinks_yield(table, shares, floats_yield, notes)
    s, f = shares["sinks"], shares["floats"]
    # a share between two shares; the sum of the two products can round an ulp above 1
    feed = np.clip(sinks_yield * s + (1 - sinks_yield) * f, 0.0, 1.0)
    partition = partition_to_fines(feed, s, f, sinks_yield)
    used = np.isfinite(partition)
    if not used.all():
        notes.append(
            f"no material in the fraction(s) at {', '.join(f'{d:g}' for d in density[~used])} of either product: left out"
        )
    points = pd.DataFrame(
        {
            "density": density,
            "partition_sinks": partition,
            "density_lower": lower,
            "density_upper": upper,
            "feed": feed,
            "floats": f,
            "sinks": s,
            "weight": feed,
            "row": table.rows,
            "used": used,
        }
    )
    if "feed" in shares:
        points["feed_measured"] = shares["feed"]
        points["balance_residual"] = shares["feed"] - feed
    for column in ASH_COLUMNS:
        if column in table.frame.columns:
            ash = table.numeric(column, allow_blank=True)
            bad = np.flatnonzero((ash < 0) | (ash > 100))
            if bad.size:
                raise table.error(f"ash {ash[bad[0]]:g} % outside 0..100", index=int(bad[0]), column=column)
            points[column] = ash
    return _base_sample(
        table,
        context,
        "float-sink",
        points,
        notes,
        floats_yield=1.0 - sinks_yield,
        yield_source=yield_source,
        yield_estimate=estimate,
    )


def _stated_floats_yield(table: Table, option: float | None) -> tuple[float | None, str]:
    if option is not None:
        return float(option), "option floats_yield"
    if "floats_yield" not in table.frame.columns:
        return None, ""
    values = table.numeric("floats_yield", allow_blank=True)
    table.refuse_where(
        np.isfinite(values) & ((values <= 0) | (values >= 1)),
        "floats_yield",
        lambda i: f"floats yield {values[i]:g} outside (0, 1) (a share of the feed, not per cent)",
    )
    given = values[np.isfinite(values)]
    if given.size == 0:
        return None, ""
    if np.ptp(given) > 1e-12:
        i = int(np.flatnonzero(np.isfinite(values) & (values != given[0]))[0])
        raise table.error("the floats yield differs between rows of the same test", index=i, column="floats_yield")
    return float(given[0]), "column floats_yield"


def _sinks_yield(table: Table, shares: dict, floats_yield: float | None, notes: list[str]):
    """The sinks yield (the size tables' "fine yield" with the sinks as that product), its source and the estimate."""
    from ..loading.lab import estimate_fine_yield, yield_contradiction

    given, source = _stated_floats_yield(table, floats_yield)
    estimate = None
    if "feed" in shares:
        try:
            estimate = estimate_fine_yield(shares["feed"], shares["sinks"], shares["floats"])
        except ValueError:
            raise InputError(
                "the floats and sinks analyses are identical: the yield cannot be estimated", source=table.source
            ) from None
    if given is not None:
        if estimate is not None and yield_contradiction(1.0 - given, estimate) is not None:
            notes.append(
                f"the stated floats yield {given:.3f} ({source}) contradicts the float-sink analyses, which imply "
                f"{1 - estimate.value:.3f} +/- {estimate.stderr:.3f}; the stated yield is used"
            )
        return 1.0 - given, source, estimate
    if estimate is None:
        raise InputError(
            "without a feed analysis (feed_pct) the floats yield must be given (column floats_yield or option floats_yield)",
            source=table.source,
        )
    if not YIELD_MARGIN < estimate.value < 1.0 - YIELD_MARGIN:
        raise InputError(
            f"the float-sink analyses imply a floats yield of {1 - estimate.value:.3f}, outside (0, 1): check the streams",
            source=table.source,
        )
    notes.append(
        f"floats yield {1 - estimate.value:.4f} +/- {estimate.stderr:.4f} estimated by least squares from the three analyses"
    )
    return estimate.value, "least-squares estimate", estimate
