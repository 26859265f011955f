r"""Fits of the density curves: binomial maximum likelihood for tracer counts, weighted least squares for shares.

Tracer counts
    ``k_i`` of the ``n_i`` tracers of density ``rho_i`` recovered in the sinks,
    :math:`k_i \sim \mathrm{Binomial}(n_i, P(\rho_i))`.  A plain curve is a binomial GLM
    in ``rho`` with the curve's link (probit: normal, logit: logistic, complementary
    log-log: Gompertz), fitted by iteratively reweighted least squares; ``rho50 = (q50 - a)/b``,
    ``Ep = k/b``.  A curve with limits is fitted by minimising the binomial deviance within the
    bounds from several starts (projected Fisher scoring).  The tests of a file are fitted
    together, on stacked arrays (:mod:`tromplab.density.batch`).  Goodness of fit: the deviance against :math:`\chi^2_{n - p}`.  Overdispersion:
    the Pearson :math:`X^2 / (n - p)`, flagged when the Pearson test rejects at 5 %
    (:math:`X^2 > \chi^2_{n-p, 0.95}`); the intervals use :math:`\phi = \max(1, X^2/(n - p))`
    as the quasi-binomial scale (profile deviances divided by it), with the
    :math:`F_{1, n-p}` threshold where it is estimated above 1, floored by the scale pooled over
    the file's tests (:mod:`tromplab.density.dispersion`).
Shares (float-sink partitions, a partition given directly, or tracers fitted the
spreadsheet way)
    Least squares :math:`\sum w_i (P_i - P(\rho_i))^2`, with ``w_i`` the fraction's feed
    share for float-sink data (its partition is measured on a sample mass proportional to
    it, so its variance is inversely proportional to it: the size lab tables'
    ``weight_by_feed_share``) and 1 otherwise.
Float-sink tests with all three analyses (feed, floats, sinks)
    By default fitted jointly: the curve, the feed composition and through them the yield,
    to every reported share, with Wald intervals from the joint covariance
    (:mod:`tromplab.density.joint`); ``method="least_squares"`` fits the partitions as above.

Intervals for ``rho50``, ``Ep`` and the imperfection are profile-likelihood intervals:
the curve is written in ``(rho50, Ep[, l, h])`` (``(rho50, I[, l, h])`` for the
imperfection, with ``Ep = I (rho50 - 1)``) and the other parameters re-optimised at each
value; the limits are where :math:`(D(q) - \hat D)/\phi` reaches
:math:`\chi^2_{1}(\text{ci})` (binomial; :math:`F_{1, n-p}(\text{ci})` when :math:`\phi > 1` was estimated) or :math:`(S(q) - \hat S)/(\hat S/(n-p))` reaches
:math:`F_{1, n-p}(\text{ci})` (least squares).  Curves are ranked by AIC; a difference below
2 is reported as the data not telling the curves apart.

The limits of a curve with limits are tested against the plain curve by the likelihood
ratio with the chi-bar-squared reference of parameters on their bounds (Self & Liang
1987): both limits on their bounds under the plain curve give the mixture
:math:`\tfrac14\chi^2_0 + \tfrac12\chi^2_1 + \tfrac14\chi^2_2` (exact when the two limit
estimates are uncorrelated).

References
----------
.. [Collett2003] Collett D. (2003). *Modelling Binary Data*, 2nd ed. Chapman & Hall/CRC
   (binomial GLMs, deviance, overdispersion, profile likelihood).
.. [McCullagh1989] McCullagh P., Nelder J.A. (1989). *Generalized Linear Models*, 2nd ed.
   Chapman & Hall, London (sect. 4.5: overdispersion, the quasi-binomial scale).
.. [SelfLiang1987] Self S.G., Liang K.-Y. (1987). Asymptotic properties of maximum
   likelihood estimators and likelihood ratio tests under nonstandard conditions.
   *J. Am. Stat. Assoc.* 82, 605-610. doi:10.1080/01621459.1987.10478472
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..curves.likelihood import central_hessian, step_out
from ..results_contract import ResultContract
from ..statistics.distributions import binom_logpmf, chi2_sf, f_ppf, norm_isf, norm_ppf
from .batch import LIMIT_STARTS, BinomialFit, TracerStack, deviance_terms, fit_glm, fit_limits_curve
from .dispersion import PooledDispersion, interval_rule, pearson_rejects, pool_dispersion
from .joint import JOINT_METHOD, fit_joint, has_three_analyses, joint_intervals
from .profiles import ProfileRequests, profile_limits
from .readers import DensitySample
from .registry import DensityCurve, DensityIndices, get_density_curve

#: Lowest and highest values the profile searches and the fits of a curve with limits may take.
INDEX_BOUNDS = {"rho50": (1.0 + 1e-6, 8.0), "ep": (1e-4, 2.0), "imperfection": (1e-5, 20.0)}
LIMIT_MARGIN = 1e-6  # the profiles keep l below 1/4 and h above 3/4 by this much
METHODS = ("binomial", "least_squares")
JOINT_FALLBACK_NOTE = (
    "the three analyses could not be fitted jointly (too few fractions for the parameters and the variance function, "
    "or a singular covariance): least squares on the partitions instead"
)
EXACT_SHARES = 1e-9  # share units: analyses this close to the fitted curve carry no error to make intervals from
#: What the intervals of a float-sink fit leave out (measured by benchmarks/density_validation.py).
FLOAT_SINK_INTERVAL_NOTE = (
    "the intervals treat the fractions' partitions as independent and leave out the uncertainty of the floats yield "
    "and the closure of the analyses: on simulated analyses they covered rho50 only 52-58 % of the time "
    "(Ep 90-93 %); read them as lower bounds (with a feed analysis, no stated yield and no method asked, the three "
    "analyses are fitted jointly, with intervals that covered 93 %)"
)


@dataclass(frozen=True)
class DensityCurveFit(ResultContract):
    r"""One density curve fitted to one sample (a test and size fraction).

    Attributes
    ----------
    sample : DensitySample
        The data.
    curve : DensityCurve
        The curve fitted.
    method : str
        ``"binomial"`` (maximum likelihood on tracer counts) or ``"least_squares"``.
    success : bool
        False when no curve could be fitted; ``message`` says why.
    message : str
        Why the fit failed ("" on success).
    params : dict
        The curve's parameters by name.
    indices : DensityIndices or None
        ``rho25, rho50, rho75, ep, imperfection`` read from the fitted ``P``.
    objective : float
        Binomial deviance, or the (weighted) sum of squares.
    df_resid : int
        Points used minus parameters fitted.
    gof_p : float
        p-value of the deviance goodness-of-fit test (NaN for least squares: the error
        variance is not known).
    dispersion : float
        Pearson :math:`X^2 / df` (binomial) or the residual variance (least squares).
    overdispersed : bool
        True when the Pearson test rejects at 5 %: the intervals then use the scale.
    aic : float
        Akaike's criterion (binomial: :math:`-2\log L + 2p`; least squares:
        :math:`n \ln(S/n) + 2(p + 1)`).
    intervals : dict
        ``{"rho50": (low, high), "ep": ..., "imperfection": ...}``, empty without ``ci``.
    notes : tuple of str
        What the reader must know about the fit, in words.
    pooled : PooledDispersion or None
        Binomial fits: the Pearson dispersion of the curve's fits to every tracer sample fitted
        with this one (one file), which floors the intervals' scale
        (:func:`tromplab.density.dispersion.interval_rule`).
    raw : object
        Binomial fits: the batch's record (:class:`tromplab.density.batch.BinomialFit`);
        least squares: the scipy optimisation result; the joint fit: its result.
    """

    sample: DensitySample
    curve: DensityCurve
    method: str
    success: bool
    message: str = ""
    params: dict = field(default_factory=dict)
    indices: DensityIndices | None = None
    objective: float = math.nan
    df_resid: int = 0
    gof_p: float = math.nan
    dispersion: float = math.nan
    overdispersed: bool = False
    aic: float = math.nan
    intervals: dict = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    pooled: PooledDispersion | None = field(default=None, repr=False)
    raw: object = field(default=None, repr=False, compare=False)

    def partition(self, rho) -> np.ndarray:
        """The fitted partition to sinks at ``rho``."""
        return self.curve.partition(rho, **self.params)

    def summary(self):
        """One row: the sample, the curve, the method, the indices with their intervals, the fit's criteria and notes."""
        import pandas as pd

        index = self.indices.as_dict() if self.indices else {}
        row = {"test": self.sample.test, "size_fraction": self.sample.size_fraction, "curve": self.curve.id,
               "method": self.method, "success": self.success}  # fmt: skip
        for name in ("rho50", "ep", "imperfection"):
            low, high = self.intervals.get(name, (math.nan, math.nan))
            row.update({name: index.get(name, math.nan), f"{name}_low": low, f"{name}_high": high})
        row.update({"aic": self.aic, "gof_p": self.gof_p, "notes": "; ".join((self.message, *self.notes)).strip("; ")})
        return pd.DataFrame([row])

    def _result_context(self) -> str:
        state = "fitted" if self.success else f"not fitted ({self.message})"
        return f"Density curve {self.curve.id} {state} to {self.sample.label} by {self.method}"


