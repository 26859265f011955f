"""Uncertainty of every reported number of a fitted separation curve.

* Parameters (``d_cut``, the shape, bypass / fish-hook): standard errors from lmfit's
  covariance, Wald intervals and profile-likelihood intervals (lmfit ``conf_interval``).
* Derived indices (slope, eta, eps, d25, d75, Ep, imperfection): the delta method, with
  the gradient of each index with respect to the parameters taken by central
  differences and the parameter covariance of the fit; and the bootstrap, resampling
  residuals (fitted curve + resampled residuals) or cases (points), seeded, percentile
  intervals.
* Model averaging over the formulas fitted to one experiment with Akaike weights from
  AICc, and the unconditional standard error of Burnham & Anderson (2002, eq. 4.9).

References
----------
Burnham K.P., Anderson D.R. (2002). Model Selection and Multimodel Inference, 2nd ed.
Springer.  Efron B., Tibshirani R.J. (1993). An Introduction to the Bootstrap. Chapman & Hall.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy import stats

from ..curves.curve_fit import CurveFit, attach_indices, formula_context, with_lmfit
from ..curves.engine import refit_resamples
from ..curves.fitting import on_bound
from ..curves.indices import curve_indices
from ..loading.points import TrompPoints

logger = logging.getLogger(__name__)

INDEX_NAMES = ("slope", "eta", "epsilon", "d25", "d75", "ep", "imperfection", "d50", "ep_c", "imperfection_c")


# --- the range of every reported quantity -------------------------------------------------
@dataclass(frozen=True)
class Domain:
    """The range a quantity can take, and the scale on which its intervals are made.

    ``positive`` quantities get intervals on the log scale, ones bounded on both sides
    (in [0, 1], or epsilon in [0, x_max - 1]) on the logit scale of their position in the range, ``negative`` ones on the log of minus the value, ``real`` ones on the
    natural scale; the limits are transformed back, so an interval never leaves the range.
    A quantity bounded below by another value (a shape parameter admissible above -1)
    uses the log of its distance from that bound.
    """

    name: str
    lower: float
    upper: float
    scale: str

    def contains(self, value) -> np.ndarray:
        value = np.asarray(value, dtype=float)
        return (value >= self.lower) & (value <= self.upper)

    def inside(self, value: float) -> bool:
        """Strictly inside the range (the transformed scale exists there)."""
        return bool(np.isfinite(value) and self.lower < value < self.upper)

    def forward(self, value):
        value = np.asarray(value, dtype=float)
        if self.scale == "log":
            return np.log(value - self.lower)
        if self.scale == "neglog":
            return np.log(self.upper - value)
        if self.scale == "logit":
            return np.log(value - self.lower) - np.log(self.upper - value)
        return value

    def backward(self, value):
        value = np.asarray(value, dtype=float)
        with np.errstate(over="ignore"):  # an interval end far out on the log scale is infinite, not an error
            if self.scale == "log":
                return self.lower + np.exp(value)
            if self.scale == "neglog":
                return self.upper - np.exp(value)
            if self.scale == "logit":
                return self.lower + (self.upper - self.lower) / (1.0 + np.exp(-value))
        return value

    def slope(self, value):
        """Derivative of :meth:`forward` (turns a standard error onto the transformed scale)."""
        value = np.asarray(value, dtype=float)
        if self.scale == "log":
            return 1.0 / (value - self.lower)
        if self.scale == "neglog":
            return 1.0 / (self.upper - value)
        if self.scale == "logit":
            return (self.upper - self.lower) / ((value - self.lower) * (self.upper - value))
        return np.ones_like(value)


POSITIVE = Domain("positive", 0.0, np.inf, "log")
UNIT = Domain("unit interval", 0.0, 1.0, "logit")
NEGATIVE = Domain("negative", -np.inf, 0.0, "neglog")
REAL = Domain("real", -np.inf, np.inf, "identity")

#: Range of every reported quantity (sizes in the unit of the data).  The shape parameter's
#: range follows from its formula (:func:`quantity_domain`).
QUANTITY_DOMAINS = {
    "d_cut": POSITIVE,
    "d50c": POSITIVE,
    "d50": POSITIVE,
    "d25": POSITIVE,
    "d75": POSITIVE,
    "ep": POSITIVE,
    "ep_c": POSITIVE,
    "imperfection": POSITIVE,
    "imperfection_c": POSITIVE,
    "epsilon": POSITIVE,
    "eta": UNIT,
    "bypass": UNIT,
    "sharpness": UNIT,
    "fishhook": POSITIVE,
    "slope": NEGATIVE,
}


def quantity_domain(quantity: str, formula=None, *, x_max: float | None = None) -> Domain:
    """Range of a reported quantity.

    A shape parameter is positive when its formula admits only positive values, and
    bounded below by the formula's lower shape bound otherwise (km2 and kp above -1).
    Epsilon, the area under the curve between x = 1 and ``x_max = delta_max / d_cut``,
    lies in [0, x_max - 1] when ``x_max`` is given (positive otherwise).
    """
    if quantity == "epsilon" and x_max is not None and np.isfinite(x_max) and x_max > 1.0:
        return epsilon_domain(x_max)
    if quantity in QUANTITY_DOMAINS:
        return QUANTITY_DOMAINS[quantity]
    if formula is not None and quantity == formula.shape_name:
        lower = formula.shape_bounds[0]
        return POSITIVE if lower >= 0 else Domain(f"above {lower:g}", float(lower), np.inf, "log")
    return REAL


def epsilon_domain(x_max: float) -> Domain:
    """Epsilon's range [0, x_max - 1]: the curve, at most 1, integrated over [1, x_max]."""
    return Domain("0 to x_max - 1", 0.0, float(x_max) - 1.0, "logit")


