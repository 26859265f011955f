"""What the measured points say before any fit: the measured cut, slope and efficiency,
the weights, and the inputs a formula takes from the data.

The fits start from these (:mod:`tromplab.curves.curve_fit`, :mod:`tromplab.curves.engine`),
formula (11) takes its measured efficiency from them, and the batch notes an ambiguous
measured cut with them.
"""

from __future__ import annotations

import numpy as np

from ..loading.points import TrompPoints
from .formulas import Formula
from .parameters import Parameter

GRID_SLOPES = -np.geomspace(0.02, 20.0, 41)


def measured_cut_size(points: TrompPoints, level: float = 0.5) -> float:
    """Size where the measured curve first falls through ``level`` (1/2: the measured cut),
    interpolated in log size.

    Where the points never cross the level the size of the point closest to it is returned.
    """
    phi, log_size = points.partition_fine, np.log(points.size)
    above = phi >= level
    for i in range(points.n - 1):
        if above[i] and not above[i + 1]:
            t = (phi[i] - level) / (phi[i] - phi[i + 1])
            return float(np.exp(log_size[i] + t * (log_size[i + 1] - log_size[i])))
    return float(points.size[np.argmin(np.abs(phi - level))])


#: Half-width of the band around 1/2 in which a measured partition is taken as "at the cut"
#: when the measured cut is checked for ambiguity (partitions are often given to 1-2 %).
CUT_BAND = 0.02


#: Ratio of the sizes where the measured curve falls through 1/2 + CUT_BAND and 1/2 -
#: CUT_BAND above which the measured cut is called ambiguous: a curve of Plitt slope m = 1
#: (a flat classifier) gives about 1.1, a plateau at 1/2 over one sieve interval (sqrt 2) 1.5+.
AMBIGUOUS_CUT_RATIO = 1.5


def measured_cut_band(points: TrompPoints) -> tuple[float, float]:
    """Sizes where the measured curve falls through 1/2 + :data:`CUT_BAND` and 1/2 -
    :data:`CUT_BAND`: the range of measured cuts that partitions within the band allow."""
    return measured_cut_size(points, 0.5 + CUT_BAND), measured_cut_size(points, 0.5 - CUT_BAND)


def measured_efficiency(points: TrompPoints, d_cut: float | None = None) -> float:
    """Classifier efficiency eta of the measured curve, used by formula (11).

    Rule: relative sizes ``x = size / d_cut_exp`` with ``d_cut_exp`` from
    :func:`measured_cut_size` (or the ``d_cut`` given); the points are joined linearly in
    ``x``; below the smallest measured size the curve is held at its first value (down to
    ``x = 0``), and ``phi(1) = 1/2`` closes the interval; ``eta_exp`` is the area on
    ``0 <= x <= 1``.
    """
    if d_cut is None:
        d_cut = measured_cut_size(points)
    x = points.size / d_cut
    inside = x < 1.0
    knots_x = np.concatenate(([0.0], x[inside], [1.0]))
    first = points.partition_fine[inside][0] if inside.any() else 0.5
    knots_phi = np.concatenate(([first], points.partition_fine[inside], [0.5]))
    return float(np.trapezoid(knots_phi, knots_x))


def measured_slope(points: TrompPoints, d_cut: float) -> float:
    """Slope d phi / d x near the cut: least-squares line through the points with
    0.1 <= phi <= 0.9 (or the two points nearest the cut)."""
    x = points.size / d_cut
    phi = points.partition_fine
    middle = (phi >= 0.1) & (phi <= 0.9)
    if middle.sum() < 2:
        middle = np.zeros_like(middle)
        middle[np.argsort(np.abs(x - 1.0))[:2]] = True
    slope = np.polyfit(x[middle], phi[middle], 1)[0] if np.ptp(x[middle]) > 0 else -0.5
    return float(np.clip(slope, GRID_SLOPES.min(), GRID_SLOPES.max()))