# --- the data of one fit ------------------------------------------------------------------
@dataclass(frozen=True)
class _Data:
    density: np.ndarray
    share: np.ndarray
    sinks: np.ndarray | None
    trials: np.ndarray | None
    weight: np.ndarray

    @property
    def binomial(self) -> bool:
        return self.trials is not None


def fit_data(sample: DensitySample, method: str) -> _Data:
    used = sample.used
    density, share = used["density"].to_numpy(float), used["partition_sinks"].to_numpy(float)
    if sample.layout == "tracers":
        sinks, trials = used["sinks"].to_numpy(float), used["recovered"].to_numpy(float)
        weight = np.ones_like(density)
        return _Data(density, share, sinks if method == "binomial" else None, trials if method == "binomial" else None, weight)
    weight = used["weight"].to_numpy(float) if "weight" in used else np.ones_like(density)
    return _Data(density, share, None, None, weight / weight.mean())


def objective_of(data: _Data) -> Callable[[np.ndarray], float]:
    """Deviance (binomial) or weighted sum of squares of a vector of fitted partitions."""
    if data.binomial:
        k, n = data.sinks, data.trials

        def deviance(p):
            return float(2.0 * deviance_terms(k, n, p).sum())

        return deviance
    return lambda p: float(np.sum(data.weight * (data.share - p) ** 2))


