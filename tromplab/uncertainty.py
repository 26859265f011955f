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

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import stats

from .curves import CurveFit, fit_formula
from .indices import curve_indices
from .points import TrompPoints

INDEX_NAMES = ("slope", "eta", "epsilon", "d25", "d75", "ep", "imperfection")


def _indices_at(fit: CurveFit, values: dict[str, float], delta_max: float) -> np.ndarray:
    d_cut, shape, extras = fit.curve_arguments(values)
    found = curve_indices(fit.formula, d_cut, shape, delta_max=delta_max, **fit.context, **extras)
    return np.array([getattr(found, name) for name in INDEX_NAMES])


def delta_standard_errors(fit: CurveFit, evaluate: Callable[[dict[str, float]], np.ndarray]) -> np.ndarray:
    """Delta-method standard errors of ``evaluate(parameter values)`` (an array).

    The gradient with respect to each fitted parameter is a central difference with a
    relative step of 1e-5; the variance is ``g C g^T`` with the fit's covariance ``C``.
    nan where the covariance is unknown or the gradient is not finite.
    """
    values = dict(fit.fit.values)
    centre = np.asarray(evaluate(values), dtype=float)
    covariance = fit.fit.covariance
    if covariance is None:
        return np.full(centre.shape, np.nan)
    gradient = []
    for name in fit.fit.names:
        step = 1e-5 * max(abs(values[name]), 1e-3)
        upper = np.asarray(evaluate({**values, name: values[name] + step}), dtype=float)
        lower = np.asarray(evaluate({**values, name: values[name] - step}), dtype=float)
        gradient.append((upper - lower) / (2 * step))
    gradient = np.array(gradient)
    variance = np.einsum("i...,ij,j...->...", gradient, covariance, gradient)
    return np.where(np.all(np.isfinite(gradient), axis=0), np.sqrt(np.maximum(variance, 0.0)), np.nan)


def interval_table(fit: CurveFit, *, level: float = 0.95, delta_max: float | None = None, profile: bool = True) -> pd.DataFrame:
    """Estimates, standard errors and intervals of the parameters and indices of one fit.

    Returns a DataFrame with columns ``quantity, value, stderr, low, high, method``:
    parameters by the profile likelihood (or Wald when ``profile`` is False or the
    profile fails), indices by the delta method.
    """
    if not fit.success:
        raise ValueError(f"{fit.formula.id} on {fit.experiment}: the fit failed ({fit.fit.message})")
    delta_max = fit.points.largest_size if delta_max is None else delta_max
    rows = []
    wald = fit.fit.confidence_intervals(level)
    profiled = fit.fit.profile_intervals(level) if profile else {}
    for name in fit.fit.names:
        low, high = profiled.get(name, (np.nan, np.nan))
        method = "profile"
        if not (np.isfinite(low) and np.isfinite(high)):
            low, high = wald[name]
            method = "wald"
        rows.append({"quantity": name, "value": fit.fit.values[name], "stderr": fit.fit.stderr[name], "low": low, "high": high,
                     "method": method})  # fmt: skip
    rows += _delta_rows(fit, level, delta_max)
    return pd.DataFrame(rows)


def _delta_rows(fit: CurveFit, level: float, delta_max: float) -> list[dict]:
    centre = _indices_at(fit, fit.fit.values, delta_max)
    errors = delta_standard_errors(fit, lambda values: _indices_at(fit, values, delta_max))
    dof = fit.points.n - len(fit.fit.names)
    half = stats.t.ppf(0.5 + level / 2.0, dof) if dof > 0 else np.nan
    return [{"quantity": name, "value": value, "stderr": se, "low": value - half * se, "high": value + half * se,
             "method": "delta"} for name, value, se in zip(INDEX_NAMES, centre, errors)]  # fmt: skip


@dataclass(frozen=True)
class Bootstrap:
    """Bootstrap replicates of one fit: one row per successful resample."""

    samples: pd.DataFrame
    n_requested: int
    method: str
    seed: int

    @property
    def n_failed(self) -> int:
        return self.n_requested - len(self.samples)

    def intervals(self, level: float = 0.95) -> pd.DataFrame:
        """Percentile intervals: ``quantity, low, high, stderr`` (standard deviation of the replicates)."""
        tail = (1.0 - level) / 2.0
        rows = []
        for column in self.samples.columns:
            values = self.samples[column].dropna().to_numpy()
            low, high = (np.quantile(values, [tail, 1 - tail]) if values.size else (np.nan, np.nan))
            rows.append({"quantity": column, "low": low, "high": high, "stderr": values.std(ddof=1) if values.size > 1 else np.nan})
        return pd.DataFrame(rows)


