"""From laboratory sieve data to Tromp points, with the mass balance checked.

Schema of a lab table (CSV or Excel), one row per size class (or per sieve) and
experiment - see docs/lab_tables.md for an example:

``experiment``
    optional; all rows form one experiment named after the file when absent.
size columns
    one layout of three: class bounds ``size_lower`` and ``size_upper`` (blank
    ``size_upper`` = open top class, blank or 0 ``size_lower`` = the pan); class-range
    strings in ``size_class`` ("+1168" = retained on 1168, "-1168+589", "-74" = the
    pan); or ``size`` (the sieve aperture), for cumulative data or for per-class shares
    retained on each sieve (a class then runs from its sieve to the next coarser one,
    the coarsest open at the top).  Optionally ``size_representative`` (a size per
    class, replacing the geometric mean where given).  A unit suffix (``size_um``,
    ``size_lower_mm``) names the unit and must be the same on every size column; a
    ``size_unit`` column or the ``size_unit`` option is the fallback and must agree.
    Sizes are used as given.
stream columns
    two or three of ``feed``, ``fine`` (or ``overflow``), ``coarse`` (or
    ``underflow``).  What they hold is declared, never
    guessed: either by the ``kind`` option for plain names, or by a suffix on each
    column: ``_mass`` (mass per class, any unit), ``_pct`` / ``_frac`` (share of the
    stream per class), ``_retained_pct`` / ``_retained_frac`` (cumulative share coarser
    than the sieve) or ``_passing_pct`` / ``_passing_frac`` (cumulative share finer).
``fine_yield`` or ``coarse_yield`` (``overflow_yield``, ``underflow_yield``)
    optional column (constant within an experiment) or option: the mass fraction of
    the feed reporting to that product.
``note``, ``comment``
    free text, ignored.  Any other column is refused with its name.

Per-class shares come from cumulative data by differences.  The representative size of
a class is the geometric mean of its bounds; the open top class and the pan continue
the geometric progression of their neighbour (upper = lower * r for the top class,
lower = upper / r for the pan, r = upper/lower of the adjacent class), unless
``top_size`` or ``pan_lower_size`` is given.

Partition to fines ``phi_i = y b_i / a_i`` with ``a``, ``b``, ``c`` the feed, fine and
coarse shares and ``y`` the fine yield (Shuvalov et al. 2018, introduction; spec
section 5).  With three measured streams the feed is taken as the products recombine,
``a_i = y b_i + (1-y) c_i``, so ``phi_i = y b_i / (y b_i + (1-y) c_i)`` uses both
products and exchanging them gives ``1 - phi`` (:func:`partition_to_fines`; the
measured feed alone with ``partition_from="feed"``).  With three streams and no yield,
``y`` is estimated by least squares over the classes (:func:`estimate_fine_yield`);
with a yield given too, the two are compared and a contradiction is reported.  Two
products given as masses imply the yield ``fine / (fine + coarse)``, compared likewise.
"""

from __future__ import annotations

import logging
import re
import warnings
from dataclasses import dataclass, field, fields
from typing import NamedTuple

import numpy as np
import pandas as pd

from ..errors import InputError, OptionError, YieldWarning
from ..options import DEFAULT_MIN_FEED_SHARE, DEFAULT_SUM_TOLERANCE_PCT, KINDS, PARTITION_METHODS
from ..results_contract import ResultContract
from ..validation import (
    SIZE_LIMITS,
    check_non_negative,
    check_optional,
    check_probability,
    check_range,
    check_share,
    check_size,
    check_water_recovery,
)
from .kelsall import kelsall_corrected
from .names import renamed_to_names
from .points import TrompPoints, experiment_rows, points_from_table
from .size_classes import class_string_bounds, size_columns
from .surveys import has_survey_columns, split_survey_columns, with_survey_meta
from .tables import Table, read_table

logger = logging.getLogger(__name__)

STREAMS = ("feed", "fine", "coarse")
STREAM_ALIASES = {"overflow": "fine", "underflow": "coarse"}  # hydrocyclone wording
CUMULATIVE_KINDS = {"retained_pct", "retained_frac", "passing_pct", "passing_frac"}
SIZE_STEMS = ("size", "size_lower", "size_upper", "size_class", "size_representative")
PARTITION_METHOD_TEXT = {  # how each partition method reads in outputs
    "products": "both products, y b / (y b + (1 - y) c)",
    "feed": "the fine stream over the measured feed, y b / a",
    "reconciled": "the reconciled distributions, y b' / a'",
}
YIELD_COLUMNS = {"fine_yield": "fine", "overflow_yield": "fine", "coarse_yield": "coarse", "underflow_yield": "coarse"}
YIELD_MARGIN = 1e-9  # an estimated yield this close to 0 or 1 means one product is empty
MASS_YIELD_TOLERANCE = 0.005  # |stated - implied| fine yield above which two product masses contradict a stated yield
PARTITION_SLACK = 0.02
#: Largest amount (mass) of one class: sums over any number of classes stay finite.
MAX_AMOUNT = 1e250


