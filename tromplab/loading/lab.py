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

import contextlib
import logging
import os
from collections.abc import Iterator
from dataclasses import dataclass, fields, replace
from typing import NamedTuple

import numpy as np
import pandas as pd

from ..errors import InputError, YieldWarning
from ..notices import regroup_warnings
from ..results_contract import ResultContract
from .kelsall import kelsall_corrected
from .lab_classes import (
    SizeLayout,
    class_shares,
    per_class_shares,  # noqa: F401 (tromplab.density.readers reads its analyses with it)
    read_size_layout,
    representative_class_sizes,
)
from .lab_options import LabOptions
from .lab_streams import STREAMS, is_lab_table, known_lab_columns, stream_columns
from .names import renamed_to_names
from .node_balance import (
    YieldEstimate,
    check_empty_feed,
    complete_streams,
    estimate_fine_yield,
    mass_implied_yield,
    node_fine_yield,
    node_partition,
    partition_to_fines,
    reconcile,
    reconciled_shares,
    yield_contradiction,
)
from .points import TrompPoints, experiment_rows, iter_experiments, points_from_table
from .size_classes import class_label
from .surveys import has_survey_columns, split_survey_columns, with_survey_meta
from .tables import DEFAULT_PIECE_ROWS, Table, iter_experiment_tables, read_table, read_table_in_pieces
from .weights import concentration_note, partition_weights

#: The public names, kept importable from here where they were before the lab reader was split
#: into the modules of its parts (options, columns, size classes, the balance of one node).
__all__ = [
    "PARTITION_METHOD_TEXT",
    "Experiments",
    "LabOptions",
    "MassBalance",
    "ProductPrediction",
    "YieldEstimate",
    "YieldWarning",
    "balances_from_table",
    "estimate_fine_yield",
    "is_lab_table",
    "mix_streams",
    "partition_to_fines",
    "predict_products",
    "read_experiments",
    "read_lab",
    "read_renamed",
    "reconcile",
    "yield_contradiction",
]

logger = logging.getLogger(__name__)