def _relative_size_limit(fit: CurveFit, values: dict[str, float], delta_max: float) -> float:
    """``x_max = delta_max / d_cut`` at the fitted cut (the upper end of epsilon's integral)."""
    d_cut = fit.curve_arguments(values)[0]
    return delta_max / d_cut if d_cut > 0 else np.nan


def transformed_interval(value: float, stderr: float, half: float, domain: Domain) -> tuple[float, float]:
    """``value +- half * stderr`` made on the domain's scale and transformed back.

    ``half`` is the quantile (t or normal) times one; ``stderr`` is on the natural scale
    and carried to the transformed one by the derivative of the transform (delta method).
    nan where the estimate is not strictly inside its range or the error is unknown.
    """
    if not (domain.inside(value) and np.isfinite(stderr) and np.isfinite(half)):
        return np.nan, np.nan
    centre, spread = domain.forward(value), half * stderr * domain.slope(value)
    low, high = sorted((float(domain.backward(centre - spread)), float(domain.backward(centre + spread))))
    # the round trip through the transform may move a zero-width interval off the estimate by one ulp
    return min(low, value), max(high, value)


def _method(kind: str, domain: Domain) -> str:
    return kind if domain.scale == "identity" else f"{kind}-{domain.scale}"


def _indices_at(fit: CurveFit, values: dict[str, float], delta_max: float, known: dict | None = None) -> np.ndarray:
    if known:
        found = known.get(_index_key(fit, values, delta_max))
        if found is not None:
            return found
    d_cut, shape, extras = fit.curve_arguments(values)
    found = curve_indices(fit.formula, d_cut, shape, delta_max=delta_max, **fit.context_at(values), **extras)
    return np.array([getattr(found, name) for name in INDEX_NAMES])


def _index_key(fit: CurveFit, values: dict[str, float], delta_max: float) -> tuple:
    d_cut, shape, extras = fit.curve_arguments(values)
    return (fit.formula.id, d_cut, shape, *extras.values(), *fit.context_at(values).values(), delta_max)


def _step(value: float) -> float:
    """Central-difference step of the delta method: relative 1e-5, at least 1e-8."""
    return 1e-5 * max(abs(value), 1e-3)


