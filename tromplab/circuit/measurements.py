r"""The measurements of a plant survey: size analyses of streams, solids flows, per cent solids.

File schema (CSV or Excel), a long table, one row per stream and size class:

``stream``
    a stream of the flowsheet.
size columns
    class bounds ``size_lower`` and ``size_upper`` (blank upper = the open top class, blank
    or 0 lower = the pan), or class-range strings in ``size_class`` ("+1168", "-1168+589",
    "-74"), as in lab tables; a unit suffix (``size_lower_um``) or the ``size_unit``
    option names the unit.  The classes of all streams together must tile the size range
    (no gap, no overlap); a stream may leave classes out.
exactly one value column
    ``retained_pct`` (per cent of the stream's solids retained in the class, i.e. between
    its bounds - not cumulative), ``retained_frac`` (the same as a fraction) or
    ``retained_mass`` (mass in the class, any unit; every class of the stream must then
    be given).  A blank value = the class was not measured in that stream.
``retained_sd``
    optional standard deviation of the value, in the value's unit (for masses: in mass
    units, divided by the stream's total mass).
``relative_error``, ``absolute_error``
    optional, per row (i.e. per class; give the same on every row for a per-stream
    error): the error model of the share (below).
``solids_flow``, ``solids_flow_sd``
    optional measured solids flow of the stream (any unit, t/h say; every flow in the
    same unit) and its standard deviation; an sd of 0 fixes the flow exactly (the basis
    of the survey).  Given on any row of the stream (repeated values must agree); a row
    with blank size columns may carry just the flow.
``pct_solids``, ``pct_solids_sd``
    optional per cent solids by mass of the stream's pulp and its standard deviation
    (the water balances then join the reconciliation).
``assay_<name>_pct``
    optional per-class assays: the mass per cent of component ``<name>`` in the solids of
    the row's stream and class (any number of such columns; blank = not assayed), with the
    error model of :mod:`tromplab.circuit.assays`.
``note``, ``comment``
    free text, ignored.  Any other column is refused with its name.

Error model
-----------
A measured share :math:`x` (fraction of the stream in a class) has the standard deviation

.. math:: \sigma = \sqrt{(r\,x)^2 + a^2}

with the relative error :math:`r` (default :data:`~tromplab.options.DEFAULT_RELATIVE_ERROR` = 5 %) and the
absolute error :math:`a` (default :data:`~tromplab.options.DEFAULT_ABSOLUTE_ERROR` = 0.001, i.e. 0.1
percentage point), the model of the existing one-node reconciliation
(:func:`tromplab.loading.lab.reconcile`) and of Hodouin & Everell (1980), who weight
size-analysis data by a relative error with a floor for the small classes.  ``retained_sd``
overrides it per row, ``relative_error`` / ``absolute_error`` columns per row, and
:class:`ErrorModel` ``streams`` per stream.  A measured solids flow without sd has the
relative error :data:`~tromplab.options.DEFAULT_FLOW_RELATIVE_ERROR` (5 %).  The model is evaluated at the
measured value.  The errors of the class masses of a sieve analysis are independent; a
stream measured in every class is normalised to 100 % (as lab tables are), and its shares
then carry the errors through the normalisation: with :math:`D = \mathrm{diag}(\sigma_i^2)`
and :math:`P = I - x\,\mathbf{1}^T`, their covariance is :math:`P D P^T` (rank n - 1:
the shares of a closed analysis are not independent).  A stream with classes left out is
used as given, its shares independent.  Flows and shares of different streams are
independent.

References
----------
Hodouin, D. & Everell, M. D. (1980). A hierarchical procedure for adjustment and material
balancing of mineral processes data. *International Journal of Mineral Processing* 7(2),
91-116.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd

from ..errors import InputError, OptionError
from ..loading.size_classes import class_string_bounds, size_columns
from ..loading.tables import Table, read_table
from ..options import (
    DEFAULT_ABSOLUTE_ERROR,
    DEFAULT_ASSAY_ABSOLUTE_ERROR,
    DEFAULT_ASSAY_RELATIVE_ERROR,
    DEFAULT_FLOW_RELATIVE_ERROR,
    DEFAULT_PCT_SOLIDS_SD,
    DEFAULT_RELATIVE_ERROR,
    DEFAULT_SUM_TOLERANCE_PCT,
    ERROR_MODEL_POINTS,
)
from ..validation import (
    MAX_PCT_SOLIDS_SD,
    MAX_RELATIVE_ERROR,
    MAX_SHARE_SD,
    check_assay_sd,
    check_pct_solids_sd,
    check_positive_relative_error,
    check_relative_error,
    check_share_sd,
)
from .assays import assay_columns, assays_at, empty_assays, read_assays, set_aside
from .flowsheet import Flowsheet

#: Per-class shares of a fully measured stream may miss 100 % by this much (percentage points)
#: before the table is refused, as in lab tables; within it they are used as given (each share
#: has its own error, so the sum's miss is information the balance uses).
SUM_TOLERANCE_PCT = DEFAULT_SUM_TOLERANCE_PCT
VALUE_COLUMNS = {"retained_pct": 100.0, "retained_frac": 1.0, "retained_mass": None}
#: Largest retained mass of one class (any unit): sums of masses stay far from floating point's
#: overflow, and no sample weighs more.
MAX_RETAINED_MASS = 1e12
STREAM_COLUMNS = ("solids_flow", "solids_flow_sd", "pct_solids", "pct_solids_sd")
ROW_COLUMNS = ("retained_sd", "relative_error", "absolute_error")
SIZE_STEMS = ("size_lower", "size_upper", "size_class")
#: Columns of :attr:`Survey.shares`: ``relative`` and ``absolute`` are the error model's errors of
#: the share (NaN where the table gave its sd), ``at`` the share at which its sd is evaluated.
SHARE_COLUMNS = ["stream", "class_index", "value", "sd", "row", "relative", "absolute"]
#: Columns of :attr:`Survey.flows` and :attr:`Survey.pct_solids` (``relative``: NaN where the sd was given).
STREAM_VALUE_COLUMNS = ["stream", "value", "sd", "row", "relative"]


@dataclass(frozen=True)
class ErrorModel:
    r"""Standard deviations of the measurements where the table gives none.

    Attributes
    ----------
    relative_error : float
        Relative error :math:`r` of a measured share (0.05 = 5 %).
    absolute_error : float
        Absolute error :math:`a` of a share, as a fraction of the stream (0.001 = 0.1
        percentage point); keeps small classes from getting an sd near zero.
    flow_relative_error : float
        Relative error of a measured solids flow without ``solids_flow_sd``.
    pct_solids_sd : float
        Standard deviation of a per cent solids without ``pct_solids_sd`` (percentage points).
    streams : dict
        Per-stream ``{stream: (relative_error, absolute_error)}`` overriding the two defaults.
    closure : bool
        True (default): a stream measured in every class is normalised to 100 % and its
        shares get the covariance :math:`P D P^T` of a closed analysis.  False: every share
        is used as given with its own independent error (data not normalised by the lab).
    assay_relative_error : float
        Relative error of a per-class assay (:mod:`tromplab.circuit.assays`).
    assay_absolute_error : float
        Absolute error of an assay, a fraction of the class's solids.
    components : dict
        Per-component ``{component: (relative_error, absolute_error)}`` overriding the two
        assay defaults.
    evaluated_at : {"reconciled", "measured"}
        Where :math:`\sigma(x)` and the closure :math:`P` are evaluated: at the reconciled
        shares and flows, iterated until the standard deviations settle (default: a share
        measured low or high then gets the same sd, so a test does not depend on the sign of
        a slip), or at the measured values (one reconciliation).

    Examples
    --------
    >>> model = ErrorModel(streams={"underflow": (0.1, 0.002)})
    >>> round(float(model.share_sd(0.2, "feed")), 6), round(float(model.share_sd(0.2, "underflow")), 6)
    (0.01005, 0.0201)
    """

    relative_error: float = DEFAULT_RELATIVE_ERROR
    absolute_error: float = DEFAULT_ABSOLUTE_ERROR
    flow_relative_error: float = DEFAULT_FLOW_RELATIVE_ERROR
    pct_solids_sd: float = DEFAULT_PCT_SOLIDS_SD
    streams: dict = field(default_factory=dict)
    closure: bool = True
    evaluated_at: str = "reconciled"
    assay_relative_error: float = DEFAULT_ASSAY_RELATIVE_ERROR
    assay_absolute_error: float = DEFAULT_ASSAY_ABSOLUTE_ERROR
    components: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.evaluated_at not in ERROR_MODEL_POINTS:
            raise OptionError("evaluated_at", f"is one of {', '.join(ERROR_MODEL_POINTS)}, got {self.evaluated_at!r}")
        check_relative_error(self.relative_error, "relative_error")
        check_share_sd(self.absolute_error, "absolute_error")
        check_positive_relative_error(self.flow_relative_error, "flow_relative_error")
        check_pct_solids_sd(self.pct_solids_sd, "pct_solids_sd")
        check_relative_error(self.assay_relative_error, "assay_relative_error")
        check_assay_sd(self.assay_absolute_error, "assay_absolute_error")
        if self.relative_error == 0 and self.absolute_error == 0:
            raise OptionError("relative_error", "and absolute_error are both 0: every share would be exact")
        if self.assay_relative_error == 0 and self.assay_absolute_error == 0:
            raise OptionError("assay_relative_error", "and assay_absolute_error are both 0: every assay would be exact")
        _check_error_pairs(self.streams, "streams", "stream", "share", check_share_sd)
        _check_error_pairs(self.components, "components", "component", "assay", check_assay_sd)

    def check_streams(self, flowsheet: Flowsheet) -> None:
        """Refuse a per-stream override naming a stream the flowsheet lacks (a typo would
        otherwise leave the default model in place without a word)."""
        unknown = [name for name in self.streams if name not in flowsheet.stream_index]
        if unknown:
            raise OptionError(
                "streams",
                f"of the error model names {', '.join(repr(n) for n in unknown)}, not a solids stream of the flowsheet "
                f"{flowsheet.source} ({', '.join(flowsheet.stream_names)})",
            )

    def assay_errors(self, component: str) -> tuple[float, float]:
        """``(relative, absolute)`` error of an assay of ``component``."""
        return self.components.get(component, (self.assay_relative_error, self.assay_absolute_error))

    def share_sd(self, share, stream: str = ""):
        r"""Standard deviation :math:`\sqrt{(r x)^2 + a^2}` of a measured share ``x`` of ``stream``."""
        relative, absolute = self.streams.get(stream, (self.relative_error, self.absolute_error))
        return np.sqrt((relative * np.asarray(share, dtype=float)) ** 2 + absolute**2)


def _check_error_pairs(pairs, option: str, what: str, measured: str, check_absolute) -> None:
    """Refuse a per-stream or per-component override that is not ``{name: (relative, absolute)}`` in range."""
    if not isinstance(pairs, dict):
        raise OptionError(option, f"takes a dict {{{what}: (relative_error, absolute_error)}}, got {pairs!r}")
    for name, pair in pairs.items():
        if not isinstance(pair, (tuple, list)) or len(pair) != 2:
            raise OptionError(option, f"takes (relative_error, absolute_error) pairs, got {pair!r} for '{name}'")
        relative, absolute = pair
        check_relative_error(relative, f"relative_error of {what} '{name}'")
        check_absolute(absolute, f"absolute_error of {what} '{name}'")
        if relative == 0 and absolute == 0:
            raise OptionError(f"{option}['{name}']", f"gives both errors 0: every {measured} of the {what} would be exact")


@dataclass(frozen=True)
class Survey:
    """The measurements of a survey, checked against the flowsheet.

    Attributes
    ----------
    classes : pandas.DataFrame
        The size classes, coarse to fine: ``size_lower, size_upper`` (NaN = open top /
        pan, as given), ``size`` (representative: geometric mean of the bounds, the open
        top and the pan continuing their neighbour's ratio).
    shares : pandas.DataFrame
        ``stream, class_index, value, sd, row``: measured shares (0..1) and their sd.
    flows : pandas.DataFrame
        ``stream, value, sd, row``: measured solids flows (sd 0 = fixed).
    pct_solids : pandas.DataFrame
        ``stream, value, sd, row``.
    size_unit : str
    source : str
    closed_streams : tuple of str
        Streams measured in every class, normalised to sum to 1: their shares have the
        covariance :math:`P D P^T` of the module docstring.
    unmeasured : pandas.DataFrame
        ``stream, class_index, row``: rows of the table that name a class of a stream but
        leave its value blank (or NaN); the class is not measured in that stream.
    assays : pandas.DataFrame
        ``stream, class_index, component, value, sd, row, relative, absolute``: per-class
        assays (fractions of the class's solids, :mod:`tromplab.circuit.assays`).
    components : tuple of str
        The components assayed, in the order of the table's columns.
    assays_set_aside : pandas.DataFrame
        Assays of classes measured below :data:`~tromplab.circuit.assays.MIN_ASSAYED_SHARE` of
        their stream: too little material to assay; not used.
    """

    classes: pd.DataFrame
    shares: pd.DataFrame
    flows: pd.DataFrame
    pct_solids: pd.DataFrame
    size_unit: str = ""
    source: str = ""
    closed_streams: tuple[str, ...] = ()
    unmeasured: pd.DataFrame = field(default_factory=lambda: pd.DataFrame(columns=["stream", "class_index", "row"]))
    evaluated_at: str = "reconciled"
    assays: pd.DataFrame = field(default_factory=empty_assays)
    components: tuple[str, ...] = ()
    assays_set_aside: pd.DataFrame = field(default_factory=empty_assays)

    @property
    def n_classes(self) -> int:
        return len(self.classes)

    @property
    def measured_streams(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(self.shares["stream"]))

    def exact_measurements(self) -> str:
        """The measurements given as exact (a standard deviation of 0 in the table or from an
        error model of 0), by stream and row of the table, for a message: "" when there is none."""
        parts = []
        for what, table in (("share", self.shares), ("flow", self.flows), ("per cent solids", self.pct_solids),
                            ("assay", self.assays)):  # fmt: skip
            if not len(table) or "sd" not in table:
                continue
            exact = table[table["sd"].to_numpy(float) == 0]
            if "relative" in exact:  # a flow made the basis of a survey with one flow is not given as exact
                exact = exact[exact["relative"].isna()]
            for stream, rows in exact.groupby("stream", sort=False)["row"]:
                listed = ", ".join(str(row) for row in list(dict.fromkeys(rows))[:6]) + (", ..." if rows.nunique() > 6 else "")
                parts.append(f"{what}s of {stream} (row{'s' if rows.nunique() > 1 else ''} {listed})")
        return "; ".join(parts)

    def with_errors_at(self, shares: np.ndarray, flows: np.ndarray, stream_index: dict, grades=None) -> Survey:
        """The survey with the error model evaluated at ``shares`` (streams x classes, clipped
        at 0), ``flows`` (per stream) and ``grades`` (components x streams x classes: the
        assays) instead of the measured values: the sd of every share, flow and assay whose sd
        the table did not give, and the share ``at`` which the closure of its analysis is
        linearised.  Values and given sds are unchanged."""
        table = self.shares.copy()
        if len(table):
            at = np.clip(shares[table["stream"].map(stream_index).to_numpy(), table["class_index"].to_numpy(int)], 0.0, 1.0)
            modelled = table["relative"].notna().to_numpy()
            sd = np.sqrt((table["relative"].to_numpy(float) * at) ** 2 + table["absolute"].to_numpy(float) ** 2)
            table["sd"] = np.where(modelled, sd, table["sd"].to_numpy(float))
            table["at"] = at
        flow_table = self.flows.copy()
        if len(flow_table):
            modelled = flow_table["relative"].notna().to_numpy()
            reconciled = flows[flow_table["stream"].map(stream_index).to_numpy()]
            flow_table["sd"] = np.where(modelled, flow_table["relative"].to_numpy(float) * reconciled, flow_table["sd"])
        assays = self.assays if grades is None else assays_at(self.assays, grades, stream_index, self.components)
        return replace(self, shares=table, flows=flow_table, assays=assays)


def read_survey(
    path,
    flowsheet: Flowsheet,
    *,
    errors: ErrorModel | None = None,
    size_unit: str | None = None,
    sheet=None,
    sep: str | None = None,
    decimal: str | None = None,
) -> Survey:
    """Read and check the measurement table of a survey (schema in the module docstring).

    Parameters
    ----------
    path : str, path-like or pandas.DataFrame
        CSV or Excel file, or a DataFrame with the same columns.
    flowsheet : Flowsheet
        The streams the measurements may name.
    errors : ErrorModel, optional
        Default standard deviations (module docstring).
    size_unit : str, optional
        Unit of the sizes when the size columns carry no suffix.
    sheet, sep, decimal
        As for :func:`tromplab.loading.tables.read_table`.

    Returns
    -------
    Survey

    Raises
    ------
    InputError
        Naming the file, row and column: an unknown stream, negative amounts, shares of a
        complete stream not summing to 100 %, classes that overlap or leave a gap, a class
        given twice for a stream, flows that disagree within a stream, an assay outside 0..100.
    OptionError
        An override of the error model naming a stream or component the survey lacks.
    """
    errors = _checked_errors(errors, flowsheet)
    table = read_table(path, sheet=sheet, sep=sep, decimal=decimal)
    table.require("stream")
    lower, upper, unit, size_columns = _size_bounds(table, size_unit)
    values_given = [c for c in VALUE_COLUMNS if c in table.frame.columns]
    if len(values_given) > 1:
        raise InputError(f"several value columns ({', '.join(values_given)}): give one", source=table.source)
    known = ["stream", *size_columns, "size_unit", *VALUE_COLUMNS, *ROW_COLUMNS, *STREAM_COLUMNS]
    table.refuse_unknown([*known, *assay_columns(table).values()], what="survey table")
    names = _stream_names(table, flowsheet)
    has_class = np.isfinite(lower) | np.isfinite(upper)
    classes, class_of_row = _tiled_classes(table, lower, upper, has_class, size_columns)
    shares, normalised = _shares(table, names, has_class, class_of_row, len(classes), values_given, errors)
    flows, pct = _stream_measurements(table, names, errors)
    assays, scarce = set_aside(read_assays(table, names, has_class, class_of_row, errors), shares)
    if flows.empty and shares.empty and pct.empty:
        raise InputError(
            "the survey holds no measurement (no size analysis, no solids flow, no per cent solids)", source=table.source
        )
    unmeasured = _unmeasured(table, names, has_class, class_of_row, values_given)
    return Survey(classes=classes, shares=shares, flows=flows, pct_solids=pct, size_unit=unit, source=table.source,
                  closed_streams=normalised, unmeasured=unmeasured, evaluated_at=errors.evaluated_at, assays=assays,
                  components=tuple(dict.fromkeys([*assays["component"], *scarce["component"]])),
                  assays_set_aside=scarce)  # fmt: skip


def _checked_errors(errors, flowsheet: Flowsheet) -> ErrorModel:
    errors = errors or ErrorModel()
    if not isinstance(errors, ErrorModel):
        raise OptionError("errors", f"takes an ErrorModel, got {type(errors).__name__}")
    errors.check_streams(flowsheet)
    return errors


def _stream_measurements(table: Table, names, errors: ErrorModel) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The solids flows and per cent solids of the streams, checked."""
    flows = _stream_values(
        table, names, "solids_flow", "solids_flow_sd", lambda v: errors.flow_relative_error * v, errors.flow_relative_error
    )
    pct = _stream_values(table, names, "pct_solids", "pct_solids_sd", lambda v: np.full_like(v, errors.pct_solids_sd))
    _check_stream_values(table, flows, pct)
    return flows, pct


def _unmeasured(table: Table, names, has_class, class_of_row, values_given) -> pd.DataFrame:
    """Rows that name a class of a stream but leave its value blank (or NaN): not measured."""
    columns = ["stream", "class_index", "row"]
    if not values_given:
        return pd.DataFrame(columns=columns)
    blank = has_class & np.isnan(table.numeric(values_given[0], allow_blank=True))
    where = np.flatnonzero(blank)
    return pd.DataFrame(
        {"stream": names[where], "class_index": class_of_row[where].astype(int), "row": np.asarray(table.rows)[where]},
        columns=columns,
    )


def _stream_names(table: Table, flowsheet: Flowsheet) -> np.ndarray:
    """The stream of every row, checked against the flowsheet (blank, water stream, unknown)."""
    names = np.array([_cell_text(table, i, "stream") for i in range(len(table.frame))], dtype=object)
    for i, name in enumerate(names):
        if not name:
            raise table.error("stream name is blank", index=i, column="stream")
        if name in {w.name for w in flowsheet.water_streams}:
            raise table.error(
                f"stream '{name}' is a water stream of the flowsheet: it carries no solids to analyse or weigh (its flow "
                "follows from the per cent solids of the solids streams at its node)",
                index=i,
                column="stream",
            )
        if name not in flowsheet.stream_index:
            raise table.error(
                f"unknown stream '{name}': the flowsheet {flowsheet.source} has {', '.join(flowsheet.stream_names)}",
                index=i,
                column="stream",
            )
    return names


def _check_stream_values(table: Table, flows: pd.DataFrame, pct: pd.DataFrame) -> None:
    """Refuse implausible flow and per cent solids sds and per cent solids outside (0, 100], naming the row."""
    _refuse_first(
        table,
        flows[(flows["value"] > 0) & (flows["sd"] > MAX_RELATIVE_ERROR * flows["value"])],
        "solids_flow_sd",
        lambda row: (
            f"solids flow sd {row.sd:g} is implausible for a flow of {row.value:g}: more than "
            f"{MAX_RELATIVE_ERROR:.0%} of the flow"
        ),
    )
    if len(pct):
        _refuse_first(
            table,
            pct[pct["sd"] > MAX_PCT_SOLIDS_SD],
            "pct_solids_sd",
            lambda row: (
                f"per cent solids sd {row.sd:g} is implausible: at most {MAX_PCT_SOLIDS_SD:g} percentage points "
                "(a per cent solids lies in 0..100)"
            ),
        )
        _refuse_first(
            table,
            pct[(pct["value"] <= 0) | (pct["value"] > 100)],
            "pct_solids",
            lambda row: f"per cent solids {row.value:g} outside (0, 100]",
        )


def _refuse_first(table: Table, offending: pd.DataFrame, column: str, message: Callable[[pd.Series], str]) -> None:
    """Raise an :class:`InputError` naming the file row (``row``) and ``column`` of the first of the
    ``offending`` values, if any; ``message(value)`` says what is wrong with it."""
    if len(offending):
        first = offending.iloc[0]
        raise InputError(message(first), source=table.source, row=first.row, column=column)


def _cell_text(table: Table, i: int, column: str) -> str:
    value = table.frame[column].iloc[i]
    return "" if pd.isna(value) else str(value).strip()


def _size_bounds(table: Table, size_unit):
    found, unit, _ = size_columns(table, SIZE_STEMS, size_unit)
    if not found and not any(c in table.frame.columns for c in VALUE_COLUMNS):  # per cent solids and flows only
        blank = np.full(len(table.frame), np.nan)
        return blank, blank.copy(), unit, []
    if "size_class" in found:
        if "size_lower" in found or "size_upper" in found:
            raise InputError("the sizes are given twice (size_class and size_lower/size_upper): keep one", source=table.source)
        column = found["size_class"]
        lower, upper = class_string_bounds(table, column, blank_allowed=True)  # blank: a row of stream values only
        written = table.frame[column].notna().to_numpy() & (table.frame[column].astype(str).str.strip() != "").to_numpy()
        table.refuse_where(written & ~(lower > 0) & np.isnan(upper), column, "the class has neither a lower nor an upper bound")
        lower = np.where(lower == 0, np.nan, lower)  # "+0": the pan
        table.refuse_where(
            np.isfinite(lower) & np.isfinite(upper) & (lower >= upper),
            column,
            lambda i: f"class '{table.frame[column].iloc[i]}': the lower bound is not below the upper bound",
        )
        return lower, upper, unit, [column]
    if not ("size_lower" in found and "size_upper" in found):
        raise InputError(
            "give class bounds 'size_lower' and 'size_upper' (with a unit suffix, e.g. size_lower_um) or size classes "
            '\'size_class\' ("+1168", "-1168+589", "-74")',
            source=table.source,
        )
    lower = table.numeric(found["size_lower"], allow_blank=True)
    upper = table.numeric(found["size_upper"], allow_blank=True)
    for values, column in ((lower, found["size_lower"]), (upper, found["size_upper"])):
        table.refuse_where(values < 0, column, "class bounds must be positive (a pan's lower bound may be 0 or blank)")
    table.refuse_where(upper == 0, found["size_upper"], "an upper bound must be positive")
    lower = np.where(lower == 0, np.nan, lower)
    table.refuse_where(
        np.isfinite(lower) & np.isfinite(upper) & (lower >= upper),
        found["size_lower"],
        lambda i: f"lower bound {lower[i]:g} is not below the upper bound {upper[i]:g}",
    )
    return lower, upper, unit, [found["size_lower"], found["size_upper"]]


def _tiled_classes(table: Table, lower, upper, has_class, size_columns):
    """The distinct classes, coarse to fine, checked to tile the size range; the class of each row."""
    key_lower = np.where(np.isfinite(lower), lower, 0.0)
    distinct = {}  # lower bound (0 = pan) -> (upper, first row index)
    for i in np.flatnonzero(has_class):
        k = float(key_lower[i])
        match = next((other for other in distinct if _close(other, k)), None)
        if match is None:
            distinct[k] = (upper[i], i)
            continue
        known, first = distinct[match]
        if not (np.isnan(known) and np.isnan(upper[i]) or np.isclose(known, upper[i], rtol=1e-9)):
            raise table.error(
                f"class {_name(lower[i], upper[i])} overlaps class {_name(lower[first], known)} (row {table.rows[first]}): "
                "the size classes of the streams do not tile the size range",
                index=int(i),
                column=size_columns[-1],
            )
    if not distinct:
        return pd.DataFrame({"size_lower": [], "size_upper": [], "size": []}), np.full(len(lower), -1)
    ordered = sorted(distinct, reverse=True)  # coarse to fine
    for coarser, finer in zip(ordered[:-1], ordered[1:]):
        top_of_finer, i = distinct[finer]
        if np.isnan(top_of_finer):
            raise table.error(
                f"class {_name(lower[i], top_of_finer)} is open at the top but class {_name(coarser, distinct[coarser][0])} is "
                "coarser: the classes do not tile the size range",
                index=int(i),
                column=size_columns[-1],
            )
        if not np.isclose(top_of_finer, coarser, rtol=1e-9):
            what = "a gap" if top_of_finer < coarser else "an overlap"
            raise table.error(
                f"{what} between class {_name(lower[i], top_of_finer)} and class {_name(coarser, distinct[coarser][0])}: "
                "the size classes of the streams must tile the size range (each upper bound the next class's lower bound)",
                index=int(i),
                column=size_columns[-1],
            )
    if len(ordered) == 1 and not (ordered[0] > 0 and np.isfinite(distinct[ordered[0]][0])):
        top, i = distinct[ordered[0]]
        raise table.error(
            f"the only size class, {_name(ordered[0], top)}, is open: a size analysis needs two classes or more (the "
            "partition is a curve over sizes), and an open class alone has no representative size",
            index=int(i),
            column=size_columns[-1] if np.isnan(top) else size_columns[0],
        )
    lows = np.array([k if k > 0 else np.nan for k in ordered])
    highs = np.array([distinct[k][0] for k in ordered])
    class_of_row = np.full(len(lower), -1)
    for i in np.flatnonzero(has_class):
        class_of_row[i] = int(np.argmin(np.abs(np.array(ordered) - key_lower[i])))
    return pd.DataFrame({"size_lower": lows, "size_upper": highs, "size": _representative(table, lows, highs)}), class_of_row


def _close(a: float, b: float, rtol: float = 1e-9) -> bool:
    """``np.isclose(a, b, rtol=rtol, atol=0.0)`` of two floats, without its 25 us a call (once per
    row and class of a survey)."""
    finite = b == b and abs(b) != float("inf")
    return (abs(a - b) <= rtol * abs(b) and finite) or a == b


def _name(lower, upper) -> str:
    low = "pan" if not np.isfinite(lower) or lower == 0 else f"{lower:g}"
    high = "top" if not np.isfinite(upper) else f"{upper:g}"
    return f"{low}-{high}"


def _representative(table: Table, lower, upper) -> np.ndarray:
    """Geometric means; the open top class and the pan continue their neighbour's size ratio."""
    lower, upper = lower.copy(), upper.copy()
    if len(lower) == 1 and not (np.isfinite(lower[0]) and np.isfinite(upper[0])):
        raise InputError("a single open size class has no representative size", source=table.source)
    if np.isnan(upper[0]):
        upper[0] = lower[0] * (upper[1] / lower[1] if np.isfinite(lower[1]) else 2.0)
    if np.isnan(lower[-1]):
        lower[-1] = upper[-1] / (upper[-2] / lower[-2] if np.isfinite(upper[-2]) else 2.0)
    return np.sqrt(lower) * np.sqrt(upper)


def _shares(table, names, has_class, class_of_row, n_classes, values_given, errors: ErrorModel) -> pd.DataFrame:
    """The measured shares (:data:`SHARE_COLUMNS`) and the streams normalised as closed analyses."""
    if not values_given:
        if has_class.any():
            raise InputError(
                f"size classes are given but no value column: give one of {', '.join(VALUE_COLUMNS)}", source=table.source
            )
        return pd.DataFrame(columns=SHARE_COLUMNS), ()
    column = values_given[0]
    full = VALUE_COLUMNS[column]
    values = _retained_values(table, column, full, has_class)
    row_errors = _error_columns(table, len(values), full)
    records, normalised = [], []
    for stream in dict.fromkeys(names[has_class]):
        rows = np.flatnonzero((names == stream) & has_class & np.isfinite(values))
        if not rows.size:
            continue
        _check_distinct_classes(table, stream, rows, class_of_row, column)
        scale, closed = _stream_scale(table, stream, values[rows], rows, n_classes, full, column, errors)
        if closed:
            normalised.append(stream)
        records += _stream_share_records(table, stream, rows, values[rows] / scale, scale, class_of_row, row_errors, errors)
    return pd.DataFrame(records, columns=SHARE_COLUMNS), tuple(normalised)


def _retained_values(table: Table, column: str, full, has_class) -> np.ndarray:
    """The value column, refused where negative, above the whole stream, or without a size class."""
    values = table.numeric(column, allow_blank=True)
    bad = np.flatnonzero(values < 0)
    if bad.size:
        what = "mass" if full is None else "share"
        raise table.error(f"negative retained {what} {values[bad[0]]:g}", index=int(bad[0]), column=column)
    bad = np.flatnonzero(values > full) if full is not None else np.flatnonzero(values > MAX_RETAINED_MASS)
    if bad.size:
        limit = f"{full:g} (the whole stream)" if full is not None else f"{MAX_RETAINED_MASS:g} (beyond any weighing)"
        raise table.error(f"retained value {values[bad[0]]:g} above {limit}", index=int(bad[0]), column=column)
    table.refuse_where(np.isfinite(values) & ~has_class, column, "a retained value without a size class")
    return values


def _check_distinct_classes(table: Table, stream: str, rows, class_of_row, column: str) -> None:
    seen = {}
    for i in rows:
        if class_of_row[i] in seen:
            raise table.error(
                f"stream '{stream}' gives size class {class_of_row[i] + 1} (coarse to fine) twice "
                f"(also at row {table.rows[seen[class_of_row[i]]]})",
                index=int(i),
                column=column,
            )
        seen[class_of_row[i]] = i


def _stream_scale(table: Table, stream: str, given, rows, n_classes: int, full, column: str, errors) -> tuple[float, bool]:
    """``(scale, closed)``: what the stream's values are divided by to give shares, and whether
    the stream is a closed analysis (every class given, normalised as lab tables are)."""
    total = given.sum()
    complete = rows.size == n_classes
    if full is None:
        if not complete:
            missing = n_classes - rows.size
            raise table.error(
                f"stream '{stream}' gives masses for {rows.size} of {n_classes} classes ({missing} missing): masses "
                "need every class (give shares, retained_pct, to leave classes out)",
                index=int(rows[0]),
                column=column,
            )
        if total <= 0:
            raise table.error(f"stream '{stream}' holds no material", index=int(rows[0]), column=column)
    else:
        off = 100.0 * (total - full) / full
        if (complete and abs(off) > SUM_TOLERANCE_PCT) or (not complete and off > SUM_TOLERANCE_PCT):
            raise table.error(
                f"the shares of stream '{stream}' sum to {100 * total / full:.2f} % "
                f"({'over' if off > 0 else 'short'} by {abs(off):.2f} percentage points, tolerance {SUM_TOLERANCE_PCT:g})",
                index=int(rows[0]),
                column=column,
            )
    closed = complete and (errors.closure or full is None)
    return (total if closed else full), closed


def _stream_share_records(table: Table, stream: str, rows, share, scale, class_of_row, row_errors, errors) -> list[dict]:
    """The share records of one stream with their sds: the row's ``retained_sd``, else its
    ``relative_error``/``absolute_error``, else the stream's or the default error model."""
    row_sd, relative, absolute = row_errors
    default = errors.share_sd(share, stream)
    stream_relative, stream_absolute = errors.streams.get(stream, (errors.relative_error, errors.absolute_error))
    r = np.where(np.isfinite(relative[rows]), relative[rows], stream_relative)
    a = np.where(np.isfinite(absolute[rows]), absolute[rows], stream_absolute)
    sd = np.where(np.isfinite(relative[rows]) | np.isfinite(absolute[rows]), np.sqrt((r * share) ** 2 + a**2), default)
    sd = np.where(np.isfinite(row_sd[rows]), row_sd[rows] / scale, sd)
    if np.any(sd > MAX_SHARE_SD):
        i = int(rows[np.argmax(sd)])
        raise table.error(
            f"retained sd {row_sd[i]:g} is implausible: more than {MAX_SHARE_SD:g} of the stream's total (a share lies in 0..1)",
            index=i,
            column="retained_sd",
        )
    explicit = np.isfinite(row_sd[rows])
    _refuse_modelled_exact(
        table, stream, rows, share, sd == 0, explicit, np.isfinite(relative[rows]) | np.isfinite(absolute[rows])
    )
    return [{"stream": stream, "class_index": int(class_of_row[i]), "value": x, "sd": s, "row": int(table.rows[i]),
             "relative": np.nan if given_sd else r_i, "absolute": np.nan if given_sd else a_i}
            for i, x, s, r_i, a_i, given_sd in zip(rows, share, sd, r, a, explicit)]  # fmt: skip


def _refuse_modelled_exact(table: Table, stream: str, rows, share, exact, explicit, from_row) -> None:
    """Refuse a share the error model holds exact: a share of 0 with an absolute error of 0.

    Held exact, such a share is a constraint of the balances (a stream with no material in
    the class), which the measurements then contradict as gross errors one after another; a
    share is made exact on purpose with a ``retained_sd`` of 0."""
    held = np.flatnonzero(exact & ~explicit)
    if not held.size:
        return
    k = int(held[0])
    i = int(rows[k])
    where = f"the share {share[k]:g} of stream '{stream}' at row {table.rows[i]}"
    if from_row[k]:
        raise table.error(
            f"{where} has a standard deviation of 0 from its relative_error and absolute_error, so it would be held "
            "exact: give an absolute_error above 0 (or a retained_sd of 0 to hold it exact on purpose)",
            index=i,
            column="absolute_error",
        )
    raise OptionError(
        "absolute_error",
        f"of 0 gives {where} a standard deviation of 0, so it would be held exact (a constraint no measurement may "
        "contradict): give an absolute error above 0 (or a retained_sd of 0 to hold a share exact on purpose)",
    )


def _error_columns(table: Table, n: int, full) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``retained_sd``, ``relative_error`` and ``absolute_error`` per row (NaN where blank),
    refused when negative or implausible, naming the row; ``full`` is the value column's 100 %."""
    row_sd = table.numeric("retained_sd", allow_blank=True) if "retained_sd" in table.frame.columns else np.full(n, np.nan)
    relative = _optional(table, "relative_error", n)
    absolute = _optional(table, "absolute_error", n)
    for array, name in ((row_sd, "retained_sd"), (relative, "relative_error"), (absolute, "absolute_error")):
        table.refuse_where(array < 0, name, f"{name} must not be negative")
    unit_of_value = full or 1.0  # masses: checked per stream below, once divided by the stream's total
    limits = (
        (relative, "relative_error", MAX_RELATIVE_ERROR, "a relative error of 100 % of the share"),
        (absolute, "absolute_error", MAX_SHARE_SD, "a share lies in 0..1"),
        (row_sd, "retained_sd", MAX_SHARE_SD * unit_of_value if full else np.inf, "a share lies in 0..1"),
    )
    for array, name, maximum, why in limits:
        bad = np.flatnonzero(array > maximum)
        if bad.size:
            raise table.error(
                f"{name.replace('_', ' ')} {array[bad[0]]:g} is implausible: at most {maximum:g} ({why})",
                index=int(bad[0]),
                column=name,
            )
    return row_sd, relative, absolute


def _optional(table: Table, column: str, n: int) -> np.ndarray:
    return table.numeric(column, allow_blank=True) if column in table.frame.columns else np.full(n, np.nan)


def _stream_values(table: Table, names, column: str, sd_column: str, default_sd, relative=np.nan) -> pd.DataFrame:
    """One value per stream of ``column`` with its sd (``sd_column``, else ``default_sd``);
    ``relative`` is the error model's relative error of a value without a given sd."""
    columns = STREAM_VALUE_COLUMNS
    if column not in table.frame.columns:
        if sd_column in table.frame.columns and table.frame[sd_column].notna().any():
            raise InputError(f"column '{sd_column}' without '{column}'", source=table.source, column=sd_column)
        return pd.DataFrame(columns=columns)
    values = table.numeric(column, allow_blank=True)
    sds = _optional(table, sd_column, len(values))
    table.refuse_where(values < 0, column, lambda i: f"negative {column.replace('_', ' ')} {values[i]:g}")
    table.refuse_where(sds < 0, sd_column, "a standard deviation must not be negative")
    records = []
    for stream in dict.fromkeys(names):
        rows = np.flatnonzero((names == stream) & np.isfinite(values))
        if not rows.size:
            continue
        first = rows[0]
        for i in rows[1:]:
            if not np.isclose(values[i], values[first], rtol=1e-9) or not (
                np.isnan(sds[i]) and np.isnan(sds[first]) or np.isclose(sds[i], sds[first], rtol=1e-9)
            ):
                raise table.error(
                    f"stream '{stream}' has two different {column} values (see row {table.rows[first]})",
                    index=int(i),
                    column=column,
                )
        sd = sds[first] if np.isfinite(sds[first]) else float(default_sd(np.array([values[first]]))[0])
        if column == "solids_flow" and values[first] == 0 and sd == 0:
            raise table.error(
                f"stream '{stream}': a solids flow fixed at 0 leaves no stream to balance", index=int(first), column=column
            )
        records.append({"stream": stream, "value": float(values[first]), "sd": float(sd), "row": int(table.rows[first]),
                        "relative": np.nan if np.isfinite(sds[first]) else relative})  # fmt: skip
    return pd.DataFrame(records, columns=columns)


def class_name(classes: pd.DataFrame, i: int) -> str:
    """Class ``i`` as the tables name it: ``+600`` (open top), ``-600+300``, ``-38`` (the pan)."""
    lower, upper = classes["size_lower"].to_numpy()[i], classes["size_upper"].to_numpy()[i]  # not .iloc: called per row
    if not np.isfinite(upper):
        return f"+{lower:g}"
    if not np.isfinite(lower):
        return f"-{upper:g}"
    return f"-{upper:g}+{lower:g}"
