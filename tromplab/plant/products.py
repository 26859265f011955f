r"""The products of each size fraction's device and of the plant: yields, ash, efficiency, misplaced material.

For size fraction :math:`j` (share :math:`F_j` of the plant feed) with density fractions :math:`i`
of mass :math:`m_{ij}` (per cent of the size fraction), ash :math:`a_{ij}` and density
:math:`\rho_{ij}` (mean density where measured, else the midpoint), washed by a device with
partition to sinks :math:`P_j`:

.. math::
    Y_j = \sum_i m_{ij}\,(1 - P_j(\rho_{ij})), \qquad
    A_j = \frac{\sum_i m_{ij}\,(1 - P_j(\rho_{ij}))\,a_{ij}}{Y_j}, \qquad
    Y = \sum_j F_j Y_j / 100, \qquad A = \frac{\sum_j F_j Y_j A_j}{\sum_j F_j Y_j}

(Wills & Finch 2016, ch. 11; King 2012 on coal-washing circuits).  Every function here
takes arrays of cut densities and scales (one per parameter draw) and returns one value per draw.

Definitions after ISO 923 (expression of the results of coal cleaning tests):

- *theoretical yield* at an ash: the yield of an ideal separation by density (partition 0
  below the cut, 1 above) whose clean coal has that ash, read off the cumulative floats curve
  (:meth:`tromplab.density.washability.Washability.theoretical_yield_pct`); for the plant,
  off the cumulative floats curve of the whole feed (all size fractions together,
  :func:`composite_washability`);
- *organic efficiency* = 100 x actual clean-coal yield / theoretical yield at the same ash;
- *misplaced material*: floats (material lighter than the cut density) in the sinks, and
  sinks (heavier) in the floats, per cent of the feed; a density fraction cut by the cut
  density counts with the share of its density range on each side (mass spread evenly);
- *near-gravity material*: per cent of the feed within +/- 0.1 of the cut density.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..density.washability import NEAR_GRAVITY_BAND, Washability, washability_from_arrays
from .inputs import Device, SizeFraction

#: The quantities of each row of ``products.csv``, in order (qualities follow as ``clean_<q>_pct``, ``reject_<q>_pct``).
QUANTITIES = ("clean_yield_pct", "clean_ash_pct", "reject_ash_pct", "theoretical_yield_pct", "organic_efficiency_pct",
              "misplaced_floats_pct", "misplaced_sinks_pct", "near_gravity_pct")  # fmt: skip


def fraction_products(fraction: SizeFraction, device: Device, rho50, scale, mass=None) -> dict[str, np.ndarray]:
    """Per draw (``rho50``, ``scale`` arrays of one length): the quantities of :data:`QUANTITIES` and the qualities,
    with the masses ``clean_mass`` and ``clean_ash_mass`` (per cent of the size fraction) the plant blends.

    ``mass``, optional, ``(draws, k)``: the density fractions' mass per cents of each draw (the washability's
    sampling error, :mod:`tromplab.plant.sampling`); default the washability's own for every draw."""
    washability = fraction.washability
    rho50 = np.atleast_1d(np.asarray(rho50, dtype=float))
    scale = np.broadcast_to(np.asarray(scale, dtype=float), rho50.shape)
    sinks = device.partition(washability.density[None, :], rho50[:, None], scale[:, None])
    masses = washability.mass_pct[None, :] if mass is None else np.asarray(mass, dtype=float)
    clean = masses * (1.0 - sinks)
    reject = masses * sinks
    clean_mass, reject_mass = clean.sum(axis=1), reject.sum(axis=1)
    values = {"clean_mass": clean_mass, "reject_mass": reject_mass}
    for name, per_fraction in {"ash": washability.ash_pct, **fraction.qualities}.items():
        values[f"clean_{name}_mass"] = clean @ per_fraction
        values[f"reject_{name}_mass"] = reject @ per_fraction
        values[f"clean_{name}_pct"] = _ratio(values[f"clean_{name}_mass"], clean_mass)
        values[f"reject_{name}_pct"] = _ratio(values[f"reject_{name}_mass"], reject_mass)
    values["clean_yield_pct"] = clean_mass
    values["theoretical_yield_pct"] = theoretical_yields(washability, values["clean_ash_pct"], mass)
    values["organic_efficiency_pct"] = _ratio(100.0 * clean_mass, values["theoretical_yield_pct"])
    width = washability.closed_upper - washability.closed_lower
    below = np.clip((rho50[:, None] - washability.closed_lower) / width, 0, 1)
    values["misplaced_floats_pct"] = (reject * below).sum(axis=1)
    values["misplaced_sinks_pct"] = (clean * (1.0 - below)).sum(axis=1)
    if mass is None:
        values["near_gravity_pct"] = washability.floats_mass_below(rho50 + NEAR_GRAVITY_BAND) - washability.floats_mass_below(
            rho50 - NEAR_GRAVITY_BAND
        )
    else:  # the cumulative floats of each draw's masses, linear within a fraction, between the two ends of the band
        low, high = rho50[:, None] - NEAR_GRAVITY_BAND, rho50[:, None] + NEAR_GRAVITY_BAND
        inside = np.clip(np.minimum(high, washability.closed_upper) - np.maximum(low, washability.closed_lower), 0, None)
        values["near_gravity_pct"] = (masses * inside / width).sum(axis=1)
    return values