def measured_starts(size: np.ndarray, partition: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`measured_cut_size` and :func:`measured_slope` of many point sets at once.

    ``size`` (increasing along each row) and ``partition`` are ``(sets, points)`` arrays, one
    point set per row (the bootstrap's resamples of one experiment).  The same rules on
    arrays; the slope is the least-squares line's in closed form, which agrees with
    ``numpy.polyfit`` to rounding.
    """
    size, phi = np.broadcast_arrays(np.asarray(size, dtype=float), np.asarray(partition, dtype=float))
    cut = _measured_cuts(size, phi)
    x = size / cut[:, None]
    middle = (phi >= 0.1) & (phi <= 0.9)
    few = middle.sum(axis=1) < 2
    if few.any():  # the two points nearest the cut instead
        closest = np.argsort(np.abs(x[few] - 1.0), axis=1, kind="stable")[:, :2]
        middle[few] = False
        middle[np.flatnonzero(few)[:, None], closest] = True
    count = middle.sum(axis=1)
    x_mean = np.sum(x * middle, axis=1) / count
    phi_mean = np.sum(phi * middle, axis=1) / count
    spread = np.sum(middle * (x - x_mean[:, None]) ** 2, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = np.sum(middle * (x - x_mean[:, None]) * (phi - phi_mean[:, None]), axis=1) / spread
    slope = np.where(spread > 0, slope, -0.5)
    return cut, np.clip(slope, GRID_SLOPES.min(), GRID_SLOPES.max())


def _measured_cuts(size: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """:func:`measured_cut_size` (level 1/2) of every row of ``(sets, points)`` arrays."""
    rows = np.arange(phi.shape[0])
    log_size = np.log(size)
    above = phi >= 0.5
    crossing = above[:, :-1] & ~above[:, 1:]
    first = np.argmax(crossing, axis=1)
    with np.errstate(all="ignore"):  # rows that never cross 1/2 take the nearest size instead
        t = (phi[rows, first] - 0.5) / (phi[rows, first] - phi[rows, first + 1])
        crossed = np.exp(log_size[rows, first] + t * (log_size[rows, first + 1] - log_size[rows, first]))
    nearest = size[rows, np.argmin(np.abs(phi - 0.5), axis=1)]
    return np.where(crossing.any(axis=1), crossed, nearest)


def measured_efficiencies(size: np.ndarray, partition: np.ndarray) -> np.ndarray:
    """:func:`measured_efficiency` of every row of ``(sets, points)`` arrays (sizes increasing
    along each row): the same trapezoid, its knots beyond the cut moved onto its end ``(1, 1/2)``
    where they add segments of zero width (the sum agrees with one row at a time to rounding)."""
    size, phi = np.broadcast_arrays(np.asarray(size, dtype=float), np.asarray(partition, dtype=float))
    x = size / _measured_cuts(size, phi)[:, None]
    inside = x < 1.0
    first = np.where(inside[:, 0], phi[:, 0], 0.5)  # the sizes increase: the first point is inside if any is
    count = phi.shape[0]
    knots_x = np.column_stack([np.zeros(count), np.where(inside, x, 1.0), np.ones(count)])
    knots_phi = np.column_stack([first, np.where(inside, phi, 0.5), np.full(count, 0.5)])
    return np.trapezoid(knots_phi, knots_x, axis=1)


def formula_contexts(formula: Formula, size: np.ndarray, partitions: np.ndarray) -> dict[str, np.ndarray]:
    """:func:`formula_context` of many partitions of the same sizes at once (rows of ``partitions``)."""
    if formula.context_from_efficiency:
        return {"measured_efficiency": measured_efficiencies(size, partitions)}
    return {}


def parameter_specs(formula: Formula, points: TrompPoints) -> list[Parameter]:
    return list(formula.parameters(points.size))


def normalised_weights(points: TrompPoints) -> np.ndarray:
    """Least-squares weights scaled to mean 1 (all ones when the points carry none), so the
    weighted sums of squares of the fit and of the Fisher screen share one scale."""
    if points.weight is None:
        return np.ones(points.n)
    return points.weight / points.weight.mean()


def formula_context(formula: Formula, points: TrompPoints) -> dict[str, float]:
    """Inputs a formula takes from the measured points rather than from the fit
    (``measured_efficiency`` for formula (11)); empty for the others."""
    if formula.context_from_efficiency:
        return {"measured_efficiency": measured_efficiency(points)}
    return {}


#: Partitions between which a measured point sees the cut region.
CUT_BRACKET = (0.25, 0.75)
#: Start of the warning (of a fit) and note (of an experiment) on a cut the points do not bracket.
CUT_WARNING = "the cut is not bracketed by the data"
#: Reported quantities that rest on where the cut is: without a bracketed cut they get no interval.
CUT_QUANTITIES = ("d_cut", "d50", "d50c", "d25", "d75", "ep", "ep_c", "imperfection", "imperfection_c")


def unbracketed_cut(points: TrompPoints) -> str:
    """Why the measured points do not bracket the cut, in words; empty when they do.

    Rule: the cut is bracketed when some measured partition to fines lies in
    :data:`CUT_BRACKET` (0.25 to 0.75, both included) and the points lie on both sides of
    1/2 (at least one partition >= 1/2 and one <= 1/2).  Otherwise the cut size, and with it
    d50, d50c, d25, d75 and Ep, is read off the formula's shape beyond or between the
    measured points, not off measurements.

    Examples
    --------
    >>> unbracketed_cut(TrompPoints("gas cyclone", [4.1, 8.2, 16.5, 33.0], [0.2, 0.08, 0.02, 0.004]))
    'no measured partition lies between 0.25 and 0.75, and every one lies below 1/2'
    >>> unbracketed_cut(TrompPoints("sharp screen", [0.3, 0.6, 0.85, 1.2], [0.99, 0.93, 0.05, 0.01]))
    'no measured partition lies between 0.25 and 0.75: the partition falls from 0.93 to 0.05 between two adjacent measured sizes, and where in between the cut lies depends on the formula'
    >>> unbracketed_cut(TrompPoints("screen", [10, 20, 40, 80], [0.95, 0.7, 0.3, 0.05]))
    ''
    """
    low, high = CUT_BRACKET
    phi = points.partition_fine
    inside = np.any((phi >= low) & (phi <= high))
    two_sided = np.any(phi >= 0.5) and np.any(phi <= 0.5)
    if inside and two_sided:
        return ""
    side = "above" if phi.min() > 0.5 else "below"
    if inside:
        return f"every measured partition lies {side} 1/2"
    if not two_sided:
        return f"no measured partition lies between {low:g} and {high:g}, and every one lies {side} 1/2"
    last_above = np.flatnonzero(phi > 0.5)[-1] if np.any(phi > 0.5) else 0
    a, b = phi[last_above], phi[min(last_above + 1, points.n - 1)]
    return (
        f"no measured partition lies between {low:g} and {high:g}: the partition falls from {a:.3g} to {b:.3g} "
        "between two adjacent measured sizes, and where in between the cut lies depends on the formula"
    )