def batched_delta_indices(fits: Sequence[CurveFit], delta_max: float | None = None) -> dict:
    """The indices the delta method of ``fits`` evaluates, computed in one batched call per formula.

    The delta method of a fit evaluates its indices at the fitted values and one step
    either side of each parameter (and of a data-derived input such as formula (11)'s
    measured efficiency).  For the formulas :func:`~tromplab.curves.indices.batch_curve_indices`
    covers, this evaluates all of them for many fits at once; the result, passed as
    ``known`` to :func:`interval_table` or :func:`model_average`, replaces one
    :func:`~tromplab.curves.indices.curve_indices` call per evaluation (same definitions; the
    quadrature agrees with the adaptive one to 1e-9).
    """
    from ..curves.indices import batch_curve_indices, batchable_indices

    wanted: dict[str, list] = {}
    for fit in fits:
        if not (fit.success and fit.fit.covariance is not None and batchable_indices(fit.formula)):
            continue
        limit = fit.options.delta_max if delta_max is None else delta_max
        values = {**fit.context_at(), **fit.fit.values}
        sets = [values]
        for name in (*fit.fit.names, *fit.context):
            step = _step(values[name])
            sets += [{**values, name: values[name] + step}, {**values, name: values[name] - step}]
        wanted.setdefault(fit.formula.id, []).extend((fit, each, limit) for each in sets)
    known = {}
    for formula_id, evaluations in wanted.items():
        arguments = [fit.curve_arguments(values) for fit, values, _ in evaluations]
        context = [fit.context_at(values) for fit, values, _ in evaluations]
        efficiency = [c.get("measured_efficiency", np.nan) for c in context] if context[0] else None
        found = batch_curve_indices(
            formula_id,
            [a[0] for a in arguments],
            [a[1] for a in arguments],
            delta_max=[limit for _, _, limit in evaluations],
            measured_efficiency=efficiency,
        )
        for (fit, values, limit), indices in zip(evaluations, found):
            known[_index_key(fit, values, limit)] = np.array([getattr(indices, name) for name in INDEX_NAMES])
    return known


def _difference(evaluate, values: dict[str, float], name: str) -> np.ndarray:
    step = _step(values[name])
    upper = np.asarray(evaluate({**values, name: values[name] + step}), dtype=float)
    lower = np.asarray(evaluate({**values, name: values[name] - step}), dtype=float)
    return (upper - lower) / (2 * step)


def delta_standard_errors(fit: CurveFit, evaluate: Callable[[dict[str, float]], np.ndarray]) -> np.ndarray:
    """Delta-method standard errors of ``evaluate(parameter values)`` (an array).

    The gradient with respect to each fitted parameter is a central difference with a
    relative step of 1e-5; the variance is ``g C g^T`` with the fit's covariance ``C``.

    A formula that also takes inputs from the measured points (formula (11): the measured
    efficiency, which fixes the break point x_a) depends on the data twice: through the
    fitted parameters and through that input.  Its errors are propagated from the data
    themselves: with ``J`` the Jacobian of the curve at the points, ``W`` the weights and
    ``s^2`` the residual variance, a change ``d phi`` of the points moves the parameters by
    ``(J'WJ)^-1 J'W (d phi - f_e de)`` and the input by ``de = e_phi' d phi``, so the
    variance is ``s^2 sum_i (dq/dphi_i)^2 / w_i`` (this equals ``g C g^T`` when there is
    no such input).  nan where the covariance is unknown or the gradient is not finite.
    """
    values = {**fit.context_at(), **fit.fit.values}
    centre = np.asarray(evaluate(values), dtype=float)
    covariance = fit.fit.covariance
    if covariance is None:
        return np.full(centre.shape, np.nan)
    gradient = np.array([_difference(evaluate, values, name) for name in fit.fit.names])
    if not fit.context:
        variance = np.einsum("i...,ij,j...->...", gradient, covariance, gradient)
        return np.where(np.all(np.isfinite(gradient), axis=0), np.sqrt(np.maximum(variance, 0.0)), np.nan)
    points, weights = fit.points, fit.options.weights
    dof = points.n - len(fit.fit.names)
    s_sq = fit.fit.ssr / dof if dof > 0 else np.nan
    curve = lambda v: fit.predict(points.size, v)  # noqa: E731
    jacobian = np.array([_difference(curve, values, name) for name in fit.fit.names]).T  # n x p
    sensitivity = covariance / s_sq @ jacobian.T * weights  # (J'WJ)^-1 J'W, p x n
    flat = gradient.reshape(len(fit.fit.names), -1)  # p x q
    per_point = flat.T @ sensitivity  # q x n
    for name in fit.context:
        input_by_point = _input_by_point(fit, name)
        curve_by_input = _difference(curve, values, name)
        index_by_input = _difference(evaluate, values, name).reshape(-1)
        per_point += -(flat.T @ (sensitivity @ curve_by_input))[:, None] * input_by_point[None, :]
        per_point += index_by_input[:, None] * input_by_point[None, :]
    variance = s_sq * np.sum(per_point**2 / weights, axis=1)
    finite = np.all(np.isfinite(per_point), axis=1)
    return np.where(finite, np.sqrt(np.maximum(variance, 0.0)), np.nan).reshape(centre.shape)


