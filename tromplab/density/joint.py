r"""Joint least-squares fit of the three float-sink analyses: the curve, the feed and the yield together.

A float-sink test reports three analyses of the same fractions: the feed ``a_i``, the
floats ``f_i`` and the sinks ``s_i`` (mass shares, each summing to 1).  With the feed
composition :math:`\varphi_i` (:math:`\sum \varphi_i = 1`) and the partition to sinks
:math:`P_i = P(\rho_i; \theta)` of the curve, the sinks yield is
:math:`Y = \sum_j \varphi_j P_j` and the model of the three analyses is

.. math::
    a_i = \varphi_i, \qquad s_i = \frac{\varphi_i P_i}{Y}, \qquad
    f_i = \frac{\varphi_i (1 - P_i)}{1 - Y}.

All ``3n`` reported shares are fitted together by weighted least squares over
:math:`(\theta, \varphi)` (``varphi`` through a softmax, so it stays a composition), so the
yield and the closure of each analysis move the partitions the way they move in the data,
instead of being fixed at one estimate as the partition's least squares does.  The variance
of a reported share of expected value :math:`\mu` is :math:`\sigma^2 (\alpha \mu^2 + \beta)`
(a relative weighing error and an absolute one, in share units): ``alpha`` and ``beta`` are
estimated from the squared residuals of a first fit weighted by :math:`1/(a + 10^{-3})`
(``a`` the reported share),
each divided by ``1 - h`` (``h`` its leverage: a fraction's feed share is fitted almost by its
own parameter, so its residual is small), by non-negative least squares (``beta`` at least
the reporting resolution 0.01 %, squared),
and a second fit is weighted by their inverse (once: iterating lets the weights follow the
residuals and narrowed the intervals in the validation).  The covariance of the estimates
is the sandwich :math:`\hat\sigma^2 B\,J^\top C J\,B`, :math:`B = (J^\top J)^{-1}`, with
``J`` the Jacobian of the weighted residuals and ``C`` the correlation of the weighted
shares of an analysis brought back to 1 (per analysis :math:`(I - m 1^\top) V (I - 1 m^\top)`,
``m`` the fitted shares, ``V`` their variances, scaled by the weights);
:math:`\hat\sigma^2` is the weighted sum of squares over :math:`2(n - 1) - p - 2` degrees of
freedom (three closed analyses give ``3(n - 1)`` independent shares; ``n - 1 + p``
parameters and the two coefficients of the variance function are estimated).  The
intervals of rho50, Ep and the imperfection are Wald intervals with the Student t quantile
on those degrees of freedom, Ep and the imperfection on the log scale (they stay positive).
A limit fitted on its bound is held there.

References
----------
.. [Seber2003] Seber G.A.F., Wild C.J. (2003). *Nonlinear Regression*. Wiley, Hoboken
   (ch. 2: weighted least squares, the covariance of the estimates and its intervals;
   ch. 2.8: variance functions estimated from the residuals).
.. [Carroll1988] Carroll R.J., Ruppert D. (1988). *Transformation and Weighting in
   Regression*. Chapman & Hall, New York (ch. 2-3: generalized least squares with a variance
   function estimated from the residuals, and how many reweightings to make).
.. [Wills2016] Wills B.A., Finch J.A. (2016). *Wills' Mineral Processing Technology*, 8th ed.
   Butterworth-Heinemann, Oxford (ch. 11: partition from the float-sink analyses of the products).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.special

from ..statistics.distributions import t_ppf
from .registry import DensityCurve

#: ``DensitySample.yield_source`` of a yield estimated from the three analyses (none stated).
ESTIMATED_YIELD_SOURCE = "least-squares estimate"
#: The method's name in the fits' ``method`` column.
JOINT_METHOD = "joint_least_squares"
FIRST_STAGE_FLOOR = 1e-3  # share units: the first fit's weight 1/(share + floor) keeps empty fractions finite
# one reweighted fit: iterating lets the weights follow the residuals and narrowed the intervals (measured)
VARIANCE_ITERATIONS = 1
LEVERAGE_FLOOR = 0.05  # 1 - h below this (a share its parameter fits almost exactly) counts as 0.05
VARIANCE_FLOOR = 1e-8  # share units: the absolute variance is at least the reporting resolution, 0.01 percentage points, squared


@dataclass(frozen=True)
class JointFit:
    """The joint fit of one float-sink test: the curve's parameters, their covariance, the residual scale."""

    params: dict
    covariance: np.ndarray  # of the curve's free parameters (held limits excluded), natural scale
    free: tuple[str, ...]
    feed: np.ndarray
    sinks_yield: float
    ssr: float
    sigma2: float
    df_resid: int
    neg2_loglik: float
    n_params: int
    largest_residual: float  # share units, unweighted: 0 when the analyses are exact


