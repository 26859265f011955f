r"""Profile-likelihood limits of rho50, Ep and the imperfection of many binomial fits at once.

Each request is one fitted curve and one quantity: the curve is written in its indices
``(rho50, Ep[, l, h])`` (``(rho50, I[, l, h])`` for the imperfection, ``Ep = I (rho50 - 1)``,
through :meth:`~tromplab.density.registry.DensityCurve.from_indices`), the quantity is held at
a value and the other parameters re-optimised (:func:`~tromplab.density.batch.minimise_deviance`,
from the optimum of the previous value and, for a curve with limits, also from the
estimate).  A limit is where the excess :math:`(D(q) - \hat D)/\phi - c` crosses zero
(``phi`` the scale and ``c`` the threshold the caller gives).  Both sides of every request
go together: from the estimate a step of a quarter of Ep (of I) and then twice as far each
time until the excess is positive (a bracket) or the search range ends (no limit); within
each bracket regula falsi (Illinois), every side at once, converges to the last digits.  The
search is the one every curve's profile uses, size or density
(:func:`tromplab.curves.likelihood.step_out` and :func:`~tromplab.curves.likelihood.regula_falsi`);
this module gives it the excess of the re-optimised deviance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..curves.likelihood import regula_falsi, step_out
from .batch import TracerStack, centre_and_scale, minimise_deviance, partition_at
from .registry import QUARTILES

#: The excess where no curve with a finite likelihood exists at a value: beyond any limit.
BEYOND = 1e300
#: Relative and absolute (in units of the first step) tolerances of the limits.
ROOT_RELATIVE_TOLERANCE = 1e-14
ROOT_STEP_TOLERANCE = 1e-11
#: Iterations of the root search (it converges in about fifteen).
MAX_ROOT_ITERATIONS = 100


@dataclass(frozen=True)
class ProfileRequests:
    """The profiles to trace, one row per fitted curve and quantity (all of one curve).

    Attributes
    ----------
    stack : TracerStack
        The tracer counts of each row.
    imperfection : ndarray of bool
        True where the quantity is the imperfection (the second index is ``I``, not ``Ep``).
    position : ndarray of int
        The index held: 0 (rho50) or 1 (Ep or I).
    centre : ndarray
        (rows, parameters): the estimate in the indices.
    lower, upper : ndarray
        (rows, parameters): the search range of each index.
    best : ndarray
        The fit's deviance.
    scale, threshold : ndarray
        The deviance's scale (1, or the quasi-binomial scale) and the excess's threshold.
    step : ndarray
        The first step out from the estimate.
    curve : ndarray of int or None
        Which of the curves :func:`profile_limits` is given each row is (None: the one curve).
    """

    stack: TracerStack
    imperfection: np.ndarray
    position: np.ndarray
    centre: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    best: np.ndarray
    scale: np.ndarray
    threshold: np.ndarray
    step: np.ndarray
    curve: np.ndarray | None = None


def curve_of_indices(curve, q: np.ndarray, imperfection: np.ndarray) -> dict[str, np.ndarray]:
    """The curve's parameters (each (rows, 1)) from the indices ``q`` (rows, parameters), as ``from_indices`` makes them."""
    rho50, second = q[:, 0:1], q[:, 1:2]
    ep = np.where(imperfection[:, None], second * (rho50 - 1.0), second)
    if not curve.has_limits:
        return {"rho50": rho50, "ep": ep}
    light, heavy = q[:, 2:3], q[:, 3:4]
    span = heavy - light
    form = curve.form
    centre, scale_c = centre_and_scale(form)
    q25, q50, q75 = (form.quantile((p - light) / span) for p in QUARTILES)
    ep_c = ep * 2.0 * scale_c / (q75 - q25)
    rho_c = rho50 - ep_c * (q50 - centre) / scale_c
    return {"rho_c": rho_c, "ep_c": ep_c, "light_limit": light, "heavy_limit": heavy}


def _ordered(values: np.ndarray, order: np.ndarray) -> np.ndarray:
    return np.take_along_axis(values, order, axis=1)