@dataclass(frozen=True)
class LabOptions:
    """How to read a lab table.

    Attributes
    ----------
    kind : str or None
        What plain stream columns hold (one of :data:`KINDS`); not needed when every
        stream column carries a kind suffix.
    fine_yield, coarse_yield : float or None
        Yield of the fine (coarse) product as a fraction of the feed; overrides a column.
    estimate_yield : bool
        Ignore a given yield and estimate it from three streams.
    reconcile : bool
        Adjust the three distributions minimally so every class balances and compute
        the partition from the adjusted values.
    min_feed_share : float
        Classes with a smaller feed share are flagged and left out of the fit.
    sum_tolerance_pct : float
        Allowed deviation of per-class percentages from 100 % (percentage points).
    top_size, pan_lower_size : float or None
        Upper bound of the open top class, lower bound of the pan (0 or None: the pan
        continues the geometric progression of its neighbour, as a blank or 0 lower
        bound in the table does; a geometric mean with 0 would put the pan at size 0).
    rename : dict
        Column renames applied before reading (``{"sieve_um": "size"}``).
    sheet : str or None
        Excel sheet.
    weight_by_feed_share : bool
        Weight each Tromp point by the feed share of its class.  Error model: the
        partition of a class is measured on a sample mass proportional to its feed
        share, so its variance is inversely proportional to that share.
    partition_from : {"products", "feed"}
        With three measured streams: ``"products"`` (default) computes the partition
        from both products, :math:`y b / (y b + (1-y) c)`, so swapping the fine and
        coarse columns gives exactly 1 - partition; ``"feed"`` divides the fine
        stream by the measured feed, :math:`y b / a` (the fine stream alone; not
        symmetric when the balance does not close).  ``reconcile`` overrides both.
    size_unit : str or None
        Unit of the sizes when the size columns carry no unit suffix (``--size-unit``);
        a contradiction with a suffix is an error.
    sep, decimal : str or None
        CSV separator and decimal mark (detected when not given).
    water_recovery : float or None
        Share of the feed water reporting to the underflow (coarse product) of a
        hydrocyclone, in [0, 1) (``--water-recovery``); the points table then also gives
        the Kelsall-corrected partition ``partition_fine_corrected`` (see
        :func:`tromplab.loading.kelsall.kelsall_corrected`).
    """

    kind: str | None = None
    fine_yield: float | None = None
    coarse_yield: float | None = None
    estimate_yield: bool = False
    reconcile: bool = False
    min_feed_share: float = DEFAULT_MIN_FEED_SHARE
    sum_tolerance_pct: float = DEFAULT_SUM_TOLERANCE_PCT
    top_size: float | None = None
    pan_lower_size: float | None = None
    rename: dict = field(default_factory=dict)
    sheet: str | None = None
    weight_by_feed_share: bool = False
    partition_from: str = "products"
    size_unit: str | None = None
    sep: str | None = None
    decimal: str | None = None
    water_recovery: float | None = None

    def __post_init__(self):
        if self.kind is not None and self.kind not in KINDS:
            raise ValueError(f"unknown kind {self.kind!r}; choose one of {', '.join(KINDS)}")
        if self.partition_from not in PARTITION_METHODS:
            raise ValueError(f"unknown partition_from {self.partition_from!r}; choose one of {', '.join(PARTITION_METHODS)}")
        for name in ("fine_yield", "coarse_yield"):
            check_optional(check_probability, getattr(self, name), name)
        check_share(self.min_feed_share, "min_feed_share")
        check_range(self.sum_tolerance_pct, "sum_tolerance_pct", low=0.0, high=100.0)
        check_optional(check_size, self.top_size, "top_size")
        check_optional(check_range, self.pan_lower_size, "pan_lower_size", low=0.0, high=SIZE_LIMITS[1])
        check_optional(check_water_recovery, self.water_recovery, "water_recovery")
        if self.fine_yield is not None and self.coarse_yield is not None:
            if not np.isclose(self.fine_yield + self.coarse_yield, 1.0, atol=1e-6):
                raise InputError("fine_yield and coarse_yield are both given and do not add up to 1")


@dataclass(frozen=True)
class YieldEstimate:
    """Least-squares estimate of the fine yield from three size distributions."""

    value: float
    stderr: float
    n_classes: int
    residuals: np.ndarray = field(repr=False)


