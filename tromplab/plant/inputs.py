r"""The inputs of a plant: the washability of each size fraction of the feed and the device that washes it.

Washability by size fraction, one table (CSV, Excel or DataFrame), one row per size and density fraction:

``size_fraction``
    name of the size fraction (text, kept as written: ``"50x12mm"``, ``"007"``).
``fraction_pct``
    the size fraction's share of the plant feed, per cent, >= 0, the same on each of its rows;
    the size fractions add up to 100 within ``sum_tolerance_pct`` and are normalised to 100.
``density_lower``, ``density_upper``, ``mass_pct``, ``ash_pct``, ``density_mean``
    the washability of the size fraction as :func:`tromplab.density.washability.read_washability`
    reads it (``mass_pct`` within the size fraction), through the one density-fraction reader
    (:func:`tromplab.density.fractions.density_fractions`).
``<name>_pct``
    optional further qualities of each density fraction (``sulfur_pct``), per cent 0..100,
    blended by mass as the ash is.

The plant table, one row per size fraction:

``size_fraction``, ``device``, ``curve``
    the size fraction (as in the washability), the device's name (text) and its partition curve
    (a plain curve of :data:`tromplab.density.registry.DENSITY_CURVES`: ``normal``, ``logistic``,
    ``gompertz``; with ``light_limit`` / ``heavy_limit`` its variant with limits).
``rho50``
    cut density of the partition to sinks (relative density, above 1, at most 3.5).
``ep`` or ``imperfection``
    the probable error (g/cm3) or, for a device whose Ep scales with the cut, the imperfection
    I with :math:`E_p = I(\rho_{50} - 1)` (Wills & Finch 2016, ch. 11); exactly one per row;
    0 is the ideal separation (a step at the cut).
``rho50_sd``, ``ep_sd`` (or ``imperfection_sd``)
    optional standard deviations of the curve's parameters (blank = known exactly), taken
    as independent; a ``density fit`` folder gives their covariance (:func:`devices_from_fits`).
``rho50_min``, ``rho50_max``
    optional bounds of the cut density for ``plant optimize`` (default: the size fraction's
    closed density range, within (1, 3.5]).
``light_limit``, ``heavy_limit``
    optional limits of the partition (share to sinks of the lightest and heaviest material),
    held fixed.

References
----------
Wills, B. A. & Finch, J. A. (2016). *Wills' Mineral Processing Technology*, 8th ed.,
Butterworth-Heinemann, ch. 11.

ISO 923 (2000). Coal cleaning tests - Expression and presentation of results.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ..density.registry import PLAIN_CURVES, DensityCurve, get_density_curve
from ..density.washability import WASHABILITY_COLUMNS, Washability, check_reading_options, washability_of_rows
from ..errors import InputError
from ..loading.tables import Table, read_table
from ..options import DEFAULT_SUM_TOLERANCE_PCT
from ..validation import MAX_CUT_DENSITY

#: Columns of the washability-by-size table besides the qualities ``<name>_pct``.
WASHABILITY_BY_SIZE_COLUMNS = ("size_fraction", "fraction_pct") + tuple(c for c in WASHABILITY_COLUMNS if c != "test")
#: Columns of the plant table.
PLANT_COLUMNS = ("size_fraction", "device", "curve", "rho50", "ep", "imperfection", "rho50_sd", "ep_sd", "imperfection_sd",
                 "rho50_min", "rho50_max", "light_limit", "heavy_limit")  # fmt: skip
#: ``_pct`` columns that are not qualities.
_NOT_QUALITIES = ("fraction_pct", "mass_pct", "ash_pct")


@dataclass(frozen=True)
class SizeFraction:
    """One size fraction of the plant feed with its washability.

    Attributes
    ----------
    name : str
        The size fraction's name.
    feed_pct : float
        Its share of the plant feed, per cent (the size fractions add up to 100).
    washability : Washability
        Its density fractions (``mass_pct`` within the size fraction), light to heavy.
    qualities : dict
        Further qualities by name (``"sulfur"``): per cent per density fraction.
    """

    name: str
    feed_pct: float
    washability: Washability
    qualities: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Device:
    r"""The device washing one size fraction: its partition curve and how sure it is.

    Attributes
    ----------
    size_fraction, device : str
        The size fraction washed and the device's name.
    curve : DensityCurve
        The partition curve's form (a plain curve; ``light_limit``/``heavy_limit`` give its limits).
    rho50 : float
        Cut density (g/cm3).
    scale_name : str
        ``"ep"`` (Ep fixed) or ``"imperfection"`` (:math:`E_p = I(\rho_{50} - 1)`).
    scale : float
        The value of ``ep`` (g/cm3) or of the imperfection (-).
    covariance : numpy.ndarray
        2 x 2 covariance of ``(rho50, scale)``; zeros when the curve is taken as exact.
    rho50_min, rho50_max : float
        Bounds of the cut density for the optimisation (NaN: the washability's range).
    light_limit, heavy_limit : float
        Partition to sinks of the lightest and heaviest material (0 and 1: none).
    source : str
        Where the curve came from (file and row, or the fit).
    """

    size_fraction: str
    device: str
    curve: DensityCurve
    rho50: float
    scale_name: str
    scale: float
    covariance: np.ndarray
    rho50_min: float = math.nan
    rho50_max: float = math.nan
    light_limit: float = 0.0
    heavy_limit: float = 1.0
    source: str = ""

    @property
    def uncertain(self) -> bool:
        """True when the curve's parameters carry a covariance."""
        return bool(np.any(self.covariance != 0))

    def ep_at(self, rho50) -> np.ndarray:
        """The probable error at the cut ``rho50``: fixed, or ``I (rho50 - 1)``."""
        rho50 = np.asarray(rho50, dtype=float)
        return self.scale * (rho50 - 1.0) if self.scale_name == "imperfection" else np.full_like(rho50, self.scale)

    def partition(self, density, rho50=None, scale=None) -> np.ndarray:
        """Partition to sinks at ``density`` (arrays broadcast) for the cut ``rho50`` and ``scale`` (default: the device's)."""
        rho50 = np.asarray(self.rho50 if rho50 is None else rho50, dtype=float)
        scale = np.asarray(self.scale if scale is None else scale, dtype=float)
        ep = scale * (rho50 - 1.0) if self.scale_name == "imperfection" else scale
        ideal = ep == 0  # Ep 0: the ideal separation, a step at the cut (a density on the cut splits evenly)
        ep = np.where(ideal, 1.0, ep)
        if self.light_limit == 0.0 and self.heavy_limit == 1.0:
            partition = self.curve.partition(density, rho50=rho50, ep=ep)
        else:
            limited = get_density_curve(f"{self.curve.id}_limits")
            partition = limited.partition(density, **_limits_params(limited, rho50, ep, self.light_limit, self.heavy_limit))
        if not np.any(ideal):
            return partition
        above = (np.sign(np.asarray(density, dtype=float) - rho50) + 1.0) / 2.0  # 0 below the cut, 1 above, 1/2 on it
        return np.where(ideal, self.light_limit + (self.heavy_limit - self.light_limit) * above, partition)


def _limits_params(curve: DensityCurve, rho50, ep, light: float, heavy: float) -> dict:
    """``from_indices`` of a curve with limits, vectorised over rho50 and ep (its map is affine in both)."""
    base = curve.from_indices(rho50=1.0, ep=1.0, light_limit=light, heavy_limit=heavy)
    shift = 1.0 - base["rho_c"]  # rho_c = rho50 - ep * shift, ep_c = ep * base["ep_c"]
    return {"rho_c": rho50 - ep * shift, "ep_c": ep * base["ep_c"], "light_limit": light, "heavy_limit": heavy}


# --- the washability by size ---------------------------------------------------------------------
def read_plant_washability(
    path,
    *,
    sum_tolerance_pct: float = DEFAULT_SUM_TOLERANCE_PCT,
    float_lower_density: float | None = None,
    sink_upper_density: float | None = None,
    sheet=None,
    sep=None,
    decimal=None,
) -> list[SizeFraction]:
    """Read the washability of every size fraction of a plant feed from one table.

    Parameters
    ----------
    path : path or pandas.DataFrame
        The table (schema in the module docstring).
    sum_tolerance_pct : float
        Allowed deviation from 100 of the size fractions' ``fraction_pct`` and of each size
        fraction's ``mass_pct`` (percentage points).
    float_lower_density, sink_upper_density : float, optional
        Bounds closing the open float and sink fractions (as for ``read_washability``).
    sheet, sep, decimal
        As for :func:`tromplab.loading.tables.read_table`.

    Returns
    -------
    list of SizeFraction
        In the order the size fractions first appear.

    Raises
    ------
    InputError
        Naming the file, row and column of the first bad value.
    OptionError
        A negative ``sum_tolerance_pct`` or a bound that is not above 0, as
        :func:`tromplab.density.read_washability` and the command line refuse them.
    """
    sum_tolerance_pct, float_lower_density, sink_upper_density = check_reading_options(
        sum_tolerance_pct, float_lower_density, sink_upper_density
    )
    table = read_table(path, sheet=sheet, sep=sep, decimal=decimal, text_columns=("size_fraction",))
    qualities = [c for c in table.frame.columns if str(c).endswith("_pct") and c not in _NOT_QUALITIES]
    table.refuse_unknown([*WASHABILITY_BY_SIZE_COLUMNS, *qualities], what="washability-by-size table")
    table.require("size_fraction", "fraction_pct", "density_lower", "density_upper", "mass_pct", "ash_pct")
    names = table.names("size_fraction", what="size fraction")
    shares = table.numeric("fraction_pct")
    table.refuse_outside(shares, "fraction_pct", 0.0, 100.0)
    quality_values = {column: table.numeric(column) for column in qualities}
    for column, values in quality_values.items():
        table.refuse_outside(values, column, 0.0, 100.0)
    fractions = []
    for name in dict.fromkeys(names):
        rows = np.flatnonzero(names == name)
        different = rows[shares[rows] != shares[rows[0]]]
        if different.size:
            raise table.error(f"fraction_pct differs between rows of the size fraction '{name}' ({shares[rows[0]]:g} "
                              f"and {shares[different[0]]:g}); give its share of the plant feed on each of its rows",
                              index=int(different[0]), column="fraction_pct")  # fmt: skip
        washability = washability_of_rows(table.subset(rows), name, sum_tolerance_pct, float_lower_density, sink_upper_density)
        quality = {column.removesuffix("_pct"): values[rows] for column, values in quality_values.items()}
        fractions.append(SizeFraction(name, float(shares[rows[0]]), washability, quality))
    total = sum(fraction.feed_pct for fraction in fractions)
    if abs(total - 100.0) > sum_tolerance_pct:
        raise InputError(f"the size fractions' fraction_pct add up to {total:.6g}, not 100 (tolerance {sum_tolerance_pct:g} "
                         "percentage points)", source=table.source, column="fraction_pct")  # fmt: skip
    return [SizeFraction(f.name, f.feed_pct * 100.0 / total, f.washability, f.qualities) for f in fractions]


# --- the plant table ------------------------------------------------------------------------------
def read_plant(path, fractions: list[SizeFraction], *, sheet=None, sep=None, decimal=None) -> list[Device]:
    """Read the plant table: the device, curve and cut of every size fraction, in the order of ``fractions``.

    Raises
    ------
    InputError
        Naming the file, row and column: an unknown curve, a size fraction without washability or
        given twice, a size fraction of the washability without a device, both or neither of ``ep``
        and ``imperfection``, a value out of range.
    """
    table = read_table(path, sheet=sheet, sep=sep, decimal=decimal, text_columns=("size_fraction", "device", "curve"))
    table.refuse_unknown(PLANT_COLUMNS, what="plant table")
    table.require("size_fraction", "device", "curve", "rho50")
    if "ep" not in table.frame.columns and "imperfection" not in table.frame.columns:
        raise InputError("the plant table needs the column ep or imperfection", source=table.source)
    names = table.names("size_fraction", what="size fraction")
    known = [fraction.name for fraction in fractions]
    devices = {}
    for index, name in enumerate(names):
        if name not in known:
            raise table.error(f"size fraction '{name}' is not in the washability table ({', '.join(known)})",
                              index=index, column="size_fraction")  # fmt: skip
        if name in devices:
            raise table.error(f"size fraction '{name}' has a device already", index=index, column="size_fraction")
        devices[name] = _device(table, index, name)
    missing = [name for name in known if name not in devices]
    if missing:
        raise InputError(f"no device for the size fraction(s) {', '.join(missing)} of the washability table",
                         source=table.source, column="size_fraction")  # fmt: skip
    return [devices[name] for name in known]


def _cell(table: Table, index: int, column: str, low: float, high: float, *, what: str) -> float:
    """One optional number of the plant table (NaN when blank or absent), within [low, high]."""
    if column not in table.frame.columns:
        return math.nan
    value = float(table.subset([index]).numeric(column, allow_blank=True)[0])
    if math.isfinite(value) and not low <= value <= high:
        raise table.error(f"{value:g} is not {what}", index=index, column=column)
    return value


def _device(table: Table, index: int, name: str) -> Device:
    curve_id = str(table.frame["curve"].iloc[index]).strip()
    plain = {curve.id: curve for curve in PLAIN_CURVES}
    if curve_id not in plain:
        raise table.error(f"unknown curve '{curve_id}'; give one of {', '.join(plain)} (limits in light_limit, heavy_limit)",
                          index=index, column="curve")  # fmt: skip
    rho50 = _cell(
        table, index, "rho50", 1.0 + 1e-9, MAX_CUT_DENSITY, what=f"a cut density above 1 and at most {MAX_CUT_DENSITY:g}"
    )
    if math.isnan(rho50):
        raise table.error("value is missing (blank or NaN)", index=index, column="rho50")
    ep = _cell(table, index, "ep", 0.0, 2.0, what="a probable error in [0, 2] g/cm3 (0: an ideal separation)")
    imperfection = _cell(table, index, "imperfection", 0.0, 5.0, what="an imperfection in [0, 5] (0: an ideal separation)")
    if math.isnan(ep) == math.isnan(imperfection):
        raise table.error("give exactly one of ep and imperfection", index=index,
                          column="ep" if "ep" in table.frame.columns else "imperfection")  # fmt: skip
    scale_name, scale = ("ep", ep) if math.isfinite(ep) else ("imperfection", imperfection)
    rho50_sd = _cell(table, index, "rho50_sd", 0.0, 1.0, what="a standard deviation in [0, 1] g/cm3")
    scale_sd = _cell(table, index, f"{scale_name}_sd", 0.0, scale, what=f"a standard deviation in [0, {scale_name}]")
    other = "imperfection_sd" if scale_name == "ep" else "ep_sd"
    if math.isfinite(_cell(table, index, other, -np.inf, np.inf, what="")):
        raise table.error(f"the device is given by {scale_name}: give {scale_name}_sd, not {other}", index=index, column=other)
    low = _cell(table, index, "rho50_min", 1.0 + 1e-9, MAX_CUT_DENSITY, what=f"a density above 1 and at most {MAX_CUT_DENSITY:g}")
    high = _cell(
        table, index, "rho50_max", 1.0 + 1e-9, MAX_CUT_DENSITY, what=f"a density above 1 and at most {MAX_CUT_DENSITY:g}"
    )
    if math.isfinite(low) and math.isfinite(high) and not low < high:
        raise table.error(f"rho50_min {low:g} is not below rho50_max {high:g}", index=index, column="rho50_min")
    light = _cell(table, index, "light_limit", 0.0, 0.25 - 1e-9, what="a light-end limit in [0, 0.25)")
    heavy = _cell(table, index, "heavy_limit", 0.75 + 1e-9, 1.0, what="a heavy-end limit in (0.75, 1]")
    covariance = np.diag([np.nan_to_num(rho50_sd) ** 2, np.nan_to_num(scale_sd) ** 2])
    device_name = table.names("device", what="device")[index]
    return Device(name, device_name, plain[curve_id], rho50, scale_name, scale, covariance, low, high,
                  0.0 if math.isnan(light) else light, 1.0 if math.isnan(heavy) else heavy,
                  source=f"{table.source}, row {table.rows[index]}")  # fmt: skip


# --- the curves of a density fit --------------------------------------------------------------------
def devices_from_fits(fits, fractions: list[SizeFraction]) -> list[Device]:
    """The devices of a ``tromplab density fit`` result: each size fraction's best curve with its covariance.

    Parameters
    ----------
    fits : path or DensityResult
        A results folder of ``tromplab density fit`` (its ``fits.csv`` and ``covariance.csv``),
        or the :class:`~tromplab.density.results.DensityResult` itself.
    fractions : list of SizeFraction
        The size fractions to find a curve for.

    Notes
    -----
    A size fraction of the washability is matched to the fits whose ``size_fraction`` (``"8-16 mm"``)
    or, failing that, whose ``test`` has its name; of those, the curve ranked first.  The
    covariance of ``(rho50, ep)`` is ``covariance.csv``'s (:mod:`tromplab.density.covariance`);
    without it (a folder written before tromplab wrote it) the curves are taken as exact.  The
    device is named after the test.  Curves with limits keep their fitted limits, held fixed.

    Raises
    ------
    InputError
        Naming the folder's file: no fits.csv, a size fraction without a fitted curve or matched
        by fits of several tests.
    """
    if hasattr(fits, "fits_table"):
        from ..density.covariance import covariance_table

        table, source = fits.fits_table(), "the density fits"
        covariance = covariance_table(fits.fits, sizes="size_fraction" in table.columns)
    else:
        folder = Path(fits)
        source = str(folder / "fits.csv")
        if not (folder / "fits.csv").is_file():
            raise InputError("not a density fit results folder: fits.csv is missing", source=str(folder))
        table = pd.read_csv(folder / "fits.csv", dtype={"test": str, "size_fraction": str}, keep_default_na=False, na_values=[""])
        covariance = _read_covariance(folder / "covariance.csv")
    needed = {"test", "curve", "rank", "rho50", "ep", "success"}
    if not needed <= set(table.columns):
        raise InputError(f"fits.csv lacks the column(s) {', '.join(sorted(needed - set(table.columns)))}", source=source)
    best = table[(table["rank"] == 1) & table["success"].astype(str).isin(["True", "true", "1"])]
    devices = []
    for fraction in fractions:
        matched = best[best["size_fraction"].fillna("") == fraction.name] if "size_fraction" in best.columns else best[:0]
        if matched.empty:
            matched = best[best["test"] == fraction.name]
        if len(matched) != 1:
            found = "no fitted curve" if matched.empty else f"fits of {len(matched)} tests ({', '.join(matched['test'])})"
            raise InputError(f"size fraction '{fraction.name}': {found} in the density fits", source=source)
        devices.append(_fitted_device(matched.iloc[0], fraction.name, covariance, source))
    return devices


def _read_covariance(path: Path) -> pd.DataFrame | None:
    if not path.is_file():
        return None
    return pd.read_csv(path, dtype={"test": str, "size_fraction": str}, keep_default_na=False, na_values=[""])


def _fitted_device(row: pd.Series, name: str, covariance: pd.DataFrame | None, source: str) -> Device:
    curve = get_density_curve(row["curve"])
    plain = curve.limits_of or curve
    limits = (float(row.get("light_limit", 0.0)), float(row.get("heavy_limit", 1.0))) if curve.has_limits else (0.0, 1.0)
    matrix = np.zeros((2, 2))
    if covariance is not None:
        size = row.get("size_fraction", "")
        mine = covariance[(covariance["test"] == row["test"]) & (covariance["curve"] == row["curve"])]
        if "size_fraction" in covariance.columns:
            mine = mine[mine["size_fraction"].fillna("") == ("" if pd.isna(size) else size)]
        if len(mine) != 2:
            mine = mine[:0]
        block = mine.set_index("parameter").reindex(["rho50", "ep"])[["rho50", "ep"]].to_numpy(float)
        if np.isfinite(block).all():
            matrix = block
    return Device(name, str(row["test"]), plain, float(row["rho50"]), "ep", float(row["ep"]), matrix,
                  light_limit=limits[0], heavy_limit=limits[1], source=f"{source} ({row['test']}, {row['curve']})")  # fmt: skip
