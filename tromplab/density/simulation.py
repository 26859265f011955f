"""Simulated density data with a known curve: tracer tests and float-sink analyses, as a lab writes them.

:func:`simulate_tracer_test` puts ``placed`` tracers of each density into the feed of a
separator with a known partition curve, recovers each with a given probability and
counts the sinks and floats (whole numbers, the table a lab writes: ``test, density,
placed, sinks, floats``).  :func:`float_sink_table` writes the float-sink analyses of the
products of a separator with a known curve, so that the partition the reader computes
equals the curve at each fraction's mean density.  :func:`tracer_study` repeats simulated
tests and reports the bias of rho50 and Ep and the coverage of their intervals, for the
binomial fit and for least squares on the shares; :func:`limits_test_size` measures the size
of the test of the limits and :func:`float_sink_study` the float-sink fits' bias and coverage
(``benchmarks/density_validation.py`` runs them at full size; the numbers are in
``docs/density_columns.md``).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from .fitting import fit_density_curve, fit_density_curves, profile_interval
from .joint import JOINT_METHOD, has_three_analyses
from .readers import read_density
from .registry import get_density_curve


def simulate_tracer_test(
    curve, params: dict, densities, *, placed: int = 30, retrieval: float = 1.0, rng=None, test: str = "sim"
) -> pd.DataFrame:
    """A tracer test of a separator whose partition to sinks is ``curve`` with ``params``.

    Each of the ``placed`` tracers of each density reports to the sinks with probability
    ``P(density)`` and is recovered with probability ``retrieval``, independently.

    Returns
    -------
    pandas.DataFrame
        ``test, density, placed, sinks, floats`` (whole numbers).

    Examples
    --------
    >>> table = simulate_tracer_test("normal", {"rho50": 1.5, "ep": 0.05}, [1.4, 1.5, 1.6], rng=np.random.default_rng(0))
    >>> table.columns.tolist(), int(table["placed"].sum())
    (['test', 'density', 'placed', 'sinks', 'floats'], 90)
    """
    rng = np.random.default_rng(rng)
    densities = np.asarray(densities, dtype=float)
    partition = get_density_curve(curve).partition(densities, **params)
    recovered = rng.binomial(placed, retrieval, size=densities.size)
    sinks = rng.binomial(recovered, partition)
    return pd.DataFrame({"test": test, "density": densities, "placed": placed, "sinks": sinks, "floats": recovered - sinks})


def float_sink_table(curve, params: dict, bounds, feed_pct, *, test: str = "sim", with_feed: bool = True) -> pd.DataFrame:
    """Float-sink analyses of the products of a separator with a known partition curve.

    The partition of each fraction is the curve at the fraction's ``density_mean`` (its
    midpoint; for an open end, the midpoint of the fraction extended by its neighbour's width,
    the reader's convention), so the reader recovers the curve there exactly.

    Parameters
    ----------
    bounds : sequence of float
        Fraction boundaries in increasing density; the first fraction is open below (the
        float below ``bounds[0]``) and the last open above (the sink above ``bounds[-1]``).
    feed_pct : sequence of float
        Mass per cent of the feed in each of the ``len(bounds) + 1`` fractions.

    Returns
    -------
    pandas.DataFrame
        ``test, density_lower, density_upper, [feed_pct,] floats_pct, sinks_pct`` (and
        ``floats_yield`` without the feed analysis).
    """
    bounds = np.asarray(bounds, dtype=float)
    lower = np.concatenate(([np.nan], bounds))
    upper = np.concatenate((bounds, [np.nan]))
    extended_lower = np.concatenate(([bounds[0] - (bounds[1] - bounds[0])], bounds))
    extended_upper = np.concatenate((bounds, [bounds[-1] + (bounds[-1] - bounds[-2])]))
    mean = (extended_lower + extended_upper) / 2
    feed = np.asarray(feed_pct, dtype=float) / np.sum(feed_pct)
    partition = get_density_curve(curve).partition(mean, **params)
    sinks_yield = float(np.sum(feed * partition))
    table = pd.DataFrame({"test": test, "density_lower": lower, "density_upper": upper})
    if with_feed:
        table["feed_pct"] = 100 * feed
    table["floats_pct"] = 100 * feed * (1 - partition) / (1 - sinks_yield)
    table["sinks_pct"] = 100 * feed * partition / sinks_yield
    if not with_feed:
        table["floats_yield"] = 1 - sinks_yield
    return table


def tracer_study(
    *,
    rho50: float = 1.55,
    ep: float = 0.04,
    steps=(0.01, 0.02, 0.05),
    retrievals=(0.7, 0.85, 1.0),
    placed: int = 30,
    tests: int = 100,
    curve: str = "normal",
    ci: float = 0.95,
    seed: int = 0,
) -> pd.DataFrame:
    """Bias and interval coverage of rho50 and Ep over simulated tracer tests, binomial fit and least squares side by side.

    For each density step and retrieval, ``tests`` tracer tests are simulated at densities
    ``rho50 - max(3 Ep, 2 step)`` to ``rho50 + max(3 Ep, 2 step)`` in steps of ``step``, read through
    :func:`~tromplab.density.readers.read_density` as a lab file would be, and fitted with the
    true curve by binomial maximum likelihood and by least squares on the shares; each
    gives its profile intervals at ``ci``.

    Returns
    -------
    pandas.DataFrame
        One row per step, retrieval and method: ``step, retrieval, method, tests, fitted,
        rho50_bias, ep_bias, ep_relative_bias, rho50_coverage, ep_coverage,
        rho50_no_interval, ep_no_interval`` (coverage over the tests whose interval
        exists; a test whose fit failed counts in neither).
    """
    rng = np.random.default_rng(seed)
    rows = []
    for step in steps:
        half = max(3 * ep, 2 * step)
        densities = np.round(np.arange(rho50 - half, rho50 + half + step / 2, step), 6)
        for retrieval in retrievals:
            results = {"binomial": [], "least_squares": []}
            for _ in range(tests):
                table = simulate_tracer_test(
                    curve, {"rho50": rho50, "ep": ep}, densities, placed=placed, retrieval=retrieval, rng=rng
                )
                sample = read_density(table)[0]
                for method in results:
                    results[method].append(_one_test(sample, curve, method, ci))
            for method, outcomes in results.items():
                rows.append(_study_row(outcomes, step, retrieval, method, rho50, ep))
    return pd.DataFrame(rows)


def _one_test(sample, curve, method, ci) -> dict:
    fit = fit_density_curve(sample, curve, method=method, ci=ci if fit_has_own_intervals(sample, method) else None)
    if not fit.success or not math.isfinite(fit.indices.ep):
        return {"fitted": False}
    outcome = {"fitted": True, "rho50": fit.indices.rho50, "ep": fit.indices.ep}
    for quantity in ("rho50", "ep"):
        if fit.method == JOINT_METHOD:
            low, high = fit.intervals.get(quantity, (math.nan, math.nan))
        else:
            low, high, _ = profile_interval(fit, quantity, ci)
        outcome[quantity + "_interval"] = (low, high)
    return outcome


def fit_has_own_intervals(sample, method) -> bool:
    """True when the fit of ``sample`` by ``method`` is the joint fit, whose intervals come with it."""
    return method is None and has_three_analyses(sample)


def _study_row(outcomes, step, retrieval, method, rho50, ep) -> dict:
    fitted = [o for o in outcomes if o["fitted"]]
    row = {"step": step, "retrieval": retrieval, "method": method, "tests": len(outcomes), "fitted": len(fitted)}
    rho50_hat = np.array([o["rho50"] for o in fitted])
    ep_hat = np.array([o["ep"] for o in fitted])
    row["rho50_bias"] = float(np.mean(rho50_hat - rho50)) if fitted else math.nan
    row["ep_bias"] = float(np.mean(ep_hat - ep)) if fitted else math.nan
    row["ep_relative_bias"] = row["ep_bias"] / ep
    for quantity, truth in (("rho50", rho50), ("ep", ep)):
        intervals = np.array([o[quantity + "_interval"] for o in fitted]).reshape(-1, 2)
        exists = np.isfinite(intervals).all(axis=1)
        covered = (intervals[exists, 0] <= truth) & (truth <= intervals[exists, 1])
        row[f"{quantity}_coverage"] = float(covered.mean()) if exists.any() else math.nan
        row[f"{quantity}_no_interval"] = int((~exists).sum())
    return row


def limits_test_size(
    *,
    rho50: float = 1.55,
    ep: float = 0.04,
    step: float = 0.02,
    retrieval: float = 0.9,
    placed: int = 30,
    tests: int = 200,
    curve: str = "normal",
    alpha: float = 0.05,
    seed: int = 0,
) -> dict:
    """Rejection rate of the chi-bar-squared test of the limits when the true curve has none.

    Simulated tracer tests of the plain ``curve`` are fitted with it and with its variant with
    limits; the share of tests whose :func:`~tromplab.density.fitting.limits_test_p` falls
    below ``alpha`` estimates the test's size (nominal ``alpha``), beside the share a plain
    chi-square with 2 degrees of freedom would reject and the share of fits with both limits
    on their bounds.

    Returns
    -------
    dict
        ``tests, fitted, mixture_rejects, chi2_2_rejects, both_on_bounds``.
    """
    import scipy.stats

    from .fitting import limits_test_p

    rng = np.random.default_rng(seed)
    half = max(3 * ep, 2 * step)
    densities = np.round(np.arange(rho50 - half, rho50 + half + step / 2, step), 6)
    mixture, plain_chi2, on_bounds = [], [], []
    for _ in range(tests):
        sample = read_density(
            simulate_tracer_test(curve, {"rho50": rho50, "ep": ep}, densities, placed=placed, retrieval=retrieval, rng=rng)
        )[0]
        plain, limited = fit_density_curve(sample, curve), fit_density_curve(sample, f"{curve}_limits")
        if not (plain.success and limited.success):
            continue
        mixture.append(limits_test_p(plain, limited) < alpha)
        plain_chi2.append(scipy.stats.chi2.sf(max(plain.objective - limited.objective, 0.0), 2) < alpha)
        on_bounds.append(limited.params["light_limit"] <= 1e-6 and limited.params["heavy_limit"] >= 1 - 1e-6)
    return {
        "tests": tests,
        "fitted": len(mixture),
        "mixture_rejects": float(np.mean(mixture)) if mixture else math.nan,
        "chi2_2_rejects": float(np.mean(plain_chi2)) if plain_chi2 else math.nan,
        "both_on_bounds": float(np.mean(on_bounds)) if on_bounds else math.nan,
    }


#: The feed of the float-sink study: mass per cent in the fractions (float below 1.30, 0.05 steps to
#: 1.90, sink above): a coal with much clean coal, a middlings tail and a reject peak at the heavy end.
STUDY_BOUNDS = tuple(np.round(np.arange(1.30, 1.901, 0.05), 2))
STUDY_FEED_PCT = (30.0, 18.0, 11.0, 7.0, 5.0, 4.0, 3.5, 3.0, 2.5, 2.0, 2.0, 2.0, 2.0, 8.0)


def noisy_analysis(share_pct, rng, *, relative_error: float = 0.03, absolute_error: float = 0.05) -> np.ndarray:
    """One float-sink analysis as a lab reports it: each fraction weighed with a relative and an
    absolute error (percentage points), clipped at 0, brought back to 100 % and rounded to 0.01."""
    share = np.asarray(share_pct, dtype=float)
    measured = np.clip(
        share * (1 + rng.normal(0, relative_error, share.size)) + rng.normal(0, absolute_error, share.size), 0, None
    )
    return np.round(100 * measured / measured.sum(), 2)


def float_sink_study(
    *,
    rho50: float = 1.55,
    ep: float = 0.05,
    tests: int = 200,
    ci: float = 0.95,
    curve: str = "normal",
    method: str | None = None,
    seed: int = 0,
    **errors,
) -> dict:
    """Bias and interval coverage of rho50 and Ep fitted by weighted least squares to noisy float-sink analyses.

    Each test takes the float-sink analyses of a separator with the known curve
    (:func:`float_sink_table` at :data:`STUDY_BOUNDS` with :data:`STUDY_FEED_PCT`), adds the
    weighing errors of :func:`noisy_analysis` (``errors``: its ``relative_error`` and
    ``absolute_error``) to each of the three analyses, reads them through
    :func:`~tromplab.density.readers.read_density` (the floats yield estimated from the three)
    and fits the true curve with its intervals at ``ci``: by default jointly to the three
    analyses (:mod:`tromplab.density.joint`, Wald intervals), with ``method="least_squares"``
    by weighted least squares on the partitions (profile intervals).

    Returns
    -------
    dict
        ``tests, fitted, rho50_bias, ep_relative_bias, rho50_coverage, ep_coverage,
        rho50_no_interval, ep_no_interval``.
    """
    rng = np.random.default_rng(seed)
    clean = float_sink_table(curve, {"rho50": rho50, "ep": ep}, STUDY_BOUNDS, STUDY_FEED_PCT)
    outcomes = []
    for _ in range(tests):
        table = clean.copy()
        for column in ("feed_pct", "floats_pct", "sinks_pct"):
            table[column] = noisy_analysis(clean[column], rng, **errors)
        outcomes.append(_one_test(read_density(table)[0], curve, method, ci))
    row = _study_row(outcomes, math.nan, math.nan, method, rho50, ep)
    return {key: row[key] for key in ("tests", "fitted", "rho50_bias", "ep_relative_bias", "rho50_coverage", "ep_coverage",
                                      "rho50_no_interval", "ep_no_interval")}  # fmt: skip


def overdispersed_ranking_study(
    *, rho50: float = 1.55, ep: float = 0.04, step: float = 0.02, placed: int = 30, sharing: float = 4.0, tests: int = 200,
    seed: int = 0,
) -> dict:  # fmt: skip
    """How often the curve with limits is ranked first, by AIC and by QAIC, on overdispersed tracer tests of a plain curve.

    Tracers of one density share a fate: the sink probability of each density is drawn from a
    beta distribution with mean ``P(density)`` of the normal curve and ``sharing`` pseudo-tracers
    (smaller: more overdispersed), then its ``placed`` tracers sink with it (all recovered).
    Each test is read through :func:`~tromplab.density.readers.read_density` and fitted with
    the normal, logistic and normal-with-limits curves.

    Returns
    -------
    dict
        ``tests, overdispersed, limits_first_aic, limits_first_qaic`` (shares of the
        overdispersed tests whose best curve is the one with limits).
    """
    from .ranking import quasi_aic, variance_inflation

    rng = np.random.default_rng(seed)
    half = max(3 * ep, 2 * step)
    densities = np.round(np.arange(rho50 - half, rho50 + half + step / 2, step), 6)
    p = get_density_curve("normal").partition(densities, rho50=rho50, ep=ep)
    by_aic, by_qaic = [], []
    for _ in range(tests):
        sinks = rng.binomial(placed, rng.beta(p * sharing + 1e-3, (1 - p) * sharing + 1e-3))
        table = pd.DataFrame({"test": "sim", "density": densities, "placed": placed, "sinks": sinks, "floats": placed - sinks})
        sample = read_density(table)[0]
        fits = [fit_density_curve(sample, curve) for curve in ("normal", "logistic", "normal_limits")]
        inflation = variance_inflation(fits)
        done = [fit for fit in fits if fit.success]
        if not math.isfinite(inflation) or len(done) < len(fits):
            continue
        by_aic.append(min(done, key=lambda fit: fit.aic).curve.has_limits)
        by_qaic.append(min(done, key=lambda fit: quasi_aic(fit, inflation)).curve.has_limits)
    return {
        "tests": tests,
        "overdispersed": len(by_aic),
        "limits_first_aic": float(np.mean(by_aic)) if by_aic else math.nan,
        "limits_first_qaic": float(np.mean(by_qaic)) if by_qaic else math.nan,
    }


def beta_binomial_tracer_test(
    curve, params: dict, densities, *, placed: int = 30, precision: float = 10.0, rng=None, test: str = "sim"
) -> pd.DataFrame:
    """A tracer test whose tracers of one density share a fate: beta-binomial counts, as a lab writes them.

    The sink probability of each density is drawn from a beta distribution with mean
    ``P(density)`` and precision ``precision`` (its two parameters sum to it: the smaller, the
    more the tracers of a density move together), then its ``placed`` tracers sink with it,
    all recovered.  The variance of a count is the binomial one times
    ``1 + (placed - 1) / (precision + 1)``; ``precision=inf`` gives binomial counts.

    Returns
    -------
    pandas.DataFrame
        ``test, density, placed, sinks, floats`` (whole numbers).

    Examples
    --------
    >>> table = beta_binomial_tracer_test("normal", {"rho50": 1.5, "ep": 0.05}, [1.4, 1.5, 1.6], rng=np.random.default_rng(0))
    >>> (table["sinks"] + table["floats"]).tolist()
    [30, 30, 30]
    """
    rng = np.random.default_rng(rng)
    densities = np.asarray(densities, dtype=float)
    partition = get_density_curve(curve).partition(densities, **params)
    if math.isfinite(precision):
        tiny = 1e-9  # a beta parameter must be positive where the curve reaches 0 or 1
        partition = rng.beta(np.maximum(partition * precision, tiny), np.maximum((1 - partition) * precision, tiny))
    sinks = rng.binomial(placed, partition)
    return pd.DataFrame({"test": test, "density": densities, "placed": placed, "sinks": sinks, "floats": placed - sinks})


#: The rules of the intervals' scale and threshold the overdispersion study compares: the rule
#: before them (the scale only where the Pearson test rejects, and the chi-square(1) threshold even
#: then), the policies of :func:`~tromplab.density.dispersion.quasi_binomial_scale` with their
#: threshold (a test's own dispersion), and the library's policy (``"file_floor"``: floored by the
#: file's pooled dispersion, :func:`~tromplab.density.dispersion.interval_rule`).
INTERVAL_RULES = ("pearson_test_chi2", "pearson_test", "at_least_one", "file_floor")


def _rule_scale_and_threshold(rule: str, dispersion: float, df_resid: int, ci: float) -> tuple[float, float]:
    from .dispersion import profile_threshold, quasi_binomial_scale

    policy = "pearson_test" if rule == "pearson_test_chi2" else rule
    quasi = quasi_binomial_scale(dispersion, df_resid, policy=policy)
    estimated = quasi.estimated and rule != "pearson_test_chi2"
    return quasi.scale, profile_threshold(ci, df_resid, estimated)


def overdispersion_coverage_study(
    *, rho50: float = 1.55, ep: float = 0.04, densities: int = 7, placed: int = 30, precision: float = 10.0,
    tests: int = 150, tests_per_file: int = 10, ci: float = 0.95, rules=INTERVAL_RULES, seed: int = 0,
) -> pd.DataFrame:  # fmt: skip
    """Coverage of the profile intervals of rho50 and Ep on beta-binomial tracer tests, rule by rule.

    Each test (:func:`beta_binomial_tracer_test` of the normal curve at ``densities`` densities
    evenly from ``rho50 - 3 Ep`` to ``rho50 + 3 Ep``) is written, ``tests_per_file`` tests to a
    file (one device, one way of counting: the same precision), as a CSV file of whole counts,
    read back through :func:`~tromplab.density.readers.read_density` as a lab's file is, and the
    file's tests are fitted together with the normal curve and its intervals at ``ci``
    (:func:`~tromplab.density.fitting.fit_density_curves`: the library's rule, whose scale the
    file's pooled dispersion floors); the intervals of the other ``rules``
    (:data:`INTERVAL_RULES`, a test's own dispersion) are profiled on the same fits.  A test
    counts as covered when its interval holds the truth; a limit the profile does not reach
    within the search range is the range's end; a failed fit or a missing interval counts as
    not covered.  The last file holds what is left when ``tests_per_file`` does not divide ``tests``.

    Returns
    -------
    pandas.DataFrame
        One row per rule: ``densities, precision, tests_per_file, rule, tests, fitted, scaled,
        rho50_coverage, ep_coverage, rho50_no_interval, ep_no_interval, rho50_median_width,
        ep_median_width`` (``scaled``: the tests whose intervals used an estimated scale).
    """
    import tempfile
    from pathlib import Path

    from .dispersion import SCALE_POLICY

    rng = np.random.default_rng(seed)
    grid = np.round(np.linspace(rho50 - 3 * ep, rho50 + 3 * ep, densities), 6)
    truth = {"rho50": rho50, "ep": ep}
    outcomes = {rule: [] for rule in rules}
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "tracers.csv"
        for first in range(0, tests, tests_per_file):
            draws = [
                beta_binomial_tracer_test("normal", truth, grid, placed=placed, precision=precision, rng=rng, test=f"t{number}")
                for number in range(first, min(first + tests_per_file, tests))
            ]
            pd.concat(draws, ignore_index=True).to_csv(path, index=False)
            for fit in fit_density_curves(read_density(path), ["normal"], ci=ci):
                for rule in rules:
                    outcomes[rule].append(_rule_intervals(fit, rule, ci, library_rule=rule == SCALE_POLICY))
    return pd.DataFrame([_coverage_row(outcomes[rule], truth, densities, precision, rule) | {"tests_per_file": tests_per_file}
                         for rule in rules])  # fmt: skip


def _rule_intervals(fit, rule: str, ci: float, *, library_rule: bool) -> dict:
    """The intervals of rho50 and Ep of ``fit`` by ``rule`` (where the fit has one), and whether its scale was estimated."""
    from .dispersion import interval_rule
    from .fitting import INDEX_BOUNDS, binomial_profile_limits

    if not fit.success:
        return {"fitted": False}
    if library_rule:
        scale = interval_rule(fit.dispersion, fit.df_resid, ci, fit.pooled).scale
    else:
        scale, threshold = _rule_scale_and_threshold(rule, fit.dispersion, fit.df_resid, ci)
    outcome = {"fitted": True, "scaled": scale != 1.0}
    for quantity in ("rho50", "ep"):
        if quantity not in fit.intervals:  # no interval by the fit's own rules (the notes say why)
            outcome[quantity] = (math.nan, math.nan)
            continue
        low, high = fit.intervals[quantity] if library_rule else binomial_profile_limits(fit, quantity, scale, threshold)
        lowest, highest = INDEX_BOUNDS[quantity]
        outcome[quantity] = (lowest if math.isnan(low) else low, highest if math.isnan(high) else high)
    return outcome


def _coverage_row(outcomes: list[dict], truth: dict, densities: int, precision: float, rule: str) -> dict:
    fitted = [o for o in outcomes if o["fitted"]]
    row = {"densities": densities, "precision": precision, "rule": rule, "tests": len(outcomes), "fitted": len(fitted),
           "scaled": sum(o["scaled"] for o in fitted)}  # fmt: skip
    for quantity in ("rho50", "ep"):
        intervals = np.array([o[quantity] for o in fitted], dtype=float).reshape(-1, 2)
        exists = np.isfinite(intervals).all(axis=1)
        covered = exists & (intervals[:, 0] <= truth[quantity]) & (truth[quantity] <= intervals[:, 1])
        row[f"{quantity}_coverage"] = float(covered.sum() / len(outcomes)) if outcomes else math.nan
        row[f"{quantity}_no_interval"] = len(outcomes) - int(exists.sum())
        widths = intervals[exists, 1] - intervals[exists, 0]
        row[f"{quantity}_median_width"] = float(np.median(widths)) if widths.size else math.nan
    return row
