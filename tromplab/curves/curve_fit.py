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

import math
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np
import pandas as pd
from scipy import optimize

from ..errors import OptionError, expect_kind
from ..loading.points import MAX_SIZE_SPAN, TrompPoints
from ..results_contract import ResultContract
from ..validation import check_probability, check_size
from .diagnostics import RESIDUAL_WARNING, ResidualDiagnostics, batch_residual_diagnostics, residual_diagnostics
from .fitting import ParameterFit, least_squares
from .formulas import Formula, NoBreakPointError, get_formula, shuvalov_break
from .indices import CurveIndices, batch_curve_indices, batchable_indices, curve_indices
from .likelihood import on_bound
from .measured import (
    CUT_WARNING,
    GRID_SLOPES,
    formula_context,
    measured_cut_size,
    measured_slope,
    normalised_weights,
    parameter_specs,
    unbracketed_cut,
)
from .screening import DEFAULT_ALPHA, FisherScreen, check_screenable, fisher_screen, observed_variance
from .views import fit_html, fit_report, fit_repr

N_GRID_STARTS = 2


@dataclass(frozen=True)
class FitOptions:
    """The options a fit was made with, recorded on the result.

    Everything derived from a fit (screen, indices, intervals, bootstrap refits, model
    averages, the report) reads these instead of defaults, so that a fit made with
    ``delta_max=2000`` is also bootstrapped and reported with it.

    Attributes
    ----------
    alpha : float
        Significance level of the Fisher screen.
    delta_max : float
        Largest feed particle size used for the misplacement epsilon (size unit of the
        data): the requested value, else the experiment's own ``delta_max``, else its
        largest measured size.
    weights : ndarray
        Least-squares weights of the points, scaled to mean 1 (all ones when unweighted).
    size_unit : str
        Unit of the sizes ("" when not given), for labels.
    global_search : bool
        Whether the profiled shape grid was searched.
    """

    alpha: float
    delta_max: float
    weights: np.ndarray = field(compare=False, repr=False)
    size_unit: str = ""
    global_search: bool = True

    @classmethod
    def for_points(
        cls,
        points: TrompPoints,
        *,
        alpha: float = DEFAULT_ALPHA,
        delta_max: float | None = None,
        size_unit: str = "",
        global_search: bool = True,
    ) -> FitOptions:
        """Options resolved against ``points`` (``delta_max`` and weights filled in); an
        :class:`~tromplab.errors.OptionError` (a ValueError) names an argument out of range."""
        alpha = check_probability(alpha, "alpha")
        if delta_max is None:
            largest = points.largest_size
        elif points.resampled:  # a bootstrap resample may lack the smallest size its original was checked with
            largest = check_size(delta_max, "delta_max")
        else:
            largest = check_delta_max(delta_max, [points])
        return cls(alpha, largest, normalised_weights(points), size_unit or "", global_search)


def check_delta_max(delta_max, experiments) -> float:
    """``delta_max`` a size (:func:`tromplab.validation.check_size`) at most
    :data:`~tromplab.loading.points.MAX_SIZE_SPAN` times the smallest size of the ``experiments``
    (the rule the sizes of one experiment follow: a larger top size is a mistyped size or unit,
    and the misplacement integral up to it would leave the floating-point range)."""
    delta_max = check_size(delta_max, "delta_max")
    smallest = min((float(points.size.min()) for points in experiments), default=np.nan)
    if delta_max / smallest > MAX_SIZE_SPAN:
        raise OptionError(
            "delta_max",
            f"of {delta_max:g} is more than {MAX_SIZE_SPAN:g} times the smallest size of the data ({smallest:g}); "
            "the top size or its unit is probably mistyped",
        )
    return delta_max


#: A parameter whose standard error exceeds this many times its value is reported as not
#: determined by the data: its 95 % interval would span the value 20 times over.
UNDETERMINED_RATIO = 10.0
#: Correlation of an extra parameter (bypass, fish-hook) with the cut or the shape above which
#: the data cannot tell them apart: the extra is then reported as not determined.
UNDETERMINED_CORRELATION = 0.95


def _undetermined(value: float, stderr: float) -> bool:
    return bool(np.isfinite(stderr) and stderr > UNDETERMINED_RATIO * abs(value))