@dataclass(frozen=True)
class MassBalance(ResultContract):
    """One experiment of a lab table turned into Tromp points.

    ``classes`` has one row per size class with columns ``experiment, size_lower,
    size_upper, size, feed, fine, coarse`` (shares of each stream, 0..1, as measured or
    derived), ``balance_residual`` (``feed - y fine - (1-y) coarse``), ``partition_fine``,
    ``partition_coarse``, ``used`` and ``flag`` (the reason a class is left out, or a note)
    and ``row`` (the file row of the class, when a class is one row).
    When reconciled, ``feed_adjusted``, ``fine_adjusted`` and ``coarse_adjusted`` hold
    the adjusted shares.  ``partition_method`` says how the partition was computed
    (see :class:`LabOptions`), ``size_unit`` the unit of the sizes ("" when unknown),
    ``water_recovery`` the water split to the underflow when given (hydrocyclones).
    :meth:`summary` is one row (the yield and the classes used), :meth:`to_frame` the classes,
    :meth:`report` what ``tromplab balance`` prints for the experiment.

    Attributes
    ----------
    experiment : str
        The experiment's name.
    classes : pandas.DataFrame
        One row per size class (columns above).
    fine_yield : float
        Mass share of the feed reporting to the fine product, 0..1.
    yield_source : str
        Where ``fine_yield`` came from (stated, estimated from the three streams, ...).
    yield_estimate : YieldEstimate or None
        The least-squares estimate from the three size distributions (None without them).
    top_size : float
        Largest size of the feed (the upper bound of the coarsest class).
    notes : tuple of str
        What was inferred or left out, in words.
    source : str
        The file the table came from.
    partition_method : str
        How the partition was computed (see :class:`LabOptions`).
    size_unit : str
        Unit of the sizes ("" when unknown).
    water_recovery : float or None
        Water split to the underflow (hydrocyclones; None when not given).
    left_out : list of str
        One message per class left out of the fit.
    """

    experiment: str
    classes: pd.DataFrame
    fine_yield: float
    yield_source: str
    yield_estimate: YieldEstimate | None
    top_size: float
    notes: tuple[str, ...] = ()
    source: str = ""
    partition_method: str = "products"
    size_unit: str = ""
    water_recovery: float | None = None

    @property
    def left_out(self) -> list[str]:
        """One message per class left out of the fit: its bounds, file row and the reason."""
        unit = f" {self.size_unit}" if self.size_unit else ""
        messages = []
        for row in self.classes.loc[~self.classes["used"]].itertuples(index=False):
            where = f" (row {row.row})" if row.row is not None else ""
            messages.append(f"class {_class_label(row.size_lower, row.size_upper)}{unit}{where} left out: {row.flag}")
        return messages

    def summary(self) -> pd.DataFrame:
        """One row: the fine yield and its source (with the three-stream estimate and its standard
        error when there is one), the partition method and the classes used of all."""
        estimate = self.yield_estimate
        row = {"experiment": self.experiment, "fine_yield": self.fine_yield, "yield_source": self.yield_source,
               "yield_estimate": estimate.value if estimate else np.nan,
               "yield_estimate_stderr": estimate.stderr if estimate else np.nan,
               "partition_method": self.partition_method, "classes": len(self.classes),
               "classes_used": int(self.classes["used"].sum()), "top_size": self.top_size}  # fmt: skip
        return pd.DataFrame([row])

    def to_frame(self) -> pd.DataFrame:
        """The classes: one row per size class with the shares, the partition and the flags."""
        return self.classes.copy()

    def _result_context(self) -> str:
        return (f"Experiment {self.experiment}: fine yield {self.fine_yield:.4f} ({self.yield_source}); "
                f"partition from {PARTITION_METHOD_TEXT[self.partition_method]}")  # fmt: skip

    def report(self) -> str:
        """What ``tromplab balance`` prints for the experiment: the yield, the estimate and the classes."""
        lines = [self._result_context()]
        estimate = self.yield_estimate
        if estimate is not None:
            lines.append(f"  least-squares estimate from the three streams: {estimate.value:.4f} +/- {estimate.stderr:.4f} "
                         f"(standard error, {estimate.n_classes} classes); coarse yield {1 - estimate.value:.4f}")  # fmt: skip
        lines.append(self.classes.to_string(index=False, float_format=lambda v: f"{v:.4g}", na_rep="-"))
        return "\n".join(lines)

    def left_out_table(self) -> pd.DataFrame:
        """``experiment, size_lower, size_upper, row, reason`` of every class left out of the fit."""
        dropped = self.classes.loc[~self.classes["used"], ["experiment", "size_lower", "size_upper", "row", "flag"]]
        return dropped.rename(columns={"flag": "reason"}).reset_index(drop=True)

    def left_out_summary(self) -> str:
        """One line: how many classes were left out and why (empty when none was)."""
        dropped = self.left_out_table()
        if dropped.empty:
            return ""
        reasons = dropped["reason"].str.replace(r"^feed share .*", "feed share below the limit", regex=True)
        counted = "; ".join(f"{reason.split(':')[0]}: {count}" for reason, count in reasons.value_counts(sort=False).items())
        unit = f" {self.size_unit}" if self.size_unit else ""
        bounds = ", ".join(_class_label(lo, hi) for lo, hi in zip(dropped["size_lower"], dropped["size_upper"]))
        return f"{len(dropped)} class(es) left out: {bounds}{unit} ({counted})"

    def to_points(self, *, weight_by_feed_share: bool = False) -> TrompPoints:
        used = self.classes[self.classes["used"]]
        return TrompPoints(
            experiment=self.experiment,
            size=used["size"].to_numpy(),
            partition_fine=used["partition_fine"].to_numpy(),
            weight=used["feed"].to_numpy() if weight_by_feed_share else None,
            delta_max=self.top_size,
            source=self.source,
            size_unit=self.size_unit,
        )

    def points_table(self, *, weight_by_feed_share: bool = False, unit_in_names: bool = False) -> pd.DataFrame:
        """Rows in the ``tromplab fit`` schema plus per-class diagnostics (and a ``weight``
        column equal to the feed share when asked); with ``unit_in_names`` the size columns
        carry the unit (``size_um``), so the file read back keeps it.  With a
        ``water_recovery`` the Kelsall-corrected partition ``partition_fine_corrected``
        follows ``partition_fine``."""
        table = self.classes.rename(columns={"feed": "feed_share"})
        columns = [
            "experiment",
            "size",
            "partition_fine",
            "size_lower",
            "size_upper",
            "feed_share",
            "balance_residual",
            "used",
            "flag",
        ]
        table = table[columns]
        if self.water_recovery is not None:
            table.insert(3, "partition_fine_corrected", kelsall_corrected(table["partition_fine"], self.water_recovery))
        if unit_in_names and self.size_unit:
            table = table.rename(columns={c: f"{c}_{self.size_unit}" for c in ("size", "size_lower", "size_upper")})
        return table.assign(weight=table["feed_share"]) if weight_by_feed_share else table


# --- reading ----------------------------------------------------------------------------
def read_lab(path, options: LabOptions | None = None, **option_values) -> list[MassBalance]:
    """Read a lab table and compute the Tromp points of each experiment.

    Parameters
    ----------
    path : str, path-like or pandas.DataFrame
        CSV or Excel file, or a DataFrame with the same columns (rows named by index label).
    options : LabOptions, optional
        How to read the table.
    option_values
        The fields of :class:`LabOptions` as keywords instead of ``options`` (the CLI's
        options with underscores: ``fine_yield=0.3``, ``kind="pct"``, ``sheet="lab"``).

    Returns
    -------
    list of MassBalance
        One per experiment; ``to_points()`` gives its Tromp points.

    Examples
    --------
    Three streams in mass % per class (blank lower bound: the pan), no yield given, so it
    is estimated by least squares:

    >>> lab = pd.DataFrame({"size_lower_um": [None, 20, 40, 80], "size_upper_um": [20, 40, 80, 160],
    ...                     "feed_pct": [30, 30, 25, 15], "fine_pct": [60, 30, 9, 1],
    ...                     "coarse_pct": [10, 30, 35.67, 24.33]})
    >>> balance = read_lab(lab)[0]
    >>> round(balance.fine_yield, 3), balance.yield_source
    (0.4, 'least-squares estimate')
    >>> balance.to_points().partition_fine.round(3).tolist()
    [0.8, 0.4, 0.144, 0.027]

    Raises
    ------
    InputError
        For every kind of bad input, naming file, row and column.
    """
    options = _options(options, option_values)
    return balances_from_table(read_renamed(path, options), options)


def _options(options: LabOptions | None, values: dict) -> LabOptions:
    if options is not None and values:
        raise TypeError("give either a LabOptions or its fields as keywords, not both")
    if options is not None:
        return options
    unknown = sorted(set(values) - {f.name for f in fields(LabOptions)})
    if unknown:
        known = ", ".join(f.name for f in fields(LabOptions))
        raise TypeError(f"unknown lab option(s) {', '.join(unknown)}; known: {known}")
    return LabOptions(**values)


def is_lab_table(columns) -> bool:
    """True when the columns look like a lab table (stream columns, no partition column)."""
    names = [str(c) for c in columns]
    has_stream = any(_stream_of(name) for name in names)
    return has_stream and not any(name.startswith("partition_") for name in names)


def balances_from_table(table: Table, options: LabOptions) -> list[MassBalance]:
    streams = _stream_columns(table, options)
    size_layout = _size_layout(table, options)
    table.refuse_unknown(_known_lab_columns(table, streams, size_layout), what="lab table")
    labels = table.experiment_labels()
    balances = []
    for name, rows in experiment_rows(labels).items():
        part = table.subset(rows)
        balances.append(_balance_one(part, name, streams, size_layout, options))
    return balances


