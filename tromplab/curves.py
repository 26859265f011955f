"""Fitting one separation-curve formula to the Tromp points of one experiment.

The least-squares optimum is reached robustly in three steps:

1. a data-driven start: ``d_cut`` where the measured curve crosses 1/2 (interpolated
   in log size) and the shape that gives the measured slope at the cut
   (``Formula.shape_for_slope``);
2. a cheap global search: a grid of shapes spanning slopes from -0.02 to -20 (the
   same sharpness for every formula), with ``d_cut`` profiled out by a bounded scalar
   minimisation at each grid shape;
3. lmfit's bounded trust-region solver from the data-driven start and from the best
   grid points; the lowest sum of squares wins.

Because the grid points are themselves starting points, the reported optimum is never
worse than the grid; the grid minimum is kept in the result so that this can be seen.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import optimize

from .diagnostics import RESIDUAL_WARNING, ResidualDiagnostics, residual_diagnostics
from .fitting import ParameterFit, ParameterSpec, least_squares
from .formulas import Formula, NoBreakPointError, get_formula, shuvalov_break
from .indices import CurveIndices, curve_indices
from .points import TrompPoints
from .screening import DEFAULT_ALPHA, FisherScreen, check_screenable, fisher_screen

GRID_SLOPES = -np.geomspace(0.02, 20.0, 41)
N_GRID_STARTS = 2
D_CUT_RANGE_FACTOR = 100.0


@dataclass(frozen=True)
class CurveFit:
    """Result of fitting one formula to one experiment.

    ``success`` is False when the fit failed; ``message`` then says why and the numbers
    are nan.  ``warnings`` lists conditions a user should know about a successful fit
    (a parameter on its bound, formula (11) without a break point, systematic residuals,
    a curve above 1).
    """

    formula: Formula
    points: TrompPoints
    fit: ParameterFit
    context: dict = field(default_factory=dict)
    screen: FisherScreen | None = None
    indices: CurveIndices | None = None
    grid_ssr: float = np.nan
    warnings: tuple[str, ...] = ()
    x_break: float = np.nan
    diagnostics: ResidualDiagnostics | None = None

    @property
    def experiment(self) -> str:
        return self.points.experiment

    @property
    def success(self) -> bool:
        return self.fit.success

    @property
    def message(self) -> str:
        """The solver's message, or why the fit failed."""
        return self.fit.message

    @property
    def d_cut(self) -> float:
        return self.fit.values["d_cut"]

    @property
    def shape(self) -> float:
        return self.fit.values[self.formula.shape_name]

    @property
    def extras(self) -> dict[str, float]:
        """Fitted bypass / fish-hook parameters (empty for the nine paper formulas)."""
        return self.curve_arguments()[2]

    def curve_arguments(self, values: dict[str, float] | None = None) -> tuple[float, float, dict[str, float]]:
        """``(d_cut, shape, extras)`` from parameter ``values`` (default: the fitted ones)."""
        values = self.fit.values if values is None else values
        extras = {extra.name: values[extra.name] for extra in self.formula.extras}
        return values["d_cut"], values[self.formula.shape_name], extras

    def predict(self, size, values: dict[str, float] | None = None) -> np.ndarray:
        """Partition to fines at ``size`` for the fitted parameters (or other ``values``)."""
        d_cut, shape, extras = self.curve_arguments(values)
        return self.formula(size, d_cut, shape, **self.context, **extras)

    def row(self) -> dict:
        """One row of ``fits.csv`` (see :data:`FIT_COLUMNS`)."""
        screen, ind = self.screen, self.indices
        criteria = self.fit.information_criteria()
        return {
            "experiment": self.experiment,
            "equation": self.formula.equation,
            "formula": self.formula.id,
            "n": self.points.n,
            "d_cut": self.d_cut,
            "d_cut_stderr": self.fit.stderr["d_cut"],
            "shape_name": self.formula.shape_name,
            "shape": self.shape,
            "shape_stderr": self.fit.stderr[self.formula.shape_name],
            "ssr": self.fit.ssr,
            "F": screen.F if screen else np.nan,
            "F_crit": screen.F_crit if screen else np.nan,
            "adequate": screen.adequate if screen and self.success else False,
            "eta": ind.eta if ind else np.nan,
            "epsilon": ind.epsilon if ind else np.nan,
            "slope": ind.slope if ind else np.nan,
            "d25": ind.d25 if ind else np.nan,
            "d75": ind.d75 if ind else np.nan,
            "ep": ind.ep if ind else np.nan,
            "imperfection": ind.imperfection if ind else np.nan,
            "aic": criteria["aic"],
            "aicc": criteria["aicc"],
            "bic": criteria["bic"],
            "runs_p": self.diagnostics.runs_p if self.diagnostics else np.nan,
            "normality_p": self.diagnostics.normality_p if self.diagnostics else np.nan,
            "residuals": self.diagnostics.verdict if self.diagnostics else "",
            "extrapolated": ";".join(ind.extrapolated) if ind else "",
            "x_break": self.x_break,
            "bypass": self.fit.values.get("bypass", np.nan),
            "fishhook": self.fit.values.get("fishhook", np.nan),
            "success": self.success,
            "message": self.message,
            "warnings": "; ".join(self.warnings),
        }


