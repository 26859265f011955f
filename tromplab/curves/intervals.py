"""Standard errors and intervals of one fit: the range of every reported quantity, Wald and
profile-likelihood intervals of the parameters, the delta method for the indices.

They are the inference of a single :class:`~tromplab.curves.curve_fit.CurveFit` (its
``report()`` prints them, as a statsmodels result prints its ``conf_int()``), so they sit
below it; the bootstrap, model averaging and the interval columns of a batch build on them
in :mod:`tromplab.statistics.uncertainty`.  ``fit`` arguments are duck-typed: a
``CurveFit`` or anything with its fields.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd
from scipy import stats

from ..errors import expect_like
from ..validation import check_optional, check_probability, check_size
from .batched import BatchProblem, PaddedPoints, profile_limits, sum_of_squares
from .formulas import is_batchable
from .indices import batch_index_columns, batchable_indices, curve_indices
from .likelihood import on_bound
from .measured import CUT_QUANTITIES, formula_contexts, parameter_specs
from .parameters import D_CUT_RANGE_FACTOR

if TYPE_CHECKING:
    from .curve_fit import CurveFit

#: What a fit handed to the interval functions has (a CurveFit; this layer cannot import the class).
FIT_ATTRIBUTES = ("fit", "points", "formula", "success", "options")


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


def relative_size_limit(fit: CurveFit, values: dict[str, float], delta_max: float) -> float:
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


@lru_cache(maxsize=1024)  # a batch asks for the same few (level, dof) once per fit: scipy's ppf costs 80 us
def student_quantile(probability: float, dof: int) -> float:
    """Quantile of Student's t with ``dof`` degrees of freedom."""
    return float(stats.t.ppf(probability, dof))


@lru_cache(maxsize=64)
def normal_quantile(probability: float) -> float:
    """Quantile of the standard normal distribution."""
    return float(stats.norm.ppf(probability))


def interval_method(kind: str, domain: Domain) -> str:
    return kind if domain.scale == "identity" else f"{kind}-{domain.scale}"


def indices_at(fit: CurveFit, values: dict[str, float], delta_max: float, known: dict | None = None) -> np.ndarray:
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


def _step(value):
    """Central-difference step of the delta method: relative 1e-5, at least 1e-8 (elementwise on arrays)."""
    return 1e-5 * np.maximum(np.abs(value), 1e-3)


def batched_delta_indices(fits: Sequence[CurveFit], delta_max: float | None = None, *, epsilon: bool = True) -> dict:
    """The indices the delta method of ``fits`` evaluates, computed in one batched call per formula.

    The delta method of a fit evaluates its indices at the fitted values and one step
    either side of each parameter (and of a data-derived input such as formula (11)'s
    measured efficiency).  For the formulas :func:`~tromplab.curves.indices.batch_curve_indices`
    covers, this evaluates all of them for many fits at once; the result, passed as
    ``known`` to :func:`interval_table` or :func:`model_average`, replaces one
    :func:`~tromplab.curves.indices.curve_indices` call per evaluation (same definitions; the
    quadrature agrees with the adaptive one to 1e-9).  For a formula without data-derived
    inputs the gradients and the variances ``g C g^T`` of all its fits are formed on arrays
    too, and ``known`` holds each fit's estimates and standard errors
    (:func:`delta_indices` reads them).  ``epsilon=False`` leaves epsilon and its error nan
    (for a caller that does not report it: its integral is the costliest of the indices).
    """
    wanted: dict[str, list] = {}
    plain: dict[str, list] = {}
    for fit in fits:
        if not (fit.success and fit.fit.covariance is not None and batchable_indices(fit.formula)):
            continue
        limit = fit.options.delta_max if delta_max is None else delta_max
        if not fit.context:
            plain.setdefault(fit.formula.id, []).append((fit, limit))
            continue
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
        columns, _ = batch_index_columns(
            formula_id,
            [a[0] for a in arguments],
            [a[1] for a in arguments],
            delta_max=[limit for _, _, limit in evaluations],
            measured_efficiency=efficiency,
            epsilon=epsilon,
            **{name: [a[2][name] for a in arguments] for name in arguments[0][2]},  # the bypass of bypass curves
        )
        for (fit, values, limit), indices in zip(evaluations, index_array(columns)):
            known[_index_key(fit, values, limit)] = indices
        moving = evaluations[0][0].formula.moving_break
        if moving is not None:  # the curve's break at each evaluation, for the delta method's Jacobian at the points
            shapes, efficiencies = [a[1] for a in arguments], [c["measured_efficiency"] for c in context]
            for shape, efficiency, x_break in zip(shapes, efficiencies, moving.on_arrays(shapes, efficiencies)):
                known[("break", formula_id, shape, efficiency)] = x_break
    for formula_id, members in plain.items():
        for (fit, limit), centre, errors in zip(members, *_delta_on_arrays(formula_id, members, epsilon)):
            known[_delta_key(fit, limit)] = (centre, errors)
    with_inputs = {id(fit): fit for evaluations in wanted.values() for fit, _, _ in evaluations}
    _inputs_by_point(list(with_inputs.values()), known)
    return known


