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
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..curves.curve_fit import CurveFit, attach_indices
from ..curves.engine import refit_partitions, refit_resamples
from ..curves.formulas import is_batchable
from ..curves.indices import batch_index_columns, batchable_indices
from ..curves.intervals import (
    INDEX_NAMES,
    batched_delta_indices,
    batched_profile_intervals,
    delta_indices,
    interval_method,
    interval_rows,
    interval_table,  # noqa: F401 - part of this module's public face (tromplab.interval_table)
    is_withheld,
    normal_quantile,
    quantity_domain,
    relative_size_limit,
    withheld_interval,
)
from ..curves.likelihood import on_bound
from ..curves.measured import parameter_specs
from ..errors import InputError, expect_kind
from ..loading.points import TrompPoints
from ..options import BOOTSTRAP_METHODS
from ..results_contract import ResultContract
from ..validation import check_bootstrap, check_optional, check_probability, check_seed

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class Bootstrap(ResultContract):
    """Bootstrap replicates of one fit: one row per successful resample.

    ``bounds`` maps each quantity to the edges it cannot pass (its range, and for the
    parameters the bounds of the fit); percentile limits on an edge are flagged.
    :meth:`summary` is :meth:`intervals` at 0.95, :meth:`to_frame` the replicates.

    Attributes
    ----------
    samples : pandas.DataFrame
        One row per successful resample, one column per parameter and index.
    n_requested : int
        Resamples asked for.
    method : str
        ``"residuals"`` or ``"cases"``.
    seed : int
        Seed of the resampling.
    bounds : dict
        Quantity -> the edges it cannot pass.
    n_failed : int
        Resamples whose refit failed.
    """

    samples: pd.DataFrame
    n_requested: int
    method: str
    seed: int
    bounds: dict = field(default_factory=dict)

    @property
    def n_failed(self) -> int:
        return self.n_requested - len(self.samples)

    def summary(self, level: float = 0.95) -> pd.DataFrame:
        """One row per quantity: its percentile interval at ``level`` (:meth:`intervals`)."""
        return self.intervals(level)

    def to_frame(self) -> pd.DataFrame:
        """The replicates (:attr:`samples`): one row per successful resample."""
        return self.samples.copy()

    def _result_context(self) -> str:
        return (f"Bootstrap ({self.method}, seed {self.seed}): {len(self.samples)} of {self.n_requested} resamples "
                f"refitted, {self.n_failed} failed; 95 % percentile intervals")  # fmt: skip

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
    expect_kind(fit, CurveFit, "fit", "a CurveFit (tromplab.fit_formula)")
    if not fit.success:
        raise ValueError(f"{fit.formula.id} on {fit.experiment}: cannot bootstrap a failed fit")
    if method not in BOOTSTRAP_METHODS:
        raise ValueError(f"method must be one of {', '.join(BOOTSTRAP_METHODS)}, got {method!r}")
    if n < 2:
        raise ValueError("the bootstrap needs at least 2 resamples")
    delta_max = fit.options.delta_max if delta_max is None else delta_max
    rng = np.random.default_rng(seed)
    if method == "residuals" and is_batchable(fit.formula) and batchable_indices(fit.formula):
        # resamples as arrays end to end: no point records or result objects per resample
        samples = _replicates_on_arrays(fit, _resampled_partitions(fit, n, rng, progress), delta_max)
    else:
        refits = refit_resamples(fit, _resamples(fit, n, rng, method, progress), delta_max=delta_max)  # one batched call
        attach_indices(refits)  # and their indices in one array computation
        rows = [{**refit.fit.values, **{k: getattr(refit.indices, k) for k in INDEX_NAMES}} for refit in refits if refit.success]
        samples = pd.DataFrame(rows)
    logger.debug(
        "bootstrap %s %s: %d %s resamples, %d refits failed", fit.experiment, fit.formula.id, n, method, n - len(samples)
    )
    return Bootstrap(samples, n, method, seed, _bootstrap_bounds(fit, delta_max))