def read_renamed(path, options: LabOptions) -> Table:
    """The table at ``path`` (or a DataFrame) with ``options.rename`` applied; a column renamed
    to a name column is read as text, as the name column itself would be."""
    table = read_table(
        path, sheet=options.sheet, sep=options.sep, decimal=options.decimal, text_columns=renamed_to_names(options.rename)
    )
    return _renamed(table, options.rename)


def _renamed(table: Table, rename: dict) -> Table:
    if not rename:
        return table
    missing = [old for old in rename if old not in table.frame.columns]
    if missing:
        raise InputError(f"cannot rename missing column(s) {', '.join(missing)}", source=table.source)
    renamed = [rename.get(c, c) for c in table.frame.columns]
    clashes = sorted({c for c in renamed if renamed.count(c) > 1})
    if clashes:
        raise InputError(f"after renaming, column(s) {', '.join(clashes)} appear twice", source=table.source, column=clashes[0])
    return Table(table.frame.rename(columns=rename), table.rows, table.source, table.notes)


def _stream_of(column: str):
    """``(stream, kind)`` of a stream column (overflow = fine, underflow = coarse), else None."""
    names = "|".join((*STREAMS, *STREAM_ALIASES))
    match = re.fullmatch(r"(" + names + r")(?:_(" + "|".join(KINDS) + r"))?", column)
    if not match:
        return None
    return STREAM_ALIASES.get(match.group(1), match.group(1)), match.group(2)


def _known_lab_columns(table: Table, streams, layout) -> list[str]:
    """Every column a lab table may hold given its streams and sizes (for the unknown-column check)."""
    known = ["experiment", "size_unit", *YIELD_COLUMNS, *layout.columns, *(column for column, _ in streams.values())]
    suffix = f"_{layout.unit_suffix}" if layout.unit_suffix else ""
    known += [f"{stem}{suffix}" for stem in SIZE_STEMS]  # for suggestions: the sizes spelt as the file spells them
    known += [f"{stream}_{kind}" for stream in (*STREAMS, *STREAM_ALIASES) for kind in KINDS]
    return known


def _stream_columns(table: Table, options: LabOptions) -> dict[str, tuple[str, str]]:
    """``{stream: (column, kind)}`` for the streams present."""
    found = {}
    for column in table.frame.columns:
        parsed = _stream_of(column)
        if not parsed:
            continue
        stream, kind = parsed
        if stream in found:
            raise InputError(
                f"two columns for the {stream} stream ({found[stream][0]}, {column})", source=table.source, column=column
            )
        if kind is None:
            if options.kind is None:
                raise InputError(
                    f"what column '{column}' holds is not declared: declare it with kind='pct' (or another of "
                    f"{', '.join(KINDS)}) or name the column with a suffix, e.g. '{column}_pct'",
                    source=table.source,
                    column=column,
                )
            kind = options.kind
        found[stream] = (column, kind)
    if len(found) < 2:
        raise InputError(
            f"need at least two of the streams feed, fine, coarse; found {', '.join(found) or 'none'}", source=table.source
        )
    cumulative = {kind in CUMULATIVE_KINDS for _, kind in found.values()}
    if len(cumulative) > 1:
        raise InputError("cumulative and per-class stream columns are mixed; give all streams the same way", source=table.source)
    return found


@dataclass(frozen=True)
class _SizeLayout:
    """Where the sizes are: sieve apertures in one column, class bounds in two, or
    class-range strings ("+1168", "-1168+589", "-74") in one; optionally a column of
    representative sizes; and their unit ("" when not known)."""

    sieve_sizes: bool
    columns: tuple[str, ...]
    class_strings: bool = False
    representative: str | None = None
    unit: str = ""
    unit_suffix: str = ""


def _size_layout(table: Table, options: LabOptions | None = None) -> _SizeLayout:
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
        return _SizeLayout(
            False, (found["size_lower"], found["size_upper"]), representative=representative, unit=unit, unit_suffix=suffix
        )
    if "size_class" in found:
        return _SizeLayout(
            False, (found["size_class"],), class_strings=True, representative=representative, unit=unit, unit_suffix=suffix
        )
    if "size" in found:
        if representative:
            raise InputError(
                "a representative size column needs class bounds or size classes, not sieve sizes",
                source=table.source,
                column=representative,
            )
        return _SizeLayout(True, (found["size"],), unit=unit, unit_suffix=suffix)
    raise InputError(
        "give class bounds 'size_lower' and 'size_upper', size classes 'size_class' (\"+1168\", \"-1168+589\", \"-74\"), "
        "or sieve sizes 'size'",
        source=table.source,
    )