def _input_by_point(fit: CurveFit, name: str) -> np.ndarray:
    """Derivative of a data-derived formula input with respect to each measured partition."""
    points, step = fit.points, 1e-6
    out = np.empty(points.n)
    for i in range(points.n):
        shifted = []
        for sign in (1.0, -1.0):
            phi = points.partition_fine.copy()
            phi[i] += sign * step
            shifted.append(formula_context(fit.formula, TrompPoints(points.experiment, points.size, phi, points.weight))[name])
        out[i] = (shifted[0] - shifted[1]) / (2 * step)
    return out


def interval_table(
    fit: CurveFit, *, level: float = 0.95, delta_max: float | None = None, profile: bool = True, known: dict | None = None
) -> pd.DataFrame:
    """Estimates, standard errors and intervals of the parameters and indices of one fit.

    Returns a DataFrame with columns ``quantity, value, stderr, low, high, method, flag``.
    Every interval lies inside its quantity's range (:data:`QUANTITY_DOMAINS`):

    * parameters: the profile likelihood (``profile``; lmfit keeps it inside the
      parameter bounds), else Wald on the log / logit scale (``wald-log``,
      ``wald-logit``); a parameter on a bound of its fit gets a one-sided interval from
      that bound (``one-sided``, flagged);
    * indices: the delta method on the log / logit scale (``delta-log``, ``delta-logit``,
      ``delta-neglog`` for the negative slope).

    ``flag`` says when an interval is one-sided or could not be made.

    Parameters
    ----------
    fit : CurveFit
        A successful fit.
    level : float
        Confidence level, 0..1 (default 0.95).
    delta_max : float, optional
        Largest feed size for the misplacement (size unit); default the one the fit was
        made with.
    profile : bool
        Profile-likelihood intervals for the parameters (slower than Wald).
    known : dict, optional
        Indices evaluated beforehand by :func:`batched_delta_indices` (for many fits at once).
    """
    if not fit.success:
        raise ValueError(f"{fit.formula.id} on {fit.experiment}: the fit failed ({fit.fit.message})")
    delta_max = fit.options.delta_max if delta_max is None else delta_max
    dof = fit.points.n - len(fit.fit.names)
    two_sided = stats.t.ppf(0.5 + level / 2.0, dof) if dof > 0 else np.nan
    one_sided = stats.t.ppf(level, dof) if dof > 0 else np.nan
    profiled = with_lmfit(fit).fit.profile_intervals(level) if profile else {}  # engine fits: lmfit from the optimum
    bounds = {spec.name: (spec.lower, spec.upper) for spec in _specs(fit)}
    rows = []
    for name in fit.fit.names:
        value, se = fit.fit.values[name], fit.fit.stderr[name]
        domain = quantity_domain(name, fit.formula)
        flag = ""
        if name in fit.fit.at_bound:
            lower, upper = bounds[name]
            at_lower = on_bound(value, lower)
            low, high = _one_sided(value, se, one_sided, domain, at_lower)
            method = "one-sided"
            flag = f"{name} on its {'lower' if at_lower else 'upper'} bound {value:.4g}: one-sided interval"
        else:
            low, high = profiled.get(name, (np.nan, np.nan))
            method = "profile"
            if not (np.isfinite(low) and np.isfinite(high) and low <= value <= high):
                low, high = transformed_interval(value, se, two_sided, domain)
                method = _method("wald", domain)
        if not np.isfinite(low) or not np.isfinite(high):
            flag = flag or "interval not available (no standard error)"
        rows.append({"quantity": name, "value": value, "stderr": se, "low": low, "high": high, "method": method, "flag": flag})
    rows += _delta_rows(fit, two_sided, delta_max, known)
    return pd.DataFrame(rows)


def _specs(fit: CurveFit):
    from ..curves.curve_fit import _parameter_specs

    return _parameter_specs(fit.formula, fit.points)


def _one_sided(value: float, se: float, quantile: float, domain: Domain, at_lower: bool) -> tuple[float, float]:
    """Interval from the bound the estimate sits on to the one-sided limit on the other side."""
    if not (np.isfinite(se) and np.isfinite(quantile)):
        return (value, np.nan) if at_lower else (np.nan, value)
    if domain.inside(value):
        low, high = transformed_interval(value, se, quantile, domain)
    else:  # on the edge of the range itself (bypass = 0): the natural scale, clipped into it
        low, high = value - quantile * se, value + quantile * se
    low, high = float(np.clip(low, domain.lower, domain.upper)), float(np.clip(high, domain.lower, domain.upper))
    return (value, high) if at_lower else (low, value)


