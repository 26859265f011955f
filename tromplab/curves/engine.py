"""Batched fitting engine: one formula fitted to many experiments (or resamples) at once.

The single fit of :func:`tromplab.curves.curve_fit.fit_formula` runs a Python-level grid and three
lmfit solves per experiment; most of its time is interpreter and solver overhead, not
model evaluation.  This engine reaches the same least-squares optimum with numpy arrays
that hold every experiment and every starting point at once:

1. **Padded points.** The experiments are stacked into ``(experiments, points)`` arrays;
   missing points carry weight 0, so they add nothing to any sum of squares.
2. **Profiled shape grid.** For every experiment the sum of squares is evaluated on a
   grid of shapes (slopes from -0.02 to -20, as the single fit) times a log-spaced grid
   of ``d_cut``; at each grid shape the best ``d_cut`` is refined by a vectorised
   golden-section search in log size.  The best grid points are starting points.
3. **Bounded Levenberg-Marquardt.** From the data-driven start and the best grid points,
   a projected Levenberg-Marquardt iteration in ``(ln d_cut, shape, extras)`` runs on all
   rows at once: forward-difference Jacobians (one extra model evaluation per
   parameter), a damped Gauss-Newton step solved per row, parameters on a bound whose
   gradient points outward held fixed, and rows that have converged dropped from the
   work arrays.  The lowest sum of squares per experiment wins.
4. **Covariance.** At the optimum the Jacobian in the native parameters gives lmfit's
   covariance estimate, ``(J^T J)^{-1} SSR / (n - p)``.

Every formula whose curve broadcasts over array-valued shapes runs here, the piecewise
(10) included; a formula whose break moves with its shape, as (11), declares the hooks the
engine calls (:class:`~tromplab.curves.formulas.MovingBreak`: for (11) the vectorised
break-point solver :func:`~tromplab.curves.formulas.shuvalov_breaks`), so the engine names no formula.  Curves that
need a scalar root per parameter set (Whiten's fish-hook curve, whose ``beta*`` solves an
equation) and curves with two or more extra parameters (their extras interact, and the
engine starts them at one declared value only) are reported by :func:`~tromplab.curves.formulas.is_batchable` as not
batchable and fitted one by one by the caller.

The engine itself does not use lmfit; :func:`fit_formula_batch` wraps its optimum in the
same :class:`~tromplab.curves.curve_fit.CurveFit` a single fit returns, and
:meth:`tromplab.curves.curve_fit.CurveFit.with_lmfit` turns it into an lmfit result where one is needed
(profile intervals).
"""

from __future__ import annotations

import contextlib
import copy
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..loading.points import TrompPoints
from .batched import BatchProblem, PaddedPoints, levenberg_marquardt, sum_of_squares
from .curve_fit import CurveFit, FitOptions, failed_fit, fit_formula
from .fitting import ParameterFit, parameters_at_bounds
from .formulas import Formula, get_formula, is_batchable
from .measured import (
    formula_context,
    formula_contexts,
    measured_cut_size,
    measured_slope,
    measured_starts,
    normalised_weights,
    parameter_specs,
)
from .parameters import D_CUT_RANGE_FACTOR
from .screening import DEFAULT_ALPHA

#: Slopes at the cut of the shape grid (as :data:`tromplab.curves.measured.GRID_SLOPES`, every other one).
ENGINE_GRID_SLOPES = -np.geomspace(0.02, 20.0, 21)
#: The piecewise formulas (``Formula.piecewise``: (10) and (11)) have kinks in the sum of
#: squares, where a descent method can stop short: they get the single fit's full grid and
#: more starts from it.
PIECEWISE_GRID_SLOPES = -np.geomspace(0.02, 20.0, 41)
PIECEWISE_GRID_STARTS = 6
#: Log-spaced ``d_cut`` values per grid shape, before the golden-section refinement within
#: one grid step either side.  The grid only places starts for Levenberg-Marquardt: halving
#: it from 24 cuts and 14 golden steps left every one of 90,000 fits (10,000 synthetic
#: experiments x 9 formulas) within 2e-10 of its sum of squares (one lower) and took
#: 0.8 s off 4.7 s of fitting 1,024 experiments (docs/performance.md).
GRID_CUTS = 12
GOLDEN_STEPS = 10
#: Best grid points used as starts (besides the data-driven start).
GRID_STARTS = 3
#: Elements per work array in the grid stage (bounds the memory of large batches).
GRID_CHUNK_ELEMENTS = 2_000_000
ENGINE_MESSAGE = "batched Levenberg-Marquardt: converged"


