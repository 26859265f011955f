"""Experiments as padded arrays and the batched Levenberg-Marquardt that fits them.

The array machinery of :mod:`tromplab.curves.engine`, kept below the fit results
(:mod:`tromplab.curves.curve_fit`) so that the single-fit inference of
:mod:`tromplab.curves.intervals` can re-optimise with it too (the profile likelihood):

* :class:`PaddedPoints` - experiments stacked into ``(experiments, points)`` arrays;
* :class:`BatchProblem` - the weighted residuals of one formula as a function of
  internal parameters (``ln d_cut``, the shape, the extras), row by row;
* :func:`levenberg_marquardt` - a projected Levenberg-Marquardt on every row at once.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats

from ..loading.points import TrompPoints
from .formulas import Formula
from .likelihood import regula_falsi, step_out

MAX_ITERATIONS = 400
#: Relative decrease of the sum of squares below which an accepted step ends a row.
SSR_TOLERANCE = 1e-13


@dataclass(frozen=True)
class PaddedPoints:
    """Experiments stacked into ``(experiments, points)`` arrays, padded with weight 0.

    Attributes
    ----------
    size, observed : ndarray, shape (E, P)
        Sizes and measured partition to fines; padding repeats the last point.
    root_weight : ndarray, shape (E, P)
        Square roots of the normalised weights (mean 1 over the real points); 0 on padding.
    n : ndarray of int, shape (E,)
        Number of real points per experiment.

    The sums over a row's points depend on the padded width in their last bits (numpy sums
    in blocks whose grouping moves when zeros are appended), so callers that fit a batch in
    chunks pad every chunk to one ``width`` and get the same numbers however it is cut.
    """

    size: np.ndarray
    observed: np.ndarray
    root_weight: np.ndarray
    n: np.ndarray

    @classmethod
    def from_points(cls, experiments: Sequence[TrompPoints], width: int | None = None) -> PaddedPoints:
        count = len(experiments)
        width = max(max(points.n for points in experiments), width or 0)
        size = np.ones((count, width))
        observed = np.zeros((count, width))
        root_weight = np.zeros((count, width))
        n = np.array([points.n for points in experiments])
        for row, points in enumerate(experiments):
            k = points.n
            size[row, :k], size[row, k:] = points.size, points.size[-1]
            observed[row, :k], observed[row, k:] = points.partition_fine, points.partition_fine[-1]
            weight = np.ones(k) if points.weight is None else points.weight / points.weight.mean()
            root_weight[row, :k] = np.sqrt(weight)
        return cls(size, observed, root_weight, n)

    def __len__(self) -> int:
        return self.size.shape[0]

    def take(self, rows) -> PaddedPoints:
        return PaddedPoints(self.size[rows], self.observed[rows], self.root_weight[rows], self.n[rows])

    def cut_bounds(self, factor: float) -> tuple[np.ndarray, np.ndarray]:
        """``(ln lower, ln upper)`` of ``d_cut``: smallest size / factor, largest size x factor."""
        real = self.root_weight > 0
        smallest = np.where(real, self.size, np.inf).min(axis=1)
        largest = np.where(real, self.size, -np.inf).max(axis=1)
        return np.log(smallest / factor), np.log(largest * factor)


def curve_values(formula: Formula, x, shape, extras: dict, efficiency=None, x_break=None) -> np.ndarray:
    """Partition to fines of ``formula`` with array-valued parameters broadcast against ``x``
    (``x_break``: break points of a moving break, as (11)'s, already solved for these shapes)."""
    moving = formula.moving_break
    if moving is None:
        return formula.phi(x, shape, **extras)
    if x_break is None:
        # one root per distinct (shape, efficiency): grid rows and Jacobian columns in d_cut share them
        kr, eff = np.broadcast_arrays(np.asarray(shape, dtype=float), np.asarray(efficiency, dtype=float))
        x_break = distinct_breaks(moving, kr.ravel(), eff.ravel()).reshape(kr.shape)
    return moving.phi(x, shape, x_break)


def distinct_breaks(moving, shape: np.ndarray, efficiency: np.ndarray) -> np.ndarray:
    """The break of each (shape, efficiency) pair of 1-d arrays, one root per distinct pair."""
    # a pair as one complex number: np.unique(axis=...) would compare structured rows, whose
    # dtype promotion runs Python code in which numpy turns a Ctrl-C into a TypeError
    pairs, inverse = np.unique(shape + 1j * efficiency, return_inverse=True)
    return moving.on_arrays(pairs.real, pairs.imag)[inverse.ravel()]


class BatchProblem:
    """Residuals of one formula on padded experiments, as a function of internal parameters.

    Internal parameters per row: ``ln d_cut``, the shape, then the extras.  ``rows`` maps
    each work row to its experiment (several starts share an experiment).
    """

    def __init__(self, formula: Formula, data: PaddedPoints, efficiency, cut_factor: float):
        self.formula = formula
        self.data = data
        self.efficiency = None if efficiency is None else np.asarray(efficiency, dtype=float)
        self.extra_names = tuple(extra.name for extra in formula.extras)
        low_cut, high_cut = data.cut_bounds(cut_factor)
        shape_low, shape_high = formula.shape_bounds
        extra_low = [extra.bounds[0] for extra in formula.extras]
        extra_high = [extra.bounds[1] for extra in formula.extras]
        count = len(data)
        self.lower = np.column_stack([low_cut, np.full(count, shape_low), *[np.full(count, v) for v in extra_low]])
        self.upper = np.column_stack([high_cut, np.full(count, shape_high), *[np.full(count, v) for v in extra_high]])

    def breaks(self, params: np.ndarray, rows: np.ndarray):
        """Break points of a moving break (``Formula.moving_break``, (11)) for these rows, None
        for other formulas; they depend on the shape and the measured efficiency only, so
        steps in d_cut reuse them."""
        if self.formula.moving_break is None:
            return None
        return self.formula.moving_break.on_arrays(params[:, 1], self.efficiency[rows])[:, None]

    def breaks_near(self, params: np.ndarray, rows: np.ndarray, known_shapes: np.ndarray, known_breaks: np.ndarray):
        """:meth:`breaks` at ``params``, taken from ``known_breaks`` (the breaks at the shapes
        ``known_shapes``, row by row) where the shape is the same: one root per distinct
        (shape, efficiency) of the others."""
        found = known_breaks.copy()
        other = np.flatnonzero(params[:, 1] != known_shapes)
        if other.size:
            found[other, 0] = distinct_breaks(self.formula.moving_break, params[other, 1], self.efficiency[rows[other]])
        return found

    def take(self, rows: np.ndarray) -> BatchProblem:
        """The problem of these experiments (repeated as often as ``rows`` names them), same bounds."""
        taken = copy.copy(self)
        taken.data = self.data.take(rows)
        taken.efficiency = None if self.efficiency is None else self.efficiency[rows]
        taken.lower, taken.upper = self.lower[rows].copy(), self.upper[rows].copy()
        return taken

    def residual(self, params: np.ndarray, rows: np.ndarray, x_break=None) -> np.ndarray:
        """Weighted residuals ``(len(rows), P)`` at internal parameters ``params``."""
        return self.residual_of(self.gathered(rows), params, x_break)

    def gathered(self, rows: np.ndarray) -> tuple:
        """The data of these rows (sizes, observed, root weights, efficiency) for
        :meth:`residual_of`: gathered once for the several evaluations of a Jacobian or of a
        search along ``d_cut`` on the same rows."""
        data = self.data
        efficiency = None if self.efficiency is None else self.efficiency[rows][:, None]
        return data.size[rows], data.observed[rows], data.root_weight[rows], efficiency

    def stacked(self, rows: np.ndarray) -> tuple:
        """The data of these rows shaped ``(len(rows), 1, P)``, for :meth:`residual_of` with
        parameters ``(len(rows), k, p)``: k parameter sets of each row's experiment without
        the data repeated k times (the grid of starts)."""
        data = self.data
        efficiency = None if self.efficiency is None else self.efficiency[rows][:, None, None]
        return data.size[rows][:, None, :], data.observed[rows][:, None, :], data.root_weight[rows][:, None, :], efficiency

    def residual_of(self, gathered: tuple, params: np.ndarray, x_break=None) -> np.ndarray:
        """:meth:`residual` on the rows whose data are ``gathered`` (:meth:`gathered`, or
        :meth:`stacked` with parameters and breaks of one more dimension)."""
        size, observed, root_weight, efficiency = gathered
        x = size / np.exp(params[..., :1])
        extras = {name: params[..., 2 + i : 3 + i] for i, name in enumerate(self.extra_names)}
        with np.errstate(all="ignore"):
            phi = curve_values(self.formula, x, params[..., 1:2], extras, efficiency, x_break)
            return root_weight * (phi - observed)

    def ssr_on_grid(self, stacked: tuple, log_cuts: np.ndarray, shapes: np.ndarray, extras, x_break=None) -> np.ndarray:
        """Sums of squares ``(b, shapes, cuts)`` of the ``b`` experiments whose data are
        ``stacked`` (:meth:`stacked`) at each ``ln d_cut`` of ``log_cuts`` ``(b, cuts)`` with each
        of the ``shapes``, the extras at the values ``extras`` (``x_break`` ``(b, shapes)``: a
        moving break at each shape).  The residuals of :meth:`residual_of`, the sizes relative to
        each cut divided out once for all the shapes."""
        size, observed, root_weight, _ = stacked
        x = size[:, :, None, :] / np.exp(log_cuts)[:, None, :, None]  # (b, 1, cuts, P)
        extras = {name: np.full((1, 1, 1, 1), value, dtype=float) for name, value in zip(self.extra_names, extras)}
        with np.errstate(all="ignore"):
            breaks = None if x_break is None else x_break[:, :, None, None]
            phi = curve_values(self.formula, x, shapes[None, :, None, None], extras, None, breaks)
            residual = root_weight[:, :, None, :] * (phi - observed[:, :, None, :])
        rows = np.ascontiguousarray(residual).reshape(-1, size.shape[-1])  # the rows summed as residual_of's
        return sum_of_squares(rows).reshape(log_cuts.shape[0], shapes.size, log_cuts.shape[1])

    def jacobian(
        self, params: np.ndarray, rows: np.ndarray, base: np.ndarray, relative_step: float = 1.5e-8, x_break=None
    ) -> np.ndarray:
        """Forward-difference Jacobian ``(len(rows), P, p)``, stepping inwards at an upper bound
        (``x_break``: the breaks at ``params`` when the caller has them, see :meth:`breaks`)."""
        count, width = base.shape
        jac = np.empty((count, width, params.shape[1]))
        upper = self.upper[rows]
        gathered = self.gathered(rows)
        if x_break is None:
            x_break = self.breaks(params, rows)
        for j in range(params.shape[1]):
            # column 0 is ln d_cut, whose value depends on the size unit: an absolute step keeps
            # the Jacobian, and so the standard errors, the same in any unit
            step = relative_step if j == 0 else relative_step * np.maximum(np.abs(params[:, j]), 1.0)
            step = np.where(params[:, j] + step > upper[:, j], -step, step)
            moved = params.copy()
            moved[:, j] += step
            # a step in the shape moves a moving break: solved for each row (no pair repeats here)
            moved_break = x_break if j != 1 or x_break is None else self.breaks(moved, rows)
            jac[:, :, j] = (self.residual_of(gathered, moved, moved_break) - base) / step[:, None]
        return jac


def sum_of_squares(residual: np.ndarray) -> np.ndarray:
    value = np.einsum("ij,ij->i", residual, residual)
    return np.where(np.isfinite(value), value, np.inf)


def levenberg_marquardt(
    problem: BatchProblem,
    params: np.ndarray,
    rows: np.ndarray,
    *,
    max_iterations: int = MAX_ITERATIONS,
    relative_step: float = 1.5e-8,
):
    """Projected Levenberg-Marquardt on every row at once.

    Returns ``(params, ssr, nfev)`` per row.  A row stops when an accepted step lowers its
    sum of squares by less than :data:`SSR_TOLERANCE` (relative), when the damping grows
    past 1e12 without an accepted step (no descent left within the bounds), or after
    ``max_iterations``.  ``relative_step`` is the forward-difference step; a coarse step
    (1e-3) sees past the kinks of the piecewise formulas, where a fine one stalls.
    """
    state = _MarquardtRows(problem, params, rows)
    for _ in range(max_iterations):
        work = np.flatnonzero(state.alive)
        if not work.size:
            break
        state.refresh_jacobians(work, relative_step)
        state.take_step(work)
    return state.params, state.ssr, state.nfev


class _MarquardtRows:
    """The state of :func:`levenberg_marquardt`, row by row: parameters (kept within the
    bounds), residuals and their sum of squares, the breaks of a moving break (solved once per
    point: the accepted trial's breaks serve its Jacobian), the damping, the gradient and
    Gauss-Newton Hessian of the last accepted point, and which rows are still descending."""

    def __init__(self, problem: BatchProblem, params: np.ndarray, rows: np.ndarray):
        self.problem, self.rows = problem, rows
        self.lower, self.upper = problem.lower[rows], problem.upper[rows]
        self.params = np.clip(params, self.lower, self.upper)
        self.x_break = problem.breaks(self.params, rows)
        self.residual = problem.residual(self.params, rows, self.x_break)
        self.ssr = sum_of_squares(self.residual)
        n_params = self.params.shape[1]
        self.nfev = np.ones(rows.size, dtype=int)
        self.damping = np.full(rows.size, 1e-3)
        self.alive = np.isfinite(self.ssr)
        self.need_jacobian = self.alive.copy()
        self.gradient = np.zeros((rows.size, n_params))
        self.hessian = np.zeros((rows.size, n_params, n_params))
        self.eye = np.eye(n_params)
        span = self.upper - self.lower  # a parameter this close to a bound is on it (damped_step)
        self.near_lower, self.near_upper, self.no_room = self.lower + 1e-12 * span, self.upper - 1e-12 * span, span == 0

    def refresh_jacobians(self, work: np.ndarray, relative_step: float) -> None:
        """Gradient and Hessian at the rows of ``work`` that moved since their last Jacobian."""
        fresh = work[self.need_jacobian[work]]
        if not fresh.size:
            return
        breaks_here = None if self.x_break is None else self.x_break[fresh]
        residual = self.residual[fresh]
        jac = self.problem.jacobian(self.params[fresh], self.rows[fresh], residual, relative_step, breaks_here)
        self.nfev[fresh] += self.params.shape[1]
        self.gradient[fresh] = np.einsum("bkp,bk->bp", jac, residual)
        self.hessian[fresh] = np.einsum("bkp,bkq->bpq", jac, jac)
        self.need_jacobian[fresh] = False

    def damped_step(self, work: np.ndarray, p: np.ndarray) -> np.ndarray:
        """The damped Gauss-Newton step of the rows of ``work`` (at ``p``), parameters on a
        bound whose gradient points outwards held."""
        g, h, eye = self.gradient[work], self.hessian[work], self.eye
        pinned = ((p <= self.near_lower[work]) & (g > 0)) | ((p >= self.near_upper[work]) & (g < 0)) | self.no_room[work]
        free = ~pinned
        h_free = h * free[:, :, None] * free[:, None, :] + eye * pinned[:, :, None]
        diagonal = np.maximum(np.diagonal(h_free, axis1=1, axis2=2), 1e-300)
        system = h_free + self.damping[work, None, None] * eye * diagonal[:, None, :]
        with np.errstate(all="ignore"):
            try:
                step = -np.linalg.solve(system, (g * free)[..., None])[..., 0]
            except np.linalg.LinAlgError:
                step = -(g * free) / diagonal
        return np.where(np.isfinite(step), step, 0.0)

    def breaks_at(self, trial: np.ndarray, work: np.ndarray, p: np.ndarray):
        """The moving break's points at ``trial`` (None without one): those of the current point
        ``p`` where the trial keeps its shape (a shape held on a bound or fixed), solved anew
        for the others."""
        if self.x_break is None:
            return None
        found = self.x_break[work]
        moved = np.flatnonzero(trial[:, 1] != p[:, 1])
        if moved.size:
            found[moved] = self.problem.breaks(trial[moved], self.rows[work[moved]])
        return found

    def take_step(self, work: np.ndarray) -> None:
        """Try the step of every row of ``work``: keep it where the sum of squares falls (less
        damping), else more damping; end the rows that converged or cannot descend."""
        problem, p, lower, upper = self.problem, self.params[work], self.lower[work], self.upper[work]
        trial = np.clip(p + self.damped_step(work, p), lower, upper)
        work_rows = self.rows[work]
        trial_break = self.breaks_at(trial, work, p)
        trial_residual = problem.residual(trial, work_rows, trial_break)
        trial_ssr = sum_of_squares(trial_residual)
        self.nfev[work] += 1
        ssr = self.ssr[work]
        accepted = trial_ssr < ssr
        gain = np.where(accepted, (ssr - trial_ssr) / np.maximum(ssr, 1e-300), 0.0)
        took = work[accepted]
        self.params[took], self.residual[took], self.ssr[took] = trial[accepted], trial_residual[accepted], trial_ssr[accepted]
        if self.x_break is not None:
            self.x_break[took] = trial_break[accepted]
        self.need_jacobian[took] = True
        damping = self.damping
        damping[took] = np.maximum(damping[took] / 3.0, 1e-12)
        damping[work[~accepted]] *= 4.0
        stalled = (trial == p).all(axis=1)
        finished = (accepted & (gain < SSR_TOLERANCE)) | (~accepted & ((damping[work] > 1e12) | stalled))
        self.alive[work[finished]] = False


# --- the profile likelihood on arrays ----------------------------------------------------------
#: Width of the final bracket of a limit, relative to 1 + |value| in internal parameters.
PROFILE_TOLERANCE = 1e-9
#: Iterations of the root search within a bracket (:func:`~tromplab.curves.likelihood.regula_falsi`).
PROFILE_ITERATIONS = 60
#: Starts across the bounds of another parameter from which every limit is re-optimised once
#: more: a limit below which that search finds a lower sum of squares is not reported.
PROFILE_CHECK_STARTS = 16


def profile_limits(
    problem: BatchProblem, best: np.ndarray, best_ssr: np.ndarray, steps: np.ndarray, level: float
) -> tuple[np.ndarray, np.ndarray]:
    r"""Profile-likelihood limits of every parameter of every experiment of ``problem`` at once.

    The limit of parameter :math:`\theta_j` on one side is where the sum of squares,
    re-optimised over the other parameters with :math:`\theta_j` held, reaches
    :math:`S_{min} (1 + F_{1,\nu}^{-1}(\text{level}) / \nu)`, :math:`\nu` = points minus
    parameters: the F test of lmfit's ``conf_interval`` with one parameter fixed.  Every
    (experiment, parameter, side) is one row of one batched Levenberg-Marquardt per step,
    and the search is the one every curve's profile uses (:mod:`tromplab.curves.likelihood`):
    the first step (``steps``, e.g. the Wald half-width) doubles until the level is passed
    (:func:`~tromplab.curves.likelihood.step_out`), then regula falsi (Illinois,
    :func:`~tromplab.curves.likelihood.regula_falsi`) on :math:`\sqrt{S - S_{min}}` less its
    value at the level, which is linear in :math:`\theta_j` for a quadratic profile, closes
    the bracket.  Each point of the profile is re-optimised from the last one short of the
    level (continuation), and every limit found is re-optimised once more from
    :data:`PROFILE_CHECK_STARTS` starts across the bounds of another parameter: where that
    finds a sum of squares below the level, the limit is not reported (the descent missed a
    lower branch of the profile).

    Parameters
    ----------
    problem : BatchProblem
        The experiments (one row each) and their parameter bounds.
    best : ndarray, shape (E, p)
        Internal parameters at the optimum (``ln d_cut``, shape, extras).
    best_ssr : ndarray, shape (E,)
        Sums of squares at ``best``.
    steps : ndarray, shape (E, p)
        First step away from the optimum per parameter (internal units, > 0).
    level : float
        Confidence level, 0..1.

    Returns
    -------
    low, high : ndarray, shape (E, p)
        Internal limits; nan where the profile stays below the level up to the parameter's
        bound (lmfit warns "bound reached" there), where no finite sum of squares was found,
        or where the global check found the profile below the level at the limit.
    """
    count, n_params = best.shape
    free = problem.data.n - n_params
    with np.errstate(all="ignore"):
        target = best_ssr * (1.0 + stats.f.ppf(level, 1, free) / free)
    experiment = np.repeat(np.arange(count), 2 * n_params)
    column = np.tile(np.repeat(np.arange(n_params), 2), count)
    search = _ProfileSearch(problem.take(experiment), column, np.tile([-1.0, 1.0], count * n_params),
                            best[experiment, column], best_ssr[experiment], target[experiment], best[experiment])  # fmt: skip
    step = steps[experiment, column]
    step = np.where(np.isfinite(step) & (step > 0), step, 0.1)
    searching = np.flatnonzero(np.isfinite(search.goal) & (free[experiment] > 0) & (search.room > 0))
    distance = np.full(column.size, np.nan)
    if searching.size:
        distance[searching] = _search_limits(search, searching, np.minimum(step, search.room)[searching])
    limit = _confirmed_limits(search, best[experiment], distance).reshape(count, n_params, 2)
    return limit[..., 0], limit[..., 1]


def _search_limits(search: _ProfileSearch, rows: np.ndarray, step: np.ndarray) -> np.ndarray:
    """The distance from the optimum to the limit of each of ``rows`` (nan where the level was not passed)."""
    centre, side = search.centre[rows], search.side[rows]

    def stepping(at, values):  # no finite sum of squares ends the side without a limit
        distance = search.excess(rows[at], values)
        return np.where(np.isfinite(distance), distance, np.nan)

    bracket = step_out(stepping, centre, side, search.room[rows], step, -search.scale[rows])
    found = np.full(rows.size, np.nan)
    closed = np.flatnonzero(bracket.closed)
    if closed.size:
        inside = rows[closed]

        def closing(at, values):  # no finite sum of squares counts as beyond the level
            return search.excess(inside[at], values)

        width = PROFILE_TOLERANCE * (1.0 + np.abs(search.centre[inside]))
        found[closed] = regula_falsi(closing, centre[closed], side[closed], bracket.take(closed), width,
                                     excess_tolerance=1e-12 * search.scale[inside], max_iterations=PROFILE_ITERATIONS)  # fmt: skip
    return found


def _confirmed_limits(search: _ProfileSearch, best: np.ndarray, distance: np.ndarray) -> np.ndarray:
    """The limit at each ``distance`` from the optimum, nan where the level was not passed, where
    it was passed on the bound itself (the bound reached below the level: lmfit warns there) or
    where the profile re-optimised from a grid of starts (:func:`_grid_profile_ssr`) lies below
    the level at the limit (a lower branch the descent missed)."""
    limit = search.centre + search.side * distance
    on_bound = np.abs(search.bound - limit) <= PROFILE_TOLERANCE * (1.0 + np.abs(search.centre))
    found = np.flatnonzero(np.isfinite(distance) & ~on_bound)
    lowest = _grid_profile_ssr(search.rows, found, search.column[found], limit[found], best[found])
    gap = search.goal[found] - search.floor[found]
    missed = found[lowest < search.goal[found] - 1e-3 * gap]
    limit = np.where(np.isfinite(distance) & ~on_bound, limit, np.nan)
    limit[missed] = np.nan
    return limit


class _ProfileSearch:
    """The rows of :func:`profile_limits`: one per (experiment, parameter, side), the parameter
    held at a value while the others are re-optimised from ``start`` (the last point of the
    row's profile short of the level)."""

    def __init__(self, rows: BatchProblem, column, side, centre, floor, goal, start):
        self.rows, self.column, self.side, self.centre, self.floor, self.goal = rows, column, side, centre, floor, goal
        self.start = start.copy()
        index = np.arange(column.size)
        self.bound = np.where(side > 0, rows.upper[index, column], rows.lower[index, column])
        self.room = np.abs(self.bound - centre)
        self.scale = np.sqrt(np.maximum(goal - floor, 0.0))

    def excess(self, work, value):
        """sqrt(S - S_min) less its value at the level (linear in theta for a quadratic profile) at
        theta_j = ``value`` of the rows ``work``; inf where no finite sum of squares was found."""
        params, ssr = self.profile(work, value, self.start[work])
        with np.errstate(invalid="ignore"):
            distance = np.where(np.isfinite(ssr), np.sqrt(np.maximum(ssr - self.floor[work], 0.0)) - self.scale[work], np.inf)
        short = distance < 0
        self.start[work[short]] = params[short]
        return distance

    def profile(self, work, value, start):
        """Re-optimised at theta_j = ``value``, from ``start``."""
        rows, column = self.rows, self.column[work]
        held = rows.lower.copy(), rows.upper.copy()
        rows.lower[work, column] = rows.upper[work, column] = value
        params = start.copy()
        params[np.arange(work.size), column] = value
        params, ssr, _ = levenberg_marquardt(rows, params, work)
        rows.lower, rows.upper = held
        return params, ssr


def _grid_profile_ssr(problem: BatchProblem, work: np.ndarray, column: np.ndarray, value: np.ndarray, best: np.ndarray):
    """The profile's sum of squares at ``value`` of ``column`` re-optimised from a grid of
    :data:`PROFILE_CHECK_STARTS` values of the first other parameter across its bounds (the
    rest at ``best``): the cheap global search that confirms a limit found by descent."""
    if not work.size:
        return np.zeros(0)
    other = np.where(column == 0, 1, 0)
    low, high = problem.lower[work, other], problem.upper[work, other]
    positive = low > 0
    fractions = np.linspace(0.0, 1.0, PROFILE_CHECK_STARTS)
    with np.errstate(divide="ignore", invalid="ignore"):
        grid = np.where(
            positive[:, None],
            np.exp(
                np.log(np.where(positive, low, 1.0))[:, None] + fractions * np.log(np.where(positive, high / low, 1.0))[:, None]
            ),
            low[:, None] + fractions * (high - low)[:, None],
        )
    starts = np.repeat(best, PROFILE_CHECK_STARTS, axis=0)
    rows = np.repeat(work, PROFILE_CHECK_STARTS)
    flat = np.arange(rows.size)
    starts[flat, np.repeat(other, PROFILE_CHECK_STARTS)] = grid.ravel()
    starts[flat, np.repeat(column, PROFILE_CHECK_STARTS)] = np.repeat(value, PROFILE_CHECK_STARTS)
    pinned = problem.take(rows)
    pinned.lower[flat, np.repeat(column, PROFILE_CHECK_STARTS)] = np.repeat(value, PROFILE_CHECK_STARTS)
    pinned.upper[flat, np.repeat(column, PROFILE_CHECK_STARTS)] = np.repeat(value, PROFILE_CHECK_STARTS)
    _, ssr, _ = levenberg_marquardt(pinned, starts, flat)
    return ssr.reshape(work.size, PROFILE_CHECK_STARTS).min(axis=1)