def _replicates_on_arrays(fit: CurveFit, partitions: np.ndarray, delta_max: float) -> pd.DataFrame:
    """The rows of :attr:`Bootstrap.samples` from refits of the resampled ``partitions`` on arrays
    (:func:`~tromplab.curves.engine.refit_partitions`), with their indices computed on arrays."""
    optimum, efficiency = refit_partitions(fit, partitions)
    ok = optimum.success
    values = optimum.values[ok]
    shape_at = optimum.names.index(fit.formula.shape_name)
    indices, _ = batch_index_columns(
        fit.formula,
        values[:, 0],
        values[:, shape_at],
        delta_max=np.full(values.shape[0], delta_max),
        measured_efficiency=None if efficiency is None else efficiency[ok],
        **{extra.name: values[:, optimum.names.index(extra.name)] for extra in fit.formula.extras},  # the bypass
    )
    columns = {name: values[:, k] for k, name in enumerate(optimum.names)}
    columns.update((name, indices[name]) for name in INDEX_NAMES)
    return pd.DataFrame(columns)


def _resampled_partitions(fit: CurveFit, n: int, rng: np.random.Generator, progress) -> np.ndarray:
    """The partitions of ``n`` residual resamples (rows): the fitted curve plus weighted
    residuals drawn with replacement, centred and scaled as :func:`bootstrap` says."""
    points = fit.points
    fitted = fit.predict(points.size)
    root_weights = np.sqrt(fit.options.weights)
    scaled = root_weights * (points.partition_fine - fitted)
    residuals = (scaled - scaled.mean()) * np.sqrt(points.n / max(points.n - fit.formula.n_params, 1))
    for i in range(n if progress is not None else 0):
        progress(i + 1, n)
    # all draws at once: the generator gives the same numbers as one call per resample
    return fitted + rng.choice(residuals, (n, points.n)) / root_weights


def _resamples(fit: CurveFit, n: int, rng: np.random.Generator, method: str, progress) -> list[TrompPoints]:
    """The ``n`` resampled data sets of :func:`bootstrap`, drawn from ``rng`` by ``method``."""
    points = fit.points
    if method == "residuals":
        partitions = _resampled_partitions(fit, n, rng, progress)
        return [TrompPoints(points.experiment, points.size, row, points.weight, resampled=True) for row in partitions]
    samples = []
    for i in range(n):
        if progress is not None:
            progress(i + 1, n)
        while True:
            pick = rng.integers(0, points.n, points.n)
            if np.unique(points.size[pick]).size > fit.formula.n_params:
                break
        weight = None if points.weight is None else points.weight[pick]
        samples.append(TrompPoints(points.experiment, points.size[pick], points.partition_fine[pick], weight, resampled=True))
    return samples


def _bootstrap_bounds(fit: CurveFit, delta_max: float) -> dict[str, tuple[float, ...]]:
    """:attr:`Bootstrap.bounds`: the edges each parameter and index cannot pass (its range and, for a
    parameter, the bounds of the fit)."""
    x_max = relative_size_limit(fit, {**fit.context_at(), **fit.fit.values}, delta_max)
    domains = {name: quantity_domain(name, fit.formula, x_max=x_max) for name in (*fit.fit.names, *INDEX_NAMES)}
    bounds = {name: (domain.lower, domain.upper) for name, domain in domains.items()}
    for spec in parameter_specs(fit.formula, fit.points):
        bounds[spec.name] = (*bounds[spec.name], spec.lower, spec.upper)
    return bounds


