r"""Binomial fits of density curves to many tracer tests at once: stacked arrays, one Newton loop.

The tests (and size fractions) fitted with one curve are stacked into arrays of one row
each, padded to the widest test with densities of no tracer (they add nothing to the
deviance).  Every row is then fitted in the same numpy operations:

* a plain curve is the binomial GLM :math:`F^{-1}(P) = a + b\rho` with the curve's link,
  fitted by iteratively reweighted least squares (Fisher scoring; Newton's method for the
  canonical logit link) until the parameters stop changing in their last digits
  (McCullagh & Nelder 1989, sect. 2.5), with the covariance :math:`(X^\top W X)^{-1}` of
  the GLM (statsmodels' ``GLM.fit`` is the tests' oracle);
* a curve with limits, and every profile of an interval, minimises the binomial deviance
  over a box by projected Fisher scoring (:func:`minimise_deviance`): the score and the
  expected information from the derivatives of ``P`` in the parameters (central
  differences of the curve, one-sided of second order at a bound), a parameter on a bound
  held there while the score pushes it outwards, and each step halved until the deviance
  falls;
* the limits of the profile-likelihood intervals are found for every test, quantity and
  side together (:func:`tromplab.density.profiles.profile_limits`): stepping out from the
  estimate, then regula falsi on the re-optimised profile, by the search every curve's
  profile uses (:mod:`tromplab.curves.likelihood`).

References
----------
.. [McCullagh1989] McCullagh P., Nelder J.A. (1989). *Generalized Linear Models*, 2nd ed.
   Chapman & Hall, London (sect. 2.5: the iteratively reweighted least-squares fit).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import scipy.special

#: Relative change of the GLM parameters (and of a Newton step) at which an iteration stops.
PARAMETER_TOLERANCE = 1e-13
#: Relative step of a minimisation below which a row has converged (the differences of ``P`` are good to about 1e-10).
STEP_TOLERANCE = 1e-11
MAX_ITERATIONS = 200
#: Relative step of the central differences of ``P`` (about the cube root of the rounding unit).
DIFFERENCE_STEP = 6e-6
#: Relative length below which a Newton step is taken without asking the deviance to fall.
POLISH_STEP = 1e-6
#: Halvings of a step before a row is taken as converged (the deviance falls no more).
MAX_HALVINGS = 40
#: Rows of one evaluation of the partitions at displaced points (their arrays stay in the cache).
ROWS_PER_CALL = 4096
#: Rows whose scoring steps are computed together (:func:`_chunked_steps`), with derivatives by
#: differences (arrays of every displaced point) and analytic.
SCORING_CHUNK = 256
EXACT_SCORING_CHUNK = 512


@dataclass(frozen=True)
class TracerStack:
    """Tracer tests as rows of equal width: densities (g/cm3), tracers in the sinks, tracers recovered.

    A row shorter than the widest is padded with its last density and no tracer.
    """

    density: np.ndarray
    sinks: np.ndarray
    trials: np.ndarray

    @classmethod
    def of(cls, tests) -> TracerStack:
        """Stack tests given as ``(density, sinks, trials)`` triples of 1-d arrays."""
        width = max(len(density) for density, _, _ in tests)
        density, sinks, trials = np.empty((len(tests), width)), np.zeros((len(tests), width)), np.zeros((len(tests), width))
        for row, (rho, k, n) in enumerate(tests):
            size = len(rho)
            density[row, :size], density[row, size:] = rho, rho[-1]
            sinks[row, :size], trials[row, :size] = k, n
        return cls(density, sinks, trials)

    def take(self, rows) -> TracerStack:
        """The rows ``rows`` (repeated as often as listed)."""
        return TracerStack(self.density[rows], self.sinks[rows], self.trials[rows])


def deviance_terms(k: np.ndarray, n: np.ndarray, partition: np.ndarray) -> np.ndarray:
    """The binomial deviance's terms, ``k ln(k / (n p)) + (n - k) ln((n - k) / (n (1 - p)))`` of
    each point, at the partitions clipped inside (0, 1) (a count against a partition of 0 or 1
    stays finite); twice their sum is the deviance."""
    p = np.clip(partition, 1e-300, 1.0 - 1e-16)
    with np.errstate(divide="ignore", invalid="ignore"):
        return scipy.special.xlogy(k, k / (n * p)) + scipy.special.xlogy(n - k, (n - k) / (n * (1.0 - p)))


def deviance(stack: TracerStack, partition: np.ndarray) -> np.ndarray:
    """Binomial deviance of each row at the fitted partitions ``partition`` (the single fit's formula)."""
    k, n = stack.sinks, stack.trials
    return 2.0 * np.where(n > 0, deviance_terms(k, n, partition), 0.0).sum(axis=1)


@dataclass(frozen=True)
class BinomialFit:
    """The record of one binomial fit of the batch (a fit's ``raw``).

    Attributes
    ----------
    params : ndarray
        Plain curve: the GLM's intercept and slope of :math:`F^{-1}(P) = a + b\\rho`; curve
        with limits: ``rho_c, ln ep_c, light_limit, heavy_limit``.
    covariance : ndarray or None
        The GLM's covariance of ``params`` (:math:`(X^\\top W X)^{-1}`); None for a curve with limits.
    deviance : float
        The binomial deviance at ``params``.
    converged : bool
        False when the GLM's iterations stopped before the parameters settled.
    """

    params: np.ndarray
    covariance: np.ndarray | None
    deviance: float
    converged: bool


# --- plain curves: the binomial GLM ------------------------------------------------------------
@dataclass(frozen=True)
class GlmFits:
    """The binomial GLMs of a stack: ``params`` (rows, 2) intercept and slope, their
    ``covariance`` (rows, 2, 2), the ``deviance`` and whether each ``converged``."""

    params: np.ndarray
    covariance: np.ndarray
    deviance: np.ndarray
    converged: np.ndarray


def fit_glm(stack: TracerStack, form) -> GlmFits:
    r"""Binomial GLMs :math:`F^{-1}(P) = a + b\rho` of every row by iteratively reweighted least squares.

    Parameters
    ----------
    stack : TracerStack
    form : StandardForm
        The curve's standard form (its ``cdf``, ``quantile`` and ``pdf``).

    Returns
    -------
    GlmFits
    """
    k, n, rho = stack.sinks, stack.trials, stack.density
    counted = n > 0
    share = np.where(counted, k / np.where(counted, n, 1.0), 0.5)
    start = (share + 0.5) / 2.0  # statsmodels' start for the binomial family
    beta = _weighted_line(rho, form.quantile(start), n * form.pdf(form.quantile(start)) ** 2 / (start * (1 - start)))
    converged = np.zeros(len(rho), dtype=bool)
    for _ in range(MAX_ITERATIONS):
        eta = beta[:, :1] + beta[:, 1:] * rho
        mu, slope = _mean_and_slope(form, eta)
        working = eta + (share - mu) / slope
        new = _weighted_line(rho, working, n * slope**2 / (mu * (1.0 - mu)))
        change = np.abs(new - beta).max(axis=1) / np.maximum(np.abs(beta).max(axis=1), 1.0)
        beta = np.where(converged[:, None], beta, new)
        converged |= change <= PARAMETER_TOLERANCE
        if converged.all():
            break
    eta = beta[:, :1] + beta[:, 1:] * rho
    mu, slope = _mean_and_slope(form, eta)
    information = _information(rho, n * slope**2 / (mu * (1.0 - mu)))
    with np.errstate(all="ignore"):
        covariance = np.linalg.inv(information)
    return GlmFits(beta, covariance, deviance(stack, form.cdf(eta)), converged)


def _mean_and_slope(form, eta):
    # the binomial family's clip of the mean (statsmodels: FLOAT_EPS), so that its variance stays positive
    eps = np.finfo(float).eps
    mu = np.clip(form.cdf(eta), eps, 1.0 - eps)
    return mu, np.maximum(form.pdf(eta), 1e-300)


def _information(rho, weight):
    s0, s1, s2 = weight.sum(axis=1), (weight * rho).sum(axis=1), (weight * rho * rho).sum(axis=1)
    return np.stack([np.stack([s0, s1], axis=-1), np.stack([s1, s2], axis=-1)], axis=-2)


def _weighted_line(rho, response, weight) -> np.ndarray:
    """Intercept and slope of the weighted least-squares line of ``response`` on ``rho``, row by row."""
    weight = np.where(np.isfinite(weight), weight, 0.0)
    response = np.where(weight > 0, response, 0.0)
    total = weight.sum(axis=1)
    mean_rho = (weight * rho).sum(axis=1) / total
    mean_response = (weight * response).sum(axis=1) / total
    centred = rho - mean_rho[:, None]
    slope = (weight * centred * (response - mean_response[:, None])).sum(axis=1) / (weight * centred * centred).sum(axis=1)
    return np.stack([mean_response - slope * mean_rho, slope], axis=1)


# --- a box-bounded minimum of the deviance -------------------------------------------------------
@dataclass(frozen=True)
class Minimum:
    """Where :func:`minimise_deviance` ended: ``x`` (rows, parameters) and the ``deviance`` there."""

    x: np.ndarray
    deviance: np.ndarray


def minimise_deviance(stack: TracerStack, partition, start, lower, upper, *, derivatives=None) -> Minimum:
    """The deviance of each row minimised over the box ``lower <= x <= upper`` from ``start``.

    Parameters
    ----------
    stack : TracerStack
        One row per minimisation.
    partition : callable
        ``partition(x, rows)`` -> the curve's partitions (len(rows), width) at the parameters
        ``x`` (len(rows), parameters) of the rows ``rows`` (indices into ``stack``): the rows
        that have converged are left out of the next steps.
    start, lower, upper : ndarray
        (rows, parameters); a parameter with ``lower == upper`` is held fixed.
    derivatives : callable, optional
        ``derivatives(x, rows)`` -> the nonzero first and second derivatives of ``P`` in ``x``,
        analytic, as dicts ``{i: dP/dx_i}`` and ``{(i, j): d2P/dx_i dx_j}`` (``i <= j``) of
        (len(rows), width) arrays; None: by differences of ``partition``.

    Returns
    -------
    Minimum
        A row whose deviance is infinite everywhere it looked keeps its start, with an
        infinite deviance.
    """
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    x = np.clip(np.asarray(start, float), lower, upper)
    with np.errstate(all="ignore"):
        current = partition(x, np.arange(len(x)))  # the partitions at x, kept from the line search's trials
        value = deviance(stack, current)
        active = np.flatnonzero(np.isfinite(value))
        for _ in range(MAX_ITERATIONS):
            if not active.size:
                break
            rows, bounds = stack.take(active), (lower[active], upper[active])
            step, newton = _chunked_steps(stack, partition, x, current, lower, upper, active, derivatives)

            def of_active(point, subset, active=active):
                return partition(point, active[subset])

            x[active], value[active], current[active], moved = _line_search(
                rows, of_active, x[active], value[active], current[active], step, newton, *bounds
            )
            active = active[moved]
    return Minimum(x, value)


def _of(partition, rows: np.ndarray):
    """``partition`` of the rows ``rows``; a point may hold several points of every row, stacked (the differences)."""

    def of_rows(point):
        return partition(point, np.tile(rows, len(point) // len(rows)))

    return of_rows


def _chunked_steps(stack: TracerStack, partition, x, current, lower, upper, active, derivatives) -> tuple[np.ndarray, np.ndarray]:
    """The scoring steps of the rows ``active``, :data:`SCORING_CHUNK` rows at a time: each row's
    arithmetic is its own, and the arrays of a chunk (the differences of ``P`` at every displaced
    point, the curvatures) stay in the processor's cache where those of a thousand rows do not."""
    steps, newton = np.empty((len(active), x.shape[1])), np.empty(len(active), dtype=bool)
    size = SCORING_CHUNK if derivatives is None else EXACT_SCORING_CHUNK
    for first in range(0, len(active), size):
        chunk = active[first : first + size]
        exact = None if derivatives is None else (lambda point, chunk=chunk: derivatives(point, chunk))
        found = _scoring_step(
            stack.take(chunk), _of(partition, chunk), x[chunk], current[chunk], lower[chunk], upper[chunk], exact
        )
        steps[first : first + len(chunk)], newton[first : first + len(chunk)] = found
    return steps, newton


def _scoring_step(stack: TracerStack, partition, x, current, lower, upper, derivatives=None) -> tuple[np.ndarray, np.ndarray]:
    """The projected Newton step of every row (zero along parameters held on a bound), and
    whether it is Newton's (True) or Fisher scoring's.

    Newton's step on the deviance's own Hessian where it is positive definite on the free
    parameters, else the Fisher-scoring step on the expected information (always positive
    definite): near the light-end limit's bound the deviance is far from quadratic and the
    expected information, alone, converges only linearly (hundreds of steps).  ``current``: the
    partitions at ``x``.
    """
    p = np.clip(current, 1e-300, 1.0 - 1e-16)
    k, n = stack.sinks, stack.trials
    counted = n > 0
    slope = np.where(counted, 2.0 * ((n - k) / (1.0 - p) - k / p), 0.0)
    bend = np.where(counted, 2.0 * (k / p**2 + (n - k) / (1.0 - p) ** 2), 0.0)
    information = np.where(counted, 2.0 * n / (p * (1.0 - p)), 0.0)
    rows, size = x.shape
    if derivatives is None:
        jacobian, curvature = _derivatives(partition, x, lower, upper, current)  # (rows, width, m), (rows, width, m, m)
        score = np.matmul(slope[:, None, :], jacobian)[:, 0, :]
        transposed = jacobian.transpose(0, 2, 1)
        bent = np.matmul(slope[:, None, :], curvature.reshape(rows, -1, size * size)).reshape(rows, size, size)
        hessian = np.matmul(transposed * bend[:, None, :], jacobian) + bent
        fisher = np.matmul(transposed * information[:, None, :], jacobian)
    else:
        score, hessian, fisher = _contracted(*derivatives(x), slope, bend, information, size)
    held = (lower == upper) | ((x <= lower) & (score > 0)) | ((x >= upper) & (score < 0))
    free = ~held
    keep = free[:, :, None] & free[:, None, :]
    identity = np.eye(size) * held[:, :, None]
    hessian, fisher = hessian * keep + identity, fisher * keep + identity
    hessian = np.where(np.isfinite(hessian), hessian, 0.0)
    positive = np.linalg.eigvalsh(hessian).min(axis=1) > 0
    matrix = np.where(positive[:, None, None], hessian, fisher)
    # a tiny ridge keeps a flat direction (a limit the data do not inform) from a singular solve
    ridge = 1e-12 * np.maximum(np.abs(np.diagonal(matrix, axis1=1, axis2=2)).max(axis=1), 1e-300)
    matrix = matrix + ridge[:, None, None] * np.eye(size)
    step = -np.linalg.solve(matrix, (score * free)[:, :, None])[:, :, 0]
    return np.where(np.isfinite(step), step, 0.0), positive


def _contracted(first: dict, second: dict, slope, bend, information, size: int):
    """The score, Hessian and expected information of the deviance from the derivatives of ``P``
    given column by column (``first[i]``, ``second[i, j]`` for ``i <= j``, each (rows, width); a
    column left out is zero): sums over the densities, no (rows, width, m, m) array made."""
    rows = len(slope)
    score, hessian, fisher = np.zeros((rows, size)), np.zeros((rows, size, size)), np.zeros((rows, size, size))
    for i, column in first.items():
        score[:, i] = (slope * column).sum(axis=1)
        weighted, informed = bend * column, information * column
        for j, other in first.items():
            if j >= i:
                hessian[:, i, j] = hessian[:, j, i] = (weighted * other).sum(axis=1)
                fisher[:, i, j] = fisher[:, j, i] = (informed * other).sum(axis=1)
    for (i, j), column in second.items():
        hessian[:, i, j] += (slope * column).sum(axis=1)
        if i != j:
            hessian[:, j, i] = hessian[:, i, j]
    return score, hessian, fisher


def _derivatives(partition, x, lower, upper, current) -> tuple[np.ndarray, np.ndarray]:
    """``dP/dx`` and ``d2P/dx2`` by differences: central, or one-sided of second order where a
    bound is within the step (the second derivatives, which only speed the convergence, of first order).

    The displaced points (two per free parameter and one per pair of them) are evaluated stacked
    as rows, a few thousand rows to a call of ``partition`` (:func:`_stacked_partition`)."""
    rows, size = x.shape
    held_everywhere = (lower == upper).all(axis=0)  # a profile's value: no derivative to take
    free = [j for j in range(size) if not held_everywhere[j]]
    h, sign, one_sided, fixed, steps = {}, {}, {}, {}, np.zeros((rows, size))
    points = []
    for j in free:
        h[j] = DIFFERENCE_STEP * np.maximum(np.abs(x[:, j]), 1e-2)
        fixed[j] = lower[:, j] == upper[:, j]
        forward = x[:, j] - h[j] < lower[:, j]
        backward = ~forward & (x[:, j] + h[j] > upper[:, j])
        sign[j], one_sided[j] = np.where(backward, -1.0, 1.0), (forward | backward)[:, None]
        steps[:, j] = np.where(fixed[j], 0.0, sign[j] * h[j])
        points += [_moved(x, j, sign[j] * h[j]), _moved(x, j, np.where(forward | backward, 2 * sign[j] * h[j], -h[j]))]
    pairs = [(i, j) for i in free for j in free if i < j]
    points += [_moved(_moved(x, i, steps[:, i]), j, steps[:, j]) for i, j in pairs]
    zero = np.zeros_like(current)
    first, second = dict.fromkeys(range(size), zero), dict.fromkeys(((i, j) for i in range(size) for j in range(size)), zero)
    values = _stacked_partition(partition, points) if points else []
    near = {}
    for number, j in enumerate(free):
        near[j], far = values[2 * number], values[2 * number + 1]
        first[j], second[j, j] = _differences(current, near[j], far, h[j], sign[j], one_sided[j][:, 0], fixed[j])
    for both, (i, j) in zip(values[2 * len(free) :], pairs):
        with np.errstate(divide="ignore", invalid="ignore"):
            cross = (both - near[i] - near[j] + current) / (steps[:, i] * steps[:, j])[:, None]
        second[i, j] = second[j, i] = np.where(np.isfinite(cross), cross, 0.0)
    # assembled once (writing columns into a zeroed (rows, width, m, m) array one by one is slow)
    jacobian = np.stack([first[j] for j in range(size)], axis=-1)
    curvature = np.stack([np.stack([second[i, j] for j in range(size)], axis=-1) for i in range(size)], axis=-2)
    return jacobian, curvature


def _differences(current, near, far, h, sign, one_sided, fixed) -> tuple[np.ndarray, np.ndarray]:
    """The first and second differences of ``P`` along one parameter: central (``near`` at
    ``x + h``, ``far`` at ``x - h``), or one-sided of second order on the rows ``one_sided``
    (``near`` at ``x + sign h``, ``far`` at ``x + 2 sign h``); zero on the rows ``fixed``.  The
    one-sided formulas are computed on their rows only (few: those with a bound within the step)."""
    hh = h[:, None]
    slope, bend = (near - far) / (2 * hh), (near - 2.0 * current + far) / hh**2
    if one_sided.any():
        rows, side = np.flatnonzero(one_sided), sign[one_sided][:, None]
        at, step = current[rows], hh[rows]
        slope[rows] = side * (-3.0 * at + 4.0 * near[rows] - far[rows]) / (2 * step)
        bend[rows] = (at - 2.0 * near[rows] + far[rows]) / step**2
    if fixed.any():
        slope[fixed], bend[fixed] = 0.0, 0.0
    return slope, bend


def _stacked_partition(partition, points: list[np.ndarray]) -> np.ndarray:
    """``partition`` at each of ``points`` (arrays of the same rows), as (points, rows, width):
    several points to a call, while the call stays within :data:`ROWS_PER_CALL` rows (a call of
    few rows costs mostly its overhead; one of very many, arrays beyond the processor's cache)."""
    per_call = max(1, ROWS_PER_CALL // len(points[0]))
    found = [partition(np.concatenate(points[first : first + per_call])) for first in range(0, len(points), per_call)]
    return np.concatenate(found).reshape(len(points), len(points[0]), -1)


def _moved(x: np.ndarray, column: int, by: np.ndarray) -> np.ndarray:
    moved = x.copy()
    moved[:, column] += by
    return moved


def _line_search(stack, partition, x, value, current, step, newton, lower, upper):
    """Halve each row's step until its deviance falls; a row whose (projected) step no longer
    moves it, or whose deviance falls no more, is returned as not moved.  ``partition(points,
    rows)``: the partitions of the rows ``rows`` (of ``x``) at ``points``; each halving evaluates
    the rows still pending only.  Returns the new ``x``, deviance and partitions, and which rows moved.

    A Newton step shorter than :data:`POLISH_STEP` (relative) is taken whole and ends the
    row's iterations: so close to the minimum the fall of the deviance is below its rounding,
    and Newton's convergence leaves an error of about the square of that step.
    """
    scale = np.maximum(np.abs(x), 1.0)
    tolerance = STEP_TOLERANCE * scale
    polish = newton & (np.abs(step) < POLISH_STEP * scale).all(axis=1)
    length = np.ones(len(x))
    pending = np.ones(len(x), dtype=bool)
    moved = np.zeros(len(x), dtype=bool)
    new_x, new_value, new_current = x.copy(), value.copy(), current.copy()
    for _ in range(MAX_HALVINGS):
        trial = np.clip(x + length[:, None] * step, lower, upper)
        pending &= (np.abs(trial - x) > tolerance).any(axis=1)
        if not pending.any():
            break
        rows = np.flatnonzero(pending)
        partitions = partition(trial[rows], rows)
        trial_value = deviance(stack.take(rows), partitions)
        slack = np.where(polish[rows], 1e-9 * np.abs(value[rows]) + 1e-12, 0.0)
        falls = (trial_value < value[rows]) | (polish[rows] & (trial_value <= value[rows] + slack))
        better = np.isfinite(trial_value) & falls
        taken = rows[better]
        new_x[taken], new_value[taken] = trial[taken], np.minimum(trial_value[better], value[taken])
        new_current[taken] = partitions[better]
        moved[taken] = ~polish[taken]
        pending[taken] = False
        length = np.where(pending, length / 2.0, length)
    return new_x, new_value, new_current, moved


@functools.cache
def centre_and_scale(form) -> tuple[float, float]:
    """``q50`` and ``k`` of a standard form, computed once."""
    return form.centre, form.scale


def partition_at(curve, rho: np.ndarray, params: dict[str, np.ndarray]) -> np.ndarray:
    """``curve.partition(rho, **params)`` without its checks of the names (the batch's inner loop)."""
    centre, scale = centre_and_scale(curve.form)
    if curve.has_limits:
        inside = curve.form.cdf(centre + scale * (rho - params["rho_c"]) / params["ep_c"])
        return params["light_limit"] + (params["heavy_limit"] - params["light_limit"]) * inside
    return curve.form.cdf(centre + scale * (rho - params["rho50"]) / params["ep"])


# --- the curves' fits -----------------------------------------------------------------------
#: The limits the fits of a curve with limits start from (light, heavy): the best start is kept.
LIMIT_STARTS = ((0.001, 0.999), (0.03, 0.97), (0.0, 0.95), (0.05, 1.0))


def fit_limits_curve(stack: TracerStack, curve, starts: np.ndarray) -> Minimum:
    """A curve with limits fitted to every row: the parameters ``rho_c, ln ep_c, light_limit,
    heavy_limit`` within the curve's bounds, from each of :data:`LIMIT_STARTS` (``starts``:
    the rows' ``rho50, Ep`` from their data), the lowest deviance kept.

    Returns
    -------
    Minimum
        ``x`` in the optimiser's terms (``ep_c`` on a log scale), one row per row of ``stack``.
    """
    rows, width = len(starts), len(LIMIT_STARTS)
    lower = np.array([p.lower for p in curve.parameters], dtype=float)
    upper = np.array([p.upper for p in curve.parameters], dtype=float)
    lower[1], upper[1] = math.log(lower[1]), math.log(upper[1])
    first = np.column_stack([starts[:, 0], np.log(starts[:, 1])])
    begin = np.concatenate([np.column_stack([first, np.full((rows, 2), pair)]) for pair in LIMIT_STARTS])
    repeated = stack.take(np.tile(np.arange(rows), width))

    def partition(x, rows):
        return partition_at(curve, repeated.density[rows], natural_limits(x))

    found = minimise_deviance(
        repeated, partition, begin, np.broadcast_to(lower, begin.shape), np.broadcast_to(upper, begin.shape)
    )
    value = np.where(np.isfinite(found.deviance), found.deviance, np.inf).reshape(width, rows)
    best = np.argmin(value, axis=0)  # the first start among equals, as the single fit keeps it
    pick = best * rows + np.arange(rows)
    return Minimum(found.x[pick], found.deviance[pick])


def natural_limits(x: np.ndarray) -> dict[str, np.ndarray]:
    """The parameters of a curve with limits from the optimiser's columns (``ep_c`` on a log scale), as (rows, 1)."""
    return {
        "rho_c": x[:, 0:1],
        "ep_c": np.exp(x[:, 1:2]),
        "light_limit": x[:, 2:3],
        "heavy_limit": x[:, 3:4],
    }
