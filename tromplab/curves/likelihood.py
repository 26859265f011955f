r"""What the inference of every curve shares, size or density: the profile-likelihood root
search, the Hessian by central differences and the check of a value on its bound.

A profile-likelihood limit is where an *excess* crosses zero: the profile's rise over its
minimum (re-optimised over the other parameters with one held), scaled, less the level's
threshold.  It is found in two stages, every row (a fit, a quantity and a side) at once, in
distances ``t >= 0`` from the estimate along the row's side:

1. :func:`step_out` - from the estimate outwards by a first step, doubling, to the first
   value with a positive excess (a bracket), or to the edge of the search range (no limit);
2. :func:`regula_falsi` - the Illinois variant of the false position within each bracket
   (Dowell & Jarratt 1971): the secant through the bracket's ends, the weight of an end that
   stays twice in a row halved, bisection where the secant leaves the bracket; or, where the
   excess's slope comes with it, :func:`newton_in_bracket` - Newton's method kept within the
   bracket (the density curves' binomial profiles, whose slope is known at no cost).

The size curves (:func:`tromplab.curves.batched.profile_limits`, the sum of squares' F test,
on :math:`\sqrt{S - S_{min}}`, linear in the parameter for a quadratic profile) and the
density curves (:mod:`tromplab.density.profiles`, the binomial deviance;
:func:`tromplab.density.fitting.profile_interval`, least squares on shares, which closes its
bracket with Brent's method) give the excess as a function of the values of the rows it is
asked about, and keep their own warm starts; the search itself is this one.  This module
imports numpy only.

References
----------
.. [Dowell1971] Dowell M., Jarratt P. (1971). A modified regula falsi method for computing
   the root of an equation. *BIT Numerical Mathematics* 11, 168-174.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

#: Doublings of the first step before a side is given up (any finite range is crossed in far fewer).
MAX_DOUBLINGS = 60
#: Iterations of the root search within a bracket.
MAX_ROOT_ITERATIONS = 60

#: ``excess(rows, values)``: the excess at ``values`` of the rows ``rows`` (indices into the
#: arrays the search was given); NaN, while stepping out, where no profile exists at all (the
#: side ends there without a limit).
Excess = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Bracket:
    """Where :func:`step_out` stopped on each row, in distances from the estimate.

    Attributes
    ----------
    inner, outer : ndarray
        The last distance with an excess at or below zero (0, the estimate, at first) and the
        first with a positive one; ``outer`` NaN where the range ended (or the excess was NaN) first.
    inner_excess, outer_excess : ndarray
        The excess at ``inner`` and at ``outer``.
    """

    inner: np.ndarray
    outer: np.ndarray
    inner_excess: np.ndarray
    outer_excess: np.ndarray

    @property
    def closed(self) -> np.ndarray:
        """True where a positive excess was found: the rows with a root between inner and outer."""
        return np.isfinite(self.outer)

    def take(self, rows: np.ndarray) -> Bracket:
        """The brackets of these rows."""
        return Bracket(self.inner[rows], self.outer[rows], self.inner_excess[rows], self.outer_excess[rows])


def step_out(excess: Excess, centre, direction, room, step, at_centre, *, max_doublings: int = MAX_DOUBLINGS) -> Bracket:
    """From ``centre`` outwards by ``step``, doubling, to the first value with a positive excess.

    Parameters
    ----------
    excess : callable
        ``excess(rows, values)`` (:data:`Excess`), asked at ``centre + direction t``.
    centre : ndarray
        The estimate of each row.
    direction : ndarray
        +1 or -1: the side of the estimate each row searches.
    room : ndarray
        The distance from the estimate to the end of the search range (may be infinite).
    step : ndarray
        The first step (positive), in the units of the value.
    at_centre : ndarray
        The excess at the estimate (below zero).
    max_doublings : int
        Values tried on a row before it is given up (without a bracket).

    Returns
    -------
    Bracket
        Distances from ``centre``; a row that reaches ``room`` is tried there and stops.

    Examples
    --------
    >>> bracket = step_out(lambda rows, x: x**2 - 2.0, np.array([0.0]), np.array([1.0]), np.array([10.0]),
    ...                    np.array([0.5]), np.array([-2.0]))
    >>> float(bracket.inner[0]), float(bracket.outer[0])
    (1.0, 2.0)
    """
    centre, direction, room = (np.asarray(part, dtype=float) for part in (centre, direction, room))
    count = centre.size
    t = np.minimum(np.asarray(step, dtype=float), room)
    inner, outer = np.zeros(count), np.full(count, np.nan)
    inner_excess, outer_excess = np.array(at_centre, dtype=float), np.full(count, np.nan)
    active = np.ones(count, dtype=bool)
    for _ in range(max_doublings):
        work = np.flatnonzero(active)
        if not work.size:
            break
        found = excess(work, centre[work] + direction[work] * t[work])
        crossed = found >= 0
        short = found < 0
        outer[work[crossed]], outer_excess[work[crossed]] = t[work[crossed]], found[crossed]
        inner[work[short]], inner_excess[work[short]] = t[work[short]], found[short]
        at_edge = t[work] >= room[work]
        active[work[~short | at_edge]] = False
        grow = work[short & ~at_edge]
        t[grow] = np.minimum(2.0 * t[grow], room[grow])
    return Bracket(inner, outer, inner_excess, outer_excess)


def regula_falsi(
    excess: Excess,
    centre,
    direction,
    bracket: Bracket,
    width,
    *,
    excess_tolerance=0.0,
    max_iterations: int = MAX_ROOT_ITERATIONS,
) -> np.ndarray:
    """The distance from ``centre`` at which the excess crosses zero within each (closed) bracket, every row at once.

    The Illinois variant of the false position: the secant through the bracket's ends, the
    end that stays twice in a row weighted by half, bisection where the secant falls outside
    the bracket.  A row ends when its bracket is narrower than ``width`` or the last excess is
    within ``excess_tolerance`` of zero; the end with the smaller excess is returned (also
    for a row not closed within ``max_iterations``).

    Parameters
    ----------
    excess : callable
        ``excess(rows, values)`` (:data:`Excess`), ``rows`` indexing the bracket, asked at
        ``centre + direction t``; an infinite excess counts as beyond the root.
    centre, direction : ndarray
        As :func:`step_out` was given them, for the rows of ``bracket``.
    bracket : Bracket
        Closed brackets (:attr:`Bracket.closed`).
    width : ndarray
        The bracket's width at which a row has converged, in the units of the value.
    excess_tolerance : float or ndarray
        An excess this close to zero ends a row (0: only an exact zero).
    max_iterations : int
        Evaluations per row at most.

    Examples
    --------
    >>> bracket = Bracket(np.array([1.0]), np.array([2.0]), np.array([-1.0]), np.array([2.0]))
    >>> t = regula_falsi(lambda rows, x: x**2 - 2.0, np.array([0.0]), np.array([1.0]), bracket, np.array([1e-14]))
    >>> round(float(t[0]), 12)
    1.414213562373
    """
    centre, direction = np.asarray(centre, dtype=float), np.asarray(direction, dtype=float)
    ends = _Shrinking(bracket)
    width = np.broadcast_to(np.asarray(width, dtype=float), (ends.count,))
    excess_tolerance = np.broadcast_to(np.asarray(excess_tolerance, dtype=float), (ends.count,))
    solving = np.isfinite(ends.t_high)
    for _ in range(max_iterations):
        work = np.flatnonzero(solving)
        if not work.size:
            break
        trial = ends.false_position(work)
        h = excess(work, centre[work] + direction[work] * trial)
        ends.shrink(work, trial, h)
        closed = (ends.t_high[work] - ends.t_low[work] <= width[work]) | (np.abs(h) <= excess_tolerance[work])
        solving[work[closed]] = False
    return np.where(np.isfinite(ends.t_high), ends.nearer_end(slice(None)), np.nan)


def newton_in_bracket(
    excess_and_slope,
    centre,
    direction,
    bracket: Bracket,
    width,
    *,
    max_iterations: int = MAX_ROOT_ITERATIONS,
) -> np.ndarray:
    """The distance from ``centre`` at which the excess crosses zero within each (closed) bracket,
    every row at once, by Newton's method kept within the bracket: for an excess whose slope
    comes with its value (a profile's, whose slope in the held value is the deviance's partial
    derivative at the re-optimised point: the envelope theorem).

    The first trial is the secant of the bracket's ends; each next one Newton's step from the
    last trial, or, where that step leaves the bracket (from the side of a convex excess that
    it overshoots), the Illinois step of :func:`regula_falsi`, which soon brings a trial to the
    other side, from which Newton's steps stay within.  The bracket
    shrinks to every trial as in :func:`regula_falsi`.  A row ends when Newton's step is
    shorter than half ``width`` (its end point is returned: Newton's error is about the square
    of that step) or the bracket is narrower than ``width`` (the end with the smaller excess).

    Parameters
    ----------
    excess_and_slope : callable
        ``excess_and_slope(rows, values)`` -> the excess at ``values`` (as :data:`Excess`) and
        its derivative in the value (NaN where unknown).
    centre, direction, bracket, width
        As for :func:`regula_falsi`.
    max_iterations : int
        Evaluations per row at most.

    Examples
    --------
    >>> bracket = Bracket(np.array([1.0]), np.array([2.0]), np.array([-1.0]), np.array([2.0]))
    >>> t = newton_in_bracket(lambda rows, x: (x**2 - 2.0, 2.0 * x), np.array([0.0]), np.array([1.0]), bracket, np.array([1e-14]))
    >>> round(float(t[0]), 12)
    1.414213562373
    """
    centre, direction = np.asarray(centre, dtype=float), np.asarray(direction, dtype=float)
    ends = _Shrinking(bracket)
    width = np.broadcast_to(np.asarray(width, dtype=float), (ends.count,))
    solving = np.isfinite(ends.t_high)
    root = np.full(ends.count, np.nan)
    trial = ends.false_position(slice(None))
    for _ in range(max_iterations):
        work = np.flatnonzero(solving)
        if not work.size:
            break
        at = trial[work]
        h, slope = excess_and_slope(work, centre[work] + direction[work] * at)
        ends.shrink(work, at, h)
        with np.errstate(all="ignore"):
            newton = at - h / (direction[work] * slope)
        inside = np.isfinite(newton) & (newton > ends.t_low[work]) & (newton < ends.t_high[work])
        settled = np.isfinite(newton) & (np.abs(newton - at) <= 0.5 * width[work])  # also on an end of the bracket
        narrow = ~settled & ((ends.t_high[work] - ends.t_low[work] <= width[work]) | (h == 0))
        root[work[settled]] = newton[settled]
        root[work[narrow]] = ends.nearer_end(work[narrow])
        trial[work] = np.where(inside, newton, ends.false_position(work))
        solving[work[settled | narrow]] = False
    left = np.flatnonzero(solving)  # not closed within max_iterations: the end with the smaller excess
    root[left] = ends.nearer_end(left)
    return root


class _Shrinking:
    """The brackets of :func:`regula_falsi` and :func:`newton_in_bracket` as they shrink: each
    row's ends (distances ``t_low`` below the root, ``t_high`` beyond it), their excesses and
    which end moved last (-1 the low one, +1 the high one), for the Illinois weighting."""

    def __init__(self, bracket: Bracket):
        self.t_low, self.t_high = bracket.inner.copy(), bracket.outer.copy()
        self.h_low, self.h_high = bracket.inner_excess.copy(), bracket.outer_excess.copy()
        self.count = self.t_low.size
        self.last_side = np.zeros(self.count)

    def false_position(self, rows) -> np.ndarray:
        """The secant's zero within each bracket of ``rows``, or its midpoint where the secant leaves it."""
        t_low, t_high, h_low, h_high = self.t_low[rows], self.t_high[rows], self.h_low[rows], self.h_high[rows]
        with np.errstate(all="ignore"):
            trial = t_low - h_low * (t_high - t_low) / (h_high - h_low)
        return np.where(np.isfinite(trial) & (trial > t_low) & (trial < t_high), trial, 0.5 * (t_low + t_high))

    def shrink(self, rows: np.ndarray, trial: np.ndarray, h: np.ndarray) -> None:
        """Each bracket of ``rows`` shrunk to its ``trial`` (excess ``h``): the end on its side
        moves there; where the same end moved twice in a row the other's excess is halved."""
        below = h < 0
        low_rows, high_rows = rows[below], rows[~below]
        self.t_low[low_rows], self.h_low[low_rows] = trial[below], h[below]
        self.t_high[high_rows], self.h_high[high_rows] = trial[~below], h[~below]
        self.h_high[low_rows[self.last_side[low_rows] < 0]] *= 0.5
        self.h_low[high_rows[self.last_side[high_rows] > 0]] *= 0.5
        self.last_side[low_rows], self.last_side[high_rows] = -1.0, 1.0

    def nearer_end(self, rows) -> np.ndarray:
        """The end of each bracket of ``rows`` with the smaller excess."""
        return np.where(np.abs(self.h_high[rows]) <= np.abs(self.h_low[rows]), self.t_high[rows], self.t_low[rows])


