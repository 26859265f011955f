"""The binomial fits of density curves as tromplab made them before the batch engine (a frozen copy, the tests' oracle).

Provenance: ``tromplab/density/fitting.py`` at commit ed84263 (the last before
``tromplab/density/batch.py``), one fit per test and curve: statsmodels' GLM for a plain
curve, SLSQP from four starts for a curve with limits, and ``brentq`` on the profile
re-optimised by ``minimize_scalar``/SLSQP for the intervals.  Changed only: the package's
relative imports made absolute, and the optimisers' tolerances made module constants
(:data:`PROFILE_XTOL`, :data:`SLSQP_FTOL`, :data:`SCALAR_XATOL`, their values then as
defaults) so that a test can also run this path to convergence.  What the batch engine
left unchanged (the result class, the data of a fit and its objective, the starts, the
test of separation, the profile's parametrisation, which quantities get an interval, the
joint fit of three analyses) is imported from ``tromplab.density.fitting``; what it
replaced (the fits, the statistics, the profile search and its tolerance) is the copy
below, and so is the oracle; the functions the oracle's fits do not reach (the band, the
test of the limits) are left out.  ``tests/test_density_batch.py``
compares the new engine with it.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable

import numpy as np
import scipy.optimize
import scipy.stats

from tromplab.density.dispersion import profile_threshold as quasi_profile_threshold
from tromplab.density.dispersion import quasi_binomial_scale

# the helpers that the batch engine left as they were, imported rather than copied
from tromplab.density.fitting import (
    FLOAT_SINK_INTERVAL_NOTE,
    JOINT_FALLBACK_NOTE,
    DensityCurveFit,
    _Data,
    _interval_quantities,
    _joint,
    _natural,
    _replace,
    _separation,
    _starts,
    fit_data,
    index_model,
    index_vector,
    objective_of,
)
from tromplab.density.joint import has_three_analyses
from tromplab.density.readers import DensitySample
from tromplab.density.registry import DensityCurve, get_density_curve

#: brentq's absolute tolerance on a profile limit, in units of the first step (then 1e-4).
PROFILE_XTOL = 1e-4
#: SLSQP's ``ftol`` (then 1e-12) and the bounded scalar search's ``xatol`` (then 1e-9).
SLSQP_FTOL = 1e-12
SCALAR_XATOL = 1e-9
#: Options of statsmodels' ``GLM.fit`` (then none: its default tolerance on the deviance, 1e-8).
GLM_FIT_OPTIONS = {}

OVERDISPERSION_LEVEL = 0.05


# --- starts and numerical fits -------------------------------------------------------------


def _minimise(value: Callable[[np.ndarray], float], starts, bounds) -> scipy.optimize.OptimizeResult:
    if len(bounds) == 1:  # the profiles of a plain curve: Brent's bounded search is many times quicker than L-BFGS-B
        return _minimise_scalar(value, starts, bounds[0])
    best = None
    for start in starts:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore", RuntimeWarning)
            result = scipy.optimize.minimize(
                value, np.asarray(start, float), method="SLSQP", bounds=bounds, options={"ftol": SLSQP_FTOL, "maxiter": 500}
            )
        if np.isfinite(result.fun) and (best is None or result.fun < best.fun):
            best = result
    return best if best is not None else _nowhere(starts)


def _nowhere(starts) -> scipy.optimize.OptimizeResult:
    """The result of a search that found no finite value (the objective is infinite wherever it looked)."""
    return scipy.optimize.OptimizeResult(x=np.asarray(starts[0], float), fun=np.inf, success=False)


def _minimise_scalar(value, starts, bounds) -> scipy.optimize.OptimizeResult:
    best = None
    for start in starts:
        centre = float(np.clip(np.asarray(start, float).ravel()[0], *bounds))
        # the probable error's log (or rho50 itself) moves little along a profile: search near the start first
        near = (max(bounds[0], centre - 1.0), min(bounds[1], centre + 1.0))
        with np.errstate(all="ignore"):
            result = scipy.optimize.minimize_scalar(
                lambda v: value(np.array([v])), bounds=near, method="bounded", options={"xatol": SCALAR_XATOL}
            )
        result.x = np.array([result.x])
        if np.isfinite(result.fun) and (best is None or result.fun < best.fun):
            best = result
    return best if best is not None else _nowhere(starts)


def _fit_numerically(curve: DensityCurve, data: _Data, objective) -> tuple[dict, object]:
    rho50, ep = _starts(data)
    bounds = [(p.lower, p.upper) for p in curve.parameters]
    ep_index = 1
    bounds[ep_index] = (math.log(bounds[ep_index][0]), math.log(bounds[ep_index][1]))
    if curve.has_limits:
        starts = [
            (rho50, math.log(ep), light, heavy) for light, heavy in ((0.001, 0.999), (0.03, 0.97), (0.0, 0.95), (0.05, 1.0))
        ]
    else:
        starts = [(rho50, math.log(ep)), (rho50, math.log(ep) + 1.0), (rho50, math.log(ep) - 1.0)]
    if data.binomial:
        result = _minimise(lambda x: objective(curve.partition(data.density, **_natural(curve, x))), starts, bounds)
        return _natural(curve, result.x), result
    root_weight = np.sqrt(data.weight)

    def residuals(x):
        return root_weight * (curve.partition(data.density, **_natural(curve, x)) - data.share)

    best = None
    lower, upper = np.array(bounds).T
    for start in starts:
        result = scipy.optimize.least_squares(residuals, np.clip(start, lower, upper), bounds=(lower, upper), method="trf")
        if best is None or result.cost < best.cost:
            best = result
    return _natural(curve, best.x), best


def _fit_glm(curve: DensityCurve, data: _Data) -> tuple[dict, object]:
    import statsmodels.api as sm

    links = {"probit": sm.families.links.Probit, "logit": sm.families.links.Logit, "cloglog": sm.families.links.CLogLog}
    endog = np.column_stack([data.sinks, data.trials - data.sinks])
    exog = np.column_stack([np.ones_like(data.density), data.density])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = sm.GLM(endog, exog, family=sm.families.Binomial(link=links[curve.link]())).fit(**GLM_FIT_OPTIONS)
    intercept, slope = (float(v) for v in result.params)
    if not slope > 0:
        raise ValueError("the fitted partition does not rise with density")
    form = curve.form
    return {"rho50": (form.centre - intercept) / slope, "ep": form.scale / slope}, result


# --- goodness of fit, dispersion, AIC -------------------------------------------------------
def _statistics(curve: DensityCurve, data: _Data, params: dict, objective: float) -> dict:
    p_fit = np.clip(curve.partition(data.density, **params), 1e-12, 1 - 1e-12)
    df = int(data.density.size - curve.n_params)
    if data.binomial:
        k, n = data.sinks, data.trials
        pearson = float(np.sum((k - n * p_fit) ** 2 / (n * p_fit * (1 - p_fit))))
        dispersion = pearson / df if df > 0 else math.nan
        overdispersed = df > 0 and pearson > scipy.stats.chi2.ppf(1 - OVERDISPERSION_LEVEL, df)
        loglik = float(scipy.stats.binom.logpmf(k, n, p_fit).sum())
        gof_p = float(scipy.stats.chi2.sf(objective, df)) if df > 0 else math.nan
        return {
            "df_resid": df,
            "gof_p": gof_p,
            "dispersion": dispersion,
            "overdispersed": overdispersed,
            "aic": -2 * loglik + 2 * curve.n_params,
        }
    count = data.density.size
    aic = count * math.log(max(objective, 1e-300) / count) + 2 * (curve.n_params + 1)
    return {
        "df_resid": df,
        "gof_p": math.nan,
        "dispersion": objective / df if df > 0 else math.nan,
        "overdispersed": False,
        "aic": aic,
    }


# --- profile-likelihood intervals -----------------------------------------------------------


def profile_interval(fit: DensityCurveFit, quantity: str, ci: float) -> tuple[float, float, str]:
    """Profile-likelihood interval of ``quantity`` (``rho50``, ``ep``, ``imperfection``) of ``fit``.

    Returns
    -------
    tuple
        ``(low, high, note)``; a limit the profile does not reach within the search range is
        NaN and ``note`` says so.
    """
    data = fit_data(fit.sample, fit.method)
    objective = objective_of(data)
    model = index_model(fit.curve, quantity)
    centre, bounds = index_vector(fit.curve, fit.params, fit.indices, quantity)
    position = 0 if quantity == "rho50" else 1
    if data.binomial:
        quasi = quasi_binomial_scale(fit.dispersion, fit.df_resid)  # the rule of tromplab.density.dispersion
        scale, threshold = quasi.scale, quasi_profile_threshold(ci, fit.df_resid, quasi.estimated)
    else:
        scale = fit.objective / fit.df_resid if fit.df_resid > 0 else math.nan
        threshold = scipy.stats.f.ppf(ci, 1, fit.df_resid) if fit.df_resid > 0 else math.nan
    if not (np.isfinite(scale) and scale > 0):
        return math.nan, math.nan, f"{quantity} has no interval: no degrees of freedom left for the error variance"
    if not data.binomial and fit.objective <= 1e-20 * data.density.size:
        return math.nan, math.nan, f"{quantity} has no interval: the curve passes through every point (no residual variance)"
    free = [i for i in range(centre.size) if i != position]

    warm = {"x": centre[free]}  # the optimum of the last profile point: the next one starts there

    def excess(value):
        def at(x):
            q = centre.copy()
            q[position], q[free] = value, x
            return objective(fit.curve.partition(data.density, **model(q)))

        starts = [warm["x"]] if len(free) == 1 else [warm["x"], centre[free]]
        best = _minimise(at, starts, [bounds[i] for i in free])
        if not np.isfinite(best.fun):  # no finite likelihood at this value: beyond any limit
            return 1e300
        warm["x"] = best.x
        return (best.fun - fit.objective) / scale - threshold

    # a quarter of Ep (of I) is about the half-width of a 95 % interval from 30 tracers per density
    step = 0.25 * (fit.indices.imperfection if quantity == "imperfection" else fit.indices.ep)
    limits, notes = [], []
    for direction in (-1.0, 1.0):
        warm["x"] = centre[free]
        value, note = _profile_limit(excess, centre[position], direction, bounds[position], step)
        limits.append(value)
        notes += [f"{quantity}: {note}"] if note else []
    return limits[0], limits[1], "; ".join(notes)


def _profile_limit(excess, centre: float, direction: float, bounds: tuple[float, float], step: float) -> tuple[float, str]:
    """Where ``excess`` crosses 0 going from ``centre`` in ``direction``, stepping out geometrically from ``step``."""
    edge = bounds[1] if direction > 0 else bounds[0]
    tolerance = PROFILE_XTOL * step
    inner = centre
    while True:
        outer = centre + direction * step
        if (outer - edge) * direction >= 0:
            outer = edge
        if excess(outer) > 0:
            try:
                return float(scipy.optimize.brentq(excess, min(inner, outer), max(inner, outer), xtol=tolerance)), ""
            except ValueError:  # the re-optimised profile is not monotone between the two points
                side = "upper" if direction > 0 else "lower"
                return math.nan, f"the {side} limit could not be found (the profile is not monotone near {outer:.4g})"
        if outer == edge:
            side = "upper" if direction > 0 else "lower"
            return math.nan, f"the profile does not reach the {side} limit within {edge:g}"
        inner, step = outer, step * 2.0


# --- one curve, one sample ------------------------------------------------------------------
def fit_density_curve(sample: DensitySample, curve, *, ci: float | None = None, method: str | None = None) -> DensityCurveFit:
    """Fit one density curve to one sample; the result says why when no curve could be fitted.

    Parameters
    ----------
    sample : DensitySample
        One test and size fraction (:func:`tromplab.density.readers.read_density`).
    curve : DensityCurve or str
        The curve (:data:`tromplab.density.registry.DENSITY_CURVES`).
    ci : float, optional
        Level of the profile-likelihood intervals of rho50, Ep and I (none when None).
    method : {"binomial", "least_squares"}, optional
        Default: binomial for tracer counts, the joint fit of the three analyses
        (``"joint_least_squares"``) for float-sink tests with a feed analysis, least squares
        on the partitions otherwise.

    Returns
    -------
    DensityCurveFit
    """
    curve = get_density_curve(curve)
    joint = method is None and has_three_analyses(sample)
    method = method or ("binomial" if sample.layout == "tracers" else "least_squares")
    data = fit_data(sample, method)
    failed = {"sample": sample, "curve": curve, "method": method, "success": False}
    if data.density.size <= curve.n_params - (0 if data.binomial else 1):
        return DensityCurveFit(**failed, message=f"{data.density.size} densities are too few for {curve.n_params} parameters")
    separation = _separation(data)
    if separation:
        return DensityCurveFit(**failed, message=separation)
    objective = objective_of(data)
    try:
        if data.binomial and not curve.has_limits:
            params, raw = _fit_glm(curve, data)
        else:
            params, raw = _fit_numerically(curve, data, objective)
    except (ValueError, np.linalg.LinAlgError) as error:
        return DensityCurveFit(**failed, message=str(error))
    value = objective(curve.partition(data.density, **params))
    if not np.isfinite(value):
        return DensityCurveFit(**failed, message="the optimiser found no curve with a finite likelihood")
    indices = curve.indices(**params)
    low, high = curve.parameters[0].bounds
    # the GLM is not held to the declared range, nor is a cut read from a curve with limits; below water it means nothing
    if not (math.isnan(indices.rho50) or low <= indices.rho50 <= high):
        return DensityCurveFit(
            **failed,
            message=f"the fitted cut density {indices.rho50:.4g} lies outside {low:g}..{high:g} g/cm3: the data do not locate the cut",
        )
    fit = DensityCurveFit(
        sample, curve, method, True, "", params, indices, value, **_statistics(curve, data, params, value), raw=raw
    )
    joint_fit = _joint(fit, ci) if joint else None
    if joint_fit is not None:
        return joint_fit
    return _with_intervals_and_notes(fit, data, ci, joint_fell_back=joint)


def _with_intervals_and_notes(fit: DensityCurveFit, data, ci: float | None, *, joint_fell_back: bool) -> DensityCurveFit:
    """The fit on the partitions with its intervals at ``ci`` and the notes on how it was made."""
    notes = [fit.indices.note] if fit.indices.note else []
    if joint_fell_back:
        notes.append(JOINT_FALLBACK_NOTE)
    if fit.overdispersed:
        notes.append(f"overdispersed (Pearson chi2/df = {fit.dispersion:.2f}: the Pearson test rejects binomial counts at 5 %)")
    intervals = {}
    if ci is not None:
        intervals, interval_notes = _intervals(fit, data, ci)
        notes += interval_notes
        quasi = quasi_binomial_scale(fit.dispersion, fit.df_resid)
        if quasi.estimated and data.binomial and intervals:
            notes.append(
                f"intervals on the quasi-binomial scale {quasi.scale:.3g} (Pearson chi2/df, above 1): deviance rises over it "
                f"against F(1, {fit.df_resid})"
            )
        if fit.sample.layout == "float-sink" and intervals:
            notes.append(FLOAT_SINK_INTERVAL_NOTE)
    return _replace(fit, intervals=intervals, notes=tuple(notes))


def _intervals(fit: DensityCurveFit, data: _Data, ci: float) -> tuple[dict, list[str]]:
    quantities, notes = _interval_quantities(fit, data)
    intervals = {}
    for quantity in quantities:
        low, high, note = profile_interval(fit, quantity, ci)
        intervals[quantity] = (low, high)
        notes += [note] if note else []
    return intervals, notes