PARTITION_METHOD_TEXT = {  # how each partition method reads in outputs
    "products": "both products, y b / (y b + (1 - y) c)",
    "feed": "the fine stream over the measured feed, y b / a",
    "reconciled": "the reconciled distributions, y b' / a'",
}
PARTITION_SLACK = 0.02


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
    ``water_recovery`` the water split to the underflow when given (hydrocyclones),
    ``weighting`` how its points are weighted in the fit (:class:`LabOptions`).
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
    weighting : str
        How its points are weighted in the fit (see :class:`LabOptions`).
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
    weighting: str = "none"

    @property
    def left_out(self) -> list[str]:
        """One message per class left out of the fit: its bounds, file row and the reason."""
        unit = f" {self.size_unit}" if self.size_unit else ""
        messages = []
        for row in self.classes.loc[~self.classes["used"]].itertuples(index=False):
            where = f" (row {row.row})" if row.row is not None else ""
            messages.append(f"class {class_label(row.size_lower, row.size_upper)}{unit}{where} left out: {row.flag}")
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
        bounds = ", ".join(class_label(lo, hi) for lo, hi in zip(dropped["size_lower"], dropped["size_upper"]))
        return f"{len(dropped)} class(es) left out: {bounds}{unit} ({counted})"

    def class_weights(self, *, weight_by_feed_share: bool = False) -> np.ndarray | None:
        """The weight of every class in the fit under :attr:`weighting` (``weight_by_feed_share``:
        the feed share when the balance has no weighting of its own), None when unweighted;
        :func:`tromplab.loading.weights.partition_weights`."""
        weighting = "feed-share" if weight_by_feed_share and self.weighting == "none" else self.weighting
        if weighting == "feed-share":
            return self.classes["feed"].to_numpy()  # every class, as the feed share column reads
        classes = self.classes
        return partition_weights(weighting, classes["partition_fine"], classes["feed"], self.fine_yield, classes["used"])

    def to_points(self, *, weight_by_feed_share: bool = False) -> TrompPoints:
        used = self.classes["used"].to_numpy()
        weight = self.class_weights(weight_by_feed_share=weight_by_feed_share)
        return TrompPoints(
            experiment=self.experiment,
            size=self.classes["size"].to_numpy()[used],
            partition_fine=self.classes["partition_fine"].to_numpy()[used],
            weight=None if weight is None else weight[used],
            delta_max=self.top_size,
            source=self.source,
            size_unit=self.size_unit,
        )

    def points_table(self, *, weight_by_feed_share: bool = False, unit_in_names: bool = False) -> pd.DataFrame:
        """Rows in the ``tromplab fit`` schema plus per-class diagnostics (and a ``weight``
        column under the balance's weighting, or the feed share when asked); with ``unit_in_names`` the size columns
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
        weight = self.class_weights(weight_by_feed_share=weight_by_feed_share)
        return table if weight is None else table.assign(weight=weight)


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


def balances_from_table(table: Table, options: LabOptions) -> list[MassBalance]:
    streams = stream_columns(table, options)
    size_layout = read_size_layout(table, options)
    table.refuse_unknown(known_lab_columns(table, streams, size_layout), what="lab table")
    labels = table.experiment_labels()
    balances = []
    # a stated yield contradicted in 93 experiments is warned of once, with the count
    with regroup_warnings(YieldWarning, stacklevel=4) as subjects:
        for name, rows in experiment_rows(labels).items():
            subjects.begin(name)
            balances.append(_balance_one(table.subset(rows), name, streams, size_layout, options))
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


# --- one experiment ---------------------------------------------------------------------
def _balance_one(table: Table, name: str, streams, layout: SizeLayout, options: LabOptions) -> MassBalance:
    lower, upper, shares, totals, notes, class_rows = class_shares(table, streams, layout, options)
    if lower.size < 3:
        raise InputError(f"experiment '{name}' has {lower.size} size class(es); at least 3 are needed", source=table.source)
    top_size, size = representative_class_sizes(table, lower, upper, options, layout.representative)
    mass_yield = mass_implied_yield(streams, totals)
    fine_yield, source_of_yield, estimate, yield_notes = node_fine_yield(table, shares, options, mass_yield)
    notes += yield_notes
    a, b, c = complete_streams(table, shares, fine_yield)
    check_empty_feed(table, a, b, c, None if class_rows[0] is None else table.rows)
    classes = pd.DataFrame(
        {"experiment": name, "size_lower": lower, "size_upper": upper, "size": size, "feed": a, "fine": b, "coarse": c}
    )
    classes["balance_residual"] = a - fine_yield * b - (1 - fine_yield) * c
    method = options.partition_from
    if options.reconcile and len(shares) == 3:
        adjusted = reconciled_shares(a, b, c, fine_yield)
        for stream, values in zip(STREAMS, adjusted):
            classes[f"{stream}_adjusted"] = values
        a, b, c = adjusted
        method = "reconciled"
    phi = node_partition(a, b, c, fine_yield, method)
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
    balance = MassBalance(
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
        weighting=options.weighting,
    )
    return _with_weight_note(balance)


def _with_weight_note(balance: MassBalance) -> MassBalance:
    """The balance with a note when a few classes carry most of the weight of its points."""
    weight = balance.class_weights()
    if weight is None:
        return balance
    classes = balance.classes
    labels = [class_label(lo, hi, balance.size_unit) for lo, hi in zip(classes["size_lower"], classes["size_upper"])]
    note = concentration_note(np.where(classes["used"], weight, np.nan), labels)
    return replace(balance, notes=(*balance.notes, note)) if note else balance


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


def iter_experiments_in_pieces(path, options: LabOptions | None = None, *, piece_rows: int = DEFAULT_PIECE_ROWS,
                               warn: bool = True) -> Iterator[tuple[TrompPoints, MassBalance | None]]:  # fmt: skip
    """The experiments of a points file or lab table (CSV) one at a time, the file read in
    pieces: what :func:`read_experiments` reads, with its checks and messages, in the memory of
    a piece and of one experiment.

    A points file goes through :func:`~tromplab.loading.points.iter_experiments`, a lab table
    through :func:`~tromplab.loading.tables.iter_experiment_tables` and the mass balance of
    each experiment's rows (:func:`balances_from_table`).  Read whole, as
    :func:`read_experiments` reads it, is a workbook or DataFrame, a monitoring file (survey or
    date columns: its experiments go in date order) and a points file with ``options.rename``.

    Parameters
    ----------
    path : str or path-like
        The file.
    options : LabOptions, optional
        How to read a lab table, as for :func:`read_experiments`.
    piece_rows : int
        Records per piece.
    warn : bool
        Warn of the layout detected; False for a second reading of the file.

    Yields
    ------
    tuple
        ``(points, balance)`` per experiment in order of first appearance (``balance`` None
        for a points file).
    """
    options = options or LabOptions()
    text_columns = renamed_to_names(options.rename)
    head = None
    if isinstance(path, (str, os.PathLike)) and options.sheet is None:
        pieces = read_table_in_pieces(path, piece_rows=1, sep=options.sep, decimal=options.decimal,
                                      text_columns=text_columns, warn=False)  # fmt: skip
        with contextlib.closing(pieces):
            head = next(pieces, None)
    head = None if head is None else _renamed(head, options.rename)
    lab = head is not None and is_lab_table(head.frame.columns)
    if head is None or has_survey_columns(head) or (options.rename and not lab):
        found = read_experiments(path, options)
        yield from zip(found.points, found.balances or [None] * len(found.points))
        return
    if not lab:
        for points in iter_experiments(path, piece_rows=piece_rows, size_unit=options.size_unit, sep=options.sep,
                                       decimal=options.decimal, warn=warn):  # fmt: skip
            yield points, None
        return
    for table in iter_experiment_tables(path, piece_rows=piece_rows, sep=options.sep, decimal=options.decimal,
                                        text_columns=text_columns, warn=warn):  # fmt: skip
        for balance in balances_from_table(_renamed(table, options.rename), options):
            yield balance.to_points(weight_by_feed_share=options.weight_by_feed_share), balance