# --- starts and numerical fits -------------------------------------------------------------
def _starts(data: _Data) -> tuple[float, float]:
    """rho50 and Ep from the measured partitions, interpolated linearly in density."""
    share = np.maximum.accumulate(np.clip(data.share, 0, 1))
    rho = data.density

    def at(p):
        if share[0] >= p:
            return rho[0]
        if share[-1] <= p:
            return rho[-1]
        i = int(np.argmax(share >= p))
        left, right = share[i - 1], share[i]
        return rho[i - 1] + (p - left) / (right - left) * (rho[i] - rho[i - 1]) if right > left else rho[i]

    rho50 = float(np.clip(at(0.5), *INDEX_BOUNDS["rho50"]))
    span = (at(0.75) - at(0.25)) / 2.0
    ep = span if span > 0 else (rho[-1] - rho[0]) / 8.0
    return rho50, float(np.clip(ep, 1e-3, 1.0))


def _minimise(value: Callable[[np.ndarray], float], starts, bounds):
    import scipy.optimize  # the fits on shares only: the binomial fits do not need it

    if len(bounds) == 1:  # the profiles of a plain curve: Brent's bounded search is many times quicker than L-BFGS-B
        return _minimise_scalar(value, starts, bounds[0])
    best = None
    for start in starts:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore", RuntimeWarning)
            result = scipy.optimize.minimize(
                value, np.asarray(start, float), method="SLSQP", bounds=bounds, options={"ftol": 1e-12, "maxiter": 500}
            )
        if np.isfinite(result.fun) and (best is None or result.fun < best.fun):
            best = result
    return best if best is not None else _nowhere(starts)


def _nowhere(starts):
    """The result of a search that found no finite value (the objective is infinite wherever it looked)."""
    import scipy.optimize

    return scipy.optimize.OptimizeResult(x=np.asarray(starts[0], float), fun=np.inf, success=False)


def _minimise_scalar(value, starts, bounds):
    import scipy.optimize

    best = None
    for start in starts:
        centre = float(np.clip(np.asarray(start, float).ravel()[0], *bounds))
        # the probable error's log (or rho50 itself) moves little along a profile: search near the start first
        near = (max(bounds[0], centre - 1.0), min(bounds[1], centre + 1.0))
        with np.errstate(all="ignore"):
            result = scipy.optimize.minimize_scalar(
                lambda v: value(np.array([v])), bounds=near, method="bounded", options={"xatol": 1e-9}
            )
        result.x = np.array([result.x])
        if np.isfinite(result.fun) and (best is None or result.fun < best.fun):
            best = result
    return best if best is not None else _nowhere(starts)


def _natural(curve: DensityCurve, x: np.ndarray) -> dict[str, float]:
    """The curve's parameters from the optimiser's vector (the probable error on a log scale)."""
    values = dict(zip(curve.parameter_names, (float(v) for v in x)))
    ep_name = "ep_c" if curve.has_limits else "ep"
    values[ep_name] = math.exp(values[ep_name])
    return values


def _fit_numerically(curve: DensityCurve, data: _Data) -> tuple[dict, object]:
    """Least squares on the shares from several starts (binomial fits are made in batch, :mod:`.batch`)."""
    import scipy.optimize

    rho50, ep = _starts(data)
    bounds = [(p.lower, p.upper) for p in curve.parameters]
    ep_index = 1
    bounds[ep_index] = (math.log(bounds[ep_index][0]), math.log(bounds[ep_index][1]))
    if curve.has_limits:
        starts = [(rho50, math.log(ep), light, heavy) for light, heavy in LIMIT_STARTS]
    else:
        starts = [(rho50, math.log(ep)), (rho50, math.log(ep) + 1.0), (rho50, math.log(ep) - 1.0)]
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


def _separation(data: _Data) -> str:
    """Words for tracer counts that separate (no maximum-likelihood curve exists), else "".

    They separate when, but for at most one density, every tracer lighter than some
    density floats and every heavier one sinks: the likelihood then grows without bound as
    the curve steepens into a step.
    """
    if not data.binomial:
        return ""
    k, n, rho = data.sinks, data.trials, data.density
    floats, sinks = k == 0, k == n
    if floats.all() or sinks.all():
        side = "floats: rho50 lies above the heaviest" if floats.all() else "sinks: rho50 lies below the lightest"
        return f"every tracer {side} tracer density, so the test does not bound the curve"
    last_float = int(np.argmin(floats)) - 1  # the last density up to which every tracer floats (-1: none)
    first_sink = k.size - int(np.argmin(sinks[::-1]))  # the first density from which every tracer sinks (size: none)
    if first_sink - last_float > 2:  # two or more densities with tracers in both products: a likelihood maximum exists
        return ""
    low = f"{rho[last_float]:g}" if last_float >= 0 else "below the lightest density"
    high = f"{rho[first_sink]:g}" if first_sink < k.size else "above the heaviest density"
    return (
        f"the tracers separate completely between {low} and {high} (all lighter ones float, all heavier ones sink, "
        "but for at most one density between): the maximum-likelihood curve is a step there, rho50 lies between those "
        "densities and Ep is below what the test resolves"
    )


# --- goodness of fit, dispersion, AIC -------------------------------------------------------
def _statistics(curve: DensityCurve, data: _Data, params: dict, objective: float) -> dict:
    p_fit = np.clip(curve.partition(data.density, **params), 1e-12, 1 - 1e-12)
    df = int(data.density.size - curve.n_params)
    if data.binomial:
        k, n = data.sinks, data.trials
        pearson = float(np.sum((k - n * p_fit) ** 2 / (n * p_fit * (1 - p_fit))))
        dispersion = pearson / df if df > 0 else math.nan
        overdispersed = df > 0 and pearson_rejects(dispersion, df)
        loglik = float(binom_logpmf(k, n, p_fit).sum())
        gof_p = float(chi2_sf(objective, df)) if df > 0 else math.nan
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
def index_model(curve: DensityCurve, quantity: str) -> Callable[[np.ndarray], dict]:
    """Parameters of the curve from the vector ``(rho50, ep or imperfection[, light, heavy])``."""

    def params(q):
        rho50, second = float(q[0]), float(q[1])
        ep = second * (rho50 - 1.0) if quantity == "imperfection" else second
        limits = {"light_limit": float(q[2]), "heavy_limit": float(q[3])} if curve.has_limits else {}
        return curve.from_indices(rho50=rho50, ep=ep, **limits)

    return params


