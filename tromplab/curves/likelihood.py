r"""What the inference of every curve shares, size or density: the profile-likelihood root
search, the Hessian by central differences and the check of a value on its bound.

A profile-likelihood limit is where an *excess* crosses zero: the profile's rise over its
minimum (re-optimised over the other parameters with one held), scaled, less the level's
threshold.  It is found in two stages, every row (a fit, a quantity and a side) at once:

1. :func:`step_out` - from the estimate outwards by a first step, doubling, to the first
   value with a positive excess (a bracket), or to the edge of the search range (no limit);
2. :func:`chandrupatla` - Chandrupatla's (1997) root search within each bracket: inverse
   quadratic interpolation where it is safe, bisection otherwise.

The size curves (:func:`tromplab.curves.batched.profile_limits`, the sum of squares'
F test) and the density curves (:mod:`tromplab.density.profiles`, the binomial deviance;
:func:`tromplab.density.fitting.profile_interval`, least squares on shares) give the
excess as a function of the values of the rows it is asked about, and keep their own warm
starts; the search itself is this one.  This module imports numpy only.

References
----------
.. [Chandrupatla1997] Chandrupatla T.R. (1997). A new hybrid quadratic/bisection algorithm for
   finding the zero of a nonlinear function without using derivatives. *Advances in
   Engineering Software* 28(3), 145-149.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

#: Doublings of the first step before a side is given up (any finite range is crossed in far fewer).
MAX_DOUBLINGS = 60
#: Relative tolerance of a root (the absolute one, in units of the value, is the caller's).
ROOT_RELATIVE_TOLERANCE = 1e-14
#: Iterations of the root search (it converges in about ten).
MAX_ROOT_ITERATIONS = 100

#: ``excess(rows, values)``: the excess at ``values`` of the rows ``rows`` (indices into the
#: arrays the search was given); NaN where no profile exists at all (the side ends there).
Excess = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Bracket:
    """Where :func:`step_out` stopped on each row.

    Attributes
    ----------
    inner, outer : ndarray
        The last value with an excess at or below zero (the estimate at first) and the first
        with a positive one; ``outer`` NaN where the range ended (or the excess was NaN) first.
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


def step_out(excess: Excess, centre, edge, direction, step, at_centre, *, max_doublings: int = MAX_DOUBLINGS) -> Bracket:
    """From ``centre`` towards ``edge`` by ``step``, doubling, to the first value with a positive excess.

    Parameters
    ----------
    excess : callable
        ``excess(rows, values)`` (:data:`Excess`).
    centre, edge : ndarray
        The estimate and the end of the search range of each row.
    direction : ndarray
        +1 or -1: the side of the estimate each row searches.
    step : ndarray
        The first step (positive), in the units of the value.
    at_centre : ndarray
        The excess at the estimate (at or below zero).
    max_doublings : int
        Values tried on a row before it is given up (without a bracket).

    Returns
    -------
    Bracket
        A row that reaches ``edge`` is tried there (exactly) and stops.

    Examples
    --------
    >>> bracket = step_out(lambda rows, x: x**2 - 2.0, np.array([0.0]), np.array([10.0]), np.array([1.0]),
    ...                    np.array([0.5]), np.array([-2.0]))
    >>> float(bracket.inner[0]), float(bracket.outer[0])
    (1.0, 2.0)
    """
    centre, edge, direction = (np.asarray(part, dtype=float) for part in (centre, edge, direction))
    step = np.array(step, dtype=float)
    count = centre.size
    inner, outer = centre.copy(), np.full(count, np.nan)
    inner_excess, outer_excess = np.array(at_centre, dtype=float), np.full(count, np.nan)
    active = np.ones(count, dtype=bool)
    for _ in range(max_doublings):
        if not active.any():
            break
        at = np.flatnonzero(active)
        value = centre[at] + direction[at] * step[at]
        reached = (value - edge[at]) * direction[at] >= 0
        value = np.where(reached, edge[at], value)
        found = excess(at, value)
        crossed = found > 0
        outer[at[crossed]], outer_excess[at[crossed]] = value[crossed], found[crossed]
        moving = ~crossed & ~reached & ~np.isnan(found)
        inner[at[moving]], inner_excess[at[moving]] = value[moving], found[moving]
        step[at] *= 2.0
        active[at[~moving]] = False
    return Bracket(inner, outer, inner_excess, outer_excess)