# --- one experiment ---------------------------------------------------------------------
def _balance_one(table: Table, name: str, streams, layout: _SizeLayout, options: LabOptions) -> MassBalance:
    cumulative = any(kind in CUMULATIVE_KINDS for _, kind in streams.values())
    notes = []
    totals = {}
    if cumulative:
        if not layout.sieve_sizes:
            raise InputError(
                "cumulative stream columns need sieve sizes in a 'size' column, not class bounds", source=table.source
            )
        lower, upper, shares, blank_notes = _classes_from_cumulative(table, layout.columns[0], streams)
        notes += blank_notes
        class_rows = [None] * lower.size  # a class spans two sieve rows
    else:
        if layout.sieve_sizes:
            lower, upper = _retained_on_sieves(table, layout.columns[0])
        elif layout.class_strings:
            lower, upper = _checked_bounds(
                table, *class_string_bounds(table, layout.columns[0]), layout.columns[0], layout.columns[0]
            )
        else:
            lower, upper = _class_bounds(table, *layout.columns)
        shares = {}
        for stream, (column, kind) in streams.items():
            shares[stream], totals[stream], note = _per_class_shares(table, column, kind, options)
            notes += [note] if note else []
        class_rows = list(table.rows)
    if lower.size < 3:
        raise InputError(f"experiment '{name}' has {lower.size} size class(es); at least 3 are needed", source=table.source)
    top_size, size = _representative_sizes(table, lower, upper, options, layout.representative)
    mass_yield = _mass_implied_yield(streams, totals)
    fine_yield, source_of_yield, estimate, yield_notes = _fine_yield(table, shares, options, mass_yield)
    notes += yield_notes
    a, b, c = _complete_streams(table, shares, fine_yield)
    _check_empty_feed(table, a, b, c, None if cumulative else table.rows)
    classes = pd.DataFrame(
        {"experiment": name, "size_lower": lower, "size_upper": upper, "size": size, "feed": a, "fine": b, "coarse": c}
    )
    classes["balance_residual"] = a - fine_yield * b - (1 - fine_yield) * c
    method = options.partition_from
    if options.reconcile and len(shares) == 3:
        adjusted = _reconciled(a, b, c, fine_yield)
        for stream, values in zip(STREAMS, adjusted):
            classes[f"{stream}_adjusted"] = values
        a, b, c = adjusted
        method = "reconciled"
    phi = _partition(a, b, c, fine_yield, method)
    empty_products = (a > 0) & (b <= 0) & (c <= 0) & ("fine" in shares) & ("coarse" in shares)
    used, flags = _flag_classes(a, phi, options.min_feed_share, empty_products)
    classes["partition_fine"] = np.where(np.isfinite(phi), np.clip(phi, 0.0, 1.0), np.nan)
    classes["partition_coarse"] = 1.0 - classes["partition_fine"]
    classes["used"] = used
    classes["flag"] = flags
    classes["row"] = class_rows
    notes += _cut_region_note(classes, options.min_feed_share)
    if used.sum() < 3:
        raise InputError(
            f"experiment '{name}' has {int(used.sum())} usable size classes; at least 3 are needed "
            f"(flags: {'; '.join(f for f in flags if f) or 'none'})",
            source=table.source,
        )
    return MassBalance(
        name,
        classes,
        fine_yield,
        source_of_yield,
        estimate,
        top_size,
        tuple(notes),
        table.source,
        partition_method=method,
        size_unit=layout.unit,
        water_recovery=options.water_recovery,
    )


def partition_to_fines(feed, fine, coarse, fine_yield, *, method: str = "products") -> np.ndarray:
    r"""Partition to the fine product of each class from the three shares and the fine yield.

    .. math::

        \varphi_i = \frac{y\,b_i}{y\,b_i + (1-y)\,c_i} \quad\text{(products)}, \qquad
        \varphi_i = \frac{y\,b_i}{a_i} \quad\text{(feed)}

    ``"products"`` uses both products, so exchanging the fine and coarse streams (and
    ``y`` with ``1 - y``) gives exactly ``1 - phi``; ``"feed"`` divides the fine stream by
    the measured feed and is not symmetric when the balance does not close.  After
    reconciliation (``"reconciled"``) both coincide.  A class with nothing in the
    denominator gets NaN.

    Examples
    --------
    >>> partition_to_fines([0.5], [0.4], [0.5], 0.5).round(4).tolist()
    [0.4444]
    >>> partition_to_fines([0.5], [0.4], [0.5], 0.5, method="feed").round(4).tolist()
    [0.4]
    """
    a, b, c = _checked_shares(feed, fine, coarse)
    return _partition(a, b, c, check_probability(fine_yield, "fine_yield"), method)


def _partition(a, b, c, y: float, method: str) -> np.ndarray:
    """:func:`partition_to_fines` of shares the reader has checked (a stream it computed may dip below 0)."""
    denominator = a if method == "feed" else y * b + (1 - y) * c
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(denominator > 0, y * b / denominator, np.nan)


def _mass_implied_yield(streams, totals) -> float | None:
    """Fine yield implied by the masses of both products (fine / (fine + coarse)), when the two
    products (and no feed) are given as masses: the products are then taken as weighed whole."""
    if "feed" in streams or not all(stream in totals and streams[stream][1] == "mass" for stream in ("fine", "coarse")):
        return None
    return totals["fine"] / (totals["fine"] + totals["coarse"])


def _class_bounds(table: Table, lower_column: str, upper_column: str):
    lower = table.numeric(lower_column, allow_blank=True)
    upper = table.numeric(upper_column, allow_blank=True)
    return _checked_bounds(table, lower, upper, lower_column, upper_column)


def _checked_bounds(table: Table, lower, upper, lower_column: str, upper_column: str):
    """Class bounds checked: positive (a lower bound of 0 = the pan), ordered, one open top, one pan, no overlap."""
    lower = np.where(lower == 0, np.nan, lower)  # the pan written with a lower bound of 0
    for values, column in ((lower, lower_column), (upper, upper_column)):
        bad = np.flatnonzero(values <= 0)
        if bad.size:
            raise table.error(
                "class bounds must be positive (a pan's lower bound may be 0 or blank)", index=int(bad[0]), column=column
            )
    both = np.isfinite(lower) & np.isfinite(upper)
    bad = np.flatnonzero(both & (lower >= upper))
    if bad.size:
        raise table.error(
            f"lower bound {lower[bad[0]]:g} is not below the upper bound {upper[bad[0]]:g}",
            index=int(bad[0]),
            column=lower_column,
        )
    bad = np.flatnonzero(np.isnan(lower) & np.isnan(upper))
    if bad.size:
        raise table.error("the class has neither a lower nor an upper bound", index=int(bad[0]), column=lower_column)
    open_top = np.flatnonzero(np.isnan(upper))
    pan = np.flatnonzero(np.isnan(lower))
    for rows, column, what in ((open_top, upper_column, "open top class"), (pan, lower_column, "pan")):
        if rows.size > 1:
            raise table.error(f"only one {what} (blank {column}) is allowed", index=int(rows[1]), column=column)
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
    bad = np.flatnonzero(size <= 0)
    if bad.size:
        raise table.error("sieve size must be positive", index=int(bad[0]), column=size_column)
    step = np.diff(size)
    if not (np.all(step < 0) or np.all(step > 0)):
        direction = np.sign(step[0]) if step[0] != 0 else 1.0
        i = int(np.flatnonzero(step * direction <= 0)[0]) + 1
        raise table.error("sieve sizes are not strictly sorted", index=i, column=size_column)
    return size