class _Profiles:
    """Both sides of every request: row ``i`` of a side is request ``i % requests``."""

    def __init__(self, curves, requests: ProfileRequests):
        self.curves, self.requests = curves, requests
        self.has_limits = curves[0].has_limits
        if any(curve.has_limits != self.has_limits for curve in curves):
            raise ValueError("the profiles searched together are all of curves with limits or all of plain curves")
        count = len(requests.best)
        self.curve = np.zeros(count, dtype=int) if requests.curve is None else np.asarray(requests.curve)
        self.request = np.tile(np.arange(count), 2)
        self.direction = np.repeat([-1.0, 1.0], count)
        self.warm = requests.centre[self.request].copy()  # the optimum at the last value of each side

    def excess(self, sides: np.ndarray, value: np.ndarray) -> np.ndarray:
        """The excess of the re-optimised deviance at ``value`` on each of ``sides`` (warm starts updated).

        A curve with limits is re-optimised from two starts, the last optimum of the side and
        the estimate, both in one minimisation (rows stacked), the lower deviance kept (the
        last optimum among equals)."""
        r = self.requests
        count = len(sides)
        starts = [self.warm[sides]] + ([r.centre[self.request[sides]]] if self.has_limits else [])
        request = np.tile(self.request[sides], len(starts))
        stack = r.stack.take(request)
        # the held index is put first (rho50 and Ep or I swap places), so that the minimiser
        # sees one column held in every row and takes no derivative along it
        order = np.tile(np.arange(r.centre.shape[1]), (len(request), 1))
        order[:, [0, 1]] = np.where(r.position[request][:, None] == 1, [1, 0], [0, 1])
        held = np.tile(value, len(starts))
        lower, upper, start = (_ordered(part, order) for part in (r.lower[request], r.upper[request], np.concatenate(starts)))
        lower[:, 0] = upper[:, 0] = start[:, 0] = held
        imperfection, curve = r.imperfection[request], self.curve[request]

        def partition(x, rows):
            indices = _ordered(x, order[rows])  # the swap is its own inverse
            return self._partition(stack.density[rows], indices, imperfection[rows], curve[rows])

        found = minimise_deviance(stack, partition, start, lower, upper)
        x = _ordered(found.x, order).reshape(len(starts), count, -1)
        deviance = np.where(np.isfinite(found.deviance), found.deviance, np.inf).reshape(len(starts), count)
        pick = np.argmin(deviance, axis=0)  # the first start among equals
        best_x, best_value = x[pick, np.arange(count)], deviance[pick, np.arange(count)]
        finite = np.isfinite(best_value)
        self.warm[sides[finite]] = best_x[finite]
        request = request[:count]
        excess = (best_value - r.best[request]) / r.scale[request] - r.threshold[request]
        return np.where(finite, excess, BEYOND)

    def _partition(self, density, indices, imperfection, curve) -> np.ndarray:
        """The partitions of rows of several curves at their indices, each curve on its own rows."""
        if len(self.curves) == 1:
            return partition_at(self.curves[0], density, curve_of_indices(self.curves[0], indices, imperfection))
        found = np.empty(density.shape)
        for number, one in enumerate(self.curves):
            rows = curve == number
            if rows.any():
                found[rows] = partition_at(one, density[rows], curve_of_indices(one, indices[rows], imperfection[rows]))
        return found


def profile_limits(curves, requests: ProfileRequests) -> tuple[np.ndarray, np.ndarray, list[list[str]]]:
    """The lower and upper profile limits of every request, and the notes of each (none when both are found).

    Parameters
    ----------
    curves : DensityCurve or sequence of DensityCurve
        The curve of the requests, or the curves (all with limits or all without) that
        ``requests.curve`` indexes: the profiles of several curves searched together, each
        row's arithmetic its own.
    requests : ProfileRequests

    Returns
    -------
    tuple
        ``(low, high, notes)``; a limit the profile does not reach within the search range is
        NaN and a note of its request says so.
    """
    profiles = _Profiles(list(curves) if isinstance(curves, (list, tuple)) else [curves], requests)
    sides = np.arange(len(profiles.request))
    request = profiles.request
    centre = requests.centre[request, requests.position[request]]
    edge = np.where(
        profiles.direction > 0,
        requests.upper[request, requests.position[request]],
        requests.lower[request, requests.position[request]],
    )
    step = requests.step[request]
    bracket = step_out(profiles.excess, centre, profiles.direction, np.abs(edge - centre), step, -requests.threshold[request])
    limits = np.full(len(sides), np.nan)
    bracketed = np.flatnonzero(bracket.closed)
    if bracketed.size:
        width = 2.0 * (ROOT_STEP_TOLERANCE * step[bracketed] + 2.0 * ROOT_RELATIVE_TOLERANCE * np.abs(centre[bracketed]))

        def excess(rows, values):
            return profiles.excess(bracketed[rows], values)

        direction = profiles.direction[bracketed]
        distance = regula_falsi(excess, centre[bracketed], direction, bracket.take(bracketed), width,
                                max_iterations=MAX_ROOT_ITERATIONS)  # fmt: skip
        limits[bracketed] = centre[bracketed] + direction * distance
        _recheck_edges(profiles, sides, limits, edge, step)
    count = len(requests.best)
    notes = [
        [
            f"the profile does not reach the {side} limit within {edge[j]:g}"
            for side, j in (("lower", i), ("upper", i + count))
            if not np.isfinite(limits[j])
        ]
        for i in range(count)
    ]
    return limits[:count], limits[count:], notes


def _recheck_edges(profiles: _Profiles, sides, limits, edge, step) -> None:
    """A limit found at the edge of the search range is checked once more, from the optimum
    next to it: the step out reaches the edge in one jump, from which the re-optimisation of a
    curve grown nearly into a step (Ep near 0 with limits that take the misplaced tracers) can
    stall above the profile's minimum.  Where the profile at the edge is below the threshold
    after all, the limit is not reached (NaN, said so)."""
    at_edge = np.flatnonzero(np.abs(limits - edge) <= 1e-6 * step)
    if at_edge.size:
        below = profiles.excess(sides[at_edge], edge[at_edge]) <= 0
        limits[at_edge[below]] = np.nan
