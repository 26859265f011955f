r"""The fine yield, the reconciliation and the partition of one classifier (one node, three streams).

With the feed, fine and coarse shares :math:`a_i, b_i, c_i` of each class and the fine yield
:math:`y`, the balance of a class is :math:`a_i = y b_i + (1-y) c_i`.  The yield is stated or
estimated by least squares over the classes (:func:`estimate_fine_yield`); a stated yield the
size data contradict is reported (:func:`yield_contradiction`); the three distributions can be
adjusted minimally so that every class balances (:func:`reconcile`); the partition to fines
follows (:func:`partition_to_fines`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError, OptionError, YieldWarning
from ..validation import check_non_negative, check_probability
from .lab_options import LabOptions
from .lab_streams import STREAMS, YIELD_COLUMNS
from .tables import Table

YIELD_MARGIN = 1e-9  # an estimated yield this close to 0 or 1 means one product is empty
MASS_YIELD_TOLERANCE = 0.005  # |stated - implied| fine yield above which two product masses contradict a stated yield


@dataclass(frozen=True)
class YieldEstimate:
    """Least-squares estimate of the fine yield from three size distributions."""

    value: float
    stderr: float
    n_classes: int
    residuals: np.ndarray = field(repr=False)


def estimate_fine_yield(feed, fine, coarse) -> YieldEstimate:
    r"""Least-squares fine yield from three size distributions.

    Fits :math:`a_i - c_i = y (b_i - c_i)` through the origin over the classes by ordinary
    least squares, so :math:`y = \sum (a-c)(b-c) / \sum (b-c)^2` with the usual standard
    error from the residuals (:func:`_ols_through_origin`: statsmodels' ``OLS`` to the bit).

    Examples
    --------
    >>> a = 0.3 * np.array([0.5, 0.3, 0.2]) + 0.7 * np.array([0.1, 0.3, 0.6])
    >>> round(estimate_fine_yield(a, [0.5, 0.3, 0.2], [0.1, 0.3, 0.6]).value, 12)
    0.3
    """
    a, b, c = (np.asarray(v, dtype=float) for v in (feed, fine, coarse))
    design = b - c
    if np.allclose(design, 0):
        raise ValueError("the fine and coarse distributions are identical: the yield cannot be estimated")
    value, stderr, residuals = _ols_through_origin(a - c, design)
    return YieldEstimate(value, stderr if a.size > 1 else np.nan, int(a.size), residuals)


def _ols_through_origin(response: np.ndarray, regressor: np.ndarray) -> tuple[float, float, np.ndarray]:
    """``(slope, its standard error, residuals)`` of one regressor without a constant, by the
    arithmetic of statsmodels' ``OLS(response, regressor).fit()`` (its default ``pinv``
    method: the pseudo-inverse from numpy's SVD, the covariance ``pinv pinv^T`` times the
    residuals' mean square), so the numbers are statsmodels' to the last bit
    (``tests/test_start_up.py``) without its import: statsmodels.api and the formula
    machinery it loads took a quarter of the start-up of ``tromplab fit`` on a lab table."""
    exog = regressor[:, None].conjugate()  # statsmodels' design matrix: one column, copied
    u, singular, vt = np.linalg.svd(exog, False)
    inverse = np.where(singular > 1e-15 * np.maximum.reduce(singular), 1.0 / singular, 0.0)
    pseudo_inverse = np.dot(np.transpose(vt), np.multiply(inverse[:, np.newaxis], np.transpose(u)))
    slope = np.dot(pseudo_inverse, response)
    residuals = response - np.dot(exog, slope)
    with np.errstate(divide="ignore", invalid="ignore"):  # one class: no degree of freedom left
        scale = np.dot(residuals, residuals) / (response.size - 1)
    stderr = np.sqrt(np.diag(np.dot(pseudo_inverse, np.transpose(pseudo_inverse)) * scale))
    return float(slope[0]), float(stderr[0]), residuals


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
    table.refuse_where(
        np.isfinite(values) & ((values <= 0) | (values >= 1)), column, lambda i: f"yield {values[i]:g} outside (0, 1)"
    )
    if np.ptp(given) > 1e-12:
        i = int(np.flatnonzero(np.isfinite(values) & (values != given[0]))[0])
        raise table.error("the yield differs between rows of the same experiment", index=i, column=column)
    return float(given[0])


def node_fine_yield(table: Table, shares: dict, options: LabOptions, mass_yield: float | None = None):
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
    # said, so that a reader knows the partition rests on a yield the streams gave, and how well
    notes.append(
        f"fine yield estimated by least squares from the three streams: {estimate.value:.4f} +/- {estimate.stderr:.4f} "
        f"(standard error, {estimate.n_classes} classes; coarse yield {1 - estimate.value:.4f})"
    )
    return estimate.value, "least-squares estimate", estimate, notes


def mass_implied_yield(streams, totals) -> float | None:
    """Fine yield implied by the masses of both products (fine / (fine + coarse)), when the two
    products (and no feed) are given as masses: the products are then taken as weighed whole."""
    if "feed" in streams or not all(stream in totals and streams[stream][1] == "mass" for stream in ("fine", "coarse")):
        return None
    return totals["fine"] / (totals["fine"] + totals["coarse"])


def complete_streams(table: Table, shares: dict, y: float):
    """All three shares, deriving a missing stream from the balance a = y b + (1-y) c."""
    a, b, c = (shares.get(s) for s in STREAMS)
    if a is None:
        a = y * b + (1 - y) * c
    elif b is None:
        b = (a - (1 - y) * c) / y
    elif c is None:
        c = (a - y * b) / (1 - y)
    return a, b, c


def check_empty_feed(table: Table, a, b, c, class_rows) -> None:
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
    return node_partition(a, b, c, check_probability(fine_yield, "fine_yield"), method)


def node_partition(a, b, c, y: float, method: str) -> np.ndarray:
    """:func:`partition_to_fines` of shares the reader has checked (a stream it computed may dip below 0)."""
    denominator = a if method == "feed" else y * b + (1 - y) * c
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(denominator > 0, y * b / denominator, np.nan)


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
    return reconciled_shares(a, b, c, y, relative_error=relative_error, absolute_error=absolute_error)


def reconciled_shares(a, b, c, y: float, *, relative_error=0.05, absolute_error=0.001):
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