def has_three_analyses(sample) -> bool:
    """True when ``sample`` is a float-sink test with the feed, floats and sinks analyses and no stated yield.

    A stated floats yield is the one the partitions use (the reader says so); the joint fit,
    which estimates the yield, is then not made.
    """
    return (
        sample.layout == "float-sink"
        and "feed_measured" in sample.points.columns
        and sample.yield_estimate is not None
        and sample.yield_source == ESTIMATED_YIELD_SOURCE
    )


def _observations(sample) -> tuple[np.ndarray, np.ndarray]:
    used = sample.used
    shares = np.concatenate([used[c].to_numpy(float) for c in ("feed_measured", "sinks", "floats")])
    return used["density"].to_numpy(float), shares


def _predict(curve: DensityCurve, density, curve_params: dict, feed_logits: np.ndarray) -> np.ndarray:
    feed = scipy.special.softmax(np.append(feed_logits, 0.0))
    partition = curve.partition(density, **curve_params)
    sinks_yield = float(np.sum(feed * partition))
    return np.concatenate([feed, feed * partition / sinks_yield, feed * (1 - partition) / (1 - sinks_yield)])


def fit_joint(sample, curve: DensityCurve, start: dict) -> JointFit | None:
    """Fit ``curve`` jointly to the three analyses of ``sample``, starting at the curve parameters ``start``.

    Returns None when there are too few fractions (``2(n - 1) - p - 2 <= 0``), the optimiser
    finds no finite fit or the covariance is singular.
    """
    density, observed = _observations(sample)
    n = density.size
    names = list(curve.parameter_names)
    bounds = [(p.lower, p.upper) for p in curve.parameters]
    feed_start = np.clip(observed[:n], 1e-6, None)
    logits = np.log(feed_start[:-1] / feed_start[-1])
    x0 = np.concatenate([[start[name] for name in names], logits])
    lower = np.concatenate([[b[0] for b in bounds], np.full(n - 1, -50.0)])
    upper = np.concatenate([[b[1] for b in bounds], np.full(n - 1, 50.0)])
    k = len(names)

    def model(x):
        with np.errstate(all="ignore"):
            return _predict(curve, density, dict(zip(names, x[:k])), x[k:])

    def fit_with(weight, x_start):
        def residuals(x):
            value = np.sqrt(weight) * (observed - model(x))
            return np.where(np.isfinite(value), value, 1e6)

        import scipy.optimize  # imported where the float-sink fits need it: the tracer fits do not

        return scipy.optimize.least_squares(
            residuals, np.clip(x_start, lower, upper), bounds=(lower, upper), method="trf", x_scale="jac"
        )

    first = fit_with(1.0 / (observed + FIRST_STAGE_FLOOR), x0)
    mu = model(first.x)
    df = 2 * (n - 1) - k - 2  # the two coefficients of the variance function are estimated too
    if df <= 0 or not np.all(np.isfinite(mu)):
        return None
    variance = observed + FIRST_STAGE_FLOOR
    result = first
    for _ in range(VARIANCE_ITERATIONS):
        variance = _variance_function(observed - mu, mu, variance, _leverage_inflation(result.jac))
        result = fit_with(1.0 / variance, result.x)
        mu = model(result.x)
    return _summarise(curve, names, result, mu, variance, df, density, float(np.max(np.abs(observed - mu))))