def central_hessian(function: Callable[[np.ndarray], float], x: np.ndarray, steps: np.ndarray) -> np.ndarray:
    r"""The Hessian of ``function`` at ``x`` by central differences with the steps ``steps``.

    .. math:: H_{ij} = \frac{f(x + h_i + h_j) - f(x + h_i - h_j) - f(x - h_i + h_j) + f(x - h_i - h_j)}{4 h_i h_j}

    Examples
    --------
    >>> hessian = central_hessian(lambda v: v[0] ** 2 + 3 * v[0] * v[1], np.array([1.0, 2.0]), np.array([1e-3, 1e-3]))
    >>> np.round(hessian, 9).tolist()
    [[2.0, 3.0], [3.0, 0.0]]
    """
    size = x.size
    hessian = np.empty((size, size))
    unit = np.eye(size)
    for i in range(size):
        for j in range(i, size):
            di, dj = unit[i] * steps[i], unit[j] * steps[j]
            value = (function(x + di + dj) - function(x + di - dj) - function(x - di + dj) + function(x - di - dj)) / (
                4 * steps[i] * steps[j]
            )
            hessian[i, j] = hessian[j, i] = value
    return hessian


def on_bound(value: float, bound: float, *, rtol: float = 1e-5, atol_at_zero: float = 1e-8, atol: float | None = None) -> bool:
    """Whether a fitted value sits on a bound: within ``rtol`` of it relative to the bound (an
    absolute ``atol_at_zero`` when the bound is 0, as for a bypass), or within ``atol`` of it
    where that is given (a share, as a density curve's limit, whose bounds are 0..1).
    Relative by default, so a cut size is judged the same in metres as in micrometres
    (numpy.isclose's absolute 1e-8 put every cut below 1e-8 on its bound).

    Examples
    --------
    >>> on_bound(7.3e-10, 7.07e-12), on_bound(1e-9, 0.0), on_bound(0.9999995, 1.0, atol=1e-6)
    (False, True, True)
    """
    if atol is not None:
        tolerance = atol
    else:
        tolerance = rtol * abs(bound) if bound != 0 else atol_at_zero
    return abs(value - bound) <= tolerance