# --- information criteria and model averaging --------------------------------------------
def _criteria(values) -> np.ndarray:
    """A flat array of criteria (nan allowed); other shapes and non-numbers are refused in words."""
    if isinstance(values, (str, bytes, dict)):
        raise TypeError(f"aicc must be a sequence of numbers, got {type(values).__name__}")
    try:
        array = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"must be a flat sequence of numbers; {values!r:.60} is not", source="aicc") from None
    if array.ndim != 1:
        raise InputError(f"must be a flat sequence of numbers, got {array.ndim} dimension(s)", source="aicc")
    return array


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
    aicc = _criteria(aicc)
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
    as_frame: bool = True,
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
        (default: evaluated here, batched over these fits); made with ``epsilon=False``, it
        serves every quantity but epsilon.
    as_frame : bool
        False: the rows as a list of dicts (a batch builds one table from all experiments'
        rows instead of one per experiment).
    """
    if isinstance(fits, (str, bytes, CurveFit)) or not isinstance(fits, Iterable):
        raise TypeError(f"fits must be a sequence of CurveFit (the fits of one experiment), got {type(fits).__name__}")
    fits = list(fits)
    for position, fit in enumerate(fits):
        expect_kind(fit, CurveFit, f"fits[{position}]", "a CurveFit (tromplab.fit_formula)")
    good = [fit for fit in fits if fit.success]
    if not good:
        raise InputError("no successful fit to average", source="fits")
    if len({fit.experiment for fit in good}) > 1:
        raise ValueError("model averaging combines the formulas fitted to one experiment")
    (rows,) = averaged_rows([good], quantities=quantities, level=level, delta_max=delta_max, min_share=min_share, known=known)
    if as_frame:
        return pd.DataFrame(rows)
    return rows


def averaged_rows(
    groups: Sequence[Sequence[CurveFit]],
    *,
    quantities=AVERAGED_QUANTITIES,
    level: float = 0.95,
    delta_max: float | None = None,
    min_share: float = MIN_WEIGHT_SHARE,
    known: dict | None = None,
) -> list[list[dict]]:
    """The rows of :func:`model_average` of many experiments, each quantity on arrays over all of them.

    ``groups`` holds the successful fits of each experiment; the result holds each
    experiment's rows (a dict per quantity, with the weight columns; only the weight columns
    when ``quantities`` is empty).  The arguments are those of :func:`model_average`.
    """
    if known is None:
        known = batched_delta_indices([fit for fits in groups for fit in fits], delta_max, epsilon="epsilon" in quantities)
    count, width = len(groups), max((len(fits) for fits in groups), default=0)
    weights = np.zeros((count, width))
    estimates = [[_estimates_and_errors(fit, delta_max, known) for fit in fits] for fits in groups]
    for row, fits in enumerate(groups):
        weights[row, : len(fits)] = akaike_weights([fit.fit.information_criteria()["aicc"] for fit in fits])
    # epsilon: each formula's range [0, x_max - 1] lies inside that of the largest x_max
    widest_x_max = np.array(
        [max((fit.options.delta_max if delta_max is None else delta_max) / fit.d_cut for fit in fits) for fits in groups]
    )
    z = normal_quantile(0.5 + level / 2.0)
    ids = [[fit.formula.id for fit in fits] for fits in groups]
    by_quantity = []
    for quantity in quantities:
        values, errors = np.full((count, width), np.nan), np.full((count, width), np.nan)
        for row, found in enumerate(estimates):
            for column, each in enumerate(found):
                values[row, column], errors[row, column] = each.get(quantity, (np.nan, np.nan))
        averaged = _averaged_quantity(quantity, values, errors, weights, ids=ids, z=z, x_max=widest_x_max, min_share=min_share)
        by_quantity.append([_without_undetermined_interval(fits[0], each) for fits, each in zip(groups, averaged)])
    result = []
    for row, fits in enumerate(groups):
        weight_columns = {f"weight_{fit.formula.id}": weight for fit, weight in zip(fits, weights[row].tolist())}
        # the weight columns go into each row: adding them to a frame one by one cost about
        # 1 ms each (9 ms per experiment, the largest part of the averages of a batch)
        result.append([{**rows[row], **weight_columns} for rows in by_quantity] if quantities else [weight_columns])
    return result


def _averaged_quantity(quantity: str, values, errors, weights, *, ids, z: float, x_max, min_share: float) -> list[dict]:
    """The rows of one quantity of :func:`averaged_rows`: ``values``, ``errors`` and Akaike
    ``weights`` as ``(experiments, formulas)`` arrays (nan where a formula does not define the
    quantity or was not fitted), ``ids`` the formulas of each experiment."""
    usable = np.isfinite(values) & (weights > 0)
    # a sum of normalised weights can round above 1 (1.0000000000000002 with another CPU's
    # summation order): a share is held in [0, 1] by construction, not by the last bit
    share = np.clip(np.where(usable, weights, 0.0).sum(axis=1), 0.0, 1.0)
    n_formulas = usable.sum(axis=1)
    averaged = (share >= min_share) & (n_formulas > 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        w = np.where(usable, weights, 0.0) / np.where(averaged, share, 1.0)[:, None]
        theta = np.where(usable, values, 0.0)
        se = np.where(usable, errors, 0.0)  # a missing se stays missing: the average's is then unknown
        mean = (w * theta).sum(axis=1)
        stderr = (w * np.sqrt(se**2 + (theta - mean[:, None]) ** 2)).sum(axis=1)
    intervals = _averaged_intervals(quantity, usable & averaged[:, None], w, theta, se, mean, z=z, x_max=x_max)
    rows = []
    for row in range(values.shape[0]):
        found = {
            "quantity": quantity,
            "value": np.nan,
            "stderr": np.nan,
            "low": np.nan,
            "high": np.nan,
            "method": "",
            "akaike_share": float(share[row]),
            "n_formulas": int(n_formulas[row]),
            "note": "",
        }
        if not averaged[row]:
            found["note"] = (
                f"not averaged: defined only for formulas holding {share[row]:.2%} of the Akaike weight (less than {min_share:.0%})"
            )
            rows.append(found)
            continue
        found.update(value=float(mean[row]), stderr=float(stderr[row]))
        missing = np.flatnonzero(usable[row] & ~np.isfinite(errors[row]))
        if missing.size:
            found["note"] = (
                f"no standard error and no interval: the fit of {', '.join(ids[row][i] for i in missing)} "
                f"({float(w[row, missing].sum()):.2%} of the weight) gives no standard error of {quantity}"
            )
        elif intervals[row] is None:
            found["note"] = "no interval: an estimate lies on the edge of the quantity's range"
        else:
            found.update(intervals[row])
            if not (np.isfinite(found["low"]) and np.isfinite(found["high"])):
                found["note"] = (
                    f"the interval reaches the end of the quantity's range: the standard error {stderr[row]:.3g} "
                    "does not bound it"
                )
        if share[row] < 1.0 - 1e-9:
            found["note"] = found["note"] or (
                f"averaged over the {int(n_formulas[row])} formulas where it is defined ({share[row]:.2%} of the weight)"
            )
        rows.append(found)
    return rows


def _averaged_intervals(quantity: str, used, w, theta, se, mean, *, z: float, x_max) -> list[dict | None]:
    """``low, high, method`` of each experiment's average, made on the scale of the quantity's
    domain around ``g(mean)`` and transformed back; None where an estimate (or the average)
    is not strictly inside the domain.  ``used``: the formulas in each average."""
    found: list[dict | None] = [None] * len(mean)
    domains = [quantity_domain(quantity, x_max=limit) for limit in x_max]
    for domain in {id(d): d for d in domains}.values():  # the experiments whose quantity shares a domain
        rows = np.flatnonzero([d is domain for d in domains])
        inside = _strictly_inside(domain, mean[rows]) & np.all(_strictly_inside(domain, theta[rows]) | ~used[rows], axis=1)
        rows = rows[inside]
        if not rows.size:
            continue
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            centre = np.where(used[rows], theta[rows], mean[rows, None])  # unused formulas: no spread, no error
            g_mean = domain.forward(mean[rows])
            spread = (se[rows] * domain.slope(centre)) ** 2 + (domain.forward(centre) - g_mean[:, None]) ** 2
            se_g = (w[rows] * np.sqrt(np.where(used[rows], spread, 0.0))).sum(axis=1)
            ends = np.sort(np.stack([domain.backward(g_mean - z * se_g), domain.backward(g_mean + z * se_g)], axis=1), axis=1)
        method = interval_method("akaike", domain)
        for row, (low, high) in zip(rows.tolist(), ends.tolist()):
            # the round trip through the domain's scale can move an end an ulp past the average
            # when the interval is narrower than that (noise-free points): it holds it by construction
            found[row] = {"low": min(low, float(mean[row])), "high": max(high, float(mean[row])), "method": method}
    return found


def _strictly_inside(domain, value) -> np.ndarray:
    """:meth:`Domain.inside` on arrays."""
    value = np.asarray(value, dtype=float)
    return np.isfinite(value) & (domain.lower < value) & (value < domain.upper)


def _without_undetermined_interval(fit, row: dict) -> dict:
    """The averaged row without its interval when the points do not determine the quantity
    (a cut they do not bracket: :func:`~tromplab.curves.intervals.withheld_interval`)."""
    kept = withheld_interval(fit, {"quantity": row["quantity"], "low": row["low"], "high": row["high"], "flag": ""})
    if not is_withheld(kept["flag"]) or not np.isfinite(row["value"]):
        return row
    return {**row, "low": np.nan, "high": np.nan, "method": "none", "note": kept["flag"]}


def _estimates_and_errors(fit: CurveFit, delta_max: float | None, known: dict | None) -> dict[str, tuple[float, float]]:
    """``{quantity: (value, standard error)}`` of the parameters and indices of one fit, as
    :func:`interval_table` reports them (without building its table); ``d50c`` is the fitted
    ``d_cut`` of every formula (the corrected cut)."""
    limit = fit.options.delta_max if delta_max is None else delta_max
    centre, errors = delta_indices(fit, limit, known)
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
    width: int | None = None,
) -> pd.DataFrame:
    """Wide interval columns for ``fits.csv``.

    With ``level``: ``<quantity>_low``/``_high`` and ``<quantity>_method`` (how the interval
    was made, see :func:`interval_table`); with ``n_bootstrap``: ``<quantity>_boot_low`` /
    ``_boot_high`` (percentile, ``bootstrap_method`` says residuals or cases) and
    ``bootstrap_failed``.  ``interval_flags`` lists one-sided intervals, missing ones and
    bootstrap limits on a bound.  Keyed by ``experiment`` and ``formula``; failed fits
    get nan.  Every fit's own ``delta_max`` and alpha are used.  ``width`` pads the points of
    the profile search (:class:`~tromplab.curves.batched.PaddedPoints`), as the fits were.
    """
    check_optional(check_probability, level, "level")
    n_bootstrap, seed = check_bootstrap(n_bootstrap, "n_bootstrap"), check_seed(seed, "seed")
    bootstrap_level = 0.95 if level is None else level
    logger.info(
        "intervals for %d fit(s): %s, %s",
        len(fits),
        "no delta/profile intervals" if level is None else f"delta/profile at level {level:g}",
        f"bootstrap of {n_bootstrap} {method} resamples, seed {seed}" if n_bootstrap else "no bootstrap",
    )
    # the profiles and the delta method's index evaluations of all fits in one batched call per formula
    profiles = batched_profile_intervals(fits, level, width=width) if level is not None else [None] * len(fits)
    known = batched_delta_indices([fit for fit in fits if fit.success]) if level is not None else None
    rows = []
    for i, fit in enumerate(fits):
        row = {"experiment": fit.experiment, "formula": fit.formula.id}
        if progress is not None:
            progress(i + 1, len(fits), f"{fit.experiment} / {fit.formula.id}")
        if fit.success:
            flags, withheld = [], {}
            try:
                if level is not None:
                    _add_delta_profile_columns(
                        row, flags, withheld, fit, interval_rows(fit, level=level, profiled=profiles[i], known=known)
                    )
                if n_bootstrap:
                    boot = bootstrap(fit, n=n_bootstrap, seed=seed, method=method)
                    _add_bootstrap_columns(row, flags, withheld, fit, boot.intervals(bootstrap_level))
                    row["bootstrap_method"] = f"percentile ({method})"
                    row["bootstrap_failed"] = boot.n_failed
            except (ValueError, ArithmeticError, RuntimeError) as error:  # a batch reports and goes on
                row["interval_message"] = f"intervals not computed: {error}"
            flags += [f"{', '.join(dict.fromkeys(stems))}: {reason}" for reason, stems in withheld.items()]
            row["interval_flags"] = "; ".join(flags)
        rows.append(row)
    return pd.DataFrame(rows)


def _add_delta_profile_columns(row: dict, flags: list, withheld: dict, fit: CurveFit, records) -> None:
    """``<quantity>_low/_high/_method`` of the delta/profile ``records`` into ``row``; their flags
    into ``flags``, the withheld ones grouped by reason into ``withheld``."""
    for record in records:
        stem = _column(fit, record["quantity"])
        row[f"{stem}_low"], row[f"{stem}_high"] = record["low"], record["high"]
        row[f"{stem}_method"] = record["method"]
        if is_withheld(record["flag"]):
            withheld.setdefault(record["flag"], []).append(stem)
        elif record["flag"] and np.isfinite(record["value"]):
            flags.append(f"{stem}: {record['flag']}")


def _add_bootstrap_columns(row: dict, flags: list, withheld: dict, fit: CurveFit, intervals: pd.DataFrame) -> None:
    """``<quantity>_boot_low/_boot_high`` of the bootstrap ``intervals`` into ``row`` (withheld
    where the fit's delta/profile interval would be), their flags as above."""
    for quantity, low, high, flag in intervals[["quantity", "low", "high", "flag"]].itertuples(index=False):
        stem = _column(fit, quantity)
        kept = withheld_interval(fit, {"quantity": quantity, "low": low, "high": high, "flag": flag})
        row[f"{stem}_boot_low"], row[f"{stem}_boot_high"] = kept["low"], kept["high"]
        if is_withheld(kept["flag"]):
            withheld.setdefault(kept["flag"], []).append(f"{stem} bootstrap")
        elif flag:
            flags.append(f"{stem} bootstrap: {flag}")


def _column(fit: CurveFit, quantity: str) -> str:
    """Column stem of a quantity: the shape parameter is reported as ``shape``."""
    return "shape" if quantity == fit.formula.shape_name else quantity