@dataclass(frozen=True)
class CurveFit(ResultContract):
    """Result of fitting one formula to one experiment.

    The result stores what the solver found (``fit``) and the options it was made with
    (``options``); the Fisher ``screen``, the ``indices``, the residual ``diagnostics``,
    ``x_break`` and ``warnings`` are derived from these two on first use and cached.

    ``success`` is False when the fit failed; ``message`` then says why, every
    parameter and extra is nan, ``screen``, ``indices`` and ``diagnostics`` are None and
    :meth:`predict` returns nan.  ``warnings`` lists conditions a user should know about
    a successful fit (a parameter on its bound, formula (11) without a break point,
    systematic residuals, a curve above 1).

    Attributes
    ----------
    formula : Formula
        The formula fitted.
    points : TrompPoints
        The measured points it was fitted to.
    fit : ParameterFit
        What the solver found: values, standard errors, covariance, sum of squares.
    context : dict
        The formula's data-derived inputs (``measured_efficiency`` of formula (11)).
    options : FitOptions
        The options the fit was made with (alpha, weights, delta_max, ...).
    grid_ssr : float
        Sum of squares at the best point of the starting grid (nan when no grid was searched).
    experiment : str
        The experiment's name (``points.experiment``).
    success : bool
        False when the fit failed; ``message`` then says why.
    message : str
        The solver's message, or why the fit failed.
    d_cut, shape : float
        The fitted cut size and shape parameter (nan for a failed fit).
    extras : dict
        Fitted bypass / fish-hook parameters (empty for the nine paper formulas).
    screen : FisherScreen or None
        The Fisher screen of the fit (None for a failed fit).
    indices : CurveIndices or None
        Indices of the fitted curve (None for a failed fit).
    diagnostics : ResidualDiagnostics or None
        Runs and normality tests of the residuals (None for a failed fit).
    x_break : float
        Break point of formula (11) (nan for other formulas).
    unbracketed : str
        Why the points do not bracket the cut ("" when they do).
    undetermined_extras : dict
        Extra parameters the data cannot tell from the cut or the shape, with the reason.
    warnings : tuple of str
        What a user should know about a successful fit.
    """

    formula: Formula
    points: TrompPoints
    fit: ParameterFit
    context: dict = field(default_factory=dict)
    options: FitOptions | None = None
    grid_ssr: float = np.nan

    def __post_init__(self):
        if self.options is None:  # results built by hand get the defaults fit_formula would use
            object.__setattr__(self, "options", FitOptions.for_points(self.points))

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
        return self.fit.values.get("d_cut", np.nan)

    @property
    def shape(self) -> float:
        return self.fit.values.get(self.formula.shape_name, np.nan)

    @property
    def extras(self) -> dict[str, float]:
        """Fitted bypass / fish-hook parameters (empty for the nine paper formulas; nan when the fit failed)."""
        return self.curve_arguments()[2]

    def curve_arguments(self, values: dict[str, float] | None = None) -> tuple[float, float, dict[str, float]]:
        """``(d_cut, shape, extras)`` from parameter ``values`` (default: the fitted ones; nan where missing)."""
        values = self.fit.values if values is None else values
        extras = {extra.name: values.get(extra.name, np.nan) for extra in self.formula.extras}
        return values.get("d_cut", np.nan), values.get(self.formula.shape_name, np.nan), extras

    def context_at(self, values: dict[str, float] | None = None) -> dict:
        """The formula's data-derived inputs (``measured_efficiency`` of (11)), overridden by
        same-named entries of ``values``: the delta method perturbs them like parameters."""
        values = values or {}
        return {name: values.get(name, value) for name, value in self.context.items()}

    def predict(self, size, values: dict[str, float] | None = None) -> np.ndarray:
        """Partition to fines at ``size`` for the fitted parameters (or other ``values``); nan for a failed fit."""
        d_cut, shape, extras = self.curve_arguments(values)
        if not np.all(np.isfinite([d_cut, shape, *extras.values()])):
            return np.full(np.shape(np.asarray(size, dtype=float)), np.nan)
        return self.formula(size, d_cut, shape, **self.context_at(values), **extras)

    @cached_property
    def screen(self) -> FisherScreen | None:
        """Fisher screen at the recorded ``alpha`` and weights (None for a failed fit)."""
        return self.screen_with() if self.success else None

    def screen_with(self, s0_sq: float | None = None) -> FisherScreen:
        """:attr:`screen` of a successful fit, with the variance of the measured points
        ``s0_sq`` when the caller has it (:func:`attach_screens`)."""
        return fisher_screen(
            self.points.partition_fine,
            self.fit.ssr,
            alpha=self.options.alpha,
            n_params=self.formula.n_params,
            weights=self.options.weights,
            s0_sq=s0_sq,
        )

    @cached_property
    def indices(self) -> CurveIndices | None:
        """Indices of the fitted curve at the recorded ``delta_max`` (None for a failed fit)."""
        if not self.success:
            return None
        d_cut, shape, extras = self.curve_arguments()
        return curve_indices(
            self.formula,
            d_cut,
            shape,
            delta_max=self.options.delta_max,
            measured_sizes=(self.points.size.min(), self.points.size.max()),
            **self.context,
            **extras,
        )

    @cached_property
    def diagnostics(self) -> ResidualDiagnostics | None:
        """Runs and normality tests of the residuals (None for a failed fit)."""
        return (
            residual_diagnostics(self.fit.residual, alpha=self.options.alpha)
            if self.success and self.fit.residual is not None
            else None
        )

    @property
    def x_break(self) -> float:
        """Break point x_a of formula (11) at the fitted shape (nan for other formulas or without one)."""
        return self._break[0]

    @cached_property
    def _break(self) -> tuple[float, list[str]]:
        # solved once for x_break and the warnings
        if not (self.success and self.formula.context_from_efficiency):
            return np.nan, []
        return _break_point(self.shape, self.context["measured_efficiency"])

    @cached_property
    def unbracketed(self) -> str:
        """Why the measured points do not bracket the cut (empty when they do:
        :func:`tromplab.curves.measured.unbracketed_cut`); the quantities that rest on the cut
        then get no interval."""
        return unbracketed_cut(self.points)

    @cached_property
    def undetermined_extras(self) -> dict[str, str]:
        """Extra parameters (bypass, fish-hook) the data cannot tell from the cut or the shape:
        an estimate correlated with either beyond :data:`UNDETERMINED_CORRELATION`, with the
        reason.  (A standard error above :data:`UNDETERMINED_RATIO` times the value is said in
        :attr:`warnings` too, but keeps its interval: near 0 that interval still bounds the extra.)"""
        if not (self.success and self.formula.extras and self.fit.covariance is not None):
            return {}
        names, covariance = list(self.fit.names), np.asarray(self.fit.covariance, dtype=float)
        with np.errstate(invalid="ignore", divide="ignore"):
            scale = np.sqrt(np.diag(covariance))
            correlation = covariance / np.outer(scale, scale)
        found = {}
        for extra in self.formula.extras:
            if extra.name not in names or extra.name in self.fit.at_bound:
                continue
            row = correlation[names.index(extra.name)]
            for other in ("d_cut", self.formula.shape_name):
                r = row[names.index(other)] if other in names else np.nan
                if np.isfinite(r) and abs(r) > UNDETERMINED_CORRELATION:
                    found[extra.name] = f"correlated with {other} (r = {r:.3f})"
                    break
        return found

    @cached_property
    def warnings(self) -> tuple[str, ...]:
        """What a user should know about a successful fit (empty for a failed one)."""
        if not self.success:
            return ()
        warnings = []
        if self.unbracketed:
            warnings.append(
                f"{CUT_WARNING} ({self.unbracketed}): d_cut and the d50, d50c, "
                "d25, d75 and Ep that rest on it are read off the formula's shape, not off measurements, so no interval "
                "is given for them"
            )
        for name, reason in self.undetermined_extras.items():
            warnings.append(
                f"{name} = {self.fit.values[name]:.4g} is not determined by the data ({reason}): other values fit as well, "
                "so no interval is given for it"
            )
        for spec in parameter_specs(self.formula, self.points):
            if spec.name in self.fit.at_bound:
                value = self.fit.values[spec.name]
                bound = spec.lower if on_bound(value, spec.lower) else spec.upper
                on_shape_floor = spec.name == self.formula.shape_name and bound == spec.lower and self.formula.lower_bound_reason
                reason = f" ({self.formula.lower_bound_reason})" if on_shape_floor else ""
                warnings.append(
                    f"{spec.name} = {value:.4g} at its bound {bound:g}: the unconstrained optimum lies beyond "
                    f"it{reason} and the standard error is unreliable"
                )
            elif spec.name not in self.undetermined_extras and _undetermined(
                self.fit.values[spec.name], self.fit.stderr[spec.name]
            ):
                value, stderr = self.fit.values[spec.name], self.fit.stderr[spec.name]
                warnings.append(
                    f"{spec.name} = {value:.4g} is not determined by the data (standard error {stderr:.3g}): the sum "
                    "of squares is nearly flat along it, so quite different values fit as well"
                )
            elif spec.name not in self.undetermined_extras and not np.isfinite(self.fit.stderr[spec.name]):
                warnings.append(
                    f"{spec.name} = {self.fit.values[spec.name]:.4g} is not determined by the data (no standard error: "
                    "the sum of squares is flat along a direction at the optimum), so quite different values fit as well"
                )
        if self.formula.context_from_efficiency:
            warnings += self._break[1]
        if self.formula.extras:
            sizes = np.geomspace(self.points.size.min() / 10, self.points.size.max(), 400)
            peak = float(np.max(self.predict(sizes)))
            if peak > 1.0 + 1e-4:
                warnings.append(f"the fitted curve exceeds 1 (maximum {peak:.3f}): not a physical partition")
        diagnostics = self.diagnostics
        if self.screen.adequate and diagnostics is not None and diagnostics.systematic:
            warnings.append(
                f"{RESIDUAL_WARNING} are systematic ({diagnostics.n_runs} runs of signs, runs test p = {diagnostics.runs_p:.3f})"
            )
        if self.screen.adequate and diagnostics is not None and diagnostics.non_normal:
            warnings.append(
                f"{RESIDUAL_WARNING} are not normal (Shapiro-Wilk p = {diagnostics.normality_p:.2g}), as the F test assumes"
            )
        return tuple(warnings)

    def row(self) -> dict:
        """One row of ``fits.csv`` (see :data:`FIT_COLUMNS`): the one place a fit becomes a table row."""
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
            "d50": ind.d50 if ind else np.nan,
            "d50c": ind.d50c if ind else np.nan,
            "ep_c": ind.ep_c if ind else np.nan,
            "imperfection_c": ind.imperfection_c if ind else np.nan,
            "aic": criteria["aic"],
            "aicc": criteria["aicc"],
            "bic": criteria["bic"],
            "runs_p": self.diagnostics.runs_p if self.diagnostics else np.nan,
            "normality_p": self.diagnostics.normality_p if self.diagnostics else np.nan,
            "residuals": self.diagnostics.verdict if self.diagnostics else "",
            "extrapolated": ";".join((*self._sizes_outside_data(), *ind.extrapolated)) if ind else "",
            "x_break": self.x_break,
            "bypass": self.fit.values.get("bypass", np.nan),
            "fishhook": self.fit.values.get("fishhook", np.nan),
            "extras": "; ".join(f"{name}={value!r}" for name, value in self.extras.items() if name not in ("bypass", "fishhook")),
            "success": self.success,
            "message": self.message,
            "warnings": "; ".join(self.warnings),
        }

    def _sizes_outside_data(self) -> tuple[str, ...]:
        """d_cut, d50 and d50c when they lie outside the measured sizes."""
        smallest, largest = self.points.size.min(), self.points.size.max()
        sizes = {"d_cut": self.d_cut, "d50": self.indices.d50, "d50c": self.indices.d50c}
        return tuple(name for name, size in sizes.items() if np.isfinite(size) and not smallest <= size <= largest)

    # --- readable views (tromplab.curves.views): the same fields as row(), for notebooks and logs
    def __repr__(self) -> str:
        return fit_repr(self)

    def _repr_html_(self) -> str:
        return fit_html(self)

    def summary(self) -> pd.DataFrame:
        """One-row :class:`pandas.DataFrame` with the columns of ``fits.csv`` except ``rank``."""
        return pd.DataFrame([self.row()]).reindex(columns=[c for c in FIT_COLUMNS if c != "rank"])

    def to_frame(self) -> pd.DataFrame:
        """The measured points beside the fitted curve: ``size, partition_fine, fitted, residual``
        (``fitted`` nan for a failed fit)."""
        fitted = self.predict(self.points.size)
        return pd.DataFrame(
            {
                "size": self.points.size,
                "partition_fine": self.points.partition_fine,
                "fitted": fitted,
                "residual": self.points.partition_fine - fitted,
            }
        )

    def _result_context(self) -> str:
        return fit_repr(self)

    def report(self, *, level: float = 0.95, profile: bool = True) -> str:
        """Text report: parameters with standard errors and ``level`` intervals (profile
        likelihood, else Wald), the F screen, indices with delta-method errors, residual
        diagnostics and warnings (like lmfit's ``fit_report``)."""
        return fit_report(self, level=level, profile=profile)

    def model_result(self):
        """This fit as an :class:`lmfit.model.ModelResult`, made on demand from any successful fit.

        lmfit's :class:`~lmfit.model.Model` of the formula's curve in the sizes
        (independent variable ``size``, parameters ``d_cut``, the shape and any extras, with
        the fit's bounds and the square roots of its weights) is fitted by lmfit from this
        fit's optimum, so the result has lmfit's own ``eval``, ``eval_uncertainty``,
        ``plot``, ``fit_report`` and ``conf_interval``.  Its parameters equal this fit's to
        the solver's tolerance and its ``chisqr`` is this fit's ``ssr``; its ``fit_report()``
        names the model as tromplab's fit re-evaluated by lmfit from its optimum, with the fit's
        starts, and gives the fit's own function evaluations (``fit.fit.nfev``); a fit made by the
        batched engine gets one the same way (``fit.fit.raw`` is lmfit's lower-level
        ``MinimizerResult``, and None for a batched fit).  Formula (11) keeps the measured
        efficiency the fit was made with.

        Raises
        ------
        ValueError
            When the fit failed (it has no optimum to start from).

        Examples
        --------
        >>> points = TrompPoints("run", [10, 20, 40, 80, 160], [0.98, 0.91, 0.62, 0.21, 0.04])
        >>> result = fit_formula(points, "plitt").model_result()
        >>> round(result.params["d_cut"].value, 2), round(float(result.eval(size=48.21)), 3)
        (48.21, 0.5)
        """
        import inspect

        import lmfit

        if not self.success:
            raise ValueError(f"formula {self.formula.id} on {self.experiment!r} has no lmfit result: {self.message}")
        formula, context, names = self.formula, dict(self.context), list(self.fit.names)

        def partition_fine(size, **values):
            d_cut, shape, extras = self.curve_arguments(values)
            return formula(size, d_cut, shape, **context, **extras)

        arguments = [inspect.Parameter(name, inspect.Parameter.POSITIONAL_OR_KEYWORD) for name in ["size", *names]]
        partition_fine.__signature__ = inspect.Signature(arguments)
        partition_fine.__name__ = formula.id
        # the report says what the numbers are: tromplab's fit (its starts and evaluations),
        # which lmfit re-evaluates from the optimum, not a fit of lmfit's own from a guess
        origin = (
            f"{formula.id}: tromplab's fit ({self.fit.n_starts} start(s), {self.fit.nfev} function evaluations), "
            "re-evaluated by lmfit from its optimum"
        )
        model = lmfit.Model(partition_fine, independent_vars=["size"], name=origin)
        params = model.make_params()
        for spec in parameter_specs(formula, self.points):
            params[spec.name].set(value=spec.clip(self.fit.values[spec.name]), min=spec.lower, max=spec.upper)
        result = model.fit(
            self.points.partition_fine,
            params,
            size=self.points.size,
            weights=np.sqrt(self.options.weights),
            method="least_squares",
        )
        result.nfev = int(self.fit.nfev) or result.nfev  # fit_report's "function evals": the fit's, not the re-evaluation's
        return result

    def with_lmfit(self) -> CurveFit:
        """This fit with an lmfit result: a fit made by the batched engine (or one that
        travelled through a process pool) is refitted by lmfit from its optimum, without the
        grid, so that ``fit.fit.raw`` and profile intervals are available.  A fit that
        already has them, or a failed one, is returned as is; so is the fit when lmfit ends
        above its optimum."""
        if not self.success or self.fit.minimizer is not None:
            return self
        options = self.options
        polished = fit_formula(
            self.points,
            self.formula,
            alpha=options.alpha,
            delta_max=options.delta_max,
            size_unit=options.size_unit,
            global_search=False,
            starts=[dict(self.fit.values)],
        )
        if not polished.success or polished.fit.ssr > self.fit.ssr * (1 + 1e-9):
            return self
        return replace(self, fit=polished.fit)