def index_vector(curve: DensityCurve, fit_params: dict, indices: DensityIndices, quantity: str) -> tuple[np.ndarray, list]:
    second = indices.imperfection if quantity == "imperfection" else indices.ep
    name = "imperfection" if quantity == "imperfection" else "ep"
    vector = [indices.rho50, second]
    bounds = [INDEX_BOUNDS["rho50"], INDEX_BOUNDS[name]]
    if curve.has_limits:
        vector += [fit_params["light_limit"], fit_params["heavy_limit"]]
        bounds += [(0.0, 0.25 - LIMIT_MARGIN), (0.75 + LIMIT_MARGIN, 1.0)]
    return np.array(vector), bounds


def profile_scale(fit: DensityCurveFit, *, binomial: bool, ci: float = 0.95) -> float:
    """What the profile's rise of the deviance (binomial) or sum of squares is divided by: the
    quasi-binomial scale of :func:`tromplab.density.dispersion.interval_rule` at level ``ci`` (binomial);
    the residual variance for least squares (NaN without degrees of freedom)."""
    if binomial:
        return interval_rule(fit.dispersion, fit.df_resid, ci, fit.pooled).scale
    return fit.objective / fit.df_resid if fit.df_resid > 0 else math.nan


def profile_threshold(fit: DensityCurveFit, ci: float, *, binomial: bool) -> float:
    """The scaled rise at which a profile-likelihood limit at level ``ci`` lies: the
    chi-squared(1) quantile (binomial on the binomial scale), F(1, n - p)'s where a scale was
    estimated (a quasi-binomial scale above 1, :func:`tromplab.density.dispersion.interval_rule`, on the
    test's or the file's degrees of freedom; or the residual variance of least squares)."""
    if binomial:
        return interval_rule(fit.dispersion, fit.df_resid, ci, fit.pooled).threshold
    return float(f_ppf(ci, 1, fit.df_resid)) if fit.df_resid > 0 else math.nan


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
        return _binomial_profiles([(fit, quantity, data)], ci)[0]
    scale, threshold = profile_scale(fit, binomial=False), profile_threshold(fit, ci, binomial=False)
    if not (np.isfinite(scale) and scale > 0):
        return math.nan, math.nan, _NO_VARIANCE_LEFT.format(quantity=quantity)
    if fit.objective <= 1e-20 * data.density.size:
        return math.nan, math.nan, f"{quantity} has no interval: the curve passes through every point (no residual variance)"
    free = [i for i in range(centre.size) if i != position]

    warm = {"x": centre[free]}  # the optimum of the last profile point: the next one starts there

    # the limits (positions 2 and 3) held within their bounds: a limit past them has no rho50 (ValueError)
    lowest, highest = np.array([bounds[i] if i >= 2 else (-np.inf, np.inf) for i in free]).T

    def excess(value):
        def at(x):
            q = centre.copy()
            q[position], q[free] = value, np.clip(x, lowest, highest)  # SLSQP may step past a bound by a hair
            return objective(fit.curve.partition(data.density, **model(q)))

        starts = [warm["x"]] if len(free) == 1 else [warm["x"], centre[free]]
        best = _minimise(at, starts, [bounds[i] for i in free])
        if not np.isfinite(best.fun):  # no finite likelihood at this value: beyond any limit
            return 1e300
        warm["x"] = best.x
        return (best.fun - fit.objective) / scale - threshold

    step = _first_step(fit, quantity)
    limits, notes = [], []
    for direction in (-1.0, 1.0):
        warm["x"] = centre[free]
        value, note = _profile_limit(excess, centre[position], direction, bounds[position], step)
        limits.append(value)
        notes += [f"{quantity}: {note}"] if note else []
    return limits[0], limits[1], "; ".join(notes)


_NO_VARIANCE_LEFT = "{quantity} has no interval: no degrees of freedom left for the error variance"


def _first_step(fit: DensityCurveFit, quantity: str) -> float:
    """How far from the estimate a profile looks first: a quarter of Ep (of I), about the
    half-width of a 95 % interval from 30 tracers per density."""
    return 0.25 * (fit.indices.imperfection if quantity == "imperfection" else fit.indices.ep)


def _binomial_profiles(requests: list, ci: float) -> list[tuple[float, float, str]]:
    """``(low, high, note)`` of every ``(fit, quantity, data)`` of binomial fits, traced together: the
    plain curves in one search, the curves with limits in another (each row's arithmetic is its own)."""
    found: list = [None] * len(requests)
    by_kind: dict[bool, list[int]] = {}
    for position, (fit, quantity, _) in enumerate(requests):
        scale = profile_scale(fit, binomial=True)
        if np.isfinite(scale) and scale > 0:
            by_kind.setdefault(fit.curve.has_limits, []).append(position)
        else:
            found[position] = (math.nan, math.nan, _NO_VARIANCE_LEFT.format(quantity=quantity))
    for positions in by_kind.values():
        chosen = [requests[position] for position in positions]
        curves = list({fit.curve.id: fit.curve for fit, _, _ in chosen}.values())
        number = {curve.id: i for i, curve in enumerate(curves)}
        profile = dataclasses.replace(
            _profile_requests(chosen, ci), curve=np.array([number[fit.curve.id] for fit, _, _ in chosen])
        )
        low, high, notes = profile_limits(curves, profile)
        for row, (position, (_, quantity, _)) in enumerate(zip(positions, chosen)):
            found[position] = (float(low[row]), float(high[row]), "; ".join(f"{quantity}: {note}" for note in notes[row]))
    return found