@dataclass(frozen=True)
class BatchOptimum:
    """Best fit per experiment of one formula (arrays over experiments).

    ``values`` has one column per parameter (``d_cut``, the shape, the extras, in
    ``names`` order); ``covariance`` is nan where ``J^T J`` is singular; ``ssr`` is inf
    and ``success`` False where no start gave a finite sum of squares.
    """

    formula: Formula
    names: tuple[str, ...]
    values: np.ndarray
    ssr: np.ndarray
    residual: np.ndarray
    covariance: np.ndarray
    grid_ssr: np.ndarray
    nfev: np.ndarray
    n_starts: int

    @property
    def success(self) -> np.ndarray:
        return np.isfinite(self.ssr)

    def stderr(self) -> np.ndarray:
        with np.errstate(invalid="ignore"):
            return np.sqrt(np.diagonal(self.covariance, axis1=1, axis2=2))


# --- the fit -------------------------------------------------------------------------------
def golden_section(objective, lo: np.ndarray, hi: np.ndarray, steps: int):
    """Golden-section minimisation of ``objective`` on ``[lo, hi]``, elementwise on arrays:
    one evaluation per step, the bracket shrinking by 0.618 each time.  Returns the better
    interior point and its value."""
    ratio = (np.sqrt(5.0) - 1.0) / 2.0
    a, b = hi - ratio * (hi - lo), lo + ratio * (hi - lo)
    fa, fb = objective(a), objective(b)
    for _ in range(steps):
        left = fa <= fb
        lo, hi = np.where(left, lo, a), np.where(left, b, hi)
        a_new = np.where(left, hi - ratio * (hi - lo), b)
        b_new = np.where(left, a, lo + ratio * (hi - lo))
        moved = np.where(left, a_new, b_new)
        f_moved = objective(moved)
        fa, fb = np.where(left, f_moved, fb), np.where(left, fa, f_moved)
        a, b = a_new, b_new
    return np.where(fa <= fb, a, b), np.minimum(fa, fb)