def _per_class_shares(table: Table, column: str, kind: str, options: LabOptions):
    """Shares of one stream per class (summing to 1), the column's total, and a note on blank cells."""
    values = table.numeric(column, allow_blank=True)
    blank = np.flatnonzero(np.isnan(values))
    note = f"column '{column}': blank cell(s) at {_rows_text(table.rows[blank])} read as no material" if blank.size else ""
    values = np.where(np.isnan(values), 0.0, values)
    bad = np.flatnonzero(values < 0)
    if bad.size:
        raise table.error(f"negative amount {values[bad[0]]:g}", index=int(bad[0]), column=column)
    largest = {"pct": 100.0 + options.sum_tolerance_pct, "frac": 1.0 + options.sum_tolerance_pct / 100.0}.get(kind, MAX_AMOUNT)
    bad = np.flatnonzero(values > largest)
    if bad.size:  # a share above the whole, or a mass whose sum would overflow
        raise table.error(
            f"amount {values[bad[0]]:g} is above {largest:g}, more than the whole stream", index=int(bad[0]), column=column
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
                f"tolerance {options.sum_tolerance_pct:g})",
                source=table.source,
                column=column,
            )
    return values / total, float(total), note


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


def _representative_sizes(table: Table, lower, upper, options: LabOptions, representative_column: str | None = None):
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
        bad = np.flatnonzero(np.isfinite(given) & ((given <= lower * (1 - 1e-9)) | (given >= upper * (1 + 1e-9))))
        if bad.size:
            i = int(bad[0])
            raise table.error(
                f"representative size {given[i]:g} outside its class {lower[i]:g}-{upper[i]:g}",
                index=i,
                column=representative_column,
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


# --- yield and balance ------------------------------------------------------------------
def estimate_fine_yield(feed, fine, coarse) -> YieldEstimate:
    r"""Least-squares fine yield from three size distributions.

    Fits :math:`a_i - c_i = y (b_i - c_i)` through the origin over the classes
    (statsmodels OLS), so :math:`y = \sum (a-c)(b-c) / \sum (b-c)^2` with the usual
    standard error from the residuals.

    Examples
    --------
    >>> a = 0.3 * np.array([0.5, 0.3, 0.2]) + 0.7 * np.array([0.1, 0.3, 0.6])
    >>> round(estimate_fine_yield(a, [0.5, 0.3, 0.2], [0.1, 0.3, 0.6]).value, 12)
    0.3
    """
    import statsmodels.api as sm

    a, b, c = (np.asarray(v, dtype=float) for v in (feed, fine, coarse))
    design = b - c
    if np.allclose(design, 0):
        raise ValueError("the fine and coarse distributions are identical: the yield cannot be estimated")
    model = sm.OLS(a - c, design).fit()
    stderr = float(model.bse[0]) if a.size > 1 else np.nan
    return YieldEstimate(float(model.params[0]), stderr, int(a.size), np.asarray(model.resid))


def reconcile(feed, fine, coarse, fine_yield, *, relative_error=0.05, absolute_error=0.001):
    r"""Adjust the three distributions minimally so that every class balances.

    Minimises :math:`\sum (\Delta a^2/V_a + \Delta b^2/V_b + \Delta c^2/V_c)` subject to
    :math:`a' = y b' + (1-y) c'` in every class, at fixed yield ``y``; each share has
    the variance :math:`V = (r\,v)^2 + e^2` (relative and absolute error).  The
    solution per class is :math:`\lambda = r_i / (V_a + y^2 V_b + (1-y)^2 V_c)` with
    :math:`\Delta a = -\lambda V_a`, :math:`\Delta b = \lambda y V_b`,
    :math:`\Delta c = \lambda (1-y) V_c`, :math:`r_i = a - y b - (1-y) c`.  A share the
    adjustment would make negative is set to zero and held there (its variance set to 0)
    while the class is solved again.

    Returns
    -------
    tuple of ndarray
        The adjusted feed, fine and coarse shares.
    """
    a, b, c = _checked_shares(feed, fine, coarse)
    y = check_probability(fine_yield, "fine_yield")
    check_non_negative(relative_error, "relative_error")
    check_non_negative(absolute_error, "absolute_error")
    return _reconciled(a, b, c, y, relative_error=relative_error, absolute_error=absolute_error)


def _reconciled(a, b, c, y: float, *, relative_error=0.05, absolute_error=0.001):
    """:func:`reconcile` of shares and a yield the reader has checked."""
    values = np.stack([a, b, c])
    variances = (relative_error * values) ** 2 + absolute_error**2
    gains = np.array([[-1.0], [y], [1.0 - y]])  # d(share)/d(lambda) per unit variance
    for _ in range(3):  # a share pushed below zero is pinned at zero and the class solved again
        residual = a - y * b - (1 - y) * c
        multiplier = residual / np.sum(gains**2 * variances, axis=0)
        adjusted = values + gains * multiplier * variances
        negative = adjusted < 0
        if not negative.any():
            break
        variances = np.where(negative, 0.0, variances)
        values = np.where(negative, 0.0, values)
        a, b, c = values[0], values[1], values[2]
    return adjusted[0], adjusted[1], adjusted[2]


def _checked_shares(feed, fine, coarse) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The three streams' shares per class as float arrays of one length, finite and not
    negative, or an :class:`~tromplab.errors.OptionError` naming the argument at fault."""
    arrays = []
    for name, values in (("feed", feed), ("fine", fine), ("coarse", coarse)):
        try:
            raw = np.asarray(values)
        except ValueError:
            raise OptionError(name, "takes one share per class, got a ragged nesting") from None
        if np.iscomplexobj(raw) or raw.ndim != 1 or raw.dtype.kind not in "biuf":
            raise OptionError(name, f"takes one real share per class (a flat sequence of numbers), got {values!r}")
        array = raw.astype(float)
        bad = np.flatnonzero(~np.isfinite(array) | (array < 0))
        if bad.size:
            raise OptionError(name, f"takes finite shares >= 0, got {array[bad[0]]:g} in class {bad[0] + 1}")
        arrays.append(array)
    if len({array.size for array in arrays}) > 1:
        raise OptionError(
            "fine", f"feed, fine and coarse take one share per class each, got {', '.join(str(a.size) for a in arrays)}"
        )
    return arrays[0], arrays[1], arrays[2]


def _given_yield(table: Table, options: LabOptions):
    if options.fine_yield is not None:
        return options.fine_yield, "option fine_yield"
    if options.coarse_yield is not None:
        return 1.0 - options.coarse_yield, "option coarse_yield"
    columns = {}  # product -> its yield column (fine_yield or overflow_yield, coarse_yield or underflow_yield)
    for column, product in YIELD_COLUMNS.items():
        if column in table.frame.columns:
            if product in columns:
                raise InputError(
                    f"two yield columns for the {product} product ({columns[product]}, {column})",
                    source=table.source,
                    column=column,
                )
            columns[product] = column
    found = {product: (column, _yield_column(table, column)) for product, column in columns.items()}
    found = {product: pair for product, pair in found.items() if pair[1] is not None}
    if len(found) == 2 and not np.isclose(found["fine"][1] + found["coarse"][1], 1.0, atol=1e-3):
        raise InputError(
            f"{found['fine'][0]} {found['fine'][1]:g} and {found['coarse'][0]} {found['coarse'][1]:g} do not add up to 1",
            source=table.source,
            column=found["coarse"][0],
        )
    if "fine" in found:
        return found["fine"][1], f"column {found['fine'][0]}"
    if "coarse" in found:
        return 1.0 - found["coarse"][1], f"column {found['coarse'][0]}"
    return None, None


def _yield_column(table: Table, column: str) -> float | None:
    """The single yield value of a yield column (None when blank), checked to lie in (0, 1)."""
    values = table.numeric(column, allow_blank=True)
    given = values[np.isfinite(values)]
    if given.size == 0:
        return None
    bad = np.flatnonzero(np.isfinite(values) & ((values <= 0) | (values >= 1)))
    if bad.size:
        raise table.error(f"yield {values[bad[0]]:g} outside (0, 1)", index=int(bad[0]), column=column)
    if np.ptp(given) > 1e-12:
        i = int(np.flatnonzero(np.isfinite(values) & (values != given[0]))[0])
        raise table.error("the yield differs between rows of the same experiment", index=i, column=column)
    return float(given[0])


def _fine_yield(table: Table, shares: dict, options: LabOptions, mass_yield: float | None = None):
    given, source = _given_yield(table, options)
    notes = []
    estimate = None
    if len(shares) == 3:
        try:
            estimate = estimate_fine_yield(shares["feed"], shares["fine"], shares["coarse"])
        except ValueError as error:
            raise InputError(str(error), source=table.source) from None
    if mass_yield is not None:
        if given is None:
            notes.append(f"fine yield {mass_yield:.4f} taken from the product masses (fine / (fine + coarse))")
            return mass_yield, "product masses", estimate, notes
        elif abs(given - mass_yield) > MASS_YIELD_TOLERANCE:
            note = (
                f"the stated fine yield {given:.4f} ({source}) contradicts the product masses, which imply "
                f"{mass_yield:.4f} (fine / (fine + coarse)); the stated yield is used"
            )
            notes.append(note)
            warnings.warn(f"{table.source}: {note}", YieldWarning, stacklevel=4)
    if given is not None and not options.estimate_yield:
        if estimate is not None:
            note = yield_contradiction(given, estimate)
            if note:
                notes.append(note)
                warnings.warn(f"{table.source}: {note}", YieldWarning, stacklevel=4)
        return given, source, estimate, notes
    if estimate is None:
        missing = ({"feed", "fine", "coarse"} - set(shares)).pop()
        raise InputError(
            f"with only two streams (no {missing}) the fine-product yield must be given "
            "(option fine_yield / coarse_yield or a fine_yield column)",
            source=table.source,
        )
    if not YIELD_MARGIN < estimate.value < 1.0 - YIELD_MARGIN:  # symmetric, so that swapping the products cannot tip it
        raise InputError(
            f"the size data imply a fine yield of {estimate.value:.3f}, outside (0, 1): check the streams", source=table.source
        )
    return estimate.value, "least-squares estimate", estimate, notes


def yield_contradiction(given: float, estimate: YieldEstimate, *, tolerance: float = 0.02, z_limit: float = 3.0) -> str | None:
    """A message when a stated fine yield disagrees with the size data, else None.

    Disagreement: the estimate differs by more than ``tolerance`` and by more than
    ``z_limit`` standard errors.
    """
    gap = given - estimate.value
    se = estimate.stderr if np.isfinite(estimate.stderr) else 0.0
    if abs(gap) > tolerance and abs(gap) > z_limit * se:
        return (
            f"the stated fine yield {given:.3f} (coarse {1 - given:.3f}) contradicts the size data, "
            f"which imply a fine yield of {estimate.value:.3f} +/- {se:.3f} "
            f"(coarse {1 - estimate.value:.3f}); the stated yield is used - pass estimate_yield to use the estimate"
        )
    return None


def _complete_streams(table: Table, shares: dict, y: float):
    """All three shares, deriving a missing stream from the balance a = y b + (1-y) c."""
    a, b, c = (shares.get(s) for s in STREAMS)
    if a is None:
        a = y * b + (1 - y) * c
    elif b is None:
        b = (a - (1 - y) * c) / y
    elif c is None:
        c = (a - y * b) / (1 - y)
    return a, b, c


def _check_empty_feed(table: Table, a, b, c, class_rows) -> None:
    empty = np.flatnonzero((a <= 0) & ((b > 0) | (c > 0)))
    if empty.size:
        i = int(empty[0])
        row = None if class_rows is None else int(class_rows[i])
        raise InputError(
            f"the feed has no material in size class {i + 1} but a product has some: the data cannot balance",
            source=table.source,
            row=row,
            column="feed",
        )


def _class_label(lower: float, upper: float) -> str:
    """``4.1-5.3``, with ``pan`` and ``top`` for the open ends."""
    return f"{'pan' if not np.isfinite(lower) else f'{lower:g}'}-{'top' if not np.isfinite(upper) else f'{upper:g}'}"


#: Partitions around the cut: a class whose partition lies between them measures the cut region.
CUT_REGION = (0.25, 0.75)


def _cut_region_note(classes: pd.DataFrame, min_feed_share: float) -> list[str]:
    """A note when the feed-share filter left out every class around the cut (partitions in
    :data:`CUT_REGION`): the points then say nothing of the cut, whatever is fitted to them."""
    low, high = CUT_REGION
    around_cut = classes["partition_fine"].between(low, high)
    dropped = around_cut & ~classes["used"] & classes["flag"].str.startswith("feed share")
    if not dropped.any() or (around_cut & classes["used"]).any():
        return []
    return [
        f"every class around the cut (partition between {low:g} and {high:g}: {int(dropped.sum())} class(es)) was left "
        f"out by the feed-share filter (min_feed_share = {100 * min_feed_share:g} %), so the points do not measure the "
        "cut; give a smaller min_feed_share (0 keeps every class) to fit them"
    ]


def _flag_classes(feed_share, phi, min_feed_share, empty_products=None):
    used = np.ones(feed_share.size, dtype=bool)
    flags = [""] * feed_share.size
    empty_products = np.zeros(feed_share.size, dtype=bool) if empty_products is None else empty_products
    for i, (share, value) in enumerate(zip(feed_share, phi)):
        if empty_products[i]:
            used[i] = False
            flags[i] = "the feed has material in this class but neither product has any: partition undefined (check the data)"
        elif share < min_feed_share:
            used[i] = False
            flags[i] = f"feed share {100 * share:.3g} % below {100 * min_feed_share:g} %: partition not meaningful"
        elif not -PARTITION_SLACK <= value <= 1 + PARTITION_SLACK:
            used[i] = False
            flags[i] = f"partition {value:.3f} outside 0..1: the class balance does not close (check the data or reconcile)"
        elif not 0.0 <= value <= 1.0:
            flags[i] = f"partition {value:.4f} clipped to 0..1"
    return used, flags


# --- forward calculation ----------------------------------------------------------------
@dataclass(frozen=True)
class ProductPrediction:
    """Predicted products of a classifier for a given feed (spec section 5)."""

    fine_yield: float
    classes: pd.DataFrame


def predict_products(size, feed_share, partition_fine) -> ProductPrediction:
    r"""Yields and size distributions of both products from a feed and a separation curve.

    Discrete form of :math:`\bar\varphi = \int \varphi\, dR_1`: with per-class feed
    shares :math:`a_i` and the curve at the representative sizes :math:`\varphi_i`,
    the fine yield is :math:`\bar\varphi = \sum a_i \varphi_i`, the fine product
    :math:`b_i = a_i \varphi_i / \bar\varphi`, the coarse product
    :math:`c_i = a_i (1-\varphi_i)/(1-\bar\varphi)`.  Cumulative residues (share coarser
    than the class's lower bound) follow by summing from the coarse end.

    Parameters
    ----------
    size : array
        Representative sizes of the classes, any order.
    feed_share : array
        Feed share per class (normalised here).
    partition_fine : array or callable
        Partition to fines per class, or a function of size (a fitted curve's
        ``predict``).

    Examples
    --------
    >>> p = predict_products([1.0, 2.0], [0.5, 0.5], [0.8, 0.2])
    >>> round(p.fine_yield, 3), p.classes["fine"].round(3).tolist()  # coarse class first
    (0.5, [0.2, 0.8])
    """
    size = np.asarray(size, dtype=float)
    a = np.asarray(feed_share, dtype=float)
    a = a / a.sum()
    phi = np.asarray(partition_fine(size) if callable(partition_fine) else partition_fine, dtype=float)
    order = np.argsort(size)[::-1]
    y = float(np.sum(a * phi))
    b = a * phi / y
    c = a * (1 - phi) / (1 - y)
    classes = pd.DataFrame({"size": size, "feed": a, "partition_fine": phi, "fine": b, "coarse": c})
    classes = classes.iloc[order].reset_index(drop=True)
    for stream in STREAMS:
        classes[f"{stream}_retained"] = classes[stream].cumsum()
    return ProductPrediction(y, classes)


def mix_streams(shares, yields):
    """Size distribution and yield of several products taken together.

    Used to express one deck of a multi-deck screen as its own classifier: the fine
    product of the upper deck is everything that passed it, the mixture of the lower
    products weighted by their yields.

    Examples
    --------
    >>> mixed, total = mix_streams([[1.0, 0.0], [0.0, 1.0]], [0.2, 0.6])
    >>> mixed.round(12).tolist(), total
    ([0.25, 0.75], 0.8)
    """
    shares = [np.asarray(s, dtype=float) / np.sum(s) for s in shares]
    yields = np.asarray(yields, dtype=float)
    total = float(yields.sum())
    mixed = sum(w * s for w, s in zip(yields, shares)) / total
    return mixed, total


class Experiments(NamedTuple):
    """What :func:`read_experiments` returns: the points of each experiment and, for a lab
    table, the mass balances they came from (empty for a points file).  It unpacks as
    ``points, balances = read_experiments(path)`` and is taken whole by
    :func:`tromplab.fit_experiments`, which keeps the balances for the report and workbook."""

    points: list[TrompPoints]
    balances: list[MassBalance]


def read_experiments(path, options: LabOptions | None = None, **option_values) -> Experiments:
    """Tromp points from either a points file or a lab table (told apart by their columns).

    Parameters
    ----------
    path : str, path-like or pandas.DataFrame
        A Tromp-points or lab table (file or DataFrame).
    options : LabOptions, optional
        How to read a lab table (ignored for points).
    option_values
        The fields of :class:`LabOptions` as keywords instead of ``options``.

    Returns
    -------
    Experiments
        ``(points, balances)``: the points of each experiment and, for a lab table, the mass
        balances they came from (empty for a points file).
    """
    options = _options(options, option_values)
    table = read_renamed(path, options)
    if not has_survey_columns(table):
        return _experiments_from_table(table, options)
    # a monitoring file (tromplab trend) fits as it is: survey and date go with the points, in date order
    dated = "date" in table.frame.columns
    table, found = split_survey_columns(table)
    points, balances = _experiments_from_table(table, options)
    points = with_survey_meta(points, found, dated=dated)
    order = {p.experiment: i for i, p in enumerate(points)}
    return Experiments(points, sorted(balances, key=lambda b: order[b.experiment]))


def _experiments_from_table(table: Table, options: LabOptions) -> Experiments:
    if is_lab_table(table.frame.columns):
        balances = balances_from_table(table, options)
        logger.info(
            "%s: lab table, %d experiment(s) balanced (partition from %s)", table.source, len(balances), options.partition_from
        )
        return Experiments(
            [balance.to_points(weight_by_feed_share=options.weight_by_feed_share) for balance in balances], balances
        )
    experiments = points_from_table(table, size_unit=options.size_unit)
    logger.info("%s: Tromp points, %d experiment(s)", table.source, len(experiments))
    return Experiments(experiments, [])