def attach_indices(fits) -> None:
    """Compute the indices of many fits at once and cache them on each fit.

    Successful fits of the formulas :func:`tromplab.curves.indices.batchable_indices` covers are
    grouped by formula and go through :func:`tromplab.curves.indices.batch_curve_indices` (one
    array computation per formula instead of root finding and quadrature per fit); the
    cached ``CurveFit.indices`` is then not computed again.  Other fits are left to the
    lazy property.
    """
    groups: dict[str, list[CurveFit]] = {}
    for fit in fits:
        if fit.success and "indices" not in fit.__dict__ and batchable_indices(fit.formula):
            groups.setdefault(fit.formula.id, []).append(fit)
    for formula_id, group in groups.items():
        efficiency = [fit.context.get("measured_efficiency", np.nan) for fit in group]
        arguments = [fit.curve_arguments() for fit in group]
        computed = batch_curve_indices(
            formula_id,
            [d_cut for d_cut, _, _ in arguments],
            [shape for _, shape, _ in arguments],
            delta_max=[fit.options.delta_max for fit in group],
            measured_sizes=([fit.points.size.min() for fit in group], [fit.points.size.max() for fit in group]),
            measured_efficiency=efficiency if group[0].formula.context_from_efficiency else None,
            **{extra.name: [extras[extra.name] for _, _, extras in arguments] for extra in group[0].formula.extras},
        )
        for fit, indices in zip(group, computed):
            fit.__dict__["indices"] = indices  # where functools.cached_property keeps its value


