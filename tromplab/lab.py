"""From laboratory sieve data to Tromp points, with the mass balance checked.

Schema of a lab table (CSV or Excel), one row per size class (or per sieve) and
experiment - see the README for an example:

``experiment``
    optional; all rows form one experiment named after the file when absent.
size columns
    either class bounds ``size_lower`` and ``size_upper`` (blank ``size_upper`` = open
    top class, blank ``size_lower`` = the pan); or ``size`` (the sieve aperture), for
    cumulative data or for per-class shares retained on each sieve (a class then runs
    from its sieve to the next coarser one, the coarsest open at the top).  A unit suffix (``size_um``, ``size_lower_mm``)
    is allowed and must be the same on every size column; sizes are used as given.
stream columns
    two or three of ``feed``, ``fine``, ``coarse``.  What they hold is declared, never
    guessed: either by the ``kind`` option for plain names, or by a suffix on each
    column: ``_mass`` (mass per class, any unit), ``_pct`` / ``_frac`` (share of the
    stream per class), ``_retained_pct`` / ``_retained_frac`` (cumulative share coarser
    than the sieve) or ``_passing_pct`` / ``_passing_frac`` (cumulative share finer).
``fine_yield`` or ``coarse_yield``
    optional column (constant within an experiment) or option: the mass fraction of
    the feed reporting to that product.

Per-class shares come from cumulative data by differences.  The representative size of
a class is the geometric mean of its bounds; the open top class and the pan continue
the geometric progression of their neighbour (upper = lower * r for the top class,
lower = upper / r for the pan, r = upper/lower of the adjacent class), unless
``top_size`` or ``pan_lower_size`` is given.

Partition to fines ``phi_i = y b_i / a_i`` with ``a``, ``b``, ``c`` the feed, fine and
coarse shares and ``y`` the fine yield (Shuvalov et al. 2018, introduction; spec
section 5).  With three streams and no yield, ``y`` is estimated by least squares over
the classes (:func:`estimate_fine_yield`); with a yield given too, the two are compared
and a contradiction is reported.
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .errors import InputError
from .points import TrompPoints
from .tables import Table, read_table

STREAMS = ("feed", "fine", "coarse")
KINDS = ("mass", "pct", "frac", "retained_pct", "retained_frac", "passing_pct", "passing_frac")
CUMULATIVE_KINDS = {"retained_pct", "retained_frac", "passing_pct", "passing_frac"}
UNITS = ("nm", "um", "mm", "cm", "m")  # mesh numbers are not sizes (larger = finer)
DEFAULT_SUM_TOLERANCE_PCT = 1.5
DEFAULT_MIN_FEED_SHARE = 0.002
PARTITION_SLACK = 0.02


class YieldWarning(UserWarning):
    """A stated yield contradicts the size distributions."""


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
        Upper bound of the open top class, lower bound of the pan.
    rename : dict
        Column renames applied before reading (``{"sieve_um": "size"}``).
    sheet : str or None
        Excel sheet.
    weight_by_feed_share : bool
        Weight each Tromp point by the feed share of its class.  Error model: the
        partition of a class is measured on a sample mass proportional to its feed
        share, so its variance is inversely proportional to that share.
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

    def __post_init__(self):
        if self.kind is not None and self.kind not in KINDS:
            raise ValueError(f"unknown kind {self.kind!r}; choose one of {', '.join(KINDS)}")
        from .validation import check_non_negative, check_optional, check_positive, check_probability, check_share

        for name in ("fine_yield", "coarse_yield"):
            check_optional(check_probability, getattr(self, name), name)
        check_share(self.min_feed_share, "min_feed_share")
        check_non_negative(self.sum_tolerance_pct, "sum_tolerance_pct")
        check_optional(check_positive, self.top_size, "top_size")
        check_optional(check_non_negative, self.pan_lower_size, "pan_lower_size")
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
class MassBalance:
    """One experiment of a lab table turned into Tromp points.

    ``classes`` has one row per size class with columns ``experiment, size_lower,
    size_upper, size, feed, fine, coarse`` (shares of each stream, 0..1, as measured or
    derived), ``balance_residual`` (``feed - y fine - (1-y) coarse``), ``partition_fine``,
    ``partition_coarse``, ``used`` and ``flag`` (the reason a class is left out, or a note).
    When reconciled, ``feed_adjusted``, ``fine_adjusted`` and ``coarse_adjusted`` hold
    the adjusted shares.
    """

    experiment: str
    classes: pd.DataFrame
    fine_yield: float
    yield_source: str
    yield_estimate: YieldEstimate | None
    top_size: float
    notes: tuple[str, ...] = ()
    source: str = ""

    def to_points(self, *, weight_by_feed_share: bool = False) -> TrompPoints:
        used = self.classes[self.classes["used"]]
        return TrompPoints(
            experiment=self.experiment,
            size=used["size"].to_numpy(),
            partition_fine=used["partition_fine"].to_numpy(),
            weight=used["feed"].to_numpy() if weight_by_feed_share else None,
            delta_max=self.top_size,
            source=self.source,
        )

    def points_table(self, *, weight_by_feed_share: bool = False) -> pd.DataFrame:
        """Rows in the ``tromplab fit`` schema plus per-class diagnostics (and a ``weight``
        column equal to the feed share when asked)."""
        table = self.classes.rename(columns={"feed": "feed_share"})
        columns = ["experiment", "size", "partition_fine", "size_lower", "size_upper", "feed_share",
                   "balance_residual", "used", "flag"]  # fmt: skip
        table = table[columns]
        return table.assign(weight=table["feed_share"]) if weight_by_feed_share else table


# --- reading ----------------------------------------------------------------------------
def read_lab(path, options: LabOptions | None = None) -> list[MassBalance]:
    """Read a lab table and compute the Tromp points of each experiment.

    Raises
    ------
    InputError
        For every kind of bad input, naming file, row and column.
    """
    options = options or LabOptions()
    table = read_table(path, sheet=options.sheet)
    return balances_from_table(_renamed(table, options.rename), options)


def is_lab_table(columns) -> bool:
    """True when the columns look like a lab table (stream columns, no partition column)."""
    names = [str(c) for c in columns]
    has_stream = any(_stream_of(name) for name in names)
    return has_stream and not any(name.startswith("partition_") for name in names)


def balances_from_table(table: Table, options: LabOptions) -> list[MassBalance]:
    streams = _stream_columns(table, options)
    size_layout = _size_layout(table)
    labels = table.experiment_labels()
    balances = []
    for name in dict.fromkeys(labels):
        part = table.subset(labels == name)
        balances.append(_balance_one(part, name, streams, size_layout, options))
    return balances


def _renamed(table: Table, rename: dict) -> Table:
    if not rename:
        return table
    missing = [old for old in rename if old not in table.frame.columns]
    if missing:
        raise InputError(f"cannot rename missing column(s) {', '.join(missing)}", source=table.source)
    return Table(table.frame.rename(columns=rename), table.rows, table.source)


def _stream_of(column: str):
    match = re.fullmatch(r"(feed|fine|coarse)(?:_(" + "|".join(KINDS) + r"))?", column)
    return match.groups() if match else None


def _stream_columns(table: Table, options: LabOptions) -> dict[str, tuple[str, str]]:
    """``{stream: (column, kind)}`` for the streams present."""
    found = {}
    for column in table.frame.columns:
        parsed = _stream_of(column)
        if not parsed:
            continue
        stream, kind = parsed
        if stream in found:
            raise InputError(f"two columns for the {stream} stream ({found[stream][0]}, {column})", source=table.source, column=column)
        if kind is None:
            if options.kind is None:
                raise InputError(
                    f"what column '{column}' holds is not declared: pass a kind ({', '.join(KINDS)}) "
                    f"or name the column with a suffix, e.g. '{column}_pct'",
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
    """Where the sizes are: sieve apertures in one column, or class bounds in two."""

    sieve_sizes: bool
    columns: tuple[str, ...]


def _size_layout(table: Table) -> _SizeLayout:
    unit_of = {}
    for column in table.frame.columns:
        match = re.fullmatch(r"(size|size_lower|size_upper)(?:_(" + "|".join(UNITS) + r"))?", column)
        if match:
            unit_of[match.group(1)] = (column, match.group(2))
    units = {unit for _, unit in unit_of.values()}
    if len(units) > 1:
        described = ", ".join(f"{column} ({unit or 'no unit'})" for column, unit in unit_of.values())
        raise InputError(f"mixed units in the size columns: {described}; use one unit", source=table.source)
    if "size_unit" in table.frame.columns:
        given = table.frame["size_unit"].dropna().astype(str).str.strip().unique()
        if len(given) > 1:
            raise InputError(f"mixed units in column 'size_unit': {', '.join(given)}", source=table.source, column="size_unit")
    if "size_lower" in unit_of and "size_upper" in unit_of:
        return _SizeLayout(False, (unit_of["size_lower"][0], unit_of["size_upper"][0]))
    if "size" in unit_of:
        return _SizeLayout(True, (unit_of["size"][0],))
    raise InputError("give class bounds 'size_lower' and 'size_upper', or sieve sizes 'size' for cumulative data", source=table.source)


# --- one experiment ---------------------------------------------------------------------
def _balance_one(table: Table, name: str, streams, layout: _SizeLayout, options: LabOptions) -> MassBalance:
    cumulative = any(kind in CUMULATIVE_KINDS for _, kind in streams.values())
    if cumulative:
        if not layout.sieve_sizes:
            raise InputError("cumulative stream columns need sieve sizes in a 'size' column, not class bounds", source=table.source)
        lower, upper, shares = _classes_from_cumulative(table, layout.columns[0], streams)
        class_rows = None
    else:
        lower, upper = _retained_on_sieves(table, layout.columns[0]) if layout.sieve_sizes else _class_bounds(table, *layout.columns)
        shares = {stream: _per_class_shares(table, column, kind, options) for stream, (column, kind) in streams.items()}
        class_rows = table.rows
    top_size, size = _representative_sizes(table, lower, upper, options)
    fine_yield, source_of_yield, estimate, notes = _fine_yield(table, shares, options)
    a, b, c = _complete_streams(table, shares, fine_yield)
    _check_empty_feed(table, a, b, c, class_rows)
    classes = pd.DataFrame({"experiment": name, "size_lower": lower, "size_upper": upper, "size": size,
                            "feed": a, "fine": b, "coarse": c})  # fmt: skip
    classes["balance_residual"] = a - fine_yield * b - (1 - fine_yield) * c
    if options.reconcile and len(shares) == 3:
        adjusted = reconcile(a, b, c, fine_yield)
        for stream, values in zip(STREAMS, adjusted):
            classes[f"{stream}_adjusted"] = values
        a, b, c = adjusted
    with np.errstate(divide="ignore", invalid="ignore"):
        phi = np.where(a > 0, fine_yield * b / a, np.nan)
    used, flags = _flag_classes(a, phi, options.min_feed_share)
    classes["partition_fine"] = np.where(np.isfinite(phi), np.clip(phi, 0.0, 1.0), np.nan)
    classes["partition_coarse"] = 1.0 - classes["partition_fine"]
    classes["used"] = used
    classes["flag"] = flags
    if used.sum() < 3:
        raise InputError(
            f"experiment '{name}' has {int(used.sum())} usable size classes; at least 3 are needed "
            f"(flags: {'; '.join(f for f in flags if f) or 'none'})",
            source=table.source,
        )
    return MassBalance(name, classes, fine_yield, source_of_yield, estimate, top_size, tuple(notes), table.source)


def _class_bounds(table: Table, lower_column: str, upper_column: str):
    lower = table.numeric(lower_column, allow_blank=True)
    upper = table.numeric(upper_column, allow_blank=True)
    for values, column in ((lower, lower_column), (upper, upper_column)):
        bad = np.flatnonzero(values <= 0)
        if bad.size:
            raise table.error("class bounds must be positive", index=int(bad[0]), column=column)
    both = np.isfinite(lower) & np.isfinite(upper)
    bad = np.flatnonzero(both & (lower >= upper))
    if bad.size:
        raise table.error(f"lower bound {lower[bad[0]]:g} is not below the upper bound {upper[bad[0]]:g}", index=int(bad[0]), column=lower_column)
    open_top = np.flatnonzero(np.isnan(upper))
    pan = np.flatnonzero(np.isnan(lower))
    for rows, column, what in ((open_top, upper_column, "open top class"), (pan, lower_column, "pan")):
        if rows.size > 1:
            raise table.error(f"only one {what} (blank {column}) is allowed", index=int(rows[1]), column=column)
    key = np.where(np.isfinite(lower), lower, 0.0)
    step = np.diff(key)
    if not (np.all(step < 0) or np.all(step > 0)):
        i = int(np.flatnonzero(step <= 0)[0] if step[0] > 0 else np.flatnonzero(step >= 0)[0]) + 1
        raise table.error("class bounds are not sorted (give classes from coarse to fine or from fine to coarse)", index=i, column=lower_column)
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


def _per_class_shares(table: Table, column: str, kind: str, options: LabOptions) -> np.ndarray:
    values = table.numeric(column, allow_blank=True)
    values = np.where(np.isnan(values), 0.0, values)  # an empty cell in a class table means no material
    bad = np.flatnonzero(values < 0)
    if bad.size:
        raise table.error(f"negative amount {values[bad[0]]:g}", index=int(bad[0]), column=column)
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
    return values / total


def _classes_from_cumulative(table: Table, size_column: str, streams):
    size = _sorted_sieves(table, size_column)
    order = np.argsort(size)[::-1]  # coarse to fine
    sieves = size[order]
    shares = {}
    for stream, (column, kind) in streams.items():
        retained = _cumulative_retained(table, column, kind, order)
        shares[stream] = np.diff(np.concatenate(([0.0], retained, [1.0])))
    lower = np.concatenate((sieves, [np.nan]))
    upper = np.concatenate(([np.nan], sieves))
    return lower, upper, shares


def _cumulative_retained(table: Table, column: str, kind: str, order: np.ndarray) -> np.ndarray:
    """Cumulative fraction retained, coarse to fine, checked: 0..1 and non-decreasing.

    A blank at the coarse end counts as nothing retained; a blank at the fine end counts
    as everything retained only when the last given value is already 100 %.
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
    values[: given[0]] = 0.0 if not kind.startswith("passing") else full
    if given[-1] < values.size - 1:
        last = values[given[-1]]
        complete = full if kind.startswith("retained") else 0.0
        if not np.isclose(last, complete):
            raise table.error("blank at the fine end after an incomplete cumulative value", index=int(rows[given[-1] + 1]), column=column)
        values[given[-1] + 1 :] = complete
    retained = values / full if kind.startswith("retained") else 1.0 - values / full
    drops = np.flatnonzero(np.diff(retained) < -1e-12)
    if drops.size:
        what = "retained share falls" if kind.startswith("retained") else "passing share rises"
        raise table.error(f"cumulative data are not monotone: the {what} towards finer sieves", index=int(rows[drops[0] + 1]), column=column)
    return np.clip(retained, 0.0, 1.0)


