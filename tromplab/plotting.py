"""Figures of separation curves.

Plot functions take ``ax=None`` (a new figure is made) and return the Axes; nothing is
shown, and no style is set on import: scripts choose the seaborn theme.
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from .curves import CurveFit


def _axes(ax):
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(7.5, 5.0))
    return ax


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
    import matplotlib.pyplot as plt

    ax.figure.tight_layout()
    to_file = isinstance(path, (str, os.PathLike))
    ax.figure.savefig(path, dpi=dpi, format=None if to_file else "png")
    plt.close(ax.figure)


def curve_band(fit: CurveFit, size, *, level: float = 0.95):
    """Pointwise delta-method band of a fitted curve: ``(low, high)`` at ``size``.

    Standard errors by :func:`tromplab.uncertainty.delta_standard_errors`.
    """
    from scipy import stats

    from .uncertainty import delta_standard_errors

    size = np.asarray(size, dtype=float)
    centre = fit.predict(size)
    se = delta_standard_errors(fit, lambda values: fit.predict(size, values))
    half = stats.t.ppf(0.5 + level / 2, max(fit.points.n - len(fit.fit.names), 1)) * se
    return np.clip(centre - half, 0, 1), np.clip(centre + half, 0, 1)


def plot_tromp_fits(fits: Sequence[CurveFit], *, ax=None, log_size: bool = True, size_unit: str = "", band: bool = True,
                    best: CurveFit | None = None):  # fmt: skip
    """Measured Tromp points of one experiment with the fitted curves of every formula.

    Adequate fits are drawn solid, inadequate ones dashed; the best fit is drawn thick
    with its cut size marked: ``best`` when given (the top-ranked fit), otherwise the
    paper formula with the lowest sum of squares.  Failed fits are left out and
    named in the legend title.

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

    Returns
    -------
    matplotlib Axes
    """
    import seaborn as sns

    ax = _axes(ax)
    if not fits:
        raise ValueError("no fits to plot")
    points = fits[0].points
    good = [f for f in fits if f.success]
    failed = [f.formula.id for f in fits if not f.success]
    low, high = points.size.min(), points.size.max()
    if log_size:
        grid = np.geomspace(low / 1.5, high * 1.5, 400)
    else:
        grid = np.linspace(0.0, high * 1.1, 400)[1:]
    colours = sns.color_palette("tab10", n_colors=max(len(fits), 1))
    if best is None and good:
        candidates = [f for f in good if f.formula.family == "paper"] or good
        best = min(candidates, key=lambda f: f.fit.ssr)
    for colour, fit in zip(colours, fits):
        if not fit.success:
            continue
        adequate = fit.screen is not None and fit.screen.adequate
        is_best = fit is best
        label = f"({fit.formula.equation}) {fit.formula.id}, F={fit.screen.F:.3g}" + ("" if adequate else " (inadequate)")
        ax.plot(grid, fit.predict(grid), color=colour, lw=2.8 if is_best else 1.2,
                ls="-" if adequate else "--", label=label, zorder=3 if is_best else 2)  # fmt: skip
    ax.plot(points.size, points.partition_fine, "ko", ms=6, label="measured", zorder=4)
    if best is not None:
        if band:
            low, high = curve_band(best, grid)
            ax.fill_between(grid, low, high, color="0.5", alpha=0.2, lw=0, label=f"95 % band, {best.formula.id}")
        ax.axvline(best.d_cut, color="0.4", lw=0.8, ls=":")
        ax.annotate(f"d_cut = {best.d_cut:.4g}", (best.d_cut, 0.5), xytext=(6, 6), textcoords="offset points", fontsize=8)
    if log_size:
        ax.set_xscale("log")
    unit = f" [{plain_text(size_unit)}]" if size_unit else ""
    ax.set_xlabel(f"particle size{unit}")
    ax.set_ylabel("partition to fines")
    ax.set_ylim(-0.03, 1.03)
    ax.set_title(f"Experiment {plain_text(points.experiment)}")
    title = f"failed: {', '.join(failed)}" if failed else None
    ax.legend(fontsize=7, title=title, title_fontsize=7, loc="best")
    return ax


def plot_pareto(result, *, ax=None):
    """Pareto front of a :class:`tromplab.choice.ChoiceResult` in the criteria plane, with the
    single-criterion optima and the compromise marked.  Returns the Axes."""
    ax = _axes(ax)
    first, second = list(result.ranges)
    front = result.pareto.sort_values(first)
    ax.plot(front[first], front[second], "o-", color="0.3", ms=4, label="Pareto front (linear convolution)")
    for optimum, label, marker in [(result.best_first, f"max {first}", "s"), (result.best_second, f"max {second}", "D"),
                                   (result.compromise, "compromise (max-min)", "*")]:  # fmt: skip
        ax.plot(optimum.point[first], optimum.point[second], marker, ms=11 if marker == "*" else 8, label=label)
    ax.set_xlabel(first)
    ax.set_ylabel(second)
    ax.legend(fontsize=8)
    return ax


def plot_residuals(fits: Sequence[CurveFit], *, ax=None, size_unit: str = ""):
    """Residuals (measured - fitted) against size, one line per successful formula."""
    import seaborn as sns

    ax = _axes(ax)
    good = [f for f in fits if f.success]
    colours = sns.color_palette("tab10", n_colors=max(len(good), 1))
    for colour, fit in zip(colours, good):
        residual = fit.points.partition_fine - fit.predict(fit.points.size)
        ax.plot(fit.points.size, residual, "o-", color=colour, ms=3, lw=0.8, label=f"({fit.formula.equation}) {fit.formula.id}")
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_xscale("log")
    ax.set_xlabel(f"particle size{f' [{size_unit}]' if size_unit else ''}")
    ax.set_ylabel("residual (measured - fitted)")
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
    sns.heatmap(positive, ax=ax, annot=text, fmt="", cmap="viridis", norm=LogNorm(), cbar_kws={"label": "F (log scale)"},
                annot_kws={"fontsize": 7})  # fmt: skip
    critical = table.groupby("experiment", sort=False)["F_crit"].first().reindex(f_values.columns)
    ax.set_xticklabels([f"{e}\nF_crit {c:.3g}" for e, c in critical.items()], rotation=0, fontsize=7)
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


def plot_equal_slope_family(slope: float, *, ax=None, formulas=None, x_max: float = 3.0):
    """The formulas at equal slope ``slope`` at the cut (Fig. 1 at -0.5, Fig. 2 at -0.4 of
    Shuvalov et al. 2018), against the relative size x = size / d_cut."""
    from .formulas import FORMULAS

    ax = _axes(ax)
    x = np.linspace(1e-3, x_max, 600)
    for formula in formulas or FORMULAS[:7]:
        shape = formula.shape_for_slope(slope)
        ax.plot(x, formula.phi(x, shape, **formula.defaults), label=f"({formula.equation}) {formula.id}, {formula.shape_name}={shape:.4g}")
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
    :func:`tromplab.sieve.geometric_probability_curves`)."""
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
    from .sieve import distance_pdf

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