def _summarise(curve, names, result, mu, variance, df, density, largest_residual) -> JointFit | None:
    n = density.size
    k = len(names)
    params = dict(zip(names, (float(v) for v in result.x[:k])))
    held = [i for i, name in enumerate(names) if curve.limit_on_bound(name, params[name])]
    keep = [i for i in range(result.x.size) if i not in held]
    jacobian = result.jac[:, keep]
    ssr = float(2 * result.cost)
    sigma2 = ssr / df
    try:
        bread = np.linalg.inv(jacobian.T @ jacobian)
    except np.linalg.LinAlgError:
        return None
    closure = _closed_covariance(mu, variance, n)
    covariance = sigma2 * bread @ (jacobian.T @ closure @ jacobian) @ bread
    free = tuple(names[i] for i in range(k) if i not in held)
    curve_block = covariance[: len(free), : len(free)]
    if not np.all(np.isfinite(curve_block)) or np.any(np.diag(curve_block) <= 0):
        return None
    feed = scipy.special.softmax(np.append(result.x[k:], 0.0))
    sinks_yield = float(np.sum(feed * curve.partition(density, **params)))
    m = 3 * (n - 1)
    neg2_loglik = float(np.sum(np.log(2 * math.pi * (ssr / m) * variance)) * (m / (3 * n)) + m)
    return JointFit(params, curve_block, free, feed, sinks_yield, ssr, sigma2, df, neg2_loglik, len(keep) + 2, largest_residual)


def _leverage_inflation(jacobian: np.ndarray) -> np.ndarray:
    """``1/(1 - h_i)``, ``h`` the leverages of the weighted fit: a share fitted by its own parameter (a fraction's
    feed share) leaves a small residual, which would understate its variance (Carroll & Ruppert 1988, sect. 3.3)."""
    leverage = np.einsum("ij,jk,ik->i", jacobian, np.linalg.pinv(jacobian.T @ jacobian), jacobian)
    return 1.0 / np.clip(1.0 - leverage, LEVERAGE_FLOOR, None)


def _variance_function(residual, mu, previous, inflation) -> np.ndarray:
    """``alpha mu^2 + beta`` fitted to the squared residuals (weighted by the previous variance squared, as a gamma GLM would)."""
    weight = 1.0 / previous
    design = np.column_stack([mu**2, np.ones_like(mu)]) * weight[:, None]
    import scipy.optimize

    coefficients, _ = scipy.optimize.nnls(design, residual**2 * inflation * weight)
    return coefficients[0] * mu**2 + max(coefficients[1], VARIANCE_FLOOR)


def _closed_covariance(mu, variance, n) -> np.ndarray:
    """Correlation of the weighted residuals of three analyses each brought back to 1 (block per analysis)."""
    import scipy.linalg  # a joint fit of float-sink analyses only: density fit of tracers does not import it

    blocks = []
    for a in range(3):
        part = slice(a * n, (a + 1) * n)
        share = mu[part] / mu[part].sum()
        projector = np.eye(n) - np.outer(share, np.ones(n))
        raw = projector @ np.diag(variance[part]) @ projector.T
        scale = 1 / np.sqrt(variance[part])
        blocks.append(raw * np.outer(scale, scale))
    return scipy.linalg.block_diag(*blocks)


def joint_intervals(curve: DensityCurve, joint: JointFit, ci: float) -> dict:
    """Wald intervals (Student t, ``joint.df_resid`` degrees of freedom) of rho50, Ep and I from the joint fit."""
    quantile = t_ppf(0.5 + ci / 2, joint.df_resid)
    values = np.array([joint.params[name] for name in joint.free])
    steps = 1e-6 * np.maximum(np.abs(values), 1e-3)

    def indices_at(vector):
        index = curve.indices(**{**joint.params, **dict(zip(joint.free, vector))})
        return np.array([index.rho50, math.log(index.ep), math.log(index.imperfection)])

    centre = indices_at(values)
    if not np.all(np.isfinite(centre)):
        return {}
    gradient = np.stack(
        [(indices_at(values + steps[i] * np.eye(values.size)[i]) - indices_at(values - steps[i] * np.eye(values.size)[i]))
         / (2 * steps[i]) for i in range(values.size)],
        axis=1,
    )  # fmt: skip
    half = quantile * np.sqrt(np.einsum("qi,ij,qj->q", gradient, joint.covariance, gradient))
    return {
        "rho50": (float(centre[0] - half[0]), float(centre[0] + half[0])),
        "ep": (float(math.exp(centre[1] - half[1])), float(math.exp(centre[1] + half[1]))),
        "imperfection": (float(math.exp(centre[2] - half[2])), float(math.exp(centre[2] + half[2]))),
    }
