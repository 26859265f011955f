"""Brent's bracketed root search on many brackets at once, step for step as :func:`scipy.optimize.brentq`.

:func:`brent_roots` runs the iteration of :func:`scipy.optimize.brentq` (Brent 1973, as
scipy implements it: inverse quadratic interpolation or a secant step when it is short
enough, bisection otherwise) on arrays, one element per bracket: every element takes the
steps, in the same floating-point operations, that :func:`scipy.optimize.brentq` takes on
its bracket, so where the function's values are the same numbers the roots are the same to
the last bit (``tests/test_roots.py`` compares them).  One call replaces a Python loop of
root searches: the interpreter's overhead is paid once per step for all brackets, not per
bracket and step.

References
----------
Brent, R. P. (1973). *Algorithms for Minimization without Derivatives*, ch. 4. Prentice-Hall.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

#: The relative tolerance :func:`scipy.optimize.brentq` uses by default (four machine epsilons).
BRENT_RTOL = 4.0 * np.finfo(float).eps


def brent_roots(
    function: Callable[[np.ndarray, np.ndarray], np.ndarray],
    low,
    high,
    *,
    xtol: float = 2e-12,
    rtol: float = BRENT_RTOL,
    maxiter: int = 100,
) -> tuple[np.ndarray, np.ndarray]:
    """Roots of ``function`` in the brackets ``[low, high]``, each found as ``brentq`` finds it.

    Parameters
    ----------
    function : callable
        ``function(x, rows) -> values``: the function of each bracket ``rows`` (indices into
        ``low``) at the points ``x`` (one per row), evaluated elementwise.
    low, high : array_like
        The ends of the brackets (1-D, one per root), as ``brentq``'s ``a`` and ``b``.
    xtol, rtol, maxiter : float, float, int
        As for :func:`scipy.optimize.brentq` (and its defaults).

    Returns
    -------
    roots : ndarray
        The root of each bracket (nan where ``found`` is False).
    found : ndarray of bool
        False where ``brentq`` would not return a root: the function has the same sign at
        both ends or is zero at one of them (which ``brentq`` returns without a step; left to
        the caller), a value is nan (``brentq`` raises), or the search did not converge in
        ``maxiter`` steps (``brentq`` raises).  Such brackets are for the caller to search
        one by one.

    Examples
    --------
    >>> import scipy.optimize
    >>> targets = np.array([2.0, 3.0, 10.0])
    >>> roots, found = brent_roots(lambda x, rows: x * x - targets[rows], [0.0, 0.0, 0.0], [4.0, 4.0, 4.0])
    >>> bool(found.all()), [float(r) == scipy.optimize.brentq(lambda x: x * x - t, 0.0, 4.0) for r, t in zip(roots, targets)]
    (True, [True, True, True])
    """
    low, high = np.asarray(low, dtype=float), np.asarray(high, dtype=float)
    rows = np.arange(low.size)
    f_low, f_high = function(low, rows).tolist(), function(high, rows).tolist()
    roots, found = np.full(low.size, np.nan), np.zeros(low.size, dtype=bool)
    # brentq's own checks before the first step: numbers, of opposite signs (neither zero); of
    # two non-zero numbers the sign bits differ where one is negative and the other not
    searches = [
        _BrentSearch(row, a, b, fa, fb, xtol, rtol)
        for row, a, b, fa, fb in zip(rows.tolist(), low.tolist(), high.tolist(), f_low, f_high)
        if fa != 0 and fb != 0 and (fa < 0) != (fb < 0) and not (math.isnan(fa) or math.isnan(fb))
    ]
    for _ in range(maxiter):
        trials, open_ = [], []
        for search in searches:
            trial = search.next_point()
            if trial is None:
                roots[search.row], found[search.row] = search.x_current, True
            else:
                trials.append(trial)
                open_.append(search)
        if not open_:
            break
        values = function(np.array(trials), np.array([search.row for search in open_])).tolist()
        searches = []
        for search, trial, value in zip(open_, trials, values):
            if not math.isnan(value):  # brentq raises at a nan: left to the caller
                search.x_current, search.f_current = trial, value
                searches.append(search)
    return roots, found


class _BrentSearch:
    """One bracket's iterates, brentq's ``xpre, xcur, fpre, fcur, xblk, fblk, spre, scur``, in
    Python floats (the same double-precision operations as brentq's C loop); ``row`` is the
    bracket's place in :func:`brent_roots`."""

    __slots__ = (
        "row",
        "x_previous",
        "x_current",
        "f_previous",
        "f_current",
        "x_block",
        "f_block",
        "s_previous",
        "s_current",
        "xtol",
        "rtol",
    )

    def __init__(self, row: int, low: float, high: float, f_low: float, f_high: float, xtol: float, rtol: float):
        self.row, self.xtol, self.rtol = row, xtol, rtol
        self.x_previous, self.x_current, self.f_previous, self.f_current = low, high, f_low, f_high
        self.x_block = self.f_block = self.s_previous = self.s_current = 0.0

    def next_point(self) -> float | None:
        """One pass of brentq's loop body up to its next evaluation: the point to evaluate next
        (its value then goes to ``x_current, f_current``), or None when the search has converged
        (its root is then ``x_current``).  The values are never nan, so brentq's sign bits of two
        non-zero values differ where one is negative and the other not."""
        xp, xc, fp, fc = self.x_previous, self.x_current, self.f_previous, self.f_current
        xb, fb, s_previous, s_current = self.x_block, self.f_block, self.s_previous, self.s_current
        if fp != 0 and fc != 0 and (fp < 0) != (fc < 0):  # the root lies between xp and xc
            xb, fb = xp, fp
            s_previous = s_current = xc - xp
        if abs(fb) < abs(fc):  # keep the better end as the current point
            xp, xc, xb = xc, xb, xc
            fp, fc, fb = fc, fb, fc
        delta = (self.xtol + self.rtol * abs(xc)) / 2
        bisection = (xb - xc) / 2
        if fc == 0 or abs(bisection) < delta:
            self.x_current = xc
            return None
        step = bisection
        if abs(s_previous) > delta and abs(fc) < abs(fp):
            trial = _interpolated_step(xp, xc, xb, fp, fc, fb)
            if 2 * abs(trial) < min(abs(s_previous), 3 * abs(bisection) - delta):  # a short step: taken
                s_previous, step = s_current, trial
            else:
                s_previous = bisection
        else:
            s_previous = bisection
        self.x_block, self.f_block, self.s_previous, self.s_current = xb, fb, s_previous, step
        self.x_previous, self.f_previous = xc, fc
        return xc + step if abs(step) > delta else xc + (delta if bisection > 0 else -delta)


def _interpolated_step(xp: float, xc: float, xb: float, fp: float, fc: float, fb: float) -> float:
    """brentq's trial step from the current point: the secant's when the previous point is the
    block's end, else inverse quadratic interpolation's; nan where brentq's C arithmetic divides
    by zero (an infinite or nan step, which it then refuses as this one is refused)."""
    try:
        if xp == xb:
            return -fc * (xc - xp) / (fc - fp)
        slope_previous = (fp - fc) / (xp - xc)
        slope_block = (fb - fc) / (xb - xc)
        return -fc * (fb * slope_block - fp * slope_previous) / (slope_block * slope_previous * (fb - fp))
    except ZeroDivisionError:
        return math.nan
