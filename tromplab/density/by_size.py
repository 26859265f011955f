r"""Density partition by size fraction: rho50, Ep and I per size and the trend of Ep with size.

Dense-medium separators and jigs separate fine particles less sharply than coarse ones: Ep
grows as the size falls.  When a tracer or float-sink test carries size fractions, each
fraction is one curve (:func:`tromplab.density.fitting.fit_density_curve`); this module
gathers them by test and curve (:func:`by_size_table`), fits the trend of Ep against size
(:func:`fit_ep_trend`) and draws the partition surface and the indices against size.

The trend is the power law

.. math:: E_p = a\,d^{-b},

fitted as the straight line :math:`\ln E_p = \ln a - b \ln d` by weighted least squares
(statsmodels ``WLS``).  The weight of a size fraction is the inverse variance of its
:math:`\ln E_p`, read off its profile-likelihood interval as
:math:`s = (\ln E_{p,\mathrm{high}} - \ln E_{p,\mathrm{low}}) / (2 z_{(1+c)/2})`; a fraction
whose Ep has no interval is left out of a weighted trend (and said so).  Without intervals
(``ci`` not given) every fraction weighs the same.  The residual scale is estimated (so a
scatter about the power law beyond the fractions' own intervals widens the trend's
intervals) and the intervals of :math:`b` and :math:`\ln a` are Student-t intervals with
``n - 2`` degrees of freedom; ``a`` is :math:`\exp` of its log's interval.  ``d`` is the
representative size of a fraction: the geometric mean of its bounds, the open fractions
extended by their neighbour's ratio as the size classes of the lab tables are.  Two size
fractions fix the line with no degree of freedom left: no interval then, and the note says
so.

References
----------
Napier-Munn, T. J. (1991). Modelling and simulating dense medium separation processes - a
progress report. *Minerals Engineering* 4(3-4), 329-346 (Ep rising as size falls).

Wills, B. A. & Finch, J. A. (2016). *Wills' Mineral Processing Technology*, 8th ed.,
Butterworth-Heinemann, chapter 11.
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..output.csv_parts import file_writers

#: Columns of :func:`by_size_table`, in order.
BY_SIZE_COLUMNS = (
    "test",
    "curve",
    "size_lower",
    "size_upper",
    "size",
    "size_unit",
    "rho50",
    "rho50_low",
    "rho50_high",
    "ep",
    "ep_low",
    "ep_high",
    "imperfection",
    "imperfection_low",
    "imperfection_high",
    "aic",
    "ep_trend",
    "note",
)
#: Columns of :func:`ep_trend_table`, in order.
EP_TREND_COLUMNS = ("test", "curve", "size_unit", "n_sizes", "a", "a_low", "a_high", "b", "b_low", "b_high", "weighted", "note")


@dataclass(frozen=True)
class EpTrend:
    r"""The power law :math:`E_p = a\,d^{-b}` fitted to the Ep of several size fractions.

    Attributes
    ----------
    a, b : float
        Ep at unit size (in the sizes' unit) and the exponent (> 0 when Ep grows as the
        size falls).
    a_interval, b_interval : tuple of float
        Their intervals at level ``ci`` (NaN when there is no degree of freedom left).
    ci : float
        The level of the intervals.
    n_sizes : int
        Size fractions in the fit.
    weighted : bool
        True when the fractions are weighted by their Ep intervals.
    note : str
        What was left out or cannot be said, in words ("" when nothing).
    raw : object
        The statsmodels regression results (None when no trend was fitted).
    """

    a: float
    b: float
    a_interval: tuple
    b_interval: tuple
    ci: float
    n_sizes: int
    weighted: bool
    note: str = ""
    raw: object = field(default=None, repr=False, compare=False)

    def ep_at(self, size) -> np.ndarray:
        """Ep the trend gives at ``size`` (same unit as the fractions' sizes)."""
        return self.a * np.asarray(size, dtype=float) ** (-self.b)


def representative_sizes(lower, upper) -> np.ndarray:
    """Geometric mean of each size fraction's bounds; open ends extended by the neighbour's ratio.

    Examples
    --------
    >>> representative_sizes([8.0, 4.0, np.nan], [np.nan, 8.0, 4.0]).round(6).tolist()  # +8, 4-8, -4 mm
    [11.313708, 5.656854, 2.828427]
    """
    lower, upper = np.asarray(lower, dtype=float).copy(), np.asarray(upper, dtype=float).copy()
    closed = np.isfinite(lower) & np.isfinite(upper)
    if not closed.any():
        return np.full(lower.shape, np.nan)
    key = np.where(np.isfinite(lower), lower, 0.0)
    order = np.argsort(key)
    for position, i in enumerate(order):
        neighbours = [order[j] for j in (position - 1, position + 1) if 0 <= j < len(order) and closed[order[j]]]
        if not neighbours:
            continue
        ratio = upper[neighbours[0]] / lower[neighbours[0]]
        if np.isnan(upper[i]) and np.isfinite(lower[i]):
            upper[i] = lower[i] * ratio
        if np.isnan(lower[i]) and np.isfinite(upper[i]):
            lower[i] = upper[i] / ratio
    return np.sqrt(lower) * np.sqrt(upper)


def fit_ep_trend(size, ep, ep_low=None, ep_high=None, *, ci: float = 0.95) -> EpTrend:
    r"""Fit :math:`E_p = a d^{-b}` by weighted least squares on :math:`\ln E_p` (module docstring).

    Parameters
    ----------
    size : array_like
        Representative size of each fraction (> 0).
    ep : array_like
        Probable error of each fraction (> 0; NaN = not fitted, left out).
    ep_low, ep_high : array_like, optional
        The Ep intervals at level ``ci``: the weights.  Without them every fraction weighs
        the same.
    ci : float
        Level of the intervals given and of those returned.

    Returns
    -------
    EpTrend

    Examples
    --------
    >>> trend = fit_ep_trend([2.0, 4.0, 8.0, 16.0], [0.04, 0.04 * 2**-0.5, 0.02, 0.04 * 8**-0.5])
    >>> round(trend.a, 9), round(trend.b, 9)  # Ep = 0.04 (d/2)^-0.5 = 0.0566 d^-0.5
    (0.056568542, 0.5)
    """
    import scipy.stats
    import statsmodels.api as sm

    size, ep = np.asarray(size, dtype=float), np.asarray(ep, dtype=float)
    notes = []
    usable = np.isfinite(size) & (size > 0) & np.isfinite(ep) & (ep > 0)
    weighted = ep_low is not None and ep_high is not None
    weights = np.ones_like(ep)
    if weighted:
        low, high = np.asarray(ep_low, dtype=float), np.asarray(ep_high, dtype=float)
        z = scipy.stats.norm.ppf(0.5 + ci / 2.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            sd = (np.log(high) - np.log(low)) / (2.0 * z)
        has_interval = np.isfinite(sd) & (sd > 0)
        if (usable & ~has_interval).any():
            notes.append(f"{int((usable & ~has_interval).sum())} size fraction(s) without an Ep interval left out of the trend")
        usable &= has_interval
        weights = np.where(has_interval, 1.0 / np.where(has_interval, sd, 1.0) ** 2, 0.0)
    count = int(usable.sum())
    nan_pair = (math.nan, math.nan)
    if count < 2:
        notes.append(f"no trend: {count} size fraction(s) with an Ep, two are needed")
        return EpTrend(math.nan, math.nan, nan_pair, nan_pair, ci, count, weighted, "; ".join(notes))
    design = sm.add_constant(np.log(size[usable]))
    result = sm.WLS(np.log(ep[usable]), design, weights=weights[usable]).fit()
    log_a, slope = (float(value) for value in result.params)
    if count == 2:
        notes.append("two size fractions fix the line exactly: the trend has no interval")
        return EpTrend(math.exp(log_a), -slope, nan_pair, nan_pair, ci, count, weighted, "; ".join(notes), result)
    (log_a_low, log_a_high), (slope_low, slope_high) = result.conf_int(alpha=1.0 - ci)
    return EpTrend(
        math.exp(log_a),
        -slope,
        (math.exp(log_a_low), math.exp(log_a_high)),
        (-slope_high, -slope_low),
        ci,
        count,
        weighted,
        "; ".join(notes),
        result,
    )


def _fits_by_test_and_curve(fits) -> dict:
    groups: dict = {}
    for fit in fits:
        if fit.sample.has_size:
            groups.setdefault((fit.sample.test, fit.curve.id), []).append(fit)
    return groups


def by_size_table(fits, *, ci: float = 0.95) -> tuple[pd.DataFrame, pd.DataFrame]:
    """rho50, Ep and I per size fraction, and the Ep trend, of every test and curve with size fractions.

    Parameters
    ----------
    fits : iterable of DensityCurveFit
        Fits of samples with size fractions (others are skipped).
    ci : float
        Level of the fits' intervals (the weights of the trend) and of the trend's.

    Returns
    -------
    tuple of pandas.DataFrame
        ``(by_size, ep_trend)`` with the columns :data:`BY_SIZE_COLUMNS` and
        :data:`EP_TREND_COLUMNS` (defined in ``docs/density.md``); ``ep_trend`` in
        ``by_size`` is the trend's Ep at the fraction's size.
    """
    rows, trends = [], []
    for (test, curve), group in _fits_by_test_and_curve(fits).items():
        group = sorted(group, key=lambda fit: np.nan_to_num(fit.sample.size_lower, nan=0.0))
        lower = np.array([fit.sample.size_lower for fit in group])
        upper = np.array([fit.sample.size_upper for fit in group])
        sizes = representative_sizes(lower, upper)
        block = [_fraction_row(fit, size) for fit, size in zip(group, sizes)]
        frame = pd.DataFrame(block)
        trend = fit_ep_trend(
            frame["size"], frame["ep"], frame["ep_low"] if frame["ep_low"].notna().any() else None,
            frame["ep_high"] if frame["ep_high"].notna().any() else None, ci=ci,
        )  # fmt: skip
        frame["ep_trend"] = trend.ep_at(frame["size"]) if np.isfinite(trend.a) else np.nan
        rows.append(frame)
        trends.append(_trend_row(test, curve, group[0].sample.size_unit, trend))
    by_size = pd.concat(rows, ignore_index=True) if rows else pd.DataFrame()
    return by_size.reindex(columns=list(BY_SIZE_COLUMNS)), pd.DataFrame(trends, columns=list(EP_TREND_COLUMNS))


def _fraction_row(fit, size: float) -> dict:
    index = fit.indices
    row = {
        "test": fit.sample.test,
        "curve": fit.curve.id,
        "size_lower": fit.sample.size_lower,
        "size_upper": fit.sample.size_upper,
        "size": size,
        "size_unit": fit.sample.size_unit,
        "aic": fit.aic if fit.success else math.nan,
        "note": "; ".join(fit.notes) if fit.success else fit.message,
    }
    for name in ("rho50", "ep", "imperfection"):
        row[name] = getattr(index, name) if fit.success and index is not None else math.nan
        low, high = fit.intervals.get(name, (math.nan, math.nan)) if fit.success else (math.nan, math.nan)
        row[f"{name}_low"], row[f"{name}_high"] = low, high
    return row


def _trend_row(test: str, curve: str, unit: str, trend: EpTrend) -> dict:
    return {
        "test": test,
        "curve": curve,
        "size_unit": unit,
        "n_sizes": trend.n_sizes,
        "a": trend.a,
        "a_low": trend.a_interval[0],
        "a_high": trend.a_interval[1],
        "b": trend.b,
        "b_low": trend.b_interval[0],
        "b_high": trend.b_interval[1],
        "weighted": trend.weighted,
        "note": trend.note,
    }


def common_curve(by_size: pd.DataFrame, test: str) -> str | None:
    """The curve of ``test`` with the smallest AIC summed over its size fractions (every fraction fitted).

    The figures draw one curve for all fractions of a test, so that their Ep compare like
    with like; None when no curve fits every fraction.
    """
    rows = by_size[by_size["test"] == test]
    complete = rows.groupby("curve", sort=False)["aic"].agg(lambda aic: aic.sum() if aic.notna().all() else np.nan).dropna()
    return None if complete.empty else str(complete.idxmin())


# --- figures --------------------------------------------------------------------------------------
def plot_partition_surface(fits, *, test: str, curve: str, ax=None):
    """Partition to sinks (%) against density, one fitted curve and its points per size fraction.

    Parameters
    ----------
    fits : iterable of DensityCurveFit
    test, curve : str
        The test and the curve drawn.
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib.axes.Axes
    """
    import matplotlib

    if ax is None:
        from matplotlib.figure import Figure

        ax = Figure(figsize=(6.4, 4.2), layout="constrained").add_subplot()
    group = [fit for fit in fits if fit.sample.has_size and fit.sample.test == test and fit.curve.id == curve]
    group.sort(key=lambda fit: np.nan_to_num(fit.sample.size_lower, nan=0.0))
    colours = matplotlib.colormaps["viridis"](np.linspace(0.0, 0.85, max(len(group), 1)))
    points = [fit.sample.used for fit in group]
    low = min(float(p["density"].min()) for p in points) if points else 1.2
    high = max(float(p["density"].max()) for p in points) if points else 2.0
    grid = np.linspace(low - 0.05, high + 0.05, 400)
    for fit, colour, used in zip(group, colours, points):
        label = fit.sample.size_fraction
        ax.plot(used["density"], 100.0 * used["partition_sinks"], "o", color=colour, markersize=4)
        if fit.success:
            ep = fit.indices.ep
            label += f": rho50 {fit.indices.rho50:.3f}, Ep {ep:.3f}" if np.isfinite(ep) else ""
            ax.plot(grid, 100.0 * fit.partition(grid), "-", color=colour, label=label)
    ax.axhline(50.0, color="0.6", linewidth=0.8, linestyle=":")
    ax.set_xlabel("relative density (g/cm3)")
    ax.set_ylabel("partition to sinks (%)")
    ax.set_ylim(-2, 102)
    ax.set_title(f"{test}: {curve} curve per size fraction", fontsize=10)
    ax.legend(fontsize=7, frameon=False, loc="lower right")
    return ax


def plot_indices_by_size(by_size: pd.DataFrame, trends: pd.DataFrame, *, test: str, curve: str, axes=None):
    """Ep (log-log, with the fitted power law) and rho50 against size, with their intervals.

    Returns
    -------
    tuple of matplotlib.axes.Axes
        The Ep and the rho50 panels.
    """
    if axes is None:
        from matplotlib.figure import Figure

        figure = Figure(figsize=(8.4, 3.6), layout="constrained")
        axes = figure.subplots(1, 2)
    from matplotlib.ticker import FormatStrFormatter, NullFormatter

    ep_ax, rho_ax = axes
    rows = by_size[(by_size["test"] == test) & (by_size["curve"] == curve)].sort_values("size")
    unit = rows["size_unit"].iloc[0] if len(rows) else ""
    for ax, name in ((ep_ax, "ep"), (rho_ax, "rho50")):
        centre = rows[name].to_numpy(dtype=float)
        below = np.clip(centre - rows[f"{name}_low"].to_numpy(dtype=float), 0, None)
        above = np.clip(rows[f"{name}_high"].to_numpy(dtype=float) - centre, 0, None)
        errors = np.nan_to_num(np.vstack([below, above]))
        ax.errorbar(rows["size"], centre, yerr=errors, fmt="o", color="C0", capsize=3, label="per size fraction")
        ax.set_xscale("log")
        ax.set_xticks(rows["size"].to_numpy(dtype=float))
        ax.xaxis.set_major_formatter(FormatStrFormatter("%.3g"))
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel(f"size ({unit}, geometric mean of the fraction)" if unit else "size")
    trend = trends[(trends["test"] == test) & (trends["curve"] == curve)]
    if len(trend) and np.isfinite(trend["a"].iloc[0]):
        a, b = float(trend["a"].iloc[0]), float(trend["b"].iloc[0])
        sizes = np.geomspace(rows["size"].min() / 1.3, rows["size"].max() * 1.3, 100)
        ep_ax.plot(sizes, a * sizes ** (-b), "-", color="C1", label=f"Ep = {a:.3g} d^-{b:.3g}")
    ep_ax.set_yscale("log")
    for formatter in (ep_ax.yaxis.set_major_formatter, ep_ax.yaxis.set_minor_formatter):
        formatter(FormatStrFormatter("%.3g"))
    ep_ax.set_ylabel("probable error Ep (g/cm3)")
    ep_ax.legend(fontsize=7, frameon=False)
    rho_ax.set_ylabel("cut density rho50 (g/cm3)")
    ep_ax.set_title(f"{test}: Ep against size ({curve})", fontsize=10)
    rho_ax.set_title(f"{test}: rho50 against size ({curve})", fontsize=10)
    return ep_ax, rho_ax


def plot_by_size(fits, by_size: pd.DataFrame, trends: pd.DataFrame, *, test: str, curve: str | None = None):
    """One figure of a test: the partition surface, Ep and rho50 against size (``curve``: default :func:`common_curve`).

    Returns
    -------
    matplotlib.figure.Figure or None
        None when no curve fits every size fraction of the test.
    """
    from matplotlib.figure import Figure

    curve = curve or common_curve(by_size, test)
    if curve is None:
        return None
    figure = Figure(figsize=(13.0, 4.0), layout="constrained")
    surface, ep_ax, rho_ax = figure.subplots(1, 3)
    plot_partition_surface(fits, test=test, curve=curve, ax=surface)
    plot_indices_by_size(by_size, trends, test=test, curve=curve, axes=(ep_ax, rho_ax))
    return figure


def by_size_outputs(fits, *, ci: float = 0.95, figures: bool = True) -> dict:
    """The files ``tromplab density fit`` writes for tests with size fractions (none without).

    ``by_size.csv`` (:data:`BY_SIZE_COLUMNS`), ``ep_trend.csv`` (:data:`EP_TREND_COLUMNS`) and,
    with ``figures``, ``by_size_<test>.png`` per test (:func:`plot_by_size`).

    Returns
    -------
    dict
        File name -> writer taking the path (for :func:`tromplab.output.outputs.replace_folder`).
    """
    tables, pictures = by_size_artifacts(fits, ci=ci, figures=figures)
    return file_writers(tables, pictures=pictures)


def by_size_artifacts(fits, *, ci: float = 0.95, figures: bool = True) -> tuple[dict, dict]:
    """The tables (``by_size``, ``ep_trend``) and PNG figures (file name -> bytes) of the tests with size fractions.

    Both empty when no test has size fractions; :func:`by_size_outputs` writes them, the
    workbook and the report show them.
    """
    from ..output.outputs import figure_file_names

    fits = [fit for fit in fits if fit.sample.has_size]
    if not fits:
        return {}, {}
    by_size, trends = by_size_table(fits, ci=ci)
    pictures = {}
    if figures:
        tests = list(dict.fromkeys(by_size["test"]))
        for test, name in figure_file_names(tests, prefix="by_size_").items():
            figure = plot_by_size(fits, by_size, trends, test=test)
            if figure is not None:
                buffer = io.BytesIO()
                figure.savefig(buffer, dpi=120, format="png")
                pictures[name] = buffer.getvalue()
    return {"by_size": by_size, "ep_trend": trends}, pictures