def chandrupatla(
    excess: Excess, a, b, fa, fb, tolerance, *, excess_tolerance=0.0, max_iterations: int = MAX_ROOT_ITERATIONS
) -> np.ndarray:
    """The zero of the excess between ``a`` and ``b`` (excesses ``fa <= 0 < fb``) of every row at once.

    Chandrupatla's inverse quadratic interpolation, bisection where it is not safe.  A row
    ends when its bracket is narrower than about ``2 tolerance`` plus
    :data:`ROOT_RELATIVE_TOLERANCE` relative, or when the better end's excess is within
    ``excess_tolerance`` of zero; the better end (the smaller excess) is returned.

    Parameters
    ----------
    excess : callable
        ``excess(rows, values)`` (:data:`Excess`), ``rows`` indexing ``a``.
    a, b, fa, fb : ndarray
        The brackets (:attr:`Bracket.inner`, :attr:`Bracket.outer` and their excesses).
    tolerance : ndarray
        Absolute tolerance of each row's root, in the units of the value.
    excess_tolerance : float or ndarray
        An excess this close to zero is a root (0: only an exact zero).
    max_iterations : int
        Evaluations per row at most; a row not converged by then is NaN.

    Examples
    --------
    >>> root = chandrupatla(lambda rows, x: x**2 - 2.0, np.array([1.0]), np.array([2.0]), np.array([-1.0]),
    ...                     np.array([2.0]), np.array([1e-12]))
    >>> round(float(root[0]), 12)
    1.414213562373
    """
    a, b, fa, fb = (np.array(part, dtype=float) for part in (a, b, fa, fb))
    count = a.size
    tolerance = np.broadcast_to(np.asarray(tolerance, dtype=float), (count,))
    excess_tolerance = np.broadcast_to(np.asarray(excess_tolerance, dtype=float), (count,))
    c, fc = a.copy(), fa.copy()
    t = np.full(count, 0.5)
    found = np.full(count, np.nan)
    active = np.arange(count)
    for _ in range(max_iterations):
        xt = a + t * (b - a)
        ft = excess(active, xt)
        same = np.sign(ft) == np.sign(fa)
        c, fc = np.where(same, a, b), np.where(same, fa, fb)
        b, fb = np.where(same, b, a), np.where(same, fb, fa)
        a, fa = xt, ft
        closer = np.abs(fa) < np.abs(fb)
        xm, fm = np.where(closer, a, b), np.where(closer, fa, fb)
        with np.errstate(divide="ignore"):  # b == c: the bracket has closed
            limit = (2 * ROOT_RELATIVE_TOLERANCE * np.abs(xm) + tolerance[active]) / np.abs(b - c)
        done = (np.abs(fm) <= excess_tolerance[active]) | (limit > 0.5)
        found[active[done]] = xm[done]
        keep = ~done
        if not keep.any():
            break
        with np.errstate(all="ignore"):
            xi, phi = (a - b) / (c - b), (fa - fb) / (fc - fb)
            quadratic = (phi**2 < xi) & ((1 - phi) ** 2 < 1 - xi)
            interpolated = fa / (fb - fa) * fc / (fb - fc) + (c - a) / (b - a) * fa / (fc - fa) * fb / (fc - fb)
        t = np.clip(np.where(quadratic, interpolated, 0.5), limit, 1 - limit)
        a, b, c, fa, fb, fc, t, active = (part[keep] for part in (a, b, c, fa, fb, fc, t, active))
    return found


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