def binomial_profile_limits(fit: DensityCurveFit, quantity: str, scale: float, threshold: float) -> tuple[float, float]:
    """``(low, high)`` where the rise of ``quantity``'s profile deviance over the minimum, divided by
    ``scale``, reaches ``threshold``: the profile interval of a binomial fit under another rule
    than :mod:`tromplab.density.dispersion`'s (the simulation studies compare rules with it)."""
    data = fit_data(fit.sample, fit.method)
    requests = dataclasses.replace(_profile_requests([(fit, quantity, data)], 0.95), scale=np.array([scale], dtype=float),
                                   threshold=np.array([threshold], dtype=float))  # fmt: skip
    low, high, _ = profile_limits(fit.curve, requests)
    return float(low[0]), float(high[0])


def _profile_requests(chosen: list, ci: float) -> ProfileRequests:
    """The profiles of ``(fit, quantity, data)`` of one curve as stacked arrays."""
    vectors = [index_vector(fit.curve, fit.params, fit.indices, quantity) for fit, quantity, _ in chosen]
    bounds = np.array([limits for _, limits in vectors], dtype=float)
    return ProfileRequests(
        stack=TracerStack.of([(data.density, data.sinks, data.trials) for _, _, data in chosen]),
        imperfection=np.array([quantity == "imperfection" for _, quantity, _ in chosen]),
        position=np.array([0 if quantity == "rho50" else 1 for _, quantity, _ in chosen]),
        centre=np.array([vector for vector, _ in vectors], dtype=float),
        lower=bounds[:, :, 0],
        upper=bounds[:, :, 1],
        best=np.array([fit.objective for fit, _, _ in chosen]),
        scale=np.array([profile_scale(fit, binomial=True, ci=ci) for fit, _, _ in chosen]),
        threshold=np.array([profile_threshold(fit, ci, binomial=True) for fit, _, _ in chosen]),
        step=np.array([_first_step(fit, quantity) for fit, quantity, _ in chosen]),
    )


def _profile_limit(excess, centre: float, direction: float, bounds: tuple[float, float], step: float) -> tuple[float, str]:
    """Where ``excess`` crosses 0 going from ``centre`` in ``direction``: the bracket of every profile's
    search (:func:`tromplab.curves.likelihood.step_out`), closed by Brent's method to ``1e-4 step``."""
    import scipy.optimize

    edge = bounds[1] if direction > 0 else bounds[0]
    side = "upper" if direction > 0 else "lower"
    # one side at a time: the re-optimisations of a side start where the last one ended
    bracket = step_out(lambda rows, values: np.array([excess(values[0])]), [centre], [direction], [abs(edge - centre)],
                       [step], [math.nan])  # fmt: skip
    if not bracket.closed[0]:
        return math.nan, f"the profile does not reach the {side} limit within {edge:g}"
    inner, outer = (centre + direction * t for t in (bracket.inner[0], bracket.outer[0]))
    try:
        return float(scipy.optimize.brentq(excess, min(inner, outer), max(inner, outer), xtol=1e-4 * step)), ""
    except ValueError:  # the re-optimised profile is not monotone between the two points
        return math.nan, f"the {side} limit could not be found (the profile is not monotone near {outer:.4g})"


# --- curves and samples -------------------------------------------------------------------------
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
    return fit_density_curves([sample], [curve], ci=ci, method=method)[0]


def fit_density_curves(
    samples, curves, *, ci: float | None = None, method: str | None = None, pooled: dict | None = None
) -> list[DensityCurveFit]:
    """Fit every curve to every sample: the fits of :func:`fit_density_curve`, the binomial ones all at once.

    The binomial fits of one curve to every tracer sample are made together on stacked
    arrays (:mod:`tromplab.density.batch`), and so are the profile-likelihood intervals of
    every binomial fit (:mod:`tromplab.density.profiles`); the fits on shares are made one
    at a time.  The intervals' scale of the binomial fits is floored by the Pearson dispersion
    of each curve pooled over the tracer samples fitted together (:func:`pooled_dispersions`),
    or by ``pooled`` (by curve id; None for a curve: each test on its own scale) when the
    samples are part of a larger file.

    Returns
    -------
    list of DensityCurveFit
        Sample by sample, the curves of each in the order given.
    """
    curves = [get_density_curve(curve) for curve in curves]
    fits, stacked = {}, {}
    for position, sample in enumerate(samples):
        read = {}  # the sample's arrays, read from its table once for all curves
        for curve in curves:
            opened = _open(sample, curve, method, read)
            if isinstance(opened, DensityCurveFit):
                fits[position, curve.id] = opened
            elif opened.data.binomial:
                stacked.setdefault(curve.id, []).append(((position, curve.id), sample, opened))
            else:
                fits[position, curve.id] = _fit_on_shares(sample, curve, opened, ci)
    binomial = []
    for curve_id, items in stacked.items():
        curve = get_density_curve(curve_id)
        for (key, sample, opened), (params, raw) in zip(items, _fit_binomial_stack(curve, [item[2].data for item in items])):
            fits[key] = _finished(sample, curve, opened, params, raw)
            binomial += [(key, opened.data)] if fits[key].success else []
    pooled = pooled or pooled_dispersions([fits[key] for key, _ in binomial])  # floors each fit's interval scale
    for key, _ in binomial:
        fits[key] = _replace(fits[key], pooled=pooled.get(key[1]))
    profiles = _binomial_interval_plan(fits, binomial, ci)
    for key, data in binomial:
        fits[key] = _with_intervals_and_notes(fits[key], data, ci, joint_fell_back=False, profiles=profiles)
    return [fits[position, curve.id] for position in range(len(samples)) for curve in curves]


