"""Figures of separation curves.

Plot functions take ``ax=None`` (a new figure is made) and return the Axes; nothing is
shown, and no style is set on import: scripts choose the seaborn theme.
"""

from __future__ import annotations

import functools
import io
import os
import threading
from collections.abc import Sequence

import numpy as np

from ..classifiers.sieve import distance_pdf
from ..curves.curve_fit import CurveFit
from ..curves.formulas import select_formulas
from ..curves.intervals import delta_standard_errors
from ..curves.ranking import top_ranked
from .views import check_partition_to

#: Colours of up to 12 curves: tab10, then a dark indigo and a dark green, as far from every tab10 colour
#: as the tab10 colours are from each other (RGB distance >= 0.26).
CURVE_COLOURS = (
    "#1f77b4",
    "#ff7f0e",
    "#2ca02c",
    "#d62728",
    "#9467bd",
    "#8c564b",
    "#e377c2",
    "#7f7f7f",
    "#bcbd22",
    "#17becf",
    "#393b79",
    "#00441b",
)
#: Line styles cycled beside the colours, so curves stay apart in grey print too.
CURVE_LINESTYLES = ("-", "--", "-.", ":")


def curve_styles(n: int) -> list[dict]:
    """Colour and line style of ``n`` curves: every curve a different colour up to 12
    curves, and consecutive curves a different line style; beyond 12 the colours repeat
    with the line styles shifted, so up to 48 curves keep distinct styles.

    Examples
    --------
    >>> styles = curve_styles(12)
    >>> len({s["color"] for s in styles}), styles[0]["ls"], styles[1]["ls"]
    (12, '-', '--')
    """
    rounds = len(CURVE_COLOURS)
    return [
        {"color": CURVE_COLOURS[i % rounds], "ls": CURVE_LINESTYLES[(i + i // rounds) % len(CURVE_LINESTYLES)]} for i in range(n)
    ]


def log_size_axis(ax, low: float, high: float) -> None:
    """Log-scaled size axis with plain-number tick labels that do not run into each other.

    Matplotlib labels minor ticks of a log axis spanning less than about a decade, and
    those labels collide; here only major ticks are labelled: round linear steps within
    half a decade, then 1-2-3-5-7, 1-2-5 or 1 per decade as the span allows (the locator
    thins to every k-th decade beyond about ten decades).
    """
    from matplotlib.ticker import FuncFormatter, LogLocator, MaxNLocator, NullFormatter

    ax.set_xscale("log")
    decades = np.log10(high / low)
    if decades < 0.5:  # within half a decade a log axis is nearly linear: round linear steps
        ax.xaxis.set_major_locator(MaxNLocator(nbins=5, steps=[1, 2, 2.5, 5, 10]))
    else:
        subs = (1.0, 2.0, 3.0, 5.0, 7.0) if decades < 1.2 else (1.0, 2.0, 5.0) if decades < 3.0 else (1.0,)
        ax.xaxis.set_major_locator(LogLocator(base=10.0, subs=subs, numticks=12))
    ax.xaxis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
    ax.xaxis.set_minor_locator(LogLocator(base=10.0, subs=np.arange(2, 10) * 1.0, numticks=12))
    ax.xaxis.set_minor_formatter(NullFormatter())


def _axes(ax):
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(7.5, 5.0))
    return ax


def offscreen_axes(nrows: int = 1, ncols: int = 1, *, figsize=(7.5, 5.0)):
    """Axes of a figure made without pyplot, for figures written to files: no backend is
    chosen or changed (the user's stays as it is) and no figure is left open.

    The figure draws on an Agg canvas whose renderer it shares with the other figures of this
    thread of the same pixel size and resolution (:func:`_shared_renderer_canvas`)."""
    from matplotlib.figure import Figure

    figure = Figure(figsize=figsize)
    _shared_renderer_canvas()(figure)
    return figure.subplots(nrows, ncols, squeeze=True)


#: Agg renderers kept per thread, one per (width, height, dpi) drawn (more are dropped and made again).
SHARED_RENDERERS = 8
_renderers = threading.local()


@functools.cache
def _shared_renderer_canvas():
    """The Agg canvas class of :func:`offscreen_axes`: its renderer is shared by the figures
    drawn in one thread at one pixel size and dpi, where matplotlib would make one for laying
    out a figure (``tight_layout``) and another for saving it, and new ones for every figure.

    Matplotlib remembers the size of each text (tick labels, axis labels, legend entries) per
    renderer: a shared renderer measures ``0.2`` or ``particle size [um]`` once, not in each
    figure twice (drawing, laying out and saving 40 figures of a report: 20 % less time).  The
    picture is the same: every drawing clears the renderer first, a figure is saved as soon
    as it is drawn, and the renderers are per thread (matplotlib's fonts are not shared safely
    between threads)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg, RendererAgg

    class SharedRendererCanvas(FigureCanvasAgg):
        def get_renderer(self):
            width, height = self.get_width_height(physical=True)
            key = (width, height, self.figure.dpi)
            kept = _renderers.__dict__.setdefault("by_size", {})
            if key not in kept:
                if len(kept) >= SHARED_RENDERERS:
                    kept.clear()
                kept[key] = RendererAgg(width, height, self.figure.dpi)
            self.renderer = kept[key]
            return self.renderer

    return SharedRendererCanvas


def plain_text(text, *, max_length: int = 80) -> str:
    """``text`` shown literally by matplotlib: ``$`` escaped (no mathtext), control
    characters dropped, cut to ``max_length`` characters with an ellipsis.

    Examples
    --------
    >>> print(plain_text("a $x_1^2$ run"))
    a \\$x_1^2\\$ run
    """
    text = "".join(ch for ch in str(text) if ch.isprintable())
    if len(text) > max_length:
        text = text[: max_length - 1] + "\u2026"
    return text.replace("$", r"\$")


def save_figure(ax, path, *, dpi: int = 120) -> None:
    """Lay out the Axes' figure, save it (format from the file name or a file object) and close it."""
    figure = ax.figure
    figure.tight_layout()
    # tight_layout leaves a placeholder layout engine, for which savefig renders the figure
    # twice more before the real rendering (one of them to a PNG it throws away): without an
    # engine the same bytes come out in about 2/3 of the time
    figure.set_layout_engine(None)
    to_file = isinstance(path, (str, os.PathLike))
    figure.savefig(path, dpi=dpi, format=None if to_file else "png")
    if figure.canvas.manager is not None:  # made by pyplot: release it from pyplot's list of open figures
        import matplotlib.pyplot as plt

        plt.close(figure)


def figure_png(ax, *, dpi: int = 120) -> bytes:
    """The Axes' figure laid out and saved as PNG bytes (:func:`save_figure`), then closed."""
    buffer = io.BytesIO()
    save_figure(ax, buffer, dpi=dpi)
    return buffer.getvalue()


def figure_pngs(ax, dpis: Sequence[int]) -> list[bytes]:
    """The Axes' figure laid out once and saved as PNG bytes at each of ``dpis``: the same bytes
    as :func:`figure_png` at each, without drawing and laying out the figure again for each."""
    figure = ax.figure
    figure.tight_layout()
    figure.set_layout_engine(None)  # as save_figure does: the layout stays as tight_layout left it
    pictures = []
    for dpi in dpis:
        buffer = io.BytesIO()
        figure.savefig(buffer, dpi=dpi, format="png")
        pictures.append(buffer.getvalue())
    return pictures


def curve_band(fit: CurveFit, size, *, level: float = 0.95):
    """Pointwise delta-method band of a fitted curve: ``(low, high)`` at ``size``.

    Standard errors by :func:`tromplab.curves.intervals.delta_standard_errors`.
    """
    from scipy import stats

    size = np.asarray(size, dtype=float)
    centre = fit.predict(size)
    se = delta_standard_errors(fit, lambda values: fit.predict(size, values))
    half = stats.t.ppf(0.5 + level / 2, max(fit.points.n - len(fit.fit.names), 1)) * se
    return np.clip(centre - half, 0, 1), np.clip(centre + half, 0, 1)


def plot_tromp_fits(
    fits: Sequence[CurveFit],
    *,
    ax=None,
    log_size: bool = True,
    size_unit: str = "",
    band: bool = True,
    best: CurveFit | None = None,
    partition_to: str = "fine",
):
    """Measured Tromp points of one experiment with the fitted curves of every formula.

    Each formula has its own colour and line style (:func:`curve_styles`); inadequate
    fits are drawn faded and labelled so; the best fit is drawn thick with its cut size
    marked: ``best`` when given (the top-ranked fit), otherwise the paper formula with
    the lowest sum of squares.  Failed fits are left out and named in the legend title.

    Parameters
    ----------
    fits : sequence of CurveFit
        Fits to the same experiment.
    ax : matplotlib Axes, optional
    log_size : bool
        Logarithmic size axis.
    size_unit : str
        Unit shown in the axis label.
    band : bool
        Shade the 95 % delta-method band of the best fit.
    partition_to : {"fine", "coarse"}
        Draw the partition to the fine product (default) or to the coarse product
        (underflow, oversize), ``1 - phi``.

    Returns
    -------
    matplotlib Axes
    """
    ax = _axes(ax)
    if not fits:
        raise ValueError("no fits to plot")
    points = fits[0].points
    good = [f for f in fits if f.success]
    failed = [f.formula.id for f in fits if not f.success]
    low, high = points.size.min(), points.size.max()
    grid = np.geomspace(low / 1.5, high * 1.5, 400) if log_size else np.linspace(0.0, high * 1.1, 400)[1:]
    if best is None and good:  # the paper formula with the lowest sum of squares
        best = min([f for f in good if f.formula.family == "paper"] or good, key=lambda f: f.fit.ssr)
    read = _partition_reader(partition_to)
    _draw_fitted_curves(ax, fits, best, grid, read)
    ax.plot(points.size, read(points.partition_fine), "ko", ms=6, label="measured", zorder=4)
    if best is not None:
        _mark_best_fit(ax, best, grid, read, band=band)
    if log_size:
        log_size_axis(ax, grid[0], grid[-1])
    unit = f" [{plain_text(size_unit)}]" if size_unit else ""
    ax.set_xlabel(f"particle size{unit}")
    ax.set_ylabel(f"partition to {'fines' if partition_to == 'fine' else 'coarse product'}")
    ax.set_ylim(-0.03, 1.03)
    ax.set_title(f"Experiment {plain_text(points.experiment)}")
    title = f"failed: {', '.join(failed)}" if failed else None
    ax.legend(fontsize=7, title=title, title_fontsize=7, loc="best")
    return ax


def _draw_fitted_curves(ax, fits: Sequence[CurveFit], best: CurveFit | None, grid, read) -> None:
    """One line per successful fit in its registry style: the best thick, the inadequate faint."""
    for style, fit in zip(curve_styles(len(fits)), fits):
        if not fit.success:
            continue
        adequate = fit.screen is not None and fit.screen.adequate
        is_best = fit is best
        label = f"({fit.formula.equation}) {fit.formula.id}, F={fit.screen.F:.3g}" + ("" if adequate else " (inadequate)")
        ax.plot(
            grid,
            read(fit.predict(grid)),
            **style,
            lw=2.8 if is_best else 1.3,
            alpha=1.0 if adequate else 0.45,
            label=label,
            zorder=3 if is_best else 2,
        )


def _mark_best_fit(ax, best: CurveFit, grid, read, *, band: bool) -> None:
    """The best fit's cut size marked on ``ax`` and, with ``band``, its 95 % delta-method band shaded.

    No band is drawn where the fit's intervals are withheld because the points do not bracket
    the cut (``CurveFit.unbracketed``): the legend says so instead.
    """
    if band and best.unbracketed:
        ax.plot([], [], " ", label="no 95 % band: the points do not bracket the cut")
    elif band:
        low, high = sorted((read(bound) for bound in curve_band(best, grid)), key=np.sum)
        ax.fill_between(grid, low, high, color="0.5", alpha=0.2, lw=0, label=f"95 % band, {best.formula.id}")
    ax.axvline(best.d_cut, color="0.4", lw=0.8, ls=":")
    ax.annotate(f"d_cut = {best.d_cut:.4g}", (best.d_cut, 0.5), xytext=(6, 6), textcoords="offset points", fontsize=8)


def _partition_reader(partition_to: str):
    """Turn partitions to fines into the reading asked for."""
    if check_partition_to(partition_to) == "fine":
        return lambda phi: np.asarray(phi, dtype=float)
    return lambda phi: 1.0 - np.asarray(phi, dtype=float)


def plot_pareto(result, *, ax=None):
    """Pareto front of a :class:`tromplab.classifiers.choice.ChoiceResult` in the criteria plane, with the
    single-criterion optima and the compromise marked.  Returns the Axes."""
    ax = _axes(ax)
    first, second = list(result.ranges)
    front = result.pareto.sort_values(first)
    ax.plot(front[first], front[second], "o-", color="0.3", ms=4, label="Pareto front (linear convolution)")
    for optimum, label, marker in [
        (result.best_first, f"max {first}", "s"),
        (result.best_second, f"max {second}", "D"),
        (result.compromise, "compromise (max-min)", "*"),
    ]:
        ax.plot(optimum.point[first], optimum.point[second], marker, ms=11 if marker == "*" else 8, label=label)
    ax.set_xlabel(first)
    ax.set_ylabel(second)
    ax.legend(fontsize=8)
    return ax


def plot_residuals(fits: Sequence[CurveFit], *, ax=None, size_unit: str = "", partition_to: str = "fine"):
    """Residuals (measured - fitted) against size, one line per successful formula
    (of the partition to fines, or to the coarse product with ``partition_to="coarse"``,
    where every residual changes sign)."""
    ax = _axes(ax)
    good = [f for f in fits if f.success]
    read = _partition_reader(partition_to)
    for style, fit in zip(curve_styles(len(good)), good):
        residual = read(fit.points.partition_fine) - read(fit.predict(fit.points.size))
        ax.plot(fit.points.size, residual, marker="o", **style, ms=3, lw=0.8, label=f"({fit.formula.equation}) {fit.formula.id}")
    ax.axhline(0.0, color="k", lw=0.8)
    if good:
        sizes = np.concatenate([f.points.size for f in good])
        log_size_axis(ax, sizes.min(), sizes.max())
    else:
        ax.set_xscale("log")
    ax.set_xlabel(f"particle size{f' [{size_unit}]' if size_unit else ''}")
    ax.set_ylabel(f"residual of the partition to {'fines' if partition_to == 'fine' else 'coarse product'} (measured - fitted)")
    ax.legend(fontsize=7, ncol=2)
    return ax


def plot_f_heatmap(fits_table, *, ax=None):
    """Fisher's F per formula (rows) and experiment (columns), log colour scale; inadequate
    cells (F <= F_crit) marked with a star and F_crit given under each experiment."""
    import seaborn as sns
    from matplotlib.colors import LogNorm

    ax = _axes(ax)
    table = fits_table[fits_table["success"]].copy()
    table["label"] = "(" + table["equation"].astype(int).astype(str) + ") " + table["formula"]
    f_values = table.pivot(index="label", columns="experiment", values="F")
    f_values = f_values.reindex(index=list(dict.fromkeys(table["label"])), columns=list(dict.fromkeys(table["experiment"])))
    adequate = table.pivot(index="label", columns="experiment", values="adequate").reindex_like(f_values)
    text = f_values.map(lambda v: f"{v:.3g}") + adequate.map(lambda a: "" if a else "*")
    positive = f_values.where(f_values > 0)
    sns.heatmap(
        positive,
        ax=ax,
        annot=text,
        fmt="",
        cmap="viridis",
        norm=LogNorm(),
        cbar_kws={"label": "F (log scale)"},
        annot_kws={"fontsize": 7},
    )
    critical = table.groupby("experiment", sort=False)["F_crit"].first().reindex(f_values.columns)
    # seaborn labels only every k-th column of a wide table: label the ticks it kept (column i at i + 0.5)
    shown = [int(tick) for tick in ax.get_xticks()]
    ax.set_xticks([i + 0.5 for i in shown], [f"{critical.index[i]}\nF_crit {critical.iloc[i]:.3g}" for i in shown])
    ax.tick_params(axis="x", labelrotation=0, labelsize=7)
    ax.set_xlabel("experiment (* = inadequate, F <= F_crit)")
    ax.set_ylabel("")
    return ax


def plot_ranking(ranking, *, ax=None):
    """Points of each formula across experiments (lower is better), labelled with the place."""
    import seaborn as sns

    ax = _axes(ax)
    ordered = ranking.sort_values("points")
    label_column = "formula" if "formula" in ordered.columns else "equation"
    labels = [f"{row[label_column]}" for _, row in ordered.iterrows()]
    sns.barplot(x=ordered["points"].to_numpy(), y=labels, ax=ax, hue=labels, palette="crest", legend=False)
    for i, (points, place) in enumerate(zip(ordered["points"], ordered["place"])):
        ax.annotate(f"place {place}", (points, i), xytext=(4, 0), textcoords="offset points", va="center", fontsize=8)
    ax.set_xlabel("points (sum of ranks, inadequate ranks counted twice)")
    return ax


#: The equations Figs. 1 and 2 of Shuvalov et al. (2018) draw at equal slope: (3) to (9), the curves without a break.
EQUAL_SLOPE_FIGURE_EQUATIONS = (3, 4, 5, 6, 7, 8, 9)


def plot_equal_slope_family(slope: float, *, ax=None, formulas=None, x_max: float = 3.0):
    """The formulas at equal slope ``slope`` at the cut (Fig. 1 at -0.5, Fig. 2 at -0.4 of
    Shuvalov et al. 2018), against the relative size x = size / d_cut; by default those the
    figures draw (:data:`EQUAL_SLOPE_FIGURE_EQUATIONS`)."""
    ax = _axes(ax)
    x = np.linspace(1e-3, x_max, 600)
    for formula in formulas or select_formulas(EQUAL_SLOPE_FIGURE_EQUATIONS):
        shape = formula.shape_for_slope(slope)
        ax.plot(
            x,
            formula.phi(x, shape, **formula.defaults),
            label=f"({formula.equation}) {formula.id}, {formula.shape_name}={shape:.4g}",
        )
    ax.axvline(1.0, color="0.5", lw=0.8, ls=":")
    ax.set_xlabel("relative size x = size / d_cut")
    ax.set_ylabel("partition to fines")
    ax.set_title(f"Equal slope {slope:g} at the cut")
    ax.legend(fontsize=7)
    return ax


def plot_plitt_lognormal_relation(*, ax=None, ks=None):
    """Fig. 3 of Shuvalov et al. (2018): kf against ks at equal slope, the corrected
    relation (19) kf = 4/(sqrt(pi) ks) beside the printed 4/sqrt(pi ks), on ks 1..3 by default."""
    ax = _axes(ax)
    ks = np.linspace(1.0, 3.0, 100) if ks is None else np.asarray(ks, dtype=float)
    ax.plot(ks, 4 / (np.sqrt(np.pi) * ks), label="kf = 4/(sqrt(pi) ks)  (corrected (19))")
    ax.plot(ks, 4 / np.sqrt(np.pi * ks), ls="--", label="kf = 4/sqrt(pi ks)  (as printed)")
    ax.set_xlabel("ks (Plitt, (7))")
    ax.set_ylabel("kf (log-normal, (9))")
    ax.legend(fontsize=8)
    return ax


def plot_geometric_probability(curves, *, ax=None):
    """P_g against D/l for several shape factors (a frame from
    :func:`tromplab.classifiers.sieve.geometric_probability_curves`)."""
    ax = _axes(ax)
    for factor, group in curves.groupby("shape_factor"):
        ax.plot(group["D_over_l"], group["P_g"], label=f"d/l = {factor:g}")
    ax.set_xlabel("D / l")
    ax.set_ylabel("geometric probability P_g")
    ax.legend(fontsize=8)
    return ax


def plot_residue_and_efficiency(speeds, residues, efficiency, *, labels=("fraction 1", "fraction 2"), ax=None):
    """Residue share of two fractions and the sieve efficiency against the relative-speed amplitude."""
    ax = _axes(ax)
    for residue, label in zip(residues, labels):
        ax.plot(speeds, residue, label=f"residue, {label}")
    ax.set_xlabel("relative speed amplitude Va [m/s]")
    ax.set_ylabel("residue share gamma")
    twin = ax.twinx()
    twin.plot(speeds, efficiency, color="k", ls="--", label="efficiency E")
    twin.set_ylabel("efficiency E [%]")
    lines = ax.get_legend_handles_labels()
    more = twin.get_legend_handles_labels()
    ax.legend(lines[0] + more[0], lines[1] + more[1], fontsize=8, loc="center right")
    return ax


def plot_distance_densities(decks: int, c_values, *, bin_edges=None, labels=None, ax=None, x_max: float | None = None):
    """Densities f_m of the distance travelled on the bottom deck for several fractions
    (one ``C`` each), with the collecting bin shaded."""
    ax = _axes(ax)
    c_values = list(c_values)
    x_max = x_max or 2.5 * np.sqrt(2 * decks / min(c_values))
    x = np.linspace(0, x_max, 600)
    for i, c in enumerate(c_values):
        label = labels[i] if labels else f"C = {c:.3g}"
        ax.plot(x, distance_pdf(x, decks, c), label=label)
    if bin_edges is not None:
        ax.axvspan(*bin_edges, color="0.8", alpha=0.5, label=f"bin [{bin_edges[0]:.3g}, {bin_edges[1]:.3g}]")
    ax.set_xlabel("distance along the bottom deck x")
    ax.set_ylabel(f"density f_{decks}(x)")
    ax.legend(fontsize=8)
    return ax


def plot_batch_overview(fits_table, *, axes=None):
    """Overview of a large batch: distributions of d_cut, Ep and eta of each experiment's
    top-ranked fit, and how often each formula ranked first.

    Parameters
    ----------
    fits_table : pandas.DataFrame
        ``Workbench.fits_table()`` (columns ``experiment, formula, rank, d_cut, ep, eta``), or
        the top-ranked rows of a streamed batch with ``tied`` (how many formulas share the
        first place). An experiment whose first place is tied is shown by the first of its
        tied formulas, counted in the bar ``(tied first place)`` and in the title.
    axes : array of 4 matplotlib Axes, optional

    Returns
    -------
    ndarray of matplotlib Axes
    """
    import numpy as np
    import pandas as pd

    if axes is None:
        import matplotlib.pyplot as plt

        _, axes = plt.subplots(2, 2, figsize=(9, 6.5))
    axes = np.asarray(axes).ravel()
    best = fits_table if "tied" in fits_table else top_ranked(fits_table)  # a streamed batch's rows are the top ones
    tied = best["tied"].to_numpy(dtype=float) > 1
    for ax, column, label in zip(axes[:3], ("d_cut", "ep", "eta"), ("cut size d_cut", "Ecart probable Ep", "efficiency eta")):
        values = best[column].to_numpy(dtype=float)
        values = values[np.isfinite(values)]
        ax.hist(values, bins=min(40, max(5, int(np.sqrt(values.size)))) if values.size else 5, color="0.45")
        ax.set_xlabel(f"{label} (top-ranked fit)")
        ax.set_ylabel("experiments")
    wins = best.loc[~tied, "formula"].value_counts()
    if tied.any():  # formulas sharing the first place: no one of them wins the experiment
        wins = pd.concat([wins, pd.Series({"(tied first place)": int(tied.sum())})])
    axes[3].barh(wins.index[::-1], wins.to_numpy()[::-1], color="0.45")
    axes[3].set_xlabel("experiments where the formula ranks first")
    title = f"{best['experiment'].nunique()} experiments"
    if tied.any():
        title += f" ({int(tied.sum())} with formulas tied at the first place: the first of them shown above)"
    axes[0].figure.suptitle(title)
    return axes


def plot_control_chart(result, quantity: str, *, ax=None, size_unit: str = ""):
    """Control chart of one quantity of a :class:`~tromplab.trend.TrendResult` against the date.

    The survey values with their intervals, the baseline period shaded with its mean, the
    EWMA line with its limits, and the flagged surveys (changed) marked.
    """
    ax = _axes(ax)
    rows = result.table[result.table["quantity"] == quantity]
    dates = rows["date"]
    base = rows[rows["baseline"]]
    ax.axvspan(base["date"].min(), base["date"].max(), color="0.92", label="baseline")
    error = np.vstack([rows["value"] - rows["low"], rows["high"] - rows["value"]])
    ax.errorbar(
        dates,
        rows["value"],
        yerr=np.where(np.isfinite(error), np.abs(error), 0.0),
        fmt="o",
        color="0.3",
        ms=4,
        capsize=2,
        lw=0.8,
        label=f"survey value ({result.level:.0%} interval)",
    )
    centre = float(base["value"].mean())
    ax.axhline(centre, color="0.5", lw=0.8, ls=":", label="baseline mean")
    ax.plot(dates, rows["ewma"], color="C0", lw=1.6, label="EWMA")
    ax.step(dates, rows["ewma_low"], where="mid", color="C3", lw=1.0, ls="--", label="EWMA limits")
    ax.step(dates, rows["ewma_high"], where="mid", color="C3", lw=1.0, ls="--")
    flagged = rows[rows["changed"]]
    if len(flagged):
        ax.scatter(flagged["date"], flagged["value"], s=80, facecolors="none", edgecolors="C3", lw=1.5, label="changed", zorder=5)
    unit = {"size": size_unit, "fraction": "fraction"}.get(rows["unit"].iloc[0], "")
    label = {
        "d_cut": "cut size d_cut"
        + (" (corrected d50c)" if quantity == "d_cut" and "bypass" in set(result.table["quantity"]) else ""),
        "ep": "Ecart probable Ep",
        "eta": "classifier efficiency eta",
        "bypass": "bypass",
    }.get(quantity, quantity)
    ax.set_ylabel(f"{label} [{unit}]" if unit else label)
    ax.set_xlabel("survey date")
    ax.set_title(f"{quantity}: {result.formula_id}")
    ax.legend(fontsize=7, loc="best")
    ax.figure.autofmt_xdate()
    return ax