def attach_screens(fits) -> None:
    """Compute the Fisher screens of many fits and cache them on each fit: the variance of the
    measured points (:func:`~tromplab.curves.screening.observed_variance`) once per experiment
    and weights, which the formulas fitted to it share."""
    variances: dict[int, tuple[np.ndarray, float]] = {}
    for fit in fits:
        if not fit.success or "screen" in fit.__dict__:
            continue
        weights = fit.options.weights
        known = variances.get(id(fit.points))
        if known is None or (known[0] is not weights and not np.array_equal(known[0], weights)):
            known = variances[id(fit.points)] = (weights, observed_variance(fit.points.partition_fine, weights))
        fit.__dict__["screen"] = fit.screen_with(known[1])  # where functools.cached_property keeps it


#: Relative slack of the range checks of :func:`implausible_result` (rounding of the integrals).
RANGE_SLACK = 1e-9


def implausible_result(fit: CurveFit) -> str:
    """Why the results of a successful ``fit`` leave their ranges (docs/columns.md), or ''.

    d_cut, the shape, the sum of squares and eta must be finite numbers in their ranges;
    epsilon, d25, d75, d50, d50c, Ep and the slope may be missing (a curve that never
    reaches a level) but not infinite or outside their ranges.  Such a result comes from
    arithmetic that overflowed at extreme inputs; it is reported as a failed fit, never as
    a result.
    """
    if not fit.success:
        return ""
    ind, d_cut, delta_max = fit.indices, fit.d_cut, fit.options.delta_max
    x_max = delta_max / d_cut if d_cut > 0 else math.nan
    low_shape, high_shape = fit.formula.shape_bounds
    # (name, value, low, high, may be missing); plain floats and math: a batch checks every fit
    checks = (
        ("d_cut", d_cut, 0.0, math.inf, False),
        (fit.formula.shape_name, fit.shape, low_shape, high_shape, False),
        ("ssr", fit.fit.ssr, 0.0, math.inf, False),
        ("eta", ind.eta, 0.0, 1.0, False),
        ("epsilon", ind.epsilon, 0.0, max(x_max - 1.0, 0.0), True),
        ("slope", ind.slope, -math.inf, 0.0, True),
        *((name, getattr(ind, name), 0.0, math.inf, True) for name in ("d25", "d75", "ep", "d50", "d50c", "ep_c")),
    )
    for name, value, low, high, optional in checks:
        value = float(value)
        if optional and math.isnan(value):
            continue
        slack = RANGE_SLACK * max(1.0, abs(low) if math.isfinite(low) else 0.0, abs(high) if math.isfinite(high) else 0.0)
        if not (math.isfinite(value) and low - slack <= value <= high + slack):
            return (
                f"{name} = {value:g} is outside its range [{low:g}, {high:g}]: the arithmetic did not hold at these "
                f"inputs (delta_max {delta_max:g}, d_cut {d_cut:g})"
            )
    return ""