@dataclass(frozen=True)
class _Opened:
    """A fit about to be made: its method, data and whether the three float-sink analyses are fitted jointly."""

    method: str
    data: _Data
    joint: bool


def _open(sample: DensitySample, curve: DensityCurve, method: str | None, read: dict) -> _Opened | DensityCurveFit:
    """The fit's method and data (``read``: the sample's data by method, filled here), or the
    failed fit when the data cannot give the curve."""
    joint = method is None and has_three_analyses(sample)
    method = method or ("binomial" if sample.layout == "tracers" else "least_squares")
    if method not in read:
        read[method] = fit_data(sample, method)
    data = read[method]
    failed = {"sample": sample, "curve": curve, "method": method, "success": False}
    if data.density.size <= curve.n_params - (0 if data.binomial else 1):
        return DensityCurveFit(**failed, message=f"{data.density.size} densities are too few for {curve.n_params} parameters")
    separation = _separation(data)
    if separation:
        return DensityCurveFit(**failed, message=separation)
    return _Opened(method, data, joint)


def _fit_on_shares(sample: DensitySample, curve: DensityCurve, opened: _Opened, ci: float | None) -> DensityCurveFit:
    """Least squares on the partitions (or the joint fit of the three analyses), with intervals."""
    try:
        params, raw = _fit_numerically(curve, opened.data)
    except (ValueError, np.linalg.LinAlgError) as error:
        return DensityCurveFit(sample, curve, opened.method, False, message=str(error))
    fit = _finished(sample, curve, opened, params, raw)
    if not fit.success:
        return fit
    joint_fit = _joint(fit, ci) if opened.joint else None
    if joint_fit is not None:
        return joint_fit
    return _with_intervals_and_notes(fit, opened.data, ci, joint_fell_back=opened.joint)


def _finished(sample: DensitySample, curve: DensityCurve, opened: _Opened, params, raw) -> DensityCurveFit:
    """The fit at ``params`` (a message: why none) with its indices and statistics, before its intervals."""
    failed = {"sample": sample, "curve": curve, "method": opened.method, "success": False}
    if isinstance(params, str):
        return DensityCurveFit(**failed, message=params)
    data = opened.data
    value = objective_of(data)(curve.partition(data.density, **params))
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
    statistics = _statistics(curve, data, params, value)
    return DensityCurveFit(sample, curve, opened.method, True, "", params, indices, value, **statistics, raw=raw)


def _fit_binomial_stack(curve: DensityCurve, datas: list[_Data]) -> list[tuple[dict | str, BinomialFit]]:
    """The parameters (or why there are none) and the fit's record of ``curve`` on each of ``datas``, fitted together."""
    stack = TracerStack.of([(data.density, data.sinks, data.trials) for data in datas])
    if curve.has_limits:
        found = fit_limits_curve(stack, curve, np.array([_starts(data) for data in datas]))
        return [(_natural(curve, x), BinomialFit(x, None, float(value), True)) for x, value in zip(found.x, found.deviance)]
    glm = fit_glm(stack, curve.form)
    results = []
    for params, covariance, value, converged in zip(glm.params, glm.covariance, glm.deviance, glm.converged):
        intercept, slope = (float(v) for v in params)
        record = BinomialFit(params, covariance, float(value), bool(converged))
        if not slope > 0:
            results.append(("the fitted partition does not rise with density", record))
        else:
            results.append(({"rho50": (curve.form.centre - intercept) / slope, "ep": curve.form.scale / slope}, record))
    return results


def _with_intervals_and_notes(
    fit: DensityCurveFit, data, ci: float | None, *, joint_fell_back: bool, profiles: dict | None = None
) -> DensityCurveFit:
    """The fit on the partitions with its intervals at ``ci`` and the notes on how it was made
    (``profiles``: the profile intervals already traced, by fit and quantity)."""
    notes = [fit.indices.note] if fit.indices.note else []
    if joint_fell_back:
        notes.append(JOINT_FALLBACK_NOTE)
    if fit.overdispersed:
        notes.append(f"overdispersed (Pearson chi2/df = {fit.dispersion:.2f}: the Pearson test rejects binomial counts at 5 %)")
    intervals = {}
    if ci is not None:
        intervals, interval_notes = _intervals(fit, data, ci, profiles)
        notes += interval_notes
        notes += [note for note in [_scale_note(fit, ci)] if note and data.binomial and intervals]
        if fit.sample.layout == "float-sink" and intervals:
            notes.append(FLOAT_SINK_INTERVAL_NOTE)
    return _replace(fit, intervals=intervals, notes=tuple(notes))