def _delta_rows(fit: CurveFit, half: float, delta_max: float, known: dict | None = None) -> list[dict]:
    centre = _indices_at(fit, {**fit.context_at(), **fit.fit.values}, delta_max, known)
    errors = delta_standard_errors(fit, lambda values: _indices_at(fit, values, delta_max, known))
    x_max = _relative_size_limit(fit, {**fit.context_at(), **fit.fit.values}, delta_max)
    rows = []
    for name, value, se in zip(INDEX_NAMES, centre, errors):
        domain = quantity_domain(name, x_max=x_max)
        low, high = transformed_interval(value, se, half, domain)
        flag = ""
        if not np.isfinite(value):
            flag = "not defined for this curve"
        elif not (np.isfinite(low) and np.isfinite(high)):
            flag = "interval not available" + ("" if domain.inside(value) else " (estimate on the edge of its range)")
        rows.append(
            {
                "quantity": name,
                "value": value,
                "stderr": se,
                "low": low,
                "high": high,
                "method": _method("delta", domain),
                "flag": flag,
            }
        )
    return rows


@dataclass(frozen=True)
class Bootstrap:
    """Bootstrap replicates of one fit: one row per successful resample.

    ``bounds`` maps each quantity to the edges it cannot pass (its range, and for the
    parameters the bounds of the fit); percentile limits on an edge are flagged.
    """

    samples: pd.DataFrame
    n_requested: int
    method: str
    seed: int
    bounds: dict = field(default_factory=dict)

    @property
    def n_failed(self) -> int:
        return self.n_requested - len(self.samples)

    def intervals(self, level: float = 0.95) -> pd.DataFrame:
        """Percentile intervals: ``quantity, low, high, stderr`` (standard deviation of the
        replicates), ``method`` ("percentile") and ``flag`` (a limit on a bound)."""
        tail = (1.0 - level) / 2.0
        rows = []
        for column in self.samples.columns:
            values = self.samples[column].dropna().to_numpy()
            low, high = np.quantile(values, [tail, 1 - tail]) if values.size else (np.nan, np.nan)
            edges = [e for e in self.bounds.get(column, ()) if np.isfinite(e)]
            on_edge = [
                f"{side} limit on the bound {edge:g}"
                for side, limit in (("lower", low), ("upper", high))
                for edge in edges
                if on_bound(limit, edge, rtol=1e-9, atol_at_zero=1e-12)
            ]
            rows.append(
                {
                    "quantity": column,
                    "low": low,
                    "high": high,
                    "stderr": values.std(ddof=1) if values.size > 1 else np.nan,
                    "method": "percentile",
                    "flag": "; ".join(on_edge),
                }
            )
        return pd.DataFrame(rows)