def measured_cut_size(points: TrompPoints) -> float:
    """Size where the measured curve first falls through 1/2, interpolated in log size.

    Where the points never cross 1/2 the size of the point closest to 1/2 is returned.
    """
    phi, log_size = points.partition_fine, np.log(points.size)
    above = phi >= 0.5
    for i in range(points.n - 1):
        if above[i] and not above[i + 1]:
            t = (phi[i] - 0.5) / (phi[i] - phi[i + 1])
            return float(np.exp(log_size[i] + t * (log_size[i + 1] - log_size[i])))
    return float(points.size[np.argmin(np.abs(phi - 0.5))])


def measured_efficiency(points: TrompPoints) -> float:
    """Classifier efficiency eta of the measured curve, used by formula (11).

    Rule: relative sizes ``x = size / d_cut_exp`` with ``d_cut_exp`` from
    :func:`measured_cut_size`; the points are joined linearly in ``x``; below the
    smallest measured size the curve is held at its first value (down to ``x = 0``), and
    ``phi(1) = 1/2`` closes the interval; ``eta_exp`` is the area on ``0 <= x <= 1``.
    """
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


def _parameter_specs(formula: Formula, points: TrompPoints) -> list[ParameterSpec]:
    return [
        ParameterSpec("d_cut", points.size.min() / D_CUT_RANGE_FACTOR, points.size.max() * D_CUT_RANGE_FACTOR),
        ParameterSpec(formula.shape_name, *formula.shape_bounds),
        *(ParameterSpec(extra.name, *extra.bounds) for extra in formula.extras),
    ]


def normalised_weights(points: TrompPoints) -> np.ndarray:
    """Least-squares weights scaled to mean 1 (all ones when the points carry none), so the
    weighted sums of squares of the fit and of the Fisher screen share one scale."""
    if points.weight is None:
        return np.ones(points.n)
    return points.weight / points.weight.mean()