def _scale_note(fit: DensityCurveFit, ci: float) -> str:
    """How the intervals of a binomial fit were scaled (:mod:`tromplab.density.dispersion`); "" on the binomial scale."""
    rule = interval_rule(fit.dispersion, fit.df_resid, ci, fit.pooled)
    if rule.source == "binomial":
        return ""
    if rule.source == "file":
        return (
            f"intervals on the quasi-binomial scale {rule.scale:.3g} of the file (Pearson chi2/df pooled over its "
            f"{fit.pooled.fits} samples, above this test's own): deviance rises over it against F(1, {rule.df_resid})"
        )
    return (
        f"intervals on the quasi-binomial scale {rule.scale:.3g} (Pearson chi2/df, above 1): deviance rises over it "
        f"against F(1, {fit.df_resid})"
    )


def pooled_dispersions(fits) -> dict[str, PooledDispersion]:
    """The Pearson dispersion of each curve's successful binomial fits, pooled (by curve id)."""
    by_curve: dict[str, list] = {}
    for fit in fits:
        if fit.success and fit.method == "binomial":
            by_curve.setdefault(fit.curve.id, []).append(fit)
    return {
        curve_id: pool_dispersion([f.dispersion for f in chosen], [f.df_resid for f in chosen])
        for curve_id, chosen in by_curve.items()
    }


def _binomial_interval_plan(fits: dict, binomial: list, ci: float | None) -> dict:
    """The profile intervals of every binomial fit's quantities that have one, traced together, by fit and quantity."""
    if ci is None:
        return {}
    requests = [(fits[key], quantity, data) for key, data in binomial for quantity in _interval_quantities(fits[key], data)[0]]
    return {(id(fit), quantity): found for (fit, quantity, _), found in zip(requests, _binomial_profiles(requests, ci))}


def _joint(fit: DensityCurveFit, ci: float | None) -> DensityCurveFit | None:
    """The fit of the three float-sink analyses together (:mod:`tromplab.density.joint`), started at ``fit``;
    None when it cannot be made (the caller keeps the fit of the partitions)."""
    result = fit_joint(fit.sample, fit.curve, fit.params)
    if result is None:
        return None
    indices = fit.curve.indices(**result.params)
    notes = [indices.note] if indices.note else []
    intervals = {}
    if ci is not None and result.largest_residual < EXACT_SHARES:
        notes.append("no intervals: the curve passes through every analysed share (no residual variance)")
    elif ci is not None:
        intervals = joint_intervals(fit.curve, result, ci)
        if not intervals:
            notes.append("no intervals: the fitted curve has no rho50, Ep or imperfection")
    return _replace(
        fit,
        method=JOINT_METHOD,
        params=result.params,
        indices=indices,
        objective=result.ssr,
        df_resid=result.df_resid,
        dispersion=result.sigma2,
        aic=result.neg2_loglik + 2 * result.n_params,
        intervals=intervals,
        notes=tuple(notes),
        raw=result,
    )


def _replace(fit: DensityCurveFit, **changes) -> DensityCurveFit:
    from dataclasses import replace

    return replace(fit, **changes)


def _intervals(fit: DensityCurveFit, data: _Data, ci: float, profiles: dict | None = None) -> tuple[dict, list[str]]:
    quantities, notes = _interval_quantities(fit, data)
    intervals = {}
    for quantity in quantities:
        if profiles is not None:
            low, high, note = profiles[id(fit), quantity]
        else:
            low, high, note = profile_interval(fit, quantity, ci)
        intervals[quantity] = (low, high)
        notes += [note] if note else []
    return intervals, notes


def _interval_quantities(fit: DensityCurveFit, data: _Data) -> tuple[list[str], list[str]]:
    """The quantities of ``fit`` that get a profile interval, and notes on those that do not."""
    index = fit.indices
    if math.isnan(index.rho50) or math.isnan(index.ep):
        return [], ["no intervals: the fitted curve has no rho50 or Ep"]
    inside = (data.density > index.rho25) & (data.density < index.rho75)
    notes = []
    quantities = ["rho50", "ep", "imperfection"]
    if not inside.any():
        notes.append(
            f"Ep and the imperfection have no interval: no density lies between rho25 = {index.rho25:.4g} and "
            f"rho75 = {index.rho75:.4g} (the partitions 25 % and 75 %), so the data do not bound the slope"
        )
        quantities = ["rho50"]
    for quantity in list(quantities):
        value, (lowest, highest) = getattr(index, quantity), INDEX_BOUNDS[quantity]
        if math.isnan(value):  # does not exist: the notes already say why
            quantities.remove(quantity)
        elif not lowest < value < highest:  # a GLM estimate is not held to the bounds the profiles search within
            notes.append(
                f"{quantity} has no interval: its estimate {value:.4g} lies outside the range searched, {lowest:g} to {highest:g}"
            )
            quantities.remove(quantity)
    return quantities, notes