def _grid_starts(problem: BatchProblem, start_cut: np.ndarray, extra_start: np.ndarray):
    """Best ``GRID_STARTS`` profiled grid points per experiment and the grid minimum."""
    formula, data = problem.formula, problem.data
    slopes, n_starts = (PIECEWISE_GRID_SLOPES, PIECEWISE_GRID_STARTS) if formula.piecewise else (ENGINE_GRID_SLOPES, GRID_STARTS)
    shapes = np.array(sorted({formula.clip_shape(formula.shape_for_slope(s)) for s in slopes}))
    count, n_shapes = len(data), shapes.size
    low, high = problem.lower[:, 0], problem.upper[:, 0]
    # the grid spans the measured sizes with a margin; the data-driven cut adds the rest
    real = data.root_weight > 0
    span_low = np.maximum(np.log(np.where(real, data.size, np.inf).min(axis=1) / 3.0), low)
    span_high = np.minimum(np.log(np.where(real, data.size, -np.inf).max(axis=1) * 3.0), high)
    fractions = np.linspace(0.0, 1.0, GRID_CUTS)
    best_cut = np.empty((count, n_shapes))
    best_ssr = np.empty((count, n_shapes))
    chunk = max(1, GRID_CHUNK_ELEMENTS // (n_shapes * (GRID_CUTS + 1) * data.size.shape[1]))
    for first in range(0, count, chunk):
        block = np.arange(first, min(first + chunk, count))
        cuts = span_low[block, None] + fractions * (span_high - span_low)[block, None]
        cuts = np.concatenate([cuts, start_cut[block, None]], axis=1)  # (b, C)
        width = ((span_high - span_low) / (GRID_CUTS - 1))[block, None]
        best_cut[block], best_ssr[block] = _profiled_grid(problem, block, cuts, shapes, extra_start, width)
    # local minima of the profile along the shape first (one start per basin), then the rest
    padded = np.pad(best_ssr, ((0, 0), (1, 1)), constant_values=np.inf)
    basin = (best_ssr <= padded[:, :-2]) & (best_ssr <= padded[:, 2:])
    order = np.lexsort((best_ssr, ~basin), axis=1)[:, :n_starts]
    cut = np.take_along_axis(best_cut, order, axis=1)
    shape = shapes[order]
    return cut, shape, best_ssr.min(axis=1)


def _profiled_grid(problem: BatchProblem, block: np.ndarray, cuts: np.ndarray, shapes: np.ndarray, extra_start, width):
    """``(cut, ssr)``, each ``(b, shapes)``: the best ``ln d_cut`` at each grid shape for the
    experiments of ``block``, first among ``cuts`` ``(b, C)``, then refined by golden section
    within ``width`` of it (the extras at ``extra_start``)."""
    count, n_shapes = block.size, shapes.size
    fixed = np.column_stack(
        [np.zeros(count * n_shapes), np.tile(shapes, count), *[np.full(count * n_shapes, v) for v in extra_start]]
    )
    x_break = problem.breaks(fixed, np.repeat(block, n_shapes))  # the shapes stay fixed while d_cut moves
    breaks = None if x_break is None else x_break.reshape(count, n_shapes, 1)
    data = problem.stacked(block)
    ssr = problem.ssr_on_grid(data, cuts, shapes, extra_start, None if breaks is None else breaks[..., 0])
    pick = np.argmin(ssr, axis=2)
    best_cut = np.take_along_axis(np.repeat(cuts[:, None, :], n_shapes, axis=1), pick[..., None], axis=2)[..., 0]
    best_ssr = np.take_along_axis(ssr, pick[..., None], axis=2)[..., 0]
    low, high = problem.lower[block, :1], problem.upper[block, :1]

    def ssr_at(log_cut):  # (b, shapes)
        params = fixed.copy()
        params[:, 0] = log_cut.ravel()
        residual = problem.residual_of(data, params.reshape(count, n_shapes, -1), breaks)
        return sum_of_squares(residual.reshape(-1, data[0].shape[2])).reshape(count, n_shapes)

    refined, refined_ssr = golden_section(
        ssr_at, np.clip(best_cut - width, low, high), np.clip(best_cut + width, low, high), GOLDEN_STEPS
    )
    better = refined_ssr < best_ssr
    return np.where(better, refined, best_cut), np.where(better, refined_ssr, best_ssr)


def compass_search(
    problem: BatchProblem, params: np.ndarray, rows: np.ndarray, *, first_step: float = 1e-2, last_step: float = 1e-11
):
    """Derivative-free descent for the kinks of the piecewise formulas, on every row at once.

    Tries steps along each parameter and along the two diagonals of ``(ln d_cut, shape)``
    (a point crossing the break moves along such a diagonal), takes the best improving
    one, and halves the step when none improves, down to ``last_step`` (relative).
    Returns ``(params, ssr, nfev)``.
    """
    lower, upper = problem.lower[rows], problem.upper[rows]
    n_params = params.shape[1]
    directions = [row for row in np.eye(n_params)] + [
        np.r_[1.0, 1.0, np.zeros(n_params - 2)],
        np.r_[1.0, -1.0, np.zeros(n_params - 2)],
    ]
    directions = np.array(directions + [-d for d in directions])
    params = params.copy()
    x_break = problem.breaks(params, rows)
    ssr = sum_of_squares(problem.residual(params, rows, x_break))
    nfev = np.ones(rows.size, dtype=int)
    step = np.full(rows.size, first_step)
    open_ = np.flatnonzero(np.isfinite(ssr))
    while open_.size:
        scale = np.maximum(np.abs(params[open_]), 1.0) * step[open_, None]
        trials = np.clip(params[open_, None, :] + directions[None] * scale[:, None, :], lower[open_, None], upper[open_, None])
        flat = trials.reshape(-1, n_params)
        trial_rows = np.repeat(rows[open_], len(directions))
        trial_breaks = None
        if x_break is not None:  # the steps in d_cut alone keep the current break
            trial_breaks = problem.breaks_near(
                flat, trial_rows, np.repeat(params[open_, 1], len(directions)), np.repeat(x_break[open_], len(directions), axis=0)
            )
        trial_ssr = sum_of_squares(problem.residual(flat, trial_rows, trial_breaks)).reshape(open_.size, -1)
        nfev[open_] += len(directions)
        pick = np.argmin(trial_ssr, axis=1)
        best = trial_ssr[np.arange(open_.size), pick]
        improved = best < ssr[open_]
        moved = open_[improved]
        params[moved] = trials[improved, pick[improved]]
        ssr[moved] = best[improved]
        if x_break is not None:
            x_break[moved] = trial_breaks.reshape(open_.size, len(directions), 1)[improved, pick[improved]]
        step[open_[~improved]] *= 0.5
        open_ = open_[step[open_] >= last_step]
    return params, ssr, nfev


#: A measured point within this distance (in ln x) of the break of (11) at the optimum found
#: so far gets the search along its crossing (:func:`search_break_crossings`).
CROSSING_NEAR = 0.03
#: Golden-section steps along a crossing: the bracket of ln kr shrinks by 0.618 per step.
CROSSING_STEPS = 36


def search_break_crossings(problem: BatchProblem, params: np.ndarray, ssr: np.ndarray, rows: np.ndarray):
    """A moving break (``Formula.moving_break``, formula (11)): the optimum may sit where a
    measured point crosses the break, ``size_i / d_cut = x_a(kr)``.  Along that curve the sum
    of squares has a ridge of kinks that steps along the axes or diagonals
    (:func:`compass_search`) cannot follow; search it directly:
    for each point near the break, ``kr`` by golden section on ``ln kr`` (x/÷ 1.25 around the
    current value) with ``d_cut = size_i / x_a(kr)``.  Rows keep the lower sum of squares.
    Returns ``(params, ssr, nfev)``."""
    data = problem.data
    params, ssr = params.copy(), ssr.copy()
    nfev = np.zeros(rows.size, dtype=int)
    with np.errstate(all="ignore"):
        distance = np.abs(np.log(data.size[rows] / np.exp(params[:, :1])) - np.log(problem.breaks(params, rows)))
    real = np.arange(data.size.shape[1])[None, :] < data.n[rows][:, None]
    pair_row, pair_point = np.nonzero(real & (distance < CROSSING_NEAR) & np.isfinite(ssr)[:, None])
    if pair_row.size == 0:
        return params, ssr, nfev
    work_rows = rows[pair_row]
    size = data.size[work_rows, pair_point]
    efficiency = problem.efficiency[work_rows]
    cut_low, cut_high = problem.lower[work_rows, 0], problem.upper[work_rows, 0]
    center = np.log(params[pair_row, 1])
    low = np.maximum(center - np.log(1.25), np.log(problem.lower[work_rows, 1]))
    high = np.minimum(center + np.log(1.25), np.log(problem.upper[work_rows, 1]))
    gathered = problem.gathered(work_rows)

    def crossing(log_shape):
        shape = np.exp(log_shape)
        x_break = problem.formula.moving_break.on_arrays(shape, efficiency)
        with np.errstate(divide="ignore"):  # no break (x_a = 0): the crossing runs off to the cut's bound
            cut = np.clip(np.log(size / x_break), cut_low, cut_high)
        trial = np.column_stack([cut, shape])
        return trial, sum_of_squares(problem.residual_of(gathered, trial, x_break[:, None]))

    best_log_shape, _ = golden_section(lambda log_shape: crossing(log_shape)[1], low, high, CROSSING_STEPS)
    trial, trial_ssr = crossing(best_log_shape)
    np.add.at(nfev, pair_row, CROSSING_STEPS + 3)
    for pair in np.argsort(trial_ssr):  # best first, so each row keeps its lowest
        row = pair_row[pair]
        if trial_ssr[pair] < ssr[row]:
            params[row, :2], ssr[row] = trial[pair], trial_ssr[pair]
    return params, ssr, nfev


def fit_batch(
    formula,
    data: PaddedPoints,
    *,
    starts: np.ndarray,
    efficiency=None,
    global_search: bool = True,
    cut_factor: float = D_CUT_RANGE_FACTOR,
) -> BatchOptimum:
    """Fit ``formula`` to every experiment of ``data`` at once.

    Parameters
    ----------
    formula : Formula or str
        A batchable registry entry (:func:`is_batchable`).
    data : PaddedPoints
        The experiments.
    starts : ndarray, shape (E, S, p)
        Starting points per experiment in native parameters (``d_cut``, shape, extras).
    efficiency : ndarray, shape (E,), optional
        Measured classifier efficiency per experiment (formula (11) only).
    global_search : bool
        Add the best points of the profiled shape grid as further starts.
    cut_factor : float
        ``d_cut`` is bounded to [smallest size / factor, largest size x factor].

    Returns
    -------
    BatchOptimum
    """
    formula = get_formula(formula)
    if not is_batchable(formula):
        raise ValueError(f"formula {formula.id} cannot be evaluated on arrays of parameters; fit it one by one")
    problem = BatchProblem(formula, data, efficiency, cut_factor)
    count = len(data)
    starts, grid_ssr, kink = _all_starts(problem, starts, efficiency, global_search=global_search)
    n_starts = starts.shape[1]
    rows = np.repeat(np.arange(count), n_starts)
    params, ssr, nfev = levenberg_marquardt(problem, starts.reshape(count * n_starts, -1), rows)
    if formula.piecewise:  # past the kinks without derivatives, then polish again
        best = np.argmin(ssr.reshape(count, n_starts), axis=1) + np.arange(count) * n_starts
        moving = formula.moving_break if global_search else None
        _polish_piecewise(problem, params, ssr, nfev, best, rows[best], kink=kink, moving=moving)
    ssr = ssr.reshape(count, n_starts)
    best = np.argmin(ssr, axis=1)
    pick = np.arange(count) * n_starts + best
    best_params, best_ssr = params[pick], ssr[np.arange(count), best]
    all_rows = np.arange(count)
    residual = problem.residual(best_params, all_rows)
    native = best_params.copy()
    native[:, 0] = np.exp(best_params[:, 0])
    jac = problem.jacobian(best_params, all_rows, residual)
    jac[:, :, 0] /= native[:, :1]  # d r / d d_cut = (d r / d ln d_cut) / d_cut
    covariance = _covariance(jac, best_ssr, data.n, native.shape[1])
    names = ("d_cut", formula.shape_name, *problem.extra_names)
    total_nfev = nfev.reshape(count, n_starts).sum(axis=1)
    return BatchOptimum(formula, names, native, best_ssr, residual, covariance, grid_ssr, total_nfev, n_starts)


def _all_starts(problem: BatchProblem, starts, efficiency, *, global_search: bool):
    """``(starts, grid_ssr, kink)``: the given starts (``ln d_cut``, clipped into the bounds), with
    ``global_search`` the best points of the profiled shape grid and, for a moving break with a
    kink, starts on both sides of it; the grid's SSR (nan without the search) and the kink (or None)."""
    formula, count = problem.formula, len(problem.data)
    starts = np.array(starts, dtype=float)
    low, high = problem.lower[:, None, :], problem.upper[:, None, :]
    starts[..., 0] = np.log(starts[..., 0])
    starts = np.clip(starts, low, high)
    grid_ssr = np.full(count, np.nan)
    if global_search:
        extra_start = [extra.start for extra in formula.extras]
        grid_cut, grid_shape, grid_ssr = _grid_starts(problem, starts[:, 0, 0], extra_start)
        extras = np.broadcast_to(np.array(extra_start), (count, grid_cut.shape[1], len(extra_start)))
        starts = np.concatenate([starts, np.concatenate([grid_cut[..., None], grid_shape[..., None], extras], axis=2)], axis=1)
    moving = formula.moving_break if global_search else None
    kink = None
    if moving is not None and moving.kink is not None:  # start on both sides of the kink
        kink = moving.kink(efficiency, formula.shape_bounds)
        sides = np.stack([np.clip(kink * f, *formula.shape_bounds) for f in (0.97, 1.03, 1.2)], axis=1)
        near = np.stack([np.broadcast_to(starts[:, :1, 0], sides.shape), sides], axis=2)
        starts = np.concatenate([starts, near], axis=1)
    return starts, grid_ssr, kink


def _polish_piecewise(problem: BatchProblem, params, ssr, nfev, best, rows, *, kink, moving) -> None:
    """Move the ``best`` optimum of each experiment of a piecewise formula past its kinks (in place):
    a compass search without derivatives, Levenberg-Marquardt again, then ``d_cut`` alone at the
    ``kink``'s shape and the search along the crossings with the ``moving`` break, where they exist."""
    params[best], ssr[best], more = compass_search(problem, params[best], rows)
    nfev[best] += more
    params[best], ssr[best], more = levenberg_marquardt(problem, params[best], rows)
    nfev[best] += more
    if kink is not None:  # the optimum can sit on the kink itself: d_cut alone at the kink's shape
        on_kink = copy.copy(problem)
        on_kink.lower, on_kink.upper = problem.lower.copy(), problem.upper.copy()
        on_kink.lower[:, 1] = on_kink.upper[:, 1] = kink
        kinked = params[best].copy()
        kinked[:, 1] = kink
        kinked, kinked_ssr, more = levenberg_marquardt(on_kink, kinked, rows)
        nfev[best] += more
        lower_ssr = kinked_ssr < ssr[best]
        params[best[lower_ssr]], ssr[best[lower_ssr]] = kinked[lower_ssr], kinked_ssr[lower_ssr]
    if moving is not None:  # along the crossings of measured points with the moving break
        params[best], ssr[best], more = search_break_crossings(problem, params[best], ssr[best], rows)
        nfev[best] += more
        params[best], ssr[best], more = scan_shapes_nearby(problem, params[best], ssr[best], rows)
        nfev[best] += more


#: Shapes scanned around the optimum of a moving-break formula (relative to its shape, in ln):
#: the points crossing the break cut the sum of squares into basins a few per cent wide in
#: the shape, narrower than the grid's step (19 %), so a basin next to the optimum can hold no
#: grid start (8 fits of (11) among 10,000 synthetic experiments ended 0.01-1.4 % above it;
#: with this scan none ends more than 1e-7 above what a grid of 161 shapes finds).
NEARBY_SHAPES = np.linspace(-0.25, 0.25, 51)
#: Half-width (in ln d_cut) of the golden-section search of d_cut at each scanned shape.
NEARBY_CUT_SPAN = 0.15
#: Best scanned points from which Levenberg-Marquardt runs.
NEARBY_STARTS = 2
#: Golden-section steps of d_cut at each scanned shape (more than the grid's: a narrower basin).
NEARBY_GOLDEN_STEPS = GOLDEN_STEPS + 4


def scan_shapes_nearby(problem: BatchProblem, params: np.ndarray, ssr: np.ndarray, rows: np.ndarray):
    """Profile the sum of squares over shapes near each row's optimum (``d_cut`` by golden
    section at each) and run Levenberg-Marquardt from the best scanned points; a row keeps a
    lower sum of squares.  For formulas whose break moves with the shape (:class:`MovingBreak`).
    Returns ``(params, ssr, nfev)``."""
    params, ssr = params.copy(), ssr.copy()
    count, n_shapes = rows.size, NEARBY_SHAPES.size
    lower, upper = problem.lower[rows], problem.upper[rows]
    shapes = np.clip(params[:, 1:2] * np.exp(NEARBY_SHAPES), lower[:, 1:2], upper[:, 1:2])  # (rows, K)
    work_rows = np.repeat(rows, n_shapes)
    fixed = np.column_stack([np.zeros(work_rows.size), shapes.ravel(), np.repeat(params[:, 2:], n_shapes, axis=0)])
    x_break = problem.breaks(fixed, work_rows)  # the shapes stay fixed while d_cut moves
    gathered = problem.gathered(work_rows)

    def ssr_at(log_cut):
        trial = fixed.copy()
        trial[:, 0] = log_cut
        return sum_of_squares(problem.residual_of(gathered, trial, x_break))

    centre = np.repeat(params[:, 0], n_shapes)
    low = np.maximum(centre - NEARBY_CUT_SPAN, np.repeat(lower[:, 0], n_shapes))
    high = np.minimum(centre + NEARBY_CUT_SPAN, np.repeat(upper[:, 0], n_shapes))
    log_cut, scanned = golden_section(ssr_at, low, high, NEARBY_GOLDEN_STEPS)
    scanned = scanned.reshape(count, n_shapes)
    picks = np.argsort(scanned, axis=1)[:, :NEARBY_STARTS]
    starts = np.concatenate(
        [
            np.take_along_axis(log_cut.reshape(count, n_shapes), picks, axis=1)[..., None],
            np.take_along_axis(shapes, picks, axis=1)[..., None],
        ],
        axis=2,
    )
    if params.shape[1] > 2:
        starts = np.concatenate([starts, np.repeat(params[:, None, 2:], NEARBY_STARTS, axis=1)], axis=2)
    found, found_ssr, nfev = levenberg_marquardt(problem, starts.reshape(-1, params.shape[1]), np.repeat(rows, NEARBY_STARTS))
    found_ssr = found_ssr.reshape(count, NEARBY_STARTS)
    pick = np.argmin(found_ssr, axis=1)
    best_ssr = found_ssr[np.arange(count), pick]
    better = best_ssr < ssr
    params[better] = found.reshape(count, NEARBY_STARTS, -1)[np.arange(count), pick][better]
    ssr[better] = best_ssr[better]
    # golden_section evaluates two points, then one per step
    return params, ssr, n_shapes * (NEARBY_GOLDEN_STEPS + 2) + nfev.reshape(count, NEARBY_STARTS).sum(axis=1)


def _covariance(jac: np.ndarray, ssr: np.ndarray, n: np.ndarray, n_params: int) -> np.ndarray:
    """lmfit's estimate ``(J^T J)^{-1} SSR/(n - p)``; nan where singular or not finite."""
    hessian = np.einsum("bkp,bkq->bpq", jac, jac)
    covariance = np.full_like(hessian, np.nan)
    usable = np.flatnonzero(np.all(np.isfinite(hessian), axis=(1, 2)) & np.isfinite(ssr) & (n > n_params))
    try:  # all small p x p inverses in one call (LAPACK per matrix, as one by one)
        inverses = np.linalg.inv(hessian[usable])
    except np.linalg.LinAlgError:  # a singular one among them: one by one, the singular ones stay nan
        inverses = np.full((usable.size, n_params, n_params), np.nan)
        for k, row in enumerate(usable):
            with contextlib.suppress(np.linalg.LinAlgError):
                inverses[k] = np.linalg.inv(hessian[row])
    finite = np.all(np.isfinite(inverses), axis=(1, 2))
    rows = usable[finite]
    covariance[rows] = inverses[finite] * ssr[rows, None, None] / (n[rows] - n_params)[:, None, None]
    return covariance


# --- from the batched optimum to CurveFit results ----------------------------------------------
def fit_formula_batch(
    experiments: Sequence[TrompPoints],
    formula,
    *,
    alpha: float | None = None,
    delta_max: float | None = None,
    global_search: bool = True,
    start: dict[str, float] | None = None,
    size_unit: str = "",
    width: int | None = None,
    measured: Sequence[tuple[float, float]] | None = None,
    options: Sequence[FitOptions] | None = None,
) -> list:
    """:func:`tromplab.curves.curve_fit.fit_formula` for many experiments at once.

    Returns one :class:`~tromplab.curves.curve_fit.CurveFit` per experiment, in order, with the same
    recorded options as a single fit, so its screen, indices, diagnostics and warnings
    are derived in the same way.  The fit's ``ParameterFit`` is built from the batched
    optimum (``raw`` is None; :meth:`tromplab.curves.curve_fit.CurveFit.with_lmfit` gives an lmfit result).
    Experiments with too few points for the formula get a failed fit with the reason.
    ``global_search`` and ``start`` (one further start for every experiment) are as for a
    single fit; the bootstrap refits its resamples from the optimum without the grid.
    ``width`` pads the experiments to at least that many points (:class:`PaddedPoints`);
    ``measured`` gives each experiment's :func:`measured_start` when the caller fits several
    formulas to the same experiments (computed here otherwise), ``options`` each experiment's
    :class:`~tromplab.curves.curve_fit.FitOptions` with the same arguments (the formulas of
    an experiment then share them).
    """

    alpha = DEFAULT_ALPHA if alpha is None else alpha
    formula = get_formula(formula)
    usable = [i for i, points in enumerate(experiments) if points.n > formula.n_params]
    results: list = [None] * len(experiments)
    for i, points in enumerate(experiments):
        if points.n <= formula.n_params:
            message = f"{points.n} points cannot be fitted with {formula.n_params} parameters"
            results[i] = failed_fit(points, formula, message, alpha=alpha, delta_max=delta_max, size_unit=size_unit)
    if not usable:
        return results
    chosen = [experiments[i] for i in usable]
    starts = _given_starts(formula, [measured_start(experiments[i]) if measured is None else measured[i] for i in usable], start)
    contexts = [formula_context(formula, points) for points in chosen]
    efficiency = np.array([c["measured_efficiency"] for c in contexts]) if formula.context_from_efficiency else None
    data = PaddedPoints.from_points(chosen, width)
    optimum = fit_batch(formula, data, starts=starts, efficiency=efficiency, global_search=global_search)
    for row, (i, points, fit) in enumerate(zip(usable, chosen, _parameter_fits(optimum, chosen))):
        results[i] = CurveFit(
            formula=formula,
            points=points,
            fit=fit,
            context=contexts[row],
            options=options[i]
            if options is not None
            else FitOptions.for_points(
                points, alpha=alpha, delta_max=delta_max, size_unit=size_unit, global_search=global_search
            ),
            grid_ssr=float(optimum.grid_ssr[row]),
        )
    return results


def _given_starts(formula: Formula, measured: Sequence[tuple[float, float]], start: dict[str, float] | None) -> np.ndarray:
    """The starts of :func:`fit_formula_batch` in native parameters, ``(experiments, 1 or 2,
    parameters)``: each experiment's measured cut and slope (the extras at their declared
    start), and ``start`` for every experiment when given."""
    names = ("d_cut", formula.shape_name, *(extra.name for extra in formula.extras))
    starts = np.empty((len(measured), 1 if start is None else 2, len(names)))
    for row, (cut, slope) in enumerate(measured):
        starts[row, 0, :2] = cut, formula.shape_for_slope(slope)
        starts[row, 0, 2:] = [extra.start for extra in formula.extras]
    if start is not None:
        starts[:, 1, :] = [start[name] for name in names]
    return starts


def measured_start(points: TrompPoints) -> tuple[float, float]:
    """The measured cut size and the measured slope at it: the data-driven start of every formula."""
    cut = measured_cut_size(points)
    return cut, measured_slope(points, cut)


def _parameter_fits(optimum: BatchOptimum, experiments: Sequence[TrompPoints]) -> list[ParameterFit]:
    """The :class:`ParameterFit` of each experiment (row) of ``optimum``: standard errors and
    covariance where ``J^T J`` could be inverted, the parameters on a bound named."""
    names, formula = optimum.names, optimum.formula
    finite = np.isfinite(optimum.ssr).tolist()
    known = np.all(np.isfinite(optimum.covariance), axis=(1, 2)).tolist()
    values, stderr = optimum.values.tolist(), optimum.stderr().tolist()
    ssr, nfev = optimum.ssr.tolist(), optimum.nfev.tolist()
    fits = []
    for row, points in enumerate(experiments):
        specs = parameter_specs(formula, points)
        if not finite[row]:
            failed = "fit failed from every start: non-finite sum of squares"
            fits.append(ParameterFit.failed(specs, points.n, failed, optimum.n_starts))
            continue
        found = dict(zip(names, values[row]))
        fits.append(
            ParameterFit(
                names=names,
                values=found,
                stderr=dict(zip(names, stderr[row])) if known[row] else dict.fromkeys(names, np.nan),
                ssr=ssr[row],
                n_points=points.n,
                success=True,
                message=ENGINE_MESSAGE,
                at_bound=parameters_at_bounds(specs, found),
                n_starts=optimum.n_starts,
                nfev=nfev[row],
                covariance=optimum.covariance[row].copy() if known[row] else None,
                residual=optimum.residual[row, : points.n].copy(),
            )
        )
    return fits


# --- the bootstrap on the engine -------------------------------------------------------------
#: Most resamples accepted per fit; beyond it the percentiles no longer change (Efron and
#: Tibshirani 1993 suggest 1,000-2,000 for percentile intervals) and the cost only grows.
MAX_BOOTSTRAP_RESAMPLES = 100_000
#: Largest total number of bootstrap refits (resamples x fits) run without refusing.
MAX_BOOTSTRAP_REFITS = 20_000_000
#: Measured cost of one batched bootstrap refit with its indices (seconds, 2-core machine; docs/performance.md).
SECONDS_PER_BOOTSTRAP_REFIT = 1e-4  # 0.72 s for 1,000 x 9 (benchmarks/bootstrap.py); (11) about 3e-4


def check_bootstrap_request(n_resamples: int, *, n_fits: int) -> float:
    """Refuse a bootstrap too large to be useful, before any work; return its estimated seconds.

    Raises
    ------
    ValueError
        When ``n_resamples`` exceeds :data:`MAX_BOOTSTRAP_RESAMPLES` or the total number of
        refits exceeds :data:`MAX_BOOTSTRAP_REFITS`, naming the estimated time.
    """
    refits = n_resamples * max(n_fits, 1)
    seconds = refits * SECONDS_PER_BOOTSTRAP_REFIT
    estimate = f"{refits:,} refits, about {_duration(seconds)} on one core"
    if n_resamples > MAX_BOOTSTRAP_RESAMPLES:
        raise ValueError(
            f"--bootstrap {n_resamples:,} is more than the {MAX_BOOTSTRAP_RESAMPLES:,} resamples "
            f"percentile intervals need ({estimate}); 1,000-2,000 are usual"
        )
    if refits > MAX_BOOTSTRAP_REFITS:
        raise ValueError(
            f"--bootstrap {n_resamples:,} on {n_fits:,} fits means {estimate}; use fewer resamples or fewer formulas"
        )
    return seconds


def _duration(seconds: float) -> str:
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def refit_partitions(fit, partitions: np.ndarray) -> tuple[BatchOptimum, np.ndarray | None]:
    """Refit ``fit.formula`` to its points with each row of ``partitions`` as the measured
    partition (the residual bootstrap's resamples), all at once and without the grid.

    The arrays counterpart of :func:`refit_resamples` for a batchable formula: the same two
    starts (each row's measured cut and slope, and the optimum of ``fit``), the same bounds and
    weights, but no point records and no result objects per row.  Rows whose sum of squares is
    not finite failed.  Returns the optimum and, for a formula that takes the measured
    efficiency (11), each row's measured efficiency (else None).
    """
    points, formula = fit.points, fit.formula
    partitions = np.atleast_2d(np.asarray(partitions, dtype=float))
    count = partitions.shape[0]
    weight = normalised_weights(points)
    data = PaddedPoints(
        np.broadcast_to(points.size, partitions.shape).copy(),
        partitions,
        np.tile(np.sqrt(weight), (count, 1)),
        np.full(count, points.n),
    )
    names = fit.fit.names
    starts = np.empty((count, 2, len(names)))
    cut, slope = measured_starts(points.size, partitions)
    starts[:, 0, 0], starts[:, 0, 1] = cut, [formula.shape_for_slope(s) for s in slope]
    starts[:, 0, 2:] = [extra.start for extra in formula.extras]
    starts[:, 1, :] = [fit.fit.values[name] for name in names]
    efficiency = formula_contexts(formula, points.size, partitions).get("measured_efficiency")
    return fit_batch(formula, data, starts=starts, efficiency=efficiency, global_search=False), efficiency


def refit_resamples(fit, samples: Sequence[TrompPoints], *, delta_max: float | None = None) -> list:
    """Refit ``fit.formula`` to every resample at once, from the optimum of ``fit`` (no grid).

    The batched counterpart of ``fit_formula(sample, global_search=False,
    starts=[fit values])`` per resample; formulas the engine cannot evaluate on arrays are
    refitted one by one.
    """

    options = fit.options
    delta_max = options.delta_max if delta_max is None else delta_max
    start = dict(fit.fit.values)
    if is_batchable(fit.formula):
        return fit_formula_batch(
            samples,
            fit.formula,
            alpha=options.alpha,
            delta_max=delta_max,
            global_search=False,
            start=start,
            size_unit=options.size_unit,
        )
    return [
        fit_formula(
            sample,
            fit.formula,
            alpha=options.alpha,
            delta_max=delta_max,
            global_search=False,
            starts=[start],
            size_unit=options.size_unit,
        )
        for sample in samples
    ]