def _representative_sizes(table: Table, lower, upper, options: LabOptions):
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
        if options.pan_lower_size is not None:
            lower[pan] = options.pan_lower_size
        else:
            neighbour = order[-2]
            lower[pan] = upper[pan] / _ratio(table, lower[neighbour], upper[neighbour])
    if not upper[top] > lower[top] or not upper[pan] > lower[pan]:
        raise InputError("top_size must exceed the top class's lower bound and pan_lower_size must be below the pan's upper bound", source=table.source)
    return float(upper[top]), np.sqrt(lower * upper)


def _ratio(table, lower, upper) -> float:
    if not (np.isfinite(lower) and np.isfinite(upper)):
        raise InputError("the open top class and the pan need a closed neighbour class to extend; give top_size / pan_lower_size", source=table.source)
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
    a, b, c = (np.asarray(v, dtype=float) for v in (feed, fine, coarse))
    y = float(fine_yield)
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


def _given_yield(table: Table, options: LabOptions):
    if options.fine_yield is not None:
        return options.fine_yield, "option fine_yield"
    if options.coarse_yield is not None:
        return 1.0 - options.coarse_yield, "option coarse_yield"
    found = {column: _yield_column(table, column) for column in ("fine_yield", "coarse_yield") if column in table.frame.columns}
    found = {column: value for column, value in found.items() if value is not None}
    if len(found) == 2 and not np.isclose(found["fine_yield"] + found["coarse_yield"], 1.0, atol=1e-3):
        raise InputError(
            f"fine_yield {found['fine_yield']:g} and coarse_yield {found['coarse_yield']:g} do not add up to 1",
            source=table.source,
            column="coarse_yield",
        )
    if "fine_yield" in found:
        return found["fine_yield"], "column fine_yield"
    if "coarse_yield" in found:
        return 1.0 - found["coarse_yield"], "column coarse_yield"
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