def plant_products(
    fractions: list[SizeFraction], per_fraction: list[dict], composite: Washability, masses=None
) -> dict[str, np.ndarray]:
    """The blended clean coal and reject of the plant from each size fraction's :func:`fraction_products` (per draw);
    masses and per cents of the plant feed, misplaced and near-gravity material each at its own device's cut.
    ``masses``: each size fraction's ``(draws, k)`` mass per cents when they vary by draw (else None)."""
    shares = [fraction.feed_pct / 100.0 for fraction in fractions]
    mass_names = [name for name in per_fraction[0] if name.endswith("_mass")]
    total = {name: sum(share * values[name] for share, values in zip(shares, per_fraction)) for name in mass_names}
    for name in (
        n.removeprefix("clean_").removesuffix("_mass") for n in mass_names if n.startswith("clean_") and n != "clean_mass"
    ):
        total[f"clean_{name}_pct"] = _ratio(total[f"clean_{name}_mass"], total["clean_mass"])
        total[f"reject_{name}_pct"] = _ratio(total[f"reject_{name}_mass"], total["reject_mass"])
    total["clean_yield_pct"] = total["clean_mass"]
    if masses is None:
        total["theoretical_yield_pct"] = theoretical_yields(composite, total["clean_ash_pct"])
    else:
        composite_mass, composite_ash = composite_draws(fractions, composite, masses)
        total["theoretical_yield_pct"] = np.array(
            [replace(composite, mass_pct=m, ash_pct=a).theoretical_yield_pct(ash)
             for m, a, ash in zip(composite_mass, composite_ash, total["clean_ash_pct"])]
        )  # fmt: skip
    total["organic_efficiency_pct"] = _ratio(100.0 * total["clean_mass"], total["theoretical_yield_pct"])
    for name in ("misplaced_floats_pct", "misplaced_sinks_pct", "near_gravity_pct"):
        total[name] = sum(share * values[name] for share, values in zip(shares, per_fraction))
    return total


def theoretical_yields(washability: Washability, ash_pct: np.ndarray, mass=None) -> np.ndarray:
    """:meth:`Washability.theoretical_yield_pct` at each ash of ``ash_pct`` (NaN where none exists); with ``mass``
    (``(draws, k)``), each draw's on the washability of that draw's masses."""
    if mass is None:
        return np.array([washability.theoretical_yield_pct(ash) for ash in np.atleast_1d(ash_pct)], dtype=float)
    return np.array([replace(washability, mass_pct=m).theoretical_yield_pct(ash) for m, ash in zip(mass, ash_pct)], dtype=float)