def as_failure_if_implausible(fit: CurveFit) -> CurveFit:
    """``fit``, or a failed fit saying why when :func:`implausible_result` finds a result out of range."""
    reason = implausible_result(fit)
    if not reason:
        return fit
    options = fit.options
    return failed_fit(
        fit.points, fit.formula, reason, alpha=options.alpha, delta_max=options.delta_max, size_unit=options.size_unit
    )


def attach_diagnostics(fits) -> None:
    """Compute the residual diagnostics of many fits at once and cache them on each fit.

    :func:`tromplab.curves.diagnostics.batch_residual_diagnostics` gives the values
    ``CurveFit.diagnostics`` would compute fit by fit; fits without residuals (failed
    ones) are left to the lazy property.
    """
    chosen = [fit for fit in fits if fit.success and fit.fit.residual is not None and "diagnostics" not in fit.__dict__]
    found = batch_residual_diagnostics([fit.fit.residual for fit in chosen], alpha=[fit.options.alpha for fit in chosen])
    for fit, diagnostics in zip(chosen, found):
        fit.__dict__["diagnostics"] = diagnostics  # where functools.cached_property keeps its value


def fit_formula(
    points: TrompPoints,
    formula,
    *,
    alpha: float = DEFAULT_ALPHA,
    delta_max: float | None = None,
    global_search: bool = True,
    starts: list[dict] | None = None,
    size_unit: str = "",
) -> CurveFit:
    """Fit ``formula`` to ``points`` and record the options with the result.

    Only the fit is made here; the screen, indices and diagnostics of the returned
    :class:`CurveFit` are derived from it (and the recorded :class:`FitOptions`) on
    first use.

    Parameters
    ----------
    points : TrompPoints
        Measured curve (more points than the formula has parameters).
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
    size_unit : str
        Unit of the sizes, recorded for labels.

    Returns
    -------
    CurveFit
        Always; ``success`` is False with a message when the fit failed.

    Raises
    ------
    ValueError
        When the experiment has no more points than the formula has parameters (the
        screen needs ``n > p``), or ``alpha`` / ``delta_max`` are out of range.

    Examples
    --------
    >>> points = TrompPoints("run", [10, 20, 40, 80, 160], [0.98, 0.91, 0.62, 0.21, 0.04])
    >>> fit = fit_formula(points, "plitt")
    >>> round(fit.d_cut, 2), round(fit.shape, 2), fit.screen.adequate
    (48.21, 2.62, True)
    """
    expect_kind(points, TrompPoints, "points", "a TrompPoints (tromplab.TrompPoints or tromplab.read_points)")
    formula = get_formula(formula)
    check_screenable(points.n, n_params=formula.n_params)
    options = FitOptions.for_points(points, alpha=alpha, delta_max=delta_max, size_unit=size_unit, global_search=global_search)
    specs = parameter_specs(formula, points)
    context = formula_context(formula, points)
    root_weights = np.sqrt(options.weights)
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
    return CurveFit(formula=formula, points=points, fit=fit, context=context, options=options, grid_ssr=grid_ssr)