def index_array(columns: dict[str, np.ndarray]) -> np.ndarray:
    """The :data:`INDEX_NAMES` of :func:`~tromplab.curves.indices.batch_index_columns`, a row per curve."""
    return np.column_stack([columns[name] for name in INDEX_NAMES])


def _delta_on_arrays(formula_id: str, members: list, epsilon: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Indices and their delta-method standard errors of fits ``(fit, delta_max)`` of one formula
    without data-derived inputs, all at once: the central differences of
    :func:`delta_standard_errors` (the same steps) and ``g C g^T`` on arrays."""
    first = members[0][0]
    names, shape_at = first.fit.names, first.fit.names.index(first.formula.shape_name)
    values = np.array([[fit.fit.values[name] for name in names] for fit, _ in members])  # (m, p)
    covariance = np.array([fit.fit.covariance for fit, _ in members])  # (m, p, p)
    limits = np.array([limit for _, limit in members], dtype=float)
    steps = _step(values)
    count, n_params = values.shape
    sets = np.repeat(values[:, None, :], 1 + 2 * n_params, axis=1)  # centre, then + and - each parameter
    for j in range(n_params):
        sets[:, 1 + 2 * j, j] += steps[:, j]
        sets[:, 2 + 2 * j, j] -= steps[:, j]
    columns, _ = batch_index_columns(
        formula_id,
        sets[..., names.index("d_cut")].ravel(),
        sets[..., shape_at].ravel(),
        delta_max=np.repeat(limits, 1 + 2 * n_params),
        epsilon=epsilon,
        **{extra.name: sets[..., names.index(extra.name)].ravel() for extra in first.formula.extras},  # the bypass
    )
    table = index_array(columns).reshape(count, 1 + 2 * n_params, -1)
    gradient = (table[:, 1::2] - table[:, 2::2]) / (2 * steps[..., None])  # (m, p, q)
    variance = np.einsum("mpq,mpr,mrq->mq", gradient, covariance, gradient)
    errors = np.where(np.all(np.isfinite(gradient), axis=1), np.sqrt(np.maximum(variance, 0.0)), np.nan)
    return table[:, 0], errors


def _delta_key(fit: CurveFit, delta_max: float) -> tuple:
    return ("delta", fit.experiment, fit.formula.id, *fit.fit.values.values(), delta_max)


def delta_indices(fit: CurveFit, delta_max: float, known: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(indices, standard errors)`` of one fit in :data:`INDEX_NAMES` order: from ``known``
    (:func:`batched_delta_indices`) where it holds them, else by :func:`delta_standard_errors`."""
    if known:
        found = known.get(_delta_key(fit, delta_max))
        if found is not None:
            return found
    centre = indices_at(fit, {**fit.context_at(), **fit.fit.values}, delta_max, known)
    return centre, delta_standard_errors(fit, lambda values: indices_at(fit, values, delta_max, known), known)


def batched_profile_intervals(fits: Sequence[CurveFit], level: float = 0.95, *, width: int | None = None) -> list[dict | None]:
    """Profile-likelihood intervals of the parameters of many fits, one batched search per formula.

    The same intervals as lmfit's ``conf_interval`` (F test, the other parameters
    re-optimised, bounds respected; :func:`~tromplab.curves.batched.profile_limits`), to its
    tolerance (it stops at 5e-5 relative; this search at 1e-9), for every formula the
    batched engine evaluates on arrays (:func:`~tromplab.curves.formulas.is_batchable`).
    ``width`` pads the points as :class:`~tromplab.curves.batched.PaddedPoints` does.

    Returns
    -------
    list
        Per fit, ``{name: (low, high)}`` (nan where the profile reaches a bound below the
        level), or None for a failed fit or a formula that is not batchable: its intervals
        come from lmfit (:meth:`~tromplab.curves.fitting.ParameterFit.profile_intervals`).
    """
    found: list[dict | None] = [None] * len(fits)
    groups: dict[str, list[int]] = {}
    for i, fit in enumerate(fits):
        if fit.success and is_batchable(fit.formula) and all(np.isfinite(list(fit.fit.values.values()))):
            groups.setdefault(fit.formula.id, []).append(i)
    for members in groups.values():
        chosen = [fits[i] for i in members]
        formula, names = chosen[0].formula, chosen[0].fit.names
        efficiency = np.array([fit.context["measured_efficiency"] for fit in chosen]) if formula.context_from_efficiency else None
        data = PaddedPoints.from_points([fit.points for fit in chosen], width)
        problem = BatchProblem(formula, data, efficiency, D_CUT_RANGE_FACTOR)  # the bounds of the fits
        values = np.array([[fit.fit.values[name] for name in names] for fit in chosen])
        stderr = np.array([[fit.fit.stderr[name] for name in names] for fit in chosen])
        best = values.copy()
        best[:, 0] = np.log(values[:, 0])
        stderr[:, 0] = stderr[:, 0] / values[:, 0]  # of ln d_cut
        best_ssr = sum_of_squares(problem.residual(best, np.arange(len(chosen))))
        free = np.array([fit.points.n - len(names) for fit in chosen], dtype=float)
        with np.errstate(invalid="ignore", divide="ignore"):  # the Wald half-width: the limit of a quadratic profile
            steps = stderr * np.sqrt(stats.f.ppf(level, 1, free))[:, None]
        low, high = profile_limits(problem, best, best_ssr, steps, level)
        low[:, 0], high[:, 0] = np.exp(low[:, 0]), np.exp(high[:, 0])
        for row, i in enumerate(members):
            found[i] = {name: (float(low[row, k]), float(high[row, k])) for k, name in enumerate(names)}
    return found


def profile_intervals(fit: CurveFit, level: float = 0.95) -> dict[str, tuple[float, float]]:
    """Profile-likelihood intervals of one fit's parameters: the batched search where the
    formula allows (:func:`batched_profile_intervals`), else lmfit's ``conf_interval``."""
    found = batched_profile_intervals([fit], level)[0]
    return found if found is not None else fit.with_lmfit().fit.profile_intervals(level)


def _difference(evaluate, values: dict[str, float], name: str) -> np.ndarray:
    step = _step(values[name])
    upper = np.asarray(evaluate({**values, name: values[name] + step}), dtype=float)
    lower = np.asarray(evaluate({**values, name: values[name] - step}), dtype=float)
    return (upper - lower) / (2 * step)


def _curve_at(fit: CurveFit, size: np.ndarray, values: dict[str, float], known: dict | None) -> np.ndarray:
    """``fit.predict(size, values)``, with a moving break (formula (11)) taken from ``known``
    where :func:`batched_delta_indices` solved it on arrays (one brentq per call otherwise)."""
    moving = fit.formula.moving_break
    if known and moving is not None:
        d_cut, shape, _ = fit.curve_arguments(values)
        x_break = known.get(("break", fit.formula.id, shape, fit.context_at(values)["measured_efficiency"]))
        if x_break is not None:
            return moving.phi(np.asarray(size, dtype=float) / d_cut, shape, x_break)
    return fit.predict(size, values)


def delta_standard_errors(
    fit: CurveFit, evaluate: Callable[[dict[str, float]], np.ndarray], known: dict | None = None
) -> np.ndarray:
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
    ``known`` (:func:`batched_delta_indices`) supplies break points solved beforehand.
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
    curve = lambda v: _curve_at(fit, points.size, v, known)  # noqa: E731
    jacobian = np.array([_difference(curve, values, name) for name in fit.fit.names]).T  # n x p
    sensitivity = covariance / s_sq @ jacobian.T * weights  # (J'WJ)^-1 J'W, p x n
    flat = gradient.reshape(len(fit.fit.names), -1)  # p x q
    per_point = flat.T @ sensitivity  # q x n
    for name in fit.context:
        input_by_point = _input_by_point(fit, name, known)
        curve_by_input = _difference(curve, values, name)
        index_by_input = _difference(evaluate, values, name).reshape(-1)
        per_point += -(flat.T @ (sensitivity @ curve_by_input))[:, None] * input_by_point[None, :]
        per_point += index_by_input[:, None] * input_by_point[None, :]
    variance = s_sq * np.sum(per_point**2 / weights, axis=1)
    finite = np.all(np.isfinite(per_point), axis=1)
    return np.where(finite, np.sqrt(np.maximum(variance, 0.0)), np.nan).reshape(centre.shape)


#: Step of a measured partition in the derivative of a data-derived input (:func:`_input_by_point`).
INPUT_STEP = 1e-6


def _input_by_point(fit: CurveFit, name: str, known: dict | None = None) -> np.ndarray:
    """Derivative of a data-derived formula input with respect to each measured partition
    (from ``known`` where :func:`_inputs_by_point` put it)."""
    found = known.get(_input_key(fit, name)) if known else None
    if found is not None:
        return found
    points = fit.points
    inputs = formula_contexts(fit.formula, points.size, _moved_partitions(points))[name]
    return (inputs[0::2] - inputs[1::2]) / (2 * INPUT_STEP)


def _moved_partitions(points) -> np.ndarray:
    """``(2 n, n)``: the measured partitions with each point moved up, then down, by :data:`INPUT_STEP`."""
    moved = np.repeat(points.partition_fine[None, :], 2 * points.n, axis=0)
    each = np.arange(points.n)
    moved[2 * each, each] += INPUT_STEP
    moved[2 * each + 1, each] -= INPUT_STEP
    return moved


def _input_key(fit: CurveFit, name: str) -> tuple:
    points = fit.points
    return ("input", name, fit.formula.id, points.experiment, points.size.tobytes(), points.partition_fine.tobytes())


def _inputs_by_point(fits: Sequence[CurveFit], known: dict) -> None:
    """:func:`_input_by_point` of every data-derived input of ``fits`` into ``known``: the
    moved partitions of all experiments with the same number of points in one call of
    :func:`~tromplab.curves.measured.formula_contexts` per formula (row by row the same sums)."""
    groups: dict[tuple, list[CurveFit]] = {}
    for fit in fits:
        if fit.context:
            groups.setdefault((fit.formula.id, fit.points.n), []).append(fit)
    for (_, n), members in groups.items():
        size = np.repeat(np.array([fit.points.size for fit in members]), 2 * n, axis=0)
        moved = np.concatenate([_moved_partitions(fit.points) for fit in members])
        contexts = formula_contexts(members[0].formula, size, moved)
        for name, inputs in contexts.items():
            derivative = (inputs[0::2] - inputs[1::2]) / (2 * INPUT_STEP)
            for fit, each in zip(members, derivative.reshape(len(members), n)):
                known[_input_key(fit, name)] = each


def interval_table(
    fit: CurveFit,
    *,
    level: float = 0.95,
    delta_max: float | None = None,
    profile: bool = True,
    known: dict | None = None,
    profiled: dict | None = None,
) -> pd.DataFrame:
    """Estimates, standard errors and intervals of the parameters and indices of one fit.

    Returns a DataFrame with columns ``quantity, value, stderr, low, high, method, flag``
    (:func:`interval_rows`: the same rows as dicts, for many fits).
    Every interval lies inside its quantity's range (:data:`QUANTITY_DOMAINS`):

    * parameters: the profile likelihood (``profile``; the F test of lmfit's
      ``conf_interval``, found by :func:`batched_profile_intervals`, inside the parameter
      bounds; lmfit itself for a formula the engine cannot evaluate on arrays), else Wald on the log / logit scale (``wald-log``,
      ``wald-logit``); a parameter on a bound of its fit gets a one-sided interval from
      that bound (``one-sided``, flagged);
    * indices: the delta method on the log / logit scale (``delta-log``, ``delta-logit``,
      ``delta-neglog`` for the negative slope).

    ``flag`` says when an interval is one-sided or could not be made.  No interval is
    given (``method`` ``none``, ``flag`` saying why) where the data do not determine the
    quantity: d_cut, d50, d50c, d25, d75 and Ep when the points do not bracket the cut
    (:func:`~tromplab.curves.measured.unbracketed_cut`), and an extra parameter correlated
    with the cut or the shape (``CurveFit.undetermined_extras``).

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
    profiled : dict, optional
        The profile intervals of this fit made beforehand (:func:`batched_profile_intervals`,
        for many fits at once); default :func:`profile_intervals` with ``profile``.
    """
    expect_like(fit, FIT_ATTRIBUTES, "fit", "a CurveFit (tromplab.fit_formula)")
    level = check_probability(level, "level")
    delta_max = check_optional(check_size, delta_max, "delta_max")
    return pd.DataFrame(interval_rows(fit, level=level, delta_max=delta_max, profile=profile, known=known, profiled=profiled))


def interval_rows(
    fit: CurveFit,
    *,
    level: float = 0.95,
    delta_max: float | None = None,
    profile: bool = True,
    known: dict | None = None,
    profiled: dict | None = None,
) -> list[dict]:
    """The rows of :func:`interval_table` as dicts (the arguments are the same).

    Returns
    -------
    list of dict
        One per quantity, keys ``quantity, value, stderr, low, high, method, flag``.
    """
    if not fit.success:
        raise ValueError(f"{fit.formula.id} on {fit.experiment}: the fit failed ({fit.fit.message})")
    delta_max = fit.options.delta_max if delta_max is None else delta_max
    dof = fit.points.n - len(fit.fit.names)
    two_sided = student_quantile(0.5 + level / 2.0, dof) if dof > 0 else np.nan
    one_sided = student_quantile(level, dof) if dof > 0 else np.nan
    if profiled is None:
        profiled = profile_intervals(fit, level) if profile else {}
    bounds = {spec.name: (spec.lower, spec.upper) for spec in parameter_specs(fit.formula, fit.points)}
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
                method = interval_method("wald", domain)
        if not np.isfinite(low) or not np.isfinite(high):
            flag = flag or "interval not available (no standard error)"
        rows.append({"quantity": name, "value": value, "stderr": se, "low": low, "high": high, "method": method, "flag": flag})
    rows += _delta_rows(fit, two_sided, delta_max, known)
    return [withheld_interval(fit, row) for row in rows]


def withheld_interval(fit, row: dict) -> dict:
    """The row without its interval when the data do not determine the quantity: a cut the
    points do not bracket (``fit.unbracketed``, for the quantities that rest on the cut) or an
    extra parameter the data cannot tell from the cut or the shape (``fit.undetermined_extras``)."""
    unbracketed = getattr(fit, "unbracketed", "")
    undetermined = getattr(fit, "undetermined_extras", {})
    if unbracketed and row["quantity"] in CUT_QUANTITIES:
        reason = f"no interval: the cut is not bracketed by the data ({unbracketed})"
    elif row["quantity"] in undetermined:
        reason = f"no interval: not determined by the data ({undetermined[row['quantity']]})"
    else:
        return row
    return {**row, "low": np.nan, "high": np.nan, "method": "none", "flag": reason}


def is_withheld(flag: str) -> bool:
    """True for the flag :func:`withheld_interval` gives."""
    return str(flag).startswith("no interval: ")


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
    centre, errors = delta_indices(fit, delta_max, known)
    x_max = relative_size_limit(fit, {**fit.context_at(), **fit.fit.values}, delta_max)
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
                "method": interval_method("delta", domain),
                "flag": flag,
            }
        )
    return rows