def composite_draws(fractions: list[SizeFraction], composite: Washability, masses) -> tuple[np.ndarray, np.ndarray]:
    """The whole feed's mass and ash per cents by density interval of :func:`composite_washability`, for each draw
    of the size fractions' masses (``masses``: one ``(draws, k)`` array per size fraction)."""
    mass = np.zeros((len(masses[0]), composite.mass_pct.size))
    ash_mass = np.zeros_like(mass)
    for fraction, drawn in zip(fractions, masses):
        share = _interval_shares(composite.closed_lower, composite.closed_upper, fraction.washability)
        mass += fraction.feed_pct / 100.0 * (drawn @ share.T)
        ash_mass += fraction.feed_pct / 100.0 * ((drawn * fraction.washability.ash_pct) @ share.T)
    return mass, np.divide(ash_mass, mass, out=np.zeros_like(mass), where=mass > 0)


def _interval_shares(lower: np.ndarray, upper: np.ndarray, w: Washability) -> np.ndarray:
    """The share of each density fraction of ``w`` (columns) in each interval (rows): mass spread evenly over its range."""
    overlap = np.clip(np.minimum(upper[:, None], w.closed_upper) - np.maximum(lower[:, None], w.closed_lower), 0, None)
    return overlap / (w.closed_upper - w.closed_lower)


def composite_washability(fractions: list[SizeFraction]) -> Washability:
    r"""The washability of the whole plant feed: the size fractions' density fractions added at equal density.

    Each size fraction's density fractions are cut at every bound any size fraction has (its mass
    spread evenly over a fraction's density range, each part with the fraction's ash and
    qualities: the conventions of :mod:`tromplab.density.washability`), weighted by the size
    fraction's share of the feed, and summed per density interval.  Open fractions count with
    their closed bounds.

    Examples
    --------
    >>> from tromplab.density.washability import washability_from_arrays as w
    >>> coarse = SizeFraction("c", 50.0, w([1.2, 1.4], [1.4, 1.8], [60, 40], [5, 40]))
    >>> fine = SizeFraction("f", 50.0, w([1.2, 1.6], [1.6, 1.8], [80, 20], [10, 50]))
    >>> whole = composite_washability([coarse, fine])
    >>> whole.closed_lower.tolist(), whole.mass_pct.round(6).tolist()  # 1.2-1.4: 30 + 20; 1.4-1.6: 10 + 20; 1.6-1.8: 10 + 10
    ([1.2, 1.4, 1.6], [50.0, 30.0, 20.0])
    """
    bounds = np.unique(np.concatenate([np.append(f.washability.closed_lower, f.washability.closed_upper[-1]) for f in fractions]))
    lower, upper = bounds[:-1], bounds[1:]
    mass, ash_mass = np.zeros(lower.size), np.zeros(lower.size)
    for fraction in fractions:
        w = fraction.washability
        share = _interval_shares(lower, upper, w)  # of each density fraction, in each interval
        mass += fraction.feed_pct / 100.0 * (share @ w.mass_pct)
        ash_mass += fraction.feed_pct / 100.0 * (share @ (w.mass_pct * w.ash_pct))
    ash = np.divide(ash_mass, mass, out=np.zeros_like(mass), where=mass > 0)  # an empty interval's ash is never used
    return washability_from_arrays(lower, upper, mass, ash, test="plant feed")


def _ratio(numerator, denominator) -> np.ndarray:
    numerator, denominator = np.asarray(numerator, dtype=float), np.asarray(denominator, dtype=float)
    return np.divide(numerator, denominator, out=np.full(np.broadcast(numerator, denominator).shape, np.nan),
                     where=denominator > 0)  # fmt: skip
