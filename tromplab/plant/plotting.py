"""Figures of a plant prediction: yield against ash (theoretical and predicted), and the devices' partition curves.

Plot functions take ``ax=None`` (a new figure is made) and return the Axes; nothing is shown
and no style is set on import.
"""

from __future__ import annotations

import numpy as np

from ..output.plotting import curve_styles, plain_text
from .draws import parameter_draws
from .products import composite_washability, fraction_products, plant_products

#: Cut densities drawn along each predicted yield-ash curve.
CURVE_POINTS = 121


def _axes(ax):
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(7.5, 5.5))
    return ax


def _cumulative(washability):
    mass = np.append(0.0, np.cumsum(washability.mass_pct))
    ash_mass = np.append(0.0, np.cumsum(washability.mass_pct * washability.ash_pct))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(mass > 0, ash_mass / mass, np.nan), mass


def plot_yield_ash(prediction, *, ax=None):
    """Clean-coal yield against its ash: each size fraction's and the plant's theoretical curve (dashed: the
    cumulative floats), the curve its device makes as the cut moves (solid; the plant's: every cut moved
    by the same step) and the predicted point with its intervals.

    Returns
    -------
    matplotlib Axes
    """
    ax = _axes(ax)
    fractions, devices = prediction.fractions, prediction.devices
    offsets = np.linspace(-0.4, 0.6, CURVE_POINTS)
    moved = [fraction_products(f, d, np.clip(d.rho50 + offsets, 1.0 + 1e-6, 3.5), d.scale) for f, d in zip(fractions, devices)]
    composite = composite_washability(fractions)
    curves = [(f.name, f.washability, values) for f, values in zip(fractions, moved)]
    curves.append(("total", composite, plant_products(fractions, moved, composite)))
    products = prediction.products.set_index("size_fraction")
    for (name, washability, values), style in zip(curves, curve_styles(len(curves))):
        colour = style["color"]
        ash, mass = _cumulative(washability)
        ax.plot(ash, mass, ls="--", lw=1.0, color=colour)
        ax.plot(values["clean_ash_pct"], values["clean_yield_pct"], ls="-", lw=2.2 if name == "total" else 1.4, color=colour,
                label=plain_text(name))  # fmt: skip
        row = products.loc[name]
        errors = {}
        if "clean_yield_pct_low" in products.columns:
            errors = {"xerr": [[row["clean_ash_pct"] - row["clean_ash_pct_low"]], [row["clean_ash_pct_high"] - row["clean_ash_pct"]]],
                      "yerr": [[row["clean_yield_pct"] - row["clean_yield_pct_low"]],
                               [row["clean_yield_pct_high"] - row["clean_yield_pct"]]]}  # fmt: skip
            errors = {key: np.clip(value, 0, None) for key, value in errors.items()}
        ax.errorbar([row["clean_ash_pct"]], [row["clean_yield_pct"]], fmt="o", color=colour, ms=5, capsize=2, **errors)
    ax.set_xlabel("clean-coal ash (%)")
    ax.set_ylabel("clean-coal yield (% of the feed)")
    ax.set_ylim(0, 102)
    ax.set_title("yield against ash: theoretical (dashed), predicted (solid), operating point")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    return ax


def plot_partition_curves(prediction, *, ax=None):
    """The partition to sinks of every device against density, with its pointwise percentile band when uncertain.

    Returns
    -------
    matplotlib Axes
    """
    ax = _axes(ax)
    devices = prediction.devices
    low = min(f.washability.closed_lower[0] for f in prediction.fractions)
    high = max(f.washability.closed_upper[-1] for f in prediction.fractions)
    grid = np.linspace(low, high, 300)
    drawn = parameter_draws(devices, prediction.draws, prediction.seed)
    level = prediction.ci
    for device, (rho50, scale), style in zip(devices, drawn, curve_styles(len(devices))):
        label = f"{device.size_fraction}: {device.device} ({device.curve.id}), rho50 {device.rho50:.3f}"
        ax.plot(grid, 100 * device.partition(grid), lw=1.6, label=plain_text(label), **style)
        if device.uncertain and prediction.draws:
            curves = device.partition(grid[None, :], rho50[1:, None], scale[1:, None])
            band_low, band_high = np.quantile(curves, [(1 - level) / 2, (1 + level) / 2], axis=0)
            ax.fill_between(grid, 100 * band_low, 100 * band_high, color=style["color"], alpha=0.2, lw=0)
    ax.set_xlabel("relative density (g/cm3)")
    ax.set_ylabel("partition to sinks (%)")
    ax.set_ylim(-2, 102)
    ax.set_title(f"partition curves of the devices ({level:g} bands where uncertain)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    return ax
