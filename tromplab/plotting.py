"""Figures of separation curves.

Plot functions take ``ax=None`` (a new figure is made) and return the Axes; nothing is
shown, and no style is set on import: scripts choose the seaborn theme.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .curves import CurveFit


def _axes(ax):
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(7.5, 5.0))
    return ax


def plot_tromp_fits(fits: Sequence[CurveFit], *, ax=None, log_size: bool = True, size_unit: str = ""):
    """Measured Tromp points of one experiment with the fitted curves of every formula.

    Adequate fits are drawn solid, inadequate ones dashed; the best fit (lowest sum of
    squares) is drawn thick with its cut size marked.  Failed fits are left out and
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
    best = min(good, key=lambda f: f.fit.ssr) if good else None
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
        ax.axvline(best.d_cut, color="0.4", lw=0.8, ls=":")
        ax.annotate(f"d_cut = {best.d_cut:.4g}", (best.d_cut, 0.5), xytext=(6, 6), textcoords="offset points", fontsize=8)
    if log_size:
        ax.set_xscale("log")
    unit = f" [{size_unit}]" if size_unit else ""
    ax.set_xlabel(f"particle size{unit}")
    ax.set_ylabel("partition to fines")
    ax.set_ylim(-0.03, 1.03)
    ax.set_title(f"Experiment {points.experiment}")
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