def _fine_yield(table: Table, shares: dict, options: LabOptions):
    given, source = _given_yield(table, options)
    notes = []
    estimate = None
    if len(shares) == 3:
        estimate = estimate_fine_yield(shares["feed"], shares["fine"], shares["coarse"])
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
    if not 0.0 < estimate.value < 1.0:
        raise InputError(f"the size data imply a fine yield of {estimate.value:.3f}, outside (0, 1): check the streams", source=table.source)
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


def _flag_classes(feed_share, phi, min_feed_share):
    used = np.ones(feed_share.size, dtype=bool)
    flags = [""] * feed_share.size
    for i, (share, value) in enumerate(zip(feed_share, phi)):
        if share < min_feed_share:
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


def read_experiments(path, options: LabOptions | None = None) -> tuple[list[TrompPoints], list[MassBalance]]:
    """Tromp points from either a points file or a lab table (told apart by their columns).

    Returns the points of each experiment and, for a lab table, the mass balances they
    came from (empty for a points file).
    """
    from .points import points_from_table

    options = options or LabOptions()
    table = _renamed(read_table(path, sheet=options.sheet), options.rename)
    if is_lab_table(table.frame.columns):
        balances = balances_from_table(table, options)
        return [balance.to_points(weight_by_feed_share=options.weight_by_feed_share) for balance in balances], balances
    return points_from_table(table), []