# --- every curve on one sample: ranking and the test of the limits ------------------------------
def limits_test_p(plain: DensityCurveFit, limited: DensityCurveFit) -> float:
    r"""p-value of the two limits against the plain curve (chi-bar-squared, both limits on their bounds).

    The likelihood ratio :math:`\Lambda` (the deviance difference, over the quasi-binomial
    scale of the curve with limits when it is overdispersed; :math:`n\ln(S_0/S_1)` for least squares) is referred to
    :math:`\tfrac14\chi^2_0 + \tfrac12\chi^2_1 + \tfrac14\chi^2_2` (Self & Liang 1987):
    :math:`p = \tfrac12 P(\chi^2_1 > \Lambda) + \tfrac14 P(\chi^2_2 > \Lambda)` for
    :math:`\Lambda > 0`, and 1 otherwise.

    Examples
    --------
    >>> from types import SimpleNamespace as Fit
    >>> plain = Fit(method="binomial", objective=12.0, sample=None)
    >>> round(limits_test_p(plain, Fit(objective=8.16, overdispersed=False, dispersion=1.0)), 4)  # Lambda = 3.84: half the chi2(1) tail, plus a quarter of chi2(2)'s
    0.0617
    """
    if plain.method == "binomial":
        # the scale of the larger model: a plain curve that misses real limits looks overdispersed itself
        ratio = (plain.objective - limited.objective) / (limited.dispersion if limited.overdispersed else 1.0)
    else:
        count = int(plain.sample.used.shape[0])
        ratio = count * math.log(plain.objective / limited.objective) if limited.objective > 0 else math.inf
    if not ratio > 1e-9:  # the limits fitted on their bounds: the plain curve again, up to the optimiser's tolerance
        return 1.0
    return float(0.5 * chi2_sf(ratio, 1) + 0.25 * chi2_sf(ratio, 2))


def wilson_interval(count, trials, *, level: float) -> tuple[np.ndarray, np.ndarray]:
    r"""Wilson's score interval of binomial proportions ``count / trials`` at ``level``, within 0..1.

    .. math:: \frac{\hat p + z^2/2n \pm z\sqrt{\hat p(1 - \hat p)/n + z^2/4n^2}}{1 + z^2/n}

    The arithmetic of statsmodels' ``proportion_confint(method="wilson")`` step for step (so the
    tables are the same to the last bit), without importing statsmodels (seconds on a loaded machine).

    References
    ----------
    Wilson E.B. (1927). Probable inference, the law of succession, and statistical inference.
    *J. Am. Stat. Assoc.* 22, 209-212.

    Examples
    --------
    >>> low, high = wilson_interval(np.array([3]), np.array([10]), level=0.95)
    >>> round(float(low[0]), 4), round(float(high[0]), 4)
    (0.1078, 0.6032)
    """
    count, trials = np.asarray(count), np.asarray(trials)
    share = count / trials
    crit = norm_isf((1 - level) / 2.0)
    crit2 = crit**2
    denominator = 1 + crit2 / trials
    centre = (share + crit2 / (2 * trials)) / denominator
    half = crit * np.sqrt(share * (1.0 - share) / trials + crit2 / (4.0 * trials**2))
    half /= denominator
    return np.clip(centre - half, 0, 1), np.clip(centre + half, 0, 1)


# --- the band of a fitted curve ---------------------------------------------------------------
def partition_band(fit: DensityCurveFit, rho, *, level: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
    r"""Pointwise delta-method band of the fitted partition at ``rho``: ``(low, high)``, within 0..1.

    The covariance of the parameters is :math:`2 s H^{-1}`, with ``H`` the Hessian of the
    objective (deviance or weighted sum of squares, by central differences) and ``s`` the
    scale (binomial: :func:`~tromplab.density.dispersion.interval_rule`; the residual variance for
    least squares); a limit on its bound is held there.  The band is
    :math:`\hat P \pm z\,\sqrt{g^\top C g}` with ``g`` the gradient of ``P`` in the
    parameters, clipped to 0..1; ``z`` is the normal quantile, or Student's t on ``n - p`` degrees of
    freedom where the quasi-binomial scale was estimated (the square root of
    :func:`~tromplab.density.dispersion.profile_threshold`).
    """
    rho = np.asarray(rho, dtype=float)
    centre = fit.partition(rho)
    if fit.method == JOINT_METHOD:
        return _band(fit, rho, centre, list(fit.raw.free), fit.raw.covariance, level)
    names = [name for name in fit.curve.parameter_names if not fit.curve.limit_on_bound(name, fit.params[name])]
    data = fit_data(fit.sample, fit.method)
    objective = objective_of(data)
    values = np.array([fit.params[name] for name in names])
    steps = 1e-4 * np.maximum(np.abs(values), 1e-2)

    def at(vector, where):
        return fit.curve.partition(where, **{**fit.params, **dict(zip(names, vector))})

    hessian = central_hessian(lambda vector: objective(at(vector, data.density)), values, steps)
    scale = profile_scale(fit, binomial=data.binomial, ci=level)
    quantile = math.sqrt(profile_threshold(fit, level, binomial=True)) if data.binomial else None  # None: the normal's
    try:
        covariance = 2.0 * scale * np.linalg.inv(hessian)
    except np.linalg.LinAlgError:
        return np.full_like(centre, np.nan), np.full_like(centre, np.nan)
    return _band(fit, rho, centre, names, covariance, level, quantile=quantile)


def _band(fit: DensityCurveFit, rho, centre, names: list, covariance: np.ndarray, level: float, *, quantile=None):
    values = np.array([fit.params[name] for name in names])
    steps = 1e-4 * np.maximum(np.abs(values), 1e-2)

    def at(vector, where):
        return fit.curve.partition(where, **{**fit.params, **dict(zip(names, vector))})

    gradient = np.stack(
        [
            (at(values + np.eye(len(names))[i] * steps[i], rho) - at(values - np.eye(len(names))[i] * steps[i], rho))
            / (2 * steps[i])
            for i in range(len(names))
        ],
        axis=-1,
    )
    variance = np.einsum("...i,ij,...j->...", gradient, covariance, gradient)
    quantile = norm_ppf(0.5 + level / 2) if quantile is None else quantile
    half = quantile * np.sqrt(np.clip(variance, 0, None))
    return np.clip(centre - half, 0, 1), np.clip(centre + half, 0, 1)