def failed_fit(
    points: TrompPoints,
    formula,
    message: str,
    *,
    alpha: float = DEFAULT_ALPHA,
    delta_max: float | None = None,
    size_unit: str = "",
) -> CurveFit:
    """A failed :class:`CurveFit` of ``formula``: every parameter and extra nan, ``message`` saying why."""
    formula = get_formula(formula)
    try:
        options = FitOptions.for_points(points, alpha=alpha, delta_max=delta_max, size_unit=size_unit)
    except ValueError:
        options = FitOptions(float(alpha), np.nan, normalised_weights(points), size_unit or "")
    specs = parameter_specs(formula, points)
    return CurveFit(formula=formula, points=points, fit=ParameterFit.failed(specs, points.n, message), options=options)


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


#: Columns of ``fits.csv``, in order.
FIT_COLUMNS = (
    "experiment",
    "equation",
    "formula",
    "n",
    "d_cut",
    "d_cut_stderr",
    "shape_name",
    "shape",
    "shape_stderr",
    "ssr",
    "F",
    "F_crit",
    "adequate",
    "rank",
    "eta",
    "epsilon",
    "slope",
    "d25",
    "d75",
    "ep",
    "imperfection",
    "d50",
    "d50c",
    "ep_c",
    "imperfection_c",
    "aic",
    "aicc",
    "delta_aicc",
    "bic",
    "bypass",
    "fishhook",
    "extras",
    "runs_p",
    "normality_p",
    "residuals",
    "extrapolated",
    "x_break",
    "success",
    "message",
    "warnings",
)