def fit_formula(
    points: TrompPoints,
    formula,
    *,
    alpha: float = DEFAULT_ALPHA,
    delta_max: float | None = None,
    global_search: bool = True,
    starts: list[dict] | None = None,
) -> CurveFit:
    """Fit ``formula`` to ``points``, screen it and compute its indices.

    Parameters
    ----------
    points : TrompPoints
        Measured curve (more than two points).
    formula : Formula or str
        Registry entry, id or equation number.
    alpha : float
        Significance level of the Fisher screen.
    delta_max : float, optional
        Largest feed particle size for the misplacement; default ``points.largest_size``.
    global_search : bool
        Run the profiled shape grid (turn off only for refits from a known optimum, as
        the bootstrap does).
    starts : list of dict, optional
        Extra starting points (parameter name -> value).

    Returns
    -------
    CurveFit
        Always; ``success`` is False with a message when the fit failed.

    Raises
    ------
    ValueError
        When the experiment has two points or fewer (the screen needs n > 2).
    """
    formula = get_formula(formula)
    check_screenable(points.n, n_params=formula.n_params)
    specs = _parameter_specs(formula, points)
    context, warnings = {}, []
    if formula.context_from_efficiency:
        context["measured_efficiency"] = measured_efficiency(points)
    weights = normalised_weights(points)
    root_weights = np.sqrt(weights)
    extra_starts = {extra.name: extra.start for extra in formula.extras}

    def residual_at(d_cut, shape, extras):
        return root_weights * (formula(points.size, d_cut, shape, **context, **extras) - points.partition_fine)

    def residual(values):
        extras = {name: values[name] for name in extra_starts}
        return residual_at(values["d_cut"], values[formula.shape_name], extras)

    d_cut_start = measured_cut_size(points)
    shape_start = formula.shape_for_slope(measured_slope(points, d_cut_start))
    all_starts = [{"d_cut": d_cut_start, formula.shape_name: shape_start, **extra_starts}]
    grid = []
    if global_search:
        grid = _profile_grid(formula, specs, lambda d, k: residual_at(d, k, extra_starts), d_cut_start)
        all_starts += [{**start, **extra_starts} for _, start in grid[:N_GRID_STARTS]]
    all_starts += [{**all_starts[0], **start} for start in starts or []]
    fit = least_squares(residual, specs, all_starts)
    grid_ssr = grid[0][0] if grid else np.nan
    result = CurveFit(formula=formula, points=points, fit=fit, context=context, grid_ssr=grid_ssr)
    if not fit.success:
        return result
    for spec in specs:
        if spec.name in fit.at_bound:
            value = fit.values[spec.name]
            bound = spec.lower if np.isclose(value, spec.lower) else spec.upper
            on_shape_floor = spec.name == formula.shape_name and bound == spec.lower and formula.lower_bound_reason
            reason = f" ({formula.lower_bound_reason})" if on_shape_floor else ""
            warnings.append(f"{spec.name} = {value:.4g} at its bound {bound:g}: the unconstrained optimum lies beyond it{reason} "
                            "and the standard error is unreliable")  # fmt: skip
    x_break = np.nan
    if formula.context_from_efficiency:
        x_break, note = _break_point(fit.values[formula.shape_name], context["measured_efficiency"])
        warnings += note
    extras = {name: fit.values[name] for name in extra_starts}
    if extras:
        peak = float(np.max(formula(np.geomspace(points.size.min() / 10, points.size.max(), 400), fit.values["d_cut"],
                                    fit.values[formula.shape_name], **extras)))  # fmt: skip
        if peak > 1.0 + 1e-4:
            warnings.append(f"the fitted curve exceeds 1 (maximum {peak:.3f}): not a physical partition")
    screen = fisher_screen(points.partition_fine, fit.ssr, alpha=alpha, n_params=formula.n_params, weights=weights)
    largest = points.largest_size if delta_max is None else float(delta_max)
    indices = curve_indices(formula, fit.values["d_cut"], fit.values[formula.shape_name], delta_max=largest,
                            measured_sizes=(points.size.min(), points.size.max()), **context, **extras)  # fmt: skip
    diagnostics = residual_diagnostics(fit.residual, alpha=alpha)
    if screen.adequate and diagnostics.systematic:
        warnings.append(
            f"{RESIDUAL_WARNING} are systematic ({diagnostics.n_runs} runs of signs, runs test p = {diagnostics.runs_p:.3f})"
        )
    if screen.adequate and diagnostics.non_normal:
        warnings.append(f"{RESIDUAL_WARNING} are not normal (Shapiro-Wilk p = {diagnostics.normality_p:.2g}), as the F test assumes")
    return CurveFit(formula, points, fit, context, screen, indices, grid_ssr, tuple(warnings), x_break, diagnostics)


def _break_point(kr: float, efficiency: float) -> tuple[float, list[str]]:
    """x_a of formula (11) at the fitted shape, or nan and the reason none exists."""
    try:
        return shuvalov_break(kr, efficiency), []
    except NoBreakPointError as error:
        return np.nan, [f"{error}; the curve falls back to the nearer limit"]


def _profile_grid(formula, specs, residual_at, d_cut_start):
    """``[(ssr, start), ...]`` over the slope grid, best first, d_cut profiled."""
    d_cut_spec = specs[0]
    log_low, log_high = np.log(d_cut_spec.lower), np.log(d_cut_spec.upper)
    shapes = sorted({formula.clip_shape(formula.shape_for_slope(s)) for s in GRID_SLOPES})
    grid = []
    with np.errstate(all="ignore"):
        for shape in shapes:

            def ssr_of_log_cut(log_cut, shape=shape):
                value = np.sum(residual_at(np.exp(log_cut), shape) ** 2)
                return value if np.isfinite(value) else np.inf

            best = optimize.minimize_scalar(ssr_of_log_cut, bounds=(log_low, log_high), method="bounded", options={"xatol": 1e-6})
            # The bounded search can miss a narrow valley; the data-driven cut is a second candidate.
            candidates = [(best.fun, float(np.exp(best.x))), (ssr_of_log_cut(np.log(d_cut_start)), d_cut_start)]
            ssr, d_cut = min(candidates)
            if np.isfinite(ssr):
                grid.append((float(ssr), {"d_cut": d_cut, formula.shape_name: shape}))
    grid.sort(key=lambda item: item[0])
    return grid