def bootstrap(fit: CurveFit, *, n: int = 200, seed: int = 0, method: str = "residuals", delta_max: float | None = None,
              progress: Callable[[int, int], None] | None = None) -> Bootstrap:  # fmt: skip
    """Refit ``n`` resampled data sets from the optimum of ``fit``.

    ``method="residuals"``: fitted values plus residuals drawn with replacement (the
    residuals scaled by ``sqrt(n / (n - p))`` for the degrees of freedom the fit used);
    ``"cases"``: points drawn with replacement (resamples with fewer than ``p + 1``
    distinct sizes are drawn again).  Each refit starts at the original optimum, without
    the global grid.
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
    residuals = (points.partition_fine - fitted) * np.sqrt(points.n / max(points.n - p, 1))
    delta_max = points.largest_size if delta_max is None else delta_max
    rows = []
    for i in range(n):
        if progress is not None:
            progress(i + 1, n)
        if method == "residuals":
            sample = TrompPoints(points.experiment, points.size, fitted + rng.choice(residuals, points.n), points.weight)
        else:
            while True:
                pick = rng.integers(0, points.n, points.n)
                if np.unique(points.size[pick]).size > p:
                    break
            weight = None if points.weight is None else points.weight[pick]
            sample = TrompPoints(points.experiment, points.size[pick], points.partition_fine[pick], weight)
        refit = fit_formula(sample, fit.formula, alpha=fit.screen.alpha, delta_max=delta_max, global_search=False,
                            starts=[dict(fit.fit.values)])  # fmt: skip
        if not refit.success:
            continue
        rows.append({**refit.fit.values, **{k: getattr(refit.indices, k) for k in INDEX_NAMES}})
    return Bootstrap(pd.DataFrame(rows), n, method, seed)


# --- information criteria and model averaging --------------------------------------------
def akaike_weights(aicc: Sequence[float]) -> np.ndarray:
    """Akaike weights ``exp(-Delta/2) / sum exp(-Delta/2)``; missing criteria get weight 0.

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


def model_average(fits: Sequence[CurveFit], *, quantities=("d_cut", "ep", "eta"), level: float = 0.95,
                  delta_max: float | None = None) -> pd.DataFrame:  # fmt: skip
    """Akaike-weighted averages of ``quantities`` over the fits of one experiment.

    The unconditional standard error (Burnham & Anderson 2002, eq. 4.9) is
    ``sum_i w_i sqrt(se_i^2 + (theta_i - theta_bar)^2)`` with ``se_i`` from the fit
    (parameters) or the delta method (indices).  Returns ``quantity, value, stderr, low,
    high`` plus one weight column per formula (``weight_<id>``).
    """
    good = [fit for fit in fits if fit.success]
    if not good:
        raise ValueError("no successful fit to average")
    if len({fit.experiment for fit in good}) > 1:
        raise ValueError("model averaging combines the formulas fitted to one experiment")
    weights = akaike_weights([fit.fit.information_criteria()["aicc"] for fit in good])
    tables = [interval_table(fit, level=level, delta_max=delta_max, profile=False).set_index("quantity") for fit in good]
    rows = []
    z = stats.norm.ppf(0.5 + level / 2.0)
    for quantity in quantities:
        values = np.array([table.loc[quantity, "value"] for table in tables])
        errors = np.array([table.loc[quantity, "stderr"] for table in tables])
        usable = np.isfinite(values) & (weights > 0)
        w = weights[usable] / weights[usable].sum()
        mean = float(np.sum(w * values[usable]))
        se = float(np.sum(w * np.sqrt(np.nan_to_num(errors[usable]) ** 2 + (values[usable] - mean) ** 2)))
        rows.append({"quantity": quantity, "value": mean, "stderr": se, "low": mean - z * se, "high": mean + z * se})
    table = pd.DataFrame(rows)
    for fit, weight in zip(good, weights):
        table[f"weight_{fit.formula.id}"] = weight
    return table


def interval_columns(fits: Sequence[CurveFit], *, level: float | None = None, n_bootstrap: int = 0, method: str = "residuals",
                     seed: int = 0, progress: Callable[[int, int, str], None] | None = None) -> pd.DataFrame:  # fmt: skip
    """Wide interval columns for ``fits.csv``: ``<quantity>_low``/``_high`` (profile for the
    parameters, delta method for the indices) when ``level`` is given, and
    ``<quantity>_boot_low``/``_boot_high`` from ``n_bootstrap`` resamples.  Keyed by
    ``experiment`` and ``formula``; failed fits get nan."""
    from .validation import check_bootstrap, check_optional, check_probability, check_seed

    check_optional(check_probability, level, "level")
    n_bootstrap, seed = check_bootstrap(n_bootstrap, "n_bootstrap"), check_seed(seed, "seed")
    bootstrap_level = 0.95 if level is None else level
    rows = []
    for i, fit in enumerate(fits):
        row = {"experiment": fit.experiment, "formula": fit.formula.id}
        if progress is not None:
            progress(i + 1, len(fits), f"{fit.experiment} / {fit.formula.id}")
        if fit.success:
            try:
                if level is not None:
                    table = interval_table(fit, level=level).set_index("quantity")
                    for quantity in table.index:
                        row[f"{_column(fit, quantity)}_low"] = table.loc[quantity, "low"]
                        row[f"{_column(fit, quantity)}_high"] = table.loc[quantity, "high"]
                if n_bootstrap:
                    boot = bootstrap(fit, n=n_bootstrap, seed=seed, method=method)
                    for quantity, low, high in boot.intervals(bootstrap_level)[["quantity", "low", "high"]].itertuples(index=False):
                        row[f"{_column(fit, quantity)}_boot_low"] = low
                        row[f"{_column(fit, quantity)}_boot_high"] = high
                    row["bootstrap_failed"] = boot.n_failed
            except (ValueError, ArithmeticError, RuntimeError) as error:  # a batch reports and goes on
                row["interval_message"] = f"intervals not computed: {error}"
        rows.append(row)
    return pd.DataFrame(rows)


def _column(fit: CurveFit, quantity: str) -> str:
    """Column stem of a quantity: the shape parameter is reported as ``shape``."""
    return "shape" if quantity == fit.formula.shape_name else quantity