def bootstrap(
    fit: CurveFit,
    *,
    n: int = 200,
    seed: int = 0,
    method: str = "residuals",
    delta_max: float | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> Bootstrap:
    """Refit ``n`` resampled data sets from the optimum of ``fit``.

    ``method="residuals"``: fitted values plus weighted residuals drawn with replacement.
    The residuals are taken on the scale the fit used (``sqrt(w_i)`` times the raw
    residual, equal in variance under the model), centred (a least-squares fit of a
    nonlinear curve does not make them sum to zero), scaled by ``sqrt(n / (n - p))`` for
    the degrees of freedom the fit used, and divided by ``sqrt(w_j)`` of the point they
    are added to.  ``"cases"``: points drawn with replacement (resamples with fewer than
    ``p + 1`` distinct sizes are drawn again).  Each refit starts at the original
    optimum, without the global grid, with the options of the original fit (alpha,
    ``delta_max`` unless given here).

    Parameters
    ----------
    fit : CurveFit
        A successful fit.
    n : int
        Number of resamples (> 0).
    seed : int
        Seed of numpy's default generator.
    method : {"residuals", "cases"}
    delta_max : float, optional
        Largest feed size for the misplacement (size unit); default the fit's.
    progress : callable, optional
        Called as ``progress(i, n)`` before each resample.
    """
    if not fit.success:
        raise ValueError(f"{fit.formula.id} on {fit.experiment}: cannot bootstrap a failed fit")
    if method not in ("residuals", "cases"):
        raise ValueError("method must be 'residuals' or 'cases'")
    if n < 2:
        raise ValueError("the bootstrap needs at least 2 resamples")
    rng = np.random.default_rng(seed)
    points = fit.points
    p = fit.formula.n_params
    fitted = fit.predict(points.size)
    root_weights = np.sqrt(fit.options.weights)
    scaled = root_weights * (points.partition_fine - fitted)
    residuals = (scaled - scaled.mean()) * np.sqrt(points.n / max(points.n - p, 1))
    delta_max = fit.options.delta_max if delta_max is None else delta_max
    samples = []
    for i in range(n):
        if progress is not None:
            progress(i + 1, n)
        if method == "residuals":
            sample = TrompPoints(
                points.experiment,
                points.size,
                fitted + rng.choice(residuals, points.n) / root_weights,
                points.weight,
                resampled=True,
            )
            samples.append(sample)
        else:
            while True:
                pick = rng.integers(0, points.n, points.n)
                if np.unique(points.size[pick]).size > p:
                    break
            weight = None if points.weight is None else points.weight[pick]
            samples.append(TrompPoints(points.experiment, points.size[pick], points.partition_fine[pick], weight, resampled=True))
    refits = refit_resamples(fit, samples, delta_max=delta_max)  # all resamples in one batched call
    attach_indices(refits)  # and their indices in one array computation
    logger.debug(
        "bootstrap %s %s: %d %s resamples, %d refits failed",
        fit.experiment,
        fit.formula.id,
        n,
        method,
        sum(not refit.success for refit in refits),
    )
    rows = [{**refit.fit.values, **{k: getattr(refit.indices, k) for k in INDEX_NAMES}} for refit in refits if refit.success]
    x_max = _relative_size_limit(fit, {**fit.context_at(), **fit.fit.values}, delta_max)
    domains = {name: quantity_domain(name, fit.formula, x_max=x_max) for name in (*fit.fit.names, *INDEX_NAMES)}
    bounds = {name: (domain.lower, domain.upper) for name, domain in domains.items()}
    for spec in _specs(fit):
        bounds[spec.name] = (*bounds[spec.name], spec.lower, spec.upper)
    return Bootstrap(pd.DataFrame(rows), n, method, seed, bounds)


# --- information criteria and model averaging --------------------------------------------
def akaike_weights(aicc: Sequence[float]) -> np.ndarray:
    """Akaike weights ``exp(-Delta/2) / sum exp(-Delta/2)``; missing criteria get weight 0.

    Parameters
    ----------
    aicc : sequence of float
        Information criteria of the competing fits (nan for a failed fit).

    Examples
    --------
    >>> akaike_weights([10.0, 12.0, np.nan]).round(4).tolist()
    [0.7311, 0.2689, 0.0]
    """
    aicc = np.asarray(aicc, dtype=float)
    finite = np.isfinite(aicc)
    weights = np.zeros_like(aicc)
    if finite.any():
        delta = aicc[finite] - aicc[finite].min()
        raw = np.exp(-delta / 2.0)
        weights[finite] = raw / raw.sum()
    return weights


#: Quantities averaged over the formulas by default: the actual and the corrected cut, the
#: actual and the corrected Ep, and eta.
AVERAGED_QUANTITIES = ("d50", "d50c", "ep", "ep_c", "eta")

#: A model average is reported only when the formulas where the quantity is defined hold
#: at least this share of the Akaike weight.
MIN_WEIGHT_SHARE = 0.5


def model_average(
    fits: Sequence[CurveFit],
    *,
    quantities=AVERAGED_QUANTITIES,
    level: float = 0.95,
    delta_max: float | None = None,
    min_share: float = MIN_WEIGHT_SHARE,
    known: dict | None = None,
) -> pd.DataFrame:
    """Akaike-weighted averages of ``quantities`` over the fits of one experiment.

    Only the formulas where a quantity is defined (finite) enter its average, with their
    Akaike weights renormalised; ``akaike_share`` is the share of the total weight they
    hold.  Below ``min_share`` the average is left empty (nan) and ``note`` says why: the
    formulas the data favour do not have the quantity (an actual Ep when the bypass keeps
    the actual curve from reaching 0.75, say).

    The unconditional standard error (Burnham & Anderson 2002, eq. 4.9) is
    ``sum_i w_i sqrt(se_i^2 + (theta_i - theta_bar)^2)`` with ``se_i`` from the fit
    (parameters) or the delta method (indices).  The interval is made the same way on the
    log (logit for eta; for epsilon the logit of eps / (x_max - 1) with the largest x_max
    of the fits) scale around ``g(theta_bar)`` and transformed back, so it stays in the
    quantity's range (``method`` says so).  ``d50c`` is the corrected cut of each
    formula (for the nine paper formulas, which have no bypass, the corrected curve is
    the actual one and ``d50c = d50 = d_cut``); a corrected cut is never averaged with an
    actual one.  When a formula in the average has no standard error of the quantity (a
    parameter not determined), the average's ``stderr``, ``low`` and ``high`` stay empty
    (nan) and ``note`` names the formula: a missing error is not taken as zero.

    Returns ``quantity, value, stderr, low, high, method, akaike_share, n_formulas, note``
    plus one weight column per formula (``weight_<id>``).

    Parameters
    ----------
    fits : sequence of CurveFit
        Fits of several formulas to one experiment.
    quantities : sequence of str
        Parameters or indices to average (names of :func:`interval_table`).
    level : float
        Confidence level of the normal intervals, 0..1.
    delta_max : float, optional
        Largest feed size for the misplacement (size unit); default each fit's own.
    min_share : float
        Smallest share of the Akaike weight the formulas with the quantity must hold.
    known : dict, optional
        Indices of the delta method evaluated beforehand by :func:`batched_delta_indices`
        (default: evaluated here, batched over these fits).
    """
    good = [fit for fit in fits if fit.success]
    if not good:
        raise ValueError("no successful fit to average")
    if len({fit.experiment for fit in good}) > 1:
        raise ValueError("model averaging combines the formulas fitted to one experiment")
    weights = akaike_weights([fit.fit.information_criteria()["aicc"] for fit in good])
    known = batched_delta_indices(good, delta_max) if known is None else known
    estimates = [_estimates_and_errors(fit, delta_max, known) for fit in good]
    # epsilon: each formula's range [0, x_max - 1] lies inside that of the largest x_max
    widest_x_max = max((fit.options.delta_max if delta_max is None else delta_max) / fit.d_cut for fit in good)
    rows = []
    z = stats.norm.ppf(0.5 + level / 2.0)
    for quantity in quantities:
        values = np.array([found.get(quantity, (np.nan, np.nan))[0] for found in estimates])
        errors = np.array([found.get(quantity, (np.nan, np.nan))[1] for found in estimates])
        usable = np.isfinite(values) & (weights > 0)
        share = float(weights[usable].sum())
        row = {
            "quantity": quantity,
            "value": np.nan,
            "stderr": np.nan,
            "low": np.nan,
            "high": np.nan,
            "method": "",
            "akaike_share": share,
            "n_formulas": int(usable.sum()),
            "note": "",
        }
        if share < min_share or not usable.any():
            row["note"] = (
                f"not averaged: defined only for formulas holding {share:.2%} of the Akaike weight (less than {min_share:.0%})"
            )
            rows.append(row)
            continue
        w = weights[usable] / share
        theta, se = values[usable], errors[usable]  # a missing se stays missing: the average's is then unknown
        mean = float(np.sum(w * theta))
        domain = quantity_domain(quantity, x_max=widest_x_max)
        row.update(value=mean, stderr=float(np.sum(w * np.sqrt(se**2 + (theta - mean) ** 2))))
        ids = [fit.formula.id for fit, used in zip(good, usable) if used]
        without_se = [name for name, error in zip(ids, se) if not np.isfinite(error)]
        if without_se:
            row["note"] = (
                f"no standard error and no interval: the fit of {', '.join(without_se)} "
                f"({float(w[~np.isfinite(se)].sum()):.2%} of the weight) gives no standard error of {quantity}"
            )
        elif domain.inside(mean) and all(domain.inside(t) for t in theta):
            g_mean = domain.forward(mean)
            se_g = float(np.sum(w * np.sqrt((se * domain.slope(theta)) ** 2 + (domain.forward(theta) - g_mean) ** 2)))
            low, high = sorted((float(domain.backward(g_mean - z * se_g)), float(domain.backward(g_mean + z * se_g))))
            row.update(low=low, high=high, method=_method("akaike", domain))
        else:
            row["note"] = "no interval: an estimate lies on the edge of the quantity's range"
        if share < 1.0 - 1e-9:
            row["note"] = (
                row["note"] or f"averaged over the {int(usable.sum())} formulas where it is defined ({share:.2%} of the weight)"
            )
        rows.append(row)
    weight_columns = {f"weight_{fit.formula.id}": weight for fit, weight in zip(good, weights)}
    if not rows:  # no quantity asked for: the weights alone
        table = pd.DataFrame()
        for name, weight in weight_columns.items():
            table[name] = weight
        return table
    # the weight columns go into each row: adding them to the frame one by one cost about
    # 1 ms each (9 ms per experiment, the largest part of the averages of a batch)
    return pd.DataFrame([{**row, **weight_columns} for row in rows])


def _estimates_and_errors(fit: CurveFit, delta_max: float | None, known: dict | None) -> dict[str, tuple[float, float]]:
    """``{quantity: (value, standard error)}`` of the parameters and indices of one fit, as
    :func:`interval_table` reports them (without building its table); ``d50c`` is the fitted
    ``d_cut`` of every formula (the corrected cut)."""
    limit = fit.options.delta_max if delta_max is None else delta_max
    values = {**fit.context_at(), **fit.fit.values}
    centre = _indices_at(fit, values, limit, known)
    errors = delta_standard_errors(fit, lambda at: _indices_at(fit, at, limit, known))
    found = {name: (float(fit.fit.values[name]), float(fit.fit.stderr[name])) for name in fit.fit.names}
    found.update({name: (float(v), float(e)) for name, v, e in zip(INDEX_NAMES, centre, errors)})
    found["d50c"] = found["d_cut"]
    return found


def interval_columns(
    fits: Sequence[CurveFit],
    *,
    level: float | None = None,
    n_bootstrap: int = 0,
    method: str = "residuals",
    seed: int = 0,
    progress: Callable[[int, int, str], None] | None = None,
) -> pd.DataFrame:
    """Wide interval columns for ``fits.csv``.

    With ``level``: ``<quantity>_low``/``_high`` and ``<quantity>_method`` (how the interval
    was made, see :func:`interval_table`); with ``n_bootstrap``: ``<quantity>_boot_low`` /
    ``_boot_high`` (percentile, ``bootstrap_method`` says residuals or cases) and
    ``bootstrap_failed``.  ``interval_flags`` lists one-sided intervals, missing ones and
    bootstrap limits on a bound.  Keyed by ``experiment`` and ``formula``; failed fits
    get nan.  Every fit's own ``delta_max`` and alpha are used.
    """
    from ..validation import check_bootstrap, check_optional, check_probability, check_seed

    check_optional(check_probability, level, "level")
    n_bootstrap, seed = check_bootstrap(n_bootstrap, "n_bootstrap"), check_seed(seed, "seed")
    bootstrap_level = 0.95 if level is None else level
    logger.info(
        "intervals for %d fit(s): %s, %s",
        len(fits),
        "no delta/profile intervals" if level is None else f"delta/profile at level {level:g}",
        f"bootstrap of {n_bootstrap} {method} resamples, seed {seed}" if n_bootstrap else "no bootstrap",
    )
    rows = []
    for i, fit in enumerate(fits):
        row = {"experiment": fit.experiment, "formula": fit.formula.id}
        if progress is not None:
            progress(i + 1, len(fits), f"{fit.experiment} / {fit.formula.id}")
        if fit.success:
            flags = []
            try:
                if level is not None:
                    table = interval_table(fit, level=level).set_index("quantity")
                    for quantity in table.index:
                        stem = _column(fit, quantity)
                        row[f"{stem}_low"] = table.loc[quantity, "low"]
                        row[f"{stem}_high"] = table.loc[quantity, "high"]
                        row[f"{stem}_method"] = table.loc[quantity, "method"]
                        if table.loc[quantity, "flag"] and np.isfinite(table.loc[quantity, "value"]):
                            flags.append(f"{stem}: {table.loc[quantity, 'flag']}")
                if n_bootstrap:
                    boot = bootstrap(fit, n=n_bootstrap, seed=seed, method=method)
                    for quantity, low, high, flag in boot.intervals(bootstrap_level)[
                        ["quantity", "low", "high", "flag"]
                    ].itertuples(index=False):
                        stem = _column(fit, quantity)
                        row[f"{stem}_boot_low"] = low
                        row[f"{stem}_boot_high"] = high
                        if flag:
                            flags.append(f"{stem} bootstrap: {flag}")
                    row["bootstrap_method"] = f"percentile ({method})"
                    row["bootstrap_failed"] = boot.n_failed
            except (ValueError, ArithmeticError, RuntimeError) as error:  # a batch reports and goes on
                row["interval_message"] = f"intervals not computed: {error}"
            row["interval_flags"] = "; ".join(flags)
        rows.append(row)
    return pd.DataFrame(rows)


def _column(fit: CurveFit, quantity: str) -> str:
    """Column stem of a quantity: the shape parameter is reported as ``shape``."""
    return "shape" if quantity == fit.formula.shape_name else quantity
