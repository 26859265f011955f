"""The density fractions of a float-sink table: one reading of their bounds for every reader.

Both the float-sink analyses of a separator's products (:func:`tromplab.density.read_density`)
and the washability table of a feed (:func:`tromplab.density.read_washability`) give one row
per density fraction with ``density_lower`` and ``density_upper``.  :func:`density_fractions`
checks and closes these bounds for both, with one convention (``docs/density_columns.md``,
"Density fractions"):

- relative densities (g/cm3, water = 1) within :data:`DENSITY_RANGE`; a blank (or 0)
  ``density_lower`` is the open float fraction (floats of the lightest liquid), a blank
  ``density_upper`` the open sink fraction (sinks of the heaviest liquid); only the lightest
  fraction may be open below and only the heaviest open above;
- the fractions of a test are given light to heavy and tile the density range: each starts
  where the lighter one ends (within 1e-9), no gap, no overlap;
- ``density_mean`` (optional, blank where not measured) lies within its fraction's bounds;
- an open fraction is closed by the bound stated by the caller, else symmetrically about its
  measured mean density, else by the width of its neighbour;
- a fraction is placed (its partition read, plotted and fitted) at its mean density where
  measured, otherwise at the midpoint of its closed bounds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..loading.tables import Table

#: Relative densities a density table may hold (g/cm3, water = 1).
DENSITY_RANGE = (0.5, 25.0)

#: The tolerance (g/cm3) within which a fraction starts where the lighter one ends.
TILING_TOLERANCE = 1e-9


@dataclass(frozen=True)
class DensityFractions:
    """The checked fractions of one test, light to heavy.

    Attributes
    ----------
    lower, upper : ndarray
        The bounds as given (g/cm3); NaN where the fraction is open (a 0 lower bound reads as open).
    closed_lower, closed_upper : ndarray
        The bounds with the open ends closed (g/cm3).
    density : ndarray
        Where each fraction is placed: its mean density where measured, else the midpoint of
        its closed bounds (g/cm3).
    density_from : tuple of str
        ``"mean"`` or ``"midpoint"`` per fraction.
    notes : tuple of str
        How each open fraction was closed, in words.
    """

    lower: np.ndarray
    upper: np.ndarray
    closed_lower: np.ndarray
    closed_upper: np.ndarray
    density: np.ndarray
    density_from: tuple[str, ...]
    notes: tuple[str, ...]


def density_fractions(
    table: Table, *, minimum: int = 2, float_lower: float | None = None, sink_upper: float | None = None
) -> DensityFractions:
    """Read, check and close the density fractions of one test (the module's convention).

    Parameters
    ----------
    table : Table
        The rows of one test, light to heavy, with ``density_lower``, ``density_upper`` and
        optionally ``density_mean``.
    minimum : int
        The fewest fractions the caller can work with (at least 2).
    float_lower, sink_upper : float or None
        Stated bounds closing the open float and sink fractions (g/cm3); None: symmetric
        about the measured mean density, else the neighbour's width.

    Returns
    -------
    DensityFractions

    Raises
    ------
    InputError
        Naming the file, row and column of the first bound that breaks the convention.

    Examples
    --------
    >>> import pandas as pd
    >>> frame = pd.DataFrame({"density_lower": [0, 1.3, 1.4], "density_upper": [1.3, 1.4, None]})
    >>> table = Table(frame, np.arange(2, 5), "fs.csv")
    >>> density_fractions(table).density.round(3).tolist()
    [1.25, 1.35, 1.45]
    """
    lower = densities(table, "density_lower", allow_blank=True)
    lower = np.where(lower == 0, np.nan, lower)
    upper = densities(table, "density_upper", allow_blank=True, zero_is_blank=False)
    _check_each_fraction(table, lower, upper)
    if lower.size < max(minimum, 2):
        raise InputError(
            f"test has {lower.size} density fraction(s); at least {max(minimum, 2)} are needed",
            source=table.source,
            column="density_lower",
        )
    _check_tiling(table, lower, upper)
    mean = (
        densities(table, "density_mean", allow_blank=True, zero_is_blank=False)
        if "density_mean" in table.frame.columns
        else np.full(lower.size, np.nan)
    )
    outside = np.isfinite(mean) & ((mean < np.nan_to_num(lower, nan=-np.inf)) | (mean > np.nan_to_num(upper, nan=np.inf)))
    if outside.any():
        i = int(np.flatnonzero(outside)[0])
        raise table.error(
            f"mean density {mean[i]:g} lies outside its fraction {fraction_label(lower[i], upper[i])}",
            index=i,
            column="density_mean",
        )
    closed_lower, closed_upper, notes = _closed_bounds(table, lower, upper, mean, float_lower, sink_upper)
    measured = np.isfinite(mean)
    return DensityFractions(
        lower=lower,
        upper=upper,
        closed_lower=closed_lower,
        closed_upper=closed_upper,
        density=np.where(measured, mean, (closed_lower + closed_upper) / 2.0),
        density_from=tuple("mean" if m else "midpoint" for m in measured),
        notes=tuple(notes),
    )


def densities(table: Table, column: str, *, allow_blank: bool = False, zero_is_blank: bool = True) -> np.ndarray:
    """The relative densities of ``column``, each within :data:`DENSITY_RANGE` (a blank is NaN;
    with ``allow_blank`` and ``zero_is_blank`` a 0 passes, for the caller to read as blank)."""
    values = table.numeric(column, allow_blank=allow_blank)
    low, high = DENSITY_RANGE
    zero_allowed = (values == 0) & allow_blank & zero_is_blank
    table.refuse_where(
        np.isfinite(values) & ((values < low) | (values > high)) & ~zero_allowed,
        column,
        lambda i: f"relative density {values[i]:g} outside {low:g}..{high:g} (g/cm3, water = 1)",
    )
    return values


def fraction_label(lower: float, upper: float) -> str:
    """A fraction as a lab writes it: ``-1.3`` (floats), ``1.3-1.4``, ``+1.6`` (sinks)."""
    if np.isnan(lower):
        return f"-{upper:g}"
    if np.isnan(upper):
        return f"+{lower:g}"
    return f"{lower:g}-{upper:g}"


def _check_each_fraction(table: Table, lower: np.ndarray, upper: np.ndarray) -> None:
    table.refuse_where(
        lower >= upper, "density_lower", lambda i: f"lower bound {lower[i]:g} is not below the upper bound {upper[i]:g}"
    )
    table.refuse_where(np.isnan(lower) & np.isnan(upper), "density_lower", "the fraction has neither a lower nor an upper bound")


def _check_tiling(table: Table, lower: np.ndarray, upper: np.ndarray) -> None:
    key = np.where(np.isfinite(lower), lower, upper - 1e9)
    behind = np.flatnonzero(np.diff(key) <= 0)
    if behind.size:
        i = int(behind[0]) + 1
        raise table.error(
            f"density fractions not increasing: {fraction_label(lower[i], upper[i])} follows "
            f"{fraction_label(lower[i - 1], upper[i - 1])} (give the fractions of a test light to heavy)",
            index=i,
            column="density_lower",
        )
    inner_open = np.concatenate([np.flatnonzero(np.isnan(upper[:-1])), 1 + np.flatnonzero(np.isnan(lower[1:]))])
    if inner_open.size:
        i = int(inner_open.min())
        column = "density_upper" if np.isnan(upper[i]) else "density_lower"
        raise table.error("only the lightest fraction may be open below and only the heaviest open above", index=i, column=column)
    for heavier in range(1, lower.size):
        lighter = heavier - 1
        if not abs(upper[lighter] - lower[heavier]) <= TILING_TOLERANCE:
            what = "overlaps" if upper[lighter] > lower[heavier] else "leaves a gap to"
            raise table.error(
                f"fraction {fraction_label(lower[heavier], upper[heavier])} {what} the fraction "
                f"{fraction_label(lower[lighter], upper[lighter])} (each fraction starts where the lighter one ends)",
                index=heavier,
                column="density_lower",
            )


def _closed_bounds(table: Table, lower, upper, mean, float_lower, sink_upper):
    """The open fractions closed: by the stated bound, else symmetric about a measured mean density,
    else by the width of the neighbouring fraction; with a note saying how."""
    closed_lower, closed_upper, notes = lower.copy(), upper.copy(), []
    if np.isnan(lower[0]):
        closed_lower[0], how = _closing(float_lower, "float_lower_density", mean[0], upper[0], upper[1] - lower[1], -1.0)
        if np.isfinite(closed_lower[0]) and (
            not 0 < closed_lower[0] < upper[0] or closed_lower[0] > np.nan_to_num(mean[0], nan=np.inf)
        ):
            raise InputError(
                f"the open float fraction closes at {closed_lower[0]:g}, not between 0 and the lightest bound {upper[0]:g} "
                "(and its mean density); give float_lower_density",
                source=table.source,
            )
        notes.append(f"the float below {upper[0]:g} is placed as the fraction {closed_lower[0]:g}-{upper[0]:g} ({how})")
    if np.isnan(upper[-1]):
        closed_upper[-1], how = _closing(sink_upper, "sink_upper_density", mean[-1], lower[-1], upper[-2] - lower[-2], 1.0)
        if np.isfinite(closed_upper[-1]) and not closed_upper[-1] > max(lower[-1], np.nan_to_num(mean[-1], nan=-np.inf)):
            raise InputError(
                f"sink_upper_density {closed_upper[-1]:g} must lie above the heaviest bound {lower[-1]:g} and its mean density",
                source=table.source,
            )
        notes.append(f"the sink above {lower[-1]:g} is placed as the fraction {lower[-1]:g}-{closed_upper[-1]:g} ({how})")
    if not (np.all(np.isfinite(closed_lower)) and np.all(np.isfinite(closed_upper))):
        raise InputError(
            "an open fraction needs a closed neighbour to take its width from; give float_lower_density / sink_upper_density",
            source=table.source,
        )
    return closed_lower, closed_upper, notes


def _closing(stated, option: str, mean: float, bound: float, neighbour_width: float, direction: float):
    """The open end of a fraction whose other end is ``bound``, and how it was found."""
    if stated is not None:
        return float(stated), f"{option} {stated:g}"
    if np.isfinite(mean):
        return 2.0 * mean - bound, f"symmetric about its mean density {mean:g}"
    return bound + direction * neighbour_width, "the width of its neighbour"
