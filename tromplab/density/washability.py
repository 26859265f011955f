r"""Washability of a feed and the products a density separator makes of it.

A washability table is the float-sink analysis of a feed with the ash of each density
fraction.  From it: the cumulative floats and sinks curves, the near-gravity material, and,
for a partition curve :math:`P(\rho)` (the share of material of relative density
:math:`\rho` reporting to the sinks), the predicted yield and ash of both products, the
theoretical yield at the same ash and the organic efficiency.

File schema (CSV or Excel), one row per density fraction:

``density_lower``, ``density_upper``
    relative density bounds of the fraction (g/cm3, water = 1); a blank lower bound is the
    open float fraction (floats of the lightest liquid), a blank upper bound the open sink
    fraction (sinks of the heaviest liquid).  The fractions of a test are given light to
    heavy and tile the range without gap or overlap (:mod:`tromplab.density.fractions`, the
    convention every density reader shares).
``mass_pct``
    mass per cent of the feed in the fraction, >= 0; the fractions of a test must add up
    to 100 within ``sum_tolerance_pct`` and are normalised to 100.
``ash_pct``
    ash per cent (dry basis, or the basis of the whole table) of the fraction, 0..100.
``density_mean``
    optional: the measured mean relative density of the fraction (blank where not
    determined); it must lie within the fraction's bounds.
``test``
    optional name of the table (text); several tables go in one file, one name each.
``note``, ``comment``
    free text, ignored.  Any other column is refused with its name.

Conventions
-----------
*Density of a fraction.*  The partition of a fraction is read at its mean density where
given, otherwise at the midpoint of its bounds.  An open fraction is closed by the bound the
options ``float_lower_density`` / ``sink_upper_density`` state; else, when its mean density
is given, symmetrically about it (the +2.00 sinks of mean 2.31 run to 2.62); else by the
width of its neighbour (the floats below 1.30 beside 1.30-1.40 run from 1.20), as the open
size classes of the lab tables are extended by their neighbour's ratio.

*Within a fraction* mass is spread evenly over the density range (used by the near-gravity
material of a partial fraction) and every particle has the fraction's ash (used by the
theoretical yield of a cut inside a fraction).  Both are what a table of fractions can say
and no more.

References
----------
Tromp, K. F. (1937). Neue Wege für die Beurteilung der Aufbereitung von Steinkohlen.
*Glückauf* 73, 125-131, 151-156.

Bird, B. M. (1931). Interpretation of float-and-sink data. *Proceedings of the Third
International Conference on Bituminous Coal*, Pittsburgh, 2, 82-111 (near-gravity material).

Wills, B. A. & Finch, J. A. (2016). *Wills' Mineral Processing Technology*, 8th ed.,
Butterworth-Heinemann, chapter 11 (dense medium separation: washability curves, organic
efficiency).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..errors import InputError, OptionError
from ..loading.tables import Table, read_table
from ..options import DEFAULT_SUM_TOLERANCE_PCT
from ..results_contract import ResultContract
from ..validation import check_cut_density, check_non_negative, check_optional, check_percent, check_positive, check_share
from .fractions import density_fractions

#: The columns a washability table may have (besides free-text note and comment).
WASHABILITY_COLUMNS = ("test", "density_lower", "density_upper", "mass_pct", "ash_pct", "density_mean")
#: Half-width of the near-gravity band (relative density units), Bird's +/- 0.1.
NEAR_GRAVITY_BAND = 0.1
#: The prediction columns, in the order :func:`prediction_table` writes them.
PREDICTION_COLUMNS = (
    "test",
    "curve",
    "rho50",
    "ep",
    "light_limit",
    "heavy_limit",
    "target_ash_pct",
    "floats_yield_pct",
    "floats_ash_pct",
    "sinks_yield_pct",
    "sinks_ash_pct",
    "theoretical_yield_pct",
    "organic_efficiency_pct",
    "near_gravity_pct",
    "note",
)


@dataclass(frozen=True)
class Washability(ResultContract):
    """The float-sink analysis of one feed, fractions ordered light to heavy.

    Attributes
    ----------
    test : str
        Name of the table (the ``test`` column, or the file name).
    density_lower, density_upper : numpy.ndarray
        Bounds of each fraction as given (NaN for the open ends), relative density.
    closed_lower, closed_upper : numpy.ndarray
        The bounds with the open ends closed (module conventions).
    density : numpy.ndarray
        Relative density at which each fraction's partition is read: its mean density where
        given, else the midpoint of its closed bounds.
    density_from : tuple of str
        ``"mean"`` or ``"midpoint"`` per fraction.
    mass_pct : numpy.ndarray
        Mass per cent of the feed per fraction, normalised to add up to 100.
    ash_pct : numpy.ndarray
        Ash per cent per fraction.
    source : str
        The file (or ``DataFrame``) the table came from.
    rows : numpy.ndarray
        File row of each fraction (for messages).
    feed_ash_pct : float
        Ash per cent of the whole feed.

    Notes
    -----
    :meth:`summary` has one row per fraction (:meth:`cumulative_table`), as does :meth:`to_frame`.
    """

    test: str
    density_lower: np.ndarray
    density_upper: np.ndarray
    closed_lower: np.ndarray
    closed_upper: np.ndarray
    density: np.ndarray
    density_from: tuple
    mass_pct: np.ndarray
    ash_pct: np.ndarray
    source: str = "DataFrame"
    rows: np.ndarray | None = None

    @property
    def feed_ash_pct(self) -> float:
        """Ash per cent of the whole feed, :math:`\\sum m_i a_i / 100`."""
        return float(np.sum(self.mass_pct * self.ash_pct) / 100.0)

    def summary(self) -> pd.DataFrame:
        """One row per fraction: the washability table (:meth:`cumulative_table`)."""
        return self.cumulative_table()

    def _result_context(self) -> str:
        return f"Washability of {self.test}: {len(self.mass_pct)} fractions, feed ash {self.feed_ash_pct:.4g} %"

    def cumulative_table(self) -> pd.DataFrame:
        r"""The washability table: each fraction with the cumulative floats and sinks.

        ``cumulative_floats_*`` are the floats of the fraction's upper bound (this fraction
        and every lighter one), ``cumulative_sinks_*`` the sinks of its lower bound (this
        fraction and every heavier one):

        .. math:: F_j = \sum_{i \le j} m_i, \quad A^F_j = \frac{\sum_{i \le j} m_i a_i}{F_j}, \qquad
                  S_j = \sum_{i \ge j} m_i, \quad A^S_j = \frac{\sum_{i \ge j} m_i a_i}{S_j}

        ``near_gravity_pct`` is the near-gravity material at the fraction's upper bound
        (blank for the open sink fraction).
        """
        m, a = self.mass_pct, self.ash_pct
        floats_mass = np.cumsum(m)
        sinks_mass = np.cumsum(m[::-1])[::-1]
        with np.errstate(invalid="ignore", divide="ignore"):
            floats_ash = np.cumsum(m * a) / floats_mass
            sinks_ash = np.cumsum((m * a)[::-1])[::-1] / sinks_mass
        near_gravity = [self.near_gravity_pct(rho) if np.isfinite(rho) else np.nan for rho in self.density_upper]
        return pd.DataFrame(
            {
                "test": self.test,
                "density_lower": self.density_lower,
                "density_upper": self.density_upper,
                "density": self.density,
                "density_from": list(self.density_from),
                "mass_pct": m,
                "ash_pct": a,
                "cumulative_floats_mass_pct": floats_mass,
                "cumulative_floats_ash_pct": np.where(floats_mass > 0, floats_ash, np.nan),
                "cumulative_sinks_mass_pct": sinks_mass,
                "cumulative_sinks_ash_pct": np.where(sinks_mass > 0, sinks_ash, np.nan),
                "near_gravity_pct": near_gravity,
            }
        )

    def floats_mass_below(self, density) -> np.ndarray:
        """Mass per cent of the feed lighter than ``density``: the cumulative floats, linear within a fraction."""
        bounds = np.append(self.closed_lower, self.closed_upper[-1])
        cumulative = np.append(0.0, np.cumsum(self.mass_pct))
        return np.interp(np.asarray(density, dtype=float), bounds, cumulative, left=0.0, right=100.0)

    def near_gravity_pct(self, density: float, band: float = NEAR_GRAVITY_BAND) -> float:
        r"""Near-gravity material: mass per cent of the feed within ``density`` :math:`\pm` ``band``.

        Per cent of the whole feed (no fraction left out), with the mass of a fraction
        spread evenly over its density range, so a fraction cut by the band counts with the
        share of its range inside it; the open fractions use their closed bounds.

        Examples
        --------
        >>> w = washability_from_arrays([np.nan, 1.3, 1.4, 1.6], [1.3, 1.4, 1.6, np.nan], [40, 30, 20, 10], [3, 10, 25, 70])
        >>> round(w.near_gravity_pct(1.5), 6)  # 1.4 to 1.6: the whole fraction 1.4-1.6
        20.0
        >>> round(w.near_gravity_pct(1.45), 6)  # half of 1.3-1.4 and three quarters of 1.4-1.6
        30.0
        """
        density = check_positive(density, "density")
        band = check_positive(band, "band")
        return float(self.floats_mass_below(density + band) - self.floats_mass_below(density - band))

    def theoretical_yield_pct(self, ash_pct: float) -> float:
        r"""The largest floats yield of an ideal separation by density whose ash is ``ash_pct``.

        Read off the cumulative floats curve: a cut inside fraction :math:`j` takes the
        share :math:`t` of it, with yield :math:`F_{j-1} + t m_j` and ash
        :math:`(F_{j-1} A^F_{j-1} + t m_j a_j)/(F_{j-1} + t m_j)` (each fraction of uniform
        ash), so the cumulative ash mass is interpolated linearly in the yield and
        :math:`t` solves the ash equation exactly.  Where the cumulative ash rises and falls
        (fraction ash not increasing with density), the largest yield is taken.  At or above
        the feed ash the whole feed (100); below the ash of the lightest fraction NaN (no
        ideal product is that clean).

        Examples
        --------
        >>> w = washability_from_arrays([np.nan, 1.4, 1.6], [1.4, 1.6, np.nan], [50, 25, 25], [10, 50, 50])
        >>> round(w.theoretical_yield_pct(20.0), 6)  # all of -1.4 and two thirds of 1.4-1.6 make 20 % ash
        66.666667
        """
        target = float(ash_pct)
        if not np.isfinite(target):
            return np.nan
        m, a = self.mass_pct, self.ash_pct
        yield_before = np.append(0.0, np.cumsum(m)[:-1])
        ash_before = np.append(0.0, np.cumsum(m * a)[:-1])
        if target >= self.feed_ash_pct:
            return 100.0
        best = np.nan
        for previous_yield, previous_ash_mass, mass, ash in zip(yield_before, ash_before, m, a):
            if mass <= 0:
                continue
            excess_before = previous_ash_mass - target * previous_yield  # ash mass above the target's, before this fraction
            if ash == target:  # the fraction keeps the cumulative ash where it is: all of it, if that is the target
                share = 1.0 if abs(excess_before) <= 1e-12 * max(previous_yield, 1.0) else np.nan
            else:
                share = -excess_before / (mass * (ash - target))
            if np.isfinite(share) and -1e-12 <= share <= 1 + 1e-12:
                best = previous_yield + min(max(share, 0.0), 1.0) * mass
        return float(best) if np.isfinite(best) and best > 0 else np.nan

    def predict(self, partition: Callable) -> Prediction:
        """The products of a separator with partition curve ``partition`` (see :func:`predict_products`)."""
        return predict_products(self, partition)


@dataclass(frozen=True)
class Prediction(ResultContract):
    r"""Predicted products of one washability table for one partition curve.

    Attributes
    ----------
    floats_yield_pct, sinks_yield_pct : float
        Mass per cent of the feed in each product, :math:`\sum m_i (1 - P_i)` and
        :math:`\sum m_i P_i` (they add up to 100).
    floats_ash_pct, sinks_ash_pct : float
        Ash per cent of each product (NaN when the product is empty).
    theoretical_yield_pct : float
        Yield of the ideal density separation whose floats have the predicted floats ash
        (:meth:`Washability.theoretical_yield_pct`).
    organic_efficiency_pct : float
        ``100 * floats_yield_pct / theoretical_yield_pct``.
    fractions : pandas.DataFrame
        Per fraction: ``density``, ``partition_sinks`` and the mass per cent of the feed
        it sends to the floats and to the sinks.
    note : str
        Why a number is missing ("" when none is).

    Notes
    -----
    :meth:`summary` is one row (the products), :meth:`to_frame` the fractions.
    """

    floats_yield_pct: float
    floats_ash_pct: float
    sinks_yield_pct: float
    sinks_ash_pct: float
    theoretical_yield_pct: float
    organic_efficiency_pct: float
    fractions: pd.DataFrame
    note: str = ""

    def summary(self) -> pd.DataFrame:
        """One row: yield and ash of both products, the theoretical yield, the organic efficiency, the note."""
        names = ("floats_yield_pct", "floats_ash_pct", "sinks_yield_pct", "sinks_ash_pct", "theoretical_yield_pct",
                 "organic_efficiency_pct", "note")  # fmt: skip
        return pd.DataFrame([{name: getattr(self, name) for name in names}])

    def to_frame(self) -> pd.DataFrame:
        """The fractions: density, partition to sinks and the mass sent to each product."""
        return self.fractions.copy()

    def _result_context(self) -> str:
        return (f"Predicted products: floats {self.floats_yield_pct:.4g} % at {self.floats_ash_pct:.4g} % ash, "
                f"sinks {self.sinks_yield_pct:.4g} % at {self.sinks_ash_pct:.4g} % ash")  # fmt: skip


def predict_products(washability: Washability, partition: Callable) -> Prediction:
    r"""Yield and ash of floats and sinks of ``washability`` under the partition curve ``partition``.

    .. math:: Y_F = \sum_i m_i (1 - P(\rho_i)), \qquad
              A_F = \frac{\sum_i m_i (1 - P(\rho_i))\, a_i}{Y_F},

    and likewise for the sinks with :math:`P(\rho_i)`, where :math:`\rho_i` is the density of
    fraction :math:`i` (:attr:`Washability.density`).  The organic efficiency is
    :math:`100\, Y_F / Y_T(A_F)`, :math:`Y_T` the theoretical yield at the same ash.

    Parameters
    ----------
    washability : Washability
        The feed.
    partition : callable
        :math:`P(\rho)`: share of the material of relative density :math:`\rho` reporting to
        the sinks, vectorised, values in [0, 1] (a registry curve with its parameters, a
        fitted result's partition, or any function).

    Returns
    -------
    Prediction

    Examples
    --------
    >>> w = washability_from_arrays([np.nan, 1.4, 1.6], [1.4, 1.6, np.nan], [50, 25, 25], [10, 50, 50])
    >>> p = predict_products(w, lambda rho: np.where(rho < 1.4, 0.1, 0.8))
    >>> round(p.floats_yield_pct, 6), round(p.floats_ash_pct, 6)  # 45 % at 10 % ash and 10 % at 50 %
    (55.0, 17.272727)
    """
    p = np.asarray(partition(washability.density), dtype=float)
    if p.shape != washability.density.shape or not np.all(np.isfinite(p)) or np.any((p < 0) | (p > 1)):
        raise ValueError(f"the partition curve must give values in [0, 1] at every fraction's density, got {p}")
    m, a = washability.mass_pct, washability.ash_pct
    to_floats, to_sinks = m * (1.0 - p), m * p
    floats_yield, sinks_yield = float(to_floats.sum()), float(to_sinks.sum())
    floats_ash = float(np.sum(to_floats * a) / floats_yield) if floats_yield > 0 else np.nan
    sinks_ash = float(np.sum(to_sinks * a) / sinks_yield) if sinks_yield > 0 else np.nan
    theoretical = washability.theoretical_yield_pct(floats_ash)
    notes = []
    if floats_yield <= 0:
        notes.append("the curve sends everything to the sinks: the floats have no ash and no theoretical yield")
    elif not np.isfinite(theoretical):
        notes.append(
            f"floats ash {floats_ash:.4g} % is below the ash of the lightest fraction "
            f"({washability.ash_pct[washability.mass_pct > 0][0]:.4g} %): no ideal separation is that clean"
        )
    efficiency = 100.0 * floats_yield / theoretical if np.isfinite(theoretical) and theoretical > 0 else np.nan
    fractions = pd.DataFrame(
        {"density": washability.density, "partition_sinks": p, "to_floats_pct": to_floats, "to_sinks_pct": to_sinks}
    )
    return Prediction(floats_yield, floats_ash, sinks_yield, sinks_ash, theoretical, efficiency, fractions, "; ".join(notes))


def rho50_for_floats_ash(washability: Washability, target_ash_pct: float, curve_at: Callable, *, grid: int = 400):
    """The cut density whose predicted floats have ``target_ash_pct`` ash, by Brent's method.

    Parameters
    ----------
    washability : Washability
    target_ash_pct : float
        The floats ash sought, per cent.
    curve_at : callable
        ``curve_at(rho50)`` returns the partition curve :math:`P(\\rho)` with that cut (the
        other parameters held).
    grid : int
        Cut densities scanned over the table's closed density range for the first change
        of sign of (floats ash - target), which :func:`scipy.optimize.brentq` then refines
        to 1e-12.

    Returns
    -------
    tuple
        ``(rho50, note)``: the cut density, or NaN with a note saying why none was found
        (the target outside the floats ash the curve can give on this feed).
    """
    from scipy.optimize import brentq

    def excess(rho50: float) -> float:
        return predict_products(washability, curve_at(rho50)).floats_ash_pct - target_ash_pct

    cuts = np.linspace(washability.closed_lower[0], washability.closed_upper[-1], grid)
    values = np.array([excess(cut) for cut in cuts])
    finite = np.isfinite(values)
    if finite.any():
        for i in range(grid - 1):
            if finite[i] and finite[i + 1] and values[i] == 0:
                return float(cuts[i]), ""
            if finite[i] and finite[i + 1] and np.sign(values[i]) != np.sign(values[i + 1]):
                return float(brentq(excess, cuts[i], cuts[i + 1], xtol=1e-12, rtol=1e-12)), ""
        low, high = np.nanmin(values[finite]) + target_ash_pct, np.nanmax(values[finite]) + target_ash_pct
        return np.nan, (
            f"no cut density between {cuts[0]:.4g} and {cuts[-1]:.4g} gives floats of {target_ash_pct:g} % ash "
            f"with this curve (floats ash from {low:.4g} to {high:.4g} %)"
        )
    return np.nan, "the curve leaves no floats at any cut density in the table's range"


# --- reading ------------------------------------------------------------------------------
def check_reading_options(
    sum_tolerance_pct: float, float_lower_density: float | None, sink_upper_density: float | None
) -> tuple[float, float | None, float | None]:
    """The options of every washability reader, checked as the command line checks them: a
    tolerance of at least 0 and open-end densities above 0 (or None).  Raises OptionError."""
    return (
        check_non_negative(sum_tolerance_pct, "sum_tolerance_pct"),
        check_optional(check_positive, float_lower_density, "float_lower_density"),
        check_optional(check_positive, sink_upper_density, "sink_upper_density"),
    )


def read_washability(
    path,
    *,
    sum_tolerance_pct: float = DEFAULT_SUM_TOLERANCE_PCT,
    float_lower_density: float | None = None,
    sink_upper_density: float | None = None,
    sheet=None,
    sep=None,
    decimal=None,
) -> list[Washability]:
    """Read washability tables (one per ``test``) from a CSV or Excel file or a DataFrame.

    Parameters
    ----------
    path : path or pandas.DataFrame
        The table (schema in the module docstring).
    sum_tolerance_pct : float
        Allowed deviation of a test's ``mass_pct`` total from 100 (percentage points).
    float_lower_density, sink_upper_density : float, optional
        Lower bound of the open float fraction and upper bound of the open sink fraction
        (default: the width of the neighbouring fraction).
    sheet, sep, decimal
        As for :func:`tromplab.loading.tables.read_table`.

    Returns
    -------
    list of Washability
        In the order the tests first appear.

    Raises
    ------
    InputError
        Naming the file, row and column of the first bad value.
    """
    sum_tolerance_pct, float_lower_density, sink_upper_density = check_reading_options(
        sum_tolerance_pct, float_lower_density, sink_upper_density
    )
    table = read_table(path, sheet=sheet, sep=sep, decimal=decimal, text_columns=("test",))
    table.refuse_unknown(WASHABILITY_COLUMNS, what="washability table")
    table.require("density_lower", "density_upper", "mass_pct", "ash_pct")
    names = _test_names(table)
    tests = []
    for name in dict.fromkeys(names):
        rows = np.flatnonzero(names == name)
        tests.append(washability_of_rows(table.subset(rows), name, sum_tolerance_pct, float_lower_density, sink_upper_density))
    return tests


def washability_from_arrays(density_lower, density_upper, mass_pct, ash_pct, density_mean=None, *, test="feed"):
    """A :class:`Washability` from arrays (blank = NaN), checked as a file is.

    Examples
    --------
    >>> w = washability_from_arrays([np.nan, 1.3, 1.4], [1.3, 1.4, np.nan], [60, 25, 15], [4, 15, 60])
    >>> w.density.round(9).tolist(), round(w.feed_ash_pct, 6)
    ([1.25, 1.35, 1.45], 15.15)
    """
    frame = pd.DataFrame(
        {"test": test, "density_lower": density_lower, "density_upper": density_upper, "mass_pct": mass_pct, "ash_pct": ash_pct}
    )
    if density_mean is not None:
        frame["density_mean"] = density_mean
    (washability,) = read_washability(frame)
    return washability


def _test_names(table: Table) -> np.ndarray:
    if "test" not in table.frame.columns:
        from pathlib import Path

        return np.full(len(table.frame), Path(table.source).stem, dtype=object)
    names = table.frame["test"]
    text = names.astype(str).str.strip()
    blank = names.isna().to_numpy() | (text == "").to_numpy()
    table.refuse_where(blank, "test", "test name is blank")
    return text.to_numpy(dtype=object)


def washability_of_rows(table: Table, name: str, tolerance: float, float_lower, sink_upper) -> Washability:
    """The :class:`Washability` of the rows of ``table`` (one test, or one size fraction of a plant
    feed), checked as :func:`read_washability` checks a file: errors name its rows and columns."""
    fractions = density_fractions(table, float_lower=float_lower, sink_upper=sink_upper)
    mass = table.numeric("mass_pct")
    ash = table.numeric("ash_pct")
    table.refuse_outside(mass, "mass_pct", 0.0, np.inf)
    table.refuse_outside(ash, "ash_pct", 0.0, 100.0)
    total = float(mass.sum())
    if abs(total - 100.0) > tolerance:
        raise InputError(
            f"test '{name}': mass_pct adds up to {total:.6g}, not 100 (tolerance {tolerance:g} percentage points)",
            source=table.source,
            column="mass_pct",
        )
    return Washability(
        test=name,
        density_lower=fractions.lower,
        density_upper=fractions.upper,
        closed_lower=fractions.closed_lower,
        closed_upper=fractions.closed_upper,
        density=fractions.density,
        density_from=fractions.density_from,
        mass_pct=mass * (100.0 / total),
        ash_pct=ash,
        source=table.source,
        rows=table.rows,
    )


# --- tables -----------------------------------------------------------------------------------
def prediction_row(washability: Washability, prediction: Prediction, **inputs) -> dict:
    """One row of :data:`PREDICTION_COLUMNS`: the inputs (curve, rho50, ...) and the predicted numbers.

    ``near_gravity_pct`` is the near-gravity material at the cut density ``rho50``.
    """
    rho50 = inputs.get("rho50", np.nan)
    near_gravity = washability.near_gravity_pct(rho50) if rho50 is not None and np.isfinite(rho50) else np.nan
    row = dict.fromkeys(PREDICTION_COLUMNS, np.nan)
    row.update({"test": washability.test, "curve": "", "note": ""})
    row.update({key: value for key, value in inputs.items() if value is not None})
    row.update(
        floats_yield_pct=prediction.floats_yield_pct,
        floats_ash_pct=prediction.floats_ash_pct,
        sinks_yield_pct=prediction.sinks_yield_pct,
        sinks_ash_pct=prediction.sinks_ash_pct,
        theoretical_yield_pct=prediction.theoretical_yield_pct,
        organic_efficiency_pct=prediction.organic_efficiency_pct,
        near_gravity_pct=near_gravity,
    )
    row["note"] = "; ".join(text for text in (inputs.get("note", ""), prediction.note) if text)
    return row


def prediction_table(rows) -> pd.DataFrame:
    """Rows of :func:`prediction_row` as a table with the columns :data:`PREDICTION_COLUMNS`."""
    return pd.DataFrame(list(rows), columns=list(PREDICTION_COLUMNS))


# --- prediction from a registry curve ---------------------------------------------------------
def partition_curve(curve="normal", *, rho50: float, ep: float, light_limit=None, heavy_limit=None):
    """The partition function :math:`P(\\rho)` of a registry curve with cut ``rho50`` and probable error ``ep``.

    Parameters
    ----------
    curve : str or DensityCurve
        A curve of :data:`tromplab.density.registry.DENSITY_CURVES` (``"normal"``,
        ``"logistic"``, ``"gompertz"`` or a ``*_limits`` variant).  A plain curve given
        ``light_limit`` or ``heavy_limit`` becomes its variant with limits.
    rho50, ep : float
        Cut density and probable error of :math:`P` itself (for a curve with limits its
        separating part is solved for them, :meth:`DensityCurve.from_indices`).
    light_limit, heavy_limit : float, optional
        Partition to the sinks of the lightest and of the heaviest material (defaults 0
        and 1), in [0, 1/4) and (3/4, 1].

    Returns
    -------
    tuple
        ``(curve, P)``: the curve record used and the vectorised function of density.

    Examples
    --------
    >>> record, p = partition_curve("normal", rho50=1.5, ep=0.04)
    >>> record.id, round(float(p(1.54)), 12)
    ('normal', 0.75)
    """
    from .registry import get_density_curve

    try:
        record = get_density_curve(curve)
    except KeyError as error:
        raise OptionError("curve", str(error.args[0]).removeprefix("unknown density curve ")) from None
    rho50 = check_cut_density(rho50, "rho50")
    ep = check_positive(ep, "ep")
    limits = light_limit is not None or heavy_limit is not None
    if limits and not record.has_limits:
        record = get_density_curve(f"{record.id}_limits")
    light = 0.0 if light_limit is None else check_share(light_limit, "light_limit")
    heavy = 1.0 if heavy_limit is None else check_share(heavy_limit, "heavy_limit")
    if not light < 0.25:
        raise OptionError("light_limit", f"must lie in [0, 0.25) for rho25 and Ep to exist, got {light_limit!r}")
    if not heavy > 0.75:
        raise OptionError("heavy_limit", f"must lie in (0.75, 1] for rho75 and Ep to exist, got {heavy_limit!r}")
    params = record.from_indices(rho50=rho50, ep=ep, light_limit=light, heavy_limit=heavy)
    return record, lambda rho: record.partition(rho, **params)


def predict(
    washability,
    *,
    curve="normal",
    rho50=None,
    ep: float | None = None,
    light_limit: float | None = None,
    heavy_limit: float | None = None,
    target_ash_pct=None,
    **read_options,
) -> pd.DataFrame:
    """Predicted yield and ash of floats and sinks, theoretical yield and organic efficiency.

    One row per washability table and per cut density (or per ash sought), with the columns
    :data:`PREDICTION_COLUMNS` (defined in ``docs/density.md``).

    Parameters
    ----------
    washability : path, DataFrame, Washability or list of Washability
        The feed(s); files and frames are read by :func:`read_washability`.
    curve : str or DensityCurveFit
        Registry curve id (see :func:`partition_curve`), or a fitted curve
        (:func:`tromplab.density.fitting.fit_density_curve`): its partition is used as
        fitted, and ``rho50``, ``ep``, the limits and ``target_ash_pct`` are not given.
    rho50 : float or sequence of float
        Cut density (or several: one row each).  Give ``rho50`` or ``target_ash_pct``.
    ep : float
        Probable error of the partition curve, relative density units, > 0.
    light_limit, heavy_limit : float, optional
        Limits of the partition curve (see :func:`partition_curve`).
    target_ash_pct : float or sequence of float
        Floats ash sought: the cut density giving it is found by Brent's method
        (:func:`rho50_for_floats_ash`) and reported in ``rho50``.
    **read_options
        Passed to :func:`read_washability` (``sum_tolerance_pct``, ``float_lower_density``, ...).

    Returns
    -------
    pandas.DataFrame

    Examples
    --------
    >>> w = washability_from_arrays([np.nan, 1.4, 1.6], [1.4, 1.6, np.nan], [50, 25, 25], [10, 50, 50])
    >>> row = predict(w, curve="normal", rho50=1.4, ep=0.05).iloc[0]
    >>> [round(float(row[name]), 3) for name in ("floats_yield_pct", "floats_ash_pct", "organic_efficiency_pct")]
    [47.784, 11.856, 91.133]
    """
    if hasattr(curve, "sample") and hasattr(curve, "params"):
        return _predict_fitted(washability, curve, read_options, rho50, ep, light_limit, heavy_limit, target_ash_pct)
    if ep is None:
        raise OptionError("ep", "is required: the probable error of the partition curve")
    if (rho50 is None) == (target_ash_pct is None):
        raise OptionError("rho50", "or target_ash_pct: give exactly one of them")
    ep = check_positive(ep, "ep")
    cuts = [check_cut_density(value, "rho50") for value in np.atleast_1d(rho50)] if rho50 is not None else []
    targets = [check_percent(value, "target_ash_pct") for value in np.atleast_1d(target_ash_pct)] if rho50 is None else []
    tables = _washabilities(washability, read_options)
    limits = {"light_limit": light_limit, "heavy_limit": heavy_limit}
    record, _ = partition_curve(curve, rho50=1.5, ep=ep, **limits)  # checks the curve and limits once
    rows = []
    for table in tables:
        for cut in cuts:
            rows.append(_prediction(table, record, cut, ep, limits))
        for target in targets:
            cut, note = rho50_for_floats_ash(table, target, lambda r: partition_curve(record, rho50=r, ep=ep, **limits)[1])
            if np.isfinite(cut):
                rows.append(_prediction(table, record, cut, ep, limits, target_ash_pct=target))
            else:
                row = dict.fromkeys(PREDICTION_COLUMNS, np.nan)
                row.update(test=table.test, curve=record.id, ep=ep, target_ash_pct=target, note=note, **_given(limits))
                rows.append(row)
    return prediction_table(rows)


def _predict_fitted(washability, fit, read_options: dict, *given) -> pd.DataFrame:
    if any(value is not None for value in given):
        raise OptionError("curve", "is a fitted curve: rho50, ep, the limits and target_ash_pct come from the fit")
    if not fit.success:
        raise OptionError("curve", f"is a failed fit ({fit.message})")
    limits = {name: fit.params[name] for name in ("light_limit", "heavy_limit") if name in fit.params}
    inputs = {"curve": fit.curve.id, "rho50": fit.indices.rho50, "ep": fit.indices.ep, **limits}
    rows = [
        prediction_row(table, predict_products(table, fit.partition), **inputs)
        for table in _washabilities(washability, read_options)
    ]
    return prediction_table(rows)


def _prediction(table: Washability, record, cut: float, ep: float, limits: dict, **extra) -> dict:
    _, partition = partition_curve(record, rho50=cut, ep=ep, **limits)
    inputs = {"curve": record.id, "rho50": cut, "ep": ep, **_given(limits), **extra}
    return prediction_row(table, predict_products(table, partition), **inputs)


def _given(limits: dict) -> dict:
    return {name: value for name, value in limits.items() if value is not None}


def _washabilities(washability, read_options: dict) -> list[Washability]:
    if isinstance(washability, Washability):
        return [washability]
    if isinstance(washability, (list, tuple)) and all(isinstance(item, Washability) for item in washability):
        return list(washability)
    return read_washability(washability, **read_options)
