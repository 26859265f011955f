"""Figures of density partition curves: partition to sinks (per cent) against relative density (linear).

Plot functions take ``ax=None`` (a new figure is made) and return the Axes; nothing is
shown and no style is set on import.
"""

from __future__ import annotations

import numpy as np

from ..output.plotting import curve_styles, plain_text
from .fitting import DensityCurveFit, partition_band, wilson_interval
from .readers import DensitySample


def _axes(ax):
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(7.5, 5.0))
    return ax


def plot_density_fits(
    sample: DensitySample, fits: list[DensityCurveFit], best: DensityCurveFit | None = None, *, ax=None, level: float = 0.95
):
    """The measured partition to sinks with its intervals, every fitted curve and the band of the best.

    Parameters
    ----------
    sample : DensitySample
        The data; tracer partitions carry their Wilson intervals at ``level``.
    fits : list of DensityCurveFit
        The curves drawn (failed fits are skipped).
    best : DensityCurveFit, optional
        Drawn thicker, with its pointwise delta-method band at ``level``
        (:func:`tromplab.density.fitting.partition_band`).
    ax : matplotlib Axes, optional
    level : float
        Level of the intervals and the band.

    Returns
    -------
    matplotlib Axes
    """
    ax = _axes(ax)
    points = sample.points
    used = points["used"].to_numpy(bool)
    density = points["density"].to_numpy(float)
    share = 100 * points["partition_sinks"].to_numpy(float)
    low, high = density.min(), density.max()
    pad = 0.1 * (high - low) if high > low else 0.05
    grid = np.linspace(low - pad, high + pad, 300)
    done = [fit for fit in fits if fit.success]
    for fit, style in zip(done, curve_styles(len(done))):
        thick = fit is best
        label = f"{fit.curve.id}" + (f" (best): rho50 {fit.indices.rho50:.3f}, Ep {fit.indices.ep:.3f}" if thick else "")
        style = {**style, "ls": "-"} if thick else style  # the best curve solid and thick, whatever its place in the cycle
        ax.plot(
            grid, 100 * fit.partition(grid), lw=2.4 if thick else 1.2, label=plain_text(label), zorder=3 if thick else 2, **style
        )
    if best is not None:
        band_low, band_high = partition_band(best, grid, level=level)
        if np.isfinite(band_low).all():
            ax.fill_between(
                grid, 100 * band_low, 100 * band_high, color="0.6", alpha=0.3, lw=0, label=f"{100 * level:g} % band of the best"
            )
    _draw_measured_points(ax, sample, density, share, used, level)
    if (~used).any():
        ax.plot(density[~used], np.nan_to_num(share[~used]), "x", color="0.4", label="left out")
    ax.set_xlabel("relative density (g/cm3)")
    ax.set_ylabel("partition to sinks (%)")
    ax.set_ylim(-2, 102)
    ax.set_title(plain_text(f"{sample.label}: density partition"))
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    return ax


def _draw_measured_points(ax, sample, density, share, used, level: float) -> None:
    """The measured partitions (per cent): tracer counts with their Wilson interval, other layouts as points."""
    if sample.layout != "tracers":
        ax.plot(density[used], share[used], "o", color="k", ms=4, zorder=4, label="measured partition")
        return
    points = sample.points
    recovered = points["recovered"].to_numpy()
    with np.errstate(all="ignore"):
        lo, hi = wilson_interval(points["sinks"].to_numpy(), np.maximum(recovered, 1), level=level)
    errors = np.clip(np.array([share - 100 * lo, 100 * hi - share]), 0, None)  # 0 where rounding puts a limit past the share
    ax.errorbar(density[used], share[used], yerr=errors[:, used], fmt="o", color="k", ms=4, capsize=2, zorder=4,
                label=f"tracers in the sinks (Wilson {100 * level:g} %)")  # fmt: skip


#: The probable errors of the catalogue's family figures (g/cm3) at the cut 1.5, and the limits of the variants.
FAMILY_EPS = (0.02, 0.05, 0.1)
FAMILY_LIMITS = {"light_limit": 0.05, "heavy_limit": 0.95}


def plot_density_curve_family(curve, *, ax=None, rho50: float = 1.5):
    """One density curve at the cut ``rho50`` and the probable errors :data:`FAMILY_EPS` (the catalogue's figure).

    A curve with limits is drawn with the limits :data:`FAMILY_LIMITS` and the same rho50
    and Ep of ``P`` itself (:meth:`~tromplab.density.registry.DensityCurve.from_indices`).

    Returns
    -------
    matplotlib Axes
    """
    from .registry import get_density_curve

    curve = get_density_curve(curve)
    ax = _axes(ax)
    grid = np.linspace(rho50 - 0.4, rho50 + 0.4, 400)
    limits = FAMILY_LIMITS if curve.has_limits else {}
    for ep, style in zip(FAMILY_EPS, curve_styles(len(FAMILY_EPS))):
        params = curve.from_indices(rho50=rho50, ep=ep, **limits)
        ax.plot(grid, 100 * curve.partition(grid, **params), label=f"Ep {ep:g}", **style)
    ax.axvline(rho50, color="0.5", lw=0.8)
    ax.axhline(50, color="0.5", lw=0.8)
    ax.set_xlabel("relative density (g/cm3)")
    ax.set_ylabel("partition to sinks (%)")
    ax.set_title(plain_text(f"{curve.id}: rho50 {rho50:g}" + (", limits 0.05 and 0.95" if limits else "")))
    ax.legend(fontsize=8, loc="upper left")
    ax.grid(True, alpha=0.3)
    return ax


def plot_density_overview(rows: list[dict], *, axes=None):
    """rho50 and Ep of the best curve of every test and size fraction, with their intervals (the overview of a campaign).

    Parameters
    ----------
    rows : list of dict
        One per test and size fraction: ``label``, ``rho50``, ``rho50_low``, ``rho50_high``,
        ``ep``, ``ep_low``, ``ep_high`` (the interval limits NaN when there are none).
    axes : two matplotlib Axes, optional
        Where rho50 (first) and Ep (second) are drawn; a new figure when None.

    Returns
    -------
    array of two matplotlib Axes
    """
    if axes is None:
        import matplotlib.pyplot as plt

        _, axes = plt.subplots(2, 1, figsize=(9.0, 6.5), sharex=True)
    position = np.arange(len(rows))
    for ax, name, label in zip(axes, ("rho50", "ep"), ("rho50 (g/cm3)", "Ep (g/cm3)")):
        value = np.array([row[name] for row in rows], dtype=float)
        low = np.array([row[f"{name}_low"] for row in rows], dtype=float)
        high = np.array([row[f"{name}_high"] for row in rows], dtype=float)
        errors = np.array([value - low, high - value])
        ax.errorbar(position, value, yerr=np.where(np.isfinite(errors), np.clip(errors, 0, None), 0.0), fmt="o", color="k",
                    ms=3, lw=0.8, capsize=1.5)  # fmt: skip
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[0].set_title(plain_text(f"best curve of each of {len(rows)} tests and size fractions (with intervals where made)"))
    axes[-1].set_xlabel("test and size fraction (in the order of fits.csv)")
    return axes
