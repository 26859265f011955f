r"""A tested separation evaluated in the standard form: :func:`evaluate` and :class:`SeparationEvaluation`.

A two-product float-sink test gives the analyses of the clean coal (floats) and the reject
(sinks) - and of the feed - by density fraction, with the ash of each
(:func:`tromplab.density.read_density`, the float-sink layout with ``feed_ash_pct`` or
``floats_ash_pct`` and ``sinks_ash_pct``).  From them, after ISO 923 and Wills & Finch (2016,
ch. 11):

- the partition coefficient of each density fraction (the reader's mass balance) and the cut
  density, probable error and imperfection of the curve fitted to them
  (:func:`tromplab.density.fitting.fit_density_curve`);
- the feed's washability as the products recombine it: fraction :math:`i` holds
  :math:`m_i = Y f_i + (1 - Y) s_i` of the feed with ash
  :math:`(Y f_i a^F_i + (1 - Y) s_i a^S_i)/m_i`;
- the actual clean coal: yield :math:`Y` and ash :math:`A = \sum_i f_i a^F_i`;
- the theoretical yield at the actual ash :math:`Y_T(A)` and the theoretical ash at the actual
  yield :math:`A_T(Y)`, read off the cumulative floats curve of that washability (an ideal cut
  inside a fraction takes part of it, each fraction of uniform ash);
- yield error :math:`Y_T(A) - Y`, ash error :math:`A - A_T(Y)`, organic efficiency
  :math:`100\,Y / Y_T(A)`;
- misplaced material at the cut density (floats in the reject, sinks in the clean coal, per
  cent of the feed, a fraction cut by the cut density counting with the share of its range on
  each side) and the near-gravity material within +/- 0.1 of it.

``tromplab plant evaluate FILE -o DIR`` writes :meth:`SeparationEvaluation.save`:
``evaluation.csv`` (one row per test), ``fractions.csv`` (one row per test and density
fraction) and ``summary.txt``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..density.fitting import fit_density_curve
from ..density.readers import DensitySample, read_density
from ..density.registry import get_density_curve
from ..density.washability import Washability, washability_from_arrays
from ..errors import InputError, OptionError
from ..options import DEFAULT_SUM_TOLERANCE_PCT
from ..results_contract import ResultContract

#: The columns of ``evaluation.csv``.
EVALUATION_COLUMNS = ("test", "size_fraction", "curve", "rho50", "ep", "imperfection", "feed_ash_pct", "clean_yield_pct",
                      "clean_ash_pct", "reject_ash_pct", "theoretical_yield_pct", "yield_error_pct", "theoretical_ash_pct",
                      "ash_error_pct", "organic_efficiency_pct", "misplaced_floats_pct", "misplaced_sinks_pct",
                      "near_gravity_pct", "note")  # fmt: skip


@dataclass(frozen=True)
class SeparationEvaluation(ResultContract):
    """The evaluation of tested separations in the standard form (ISO 923).

    Attributes
    ----------
    evaluation : pandas.DataFrame
        ``evaluation.csv``: one row per test (columns in ``docs/plant.md``).
    fractions : pandas.DataFrame
        ``fractions.csv``: one row per test and density fraction: the recombined feed, its ash,
        each product's share of the feed and the partition coefficient, measured and fitted.
    samples : list of DensitySample
        The tests as read.
    """

    evaluation: pd.DataFrame
    fractions: pd.DataFrame
    samples: list

    def summary(self) -> pd.DataFrame:
        """``evaluation.csv``: one row per test."""
        return self.evaluation

    def _result_context(self) -> str:
        return f"Evaluation of {len(self.samples)} tested separation(s) ({', '.join(s.label for s in self.samples)})"

    def save(self, outdir) -> dict:
        """Write ``evaluation.csv``, ``fractions.csv`` and ``summary.txt`` (what ``tromplab plant evaluate`` writes).

        Returns
        -------
        dict
            File name -> written path.
        """
        from ..output.csv_parts import file_writers
        from ..output.outputs import replace_folder

        writers = file_writers(
            {"evaluation": self.evaluation, "fractions": self.fractions}, texts={"summary.txt": self.report() + "\n"}
        )
        return replace_folder(writers, outdir)


def evaluate(
    data, *, curve: str = "normal", floats_yield: float | None = None, sum_tolerance_pct: float = DEFAULT_SUM_TOLERANCE_PCT,
    sheet=None, sep=None, decimal=None,
) -> SeparationEvaluation:  # fmt: skip
    """Evaluate every two-product float-sink test of a table in the standard form.

    What ``tromplab plant evaluate`` does, with its options as keywords of the same names.

    Parameters
    ----------
    data : path or DataFrame
        Float-sink analyses of the products with ash (:func:`tromplab.density.read_density`).
    curve : str
        The partition curve fitted for rho50, Ep and the imperfection (default ``normal``).
    floats_yield, sum_tolerance_pct, sheet, sep, decimal
        As for :func:`tromplab.density.read_density`.

    Returns
    -------
    SeparationEvaluation

    Raises
    ------
    InputError
        Not a float-sink table, or no ash for a product that holds material.
    """
    try:
        get_density_curve(curve)
    except KeyError as error:
        raise OptionError("curve", str(error.args[0])) from None
    samples = read_density(
        data, sheet=sheet, sep=sep, decimal=decimal, floats_yield=floats_yield, sum_tolerance_pct=sum_tolerance_pct
    )
    rows, parts = [], []
    for sample in samples:
        if sample.layout != "float-sink":
            raise InputError(f"test '{sample.test}': an evaluation needs float-sink analyses of the products with ash, "
                             f"not {sample.layout}", source=sample.source)  # fmt: skip
        row, part = _evaluate_one(sample, curve)
        rows.append(row)
        parts.append(part)
    evaluation = pd.DataFrame(rows).reindex(columns=list(EVALUATION_COLUMNS))
    return SeparationEvaluation(evaluation, pd.concat(parts, ignore_index=True), samples)


def _product_ash(sample: DensitySample) -> tuple[np.ndarray, np.ndarray]:
    """The ash of each fraction in the floats and the sinks (each product's own, else the feed's)."""
    points = sample.points
    if not any(column in points for column in ("feed_ash_pct", "floats_ash_pct", "sinks_ash_pct")):
        raise InputError(f"test '{sample.test}': no ash columns (feed_ash_pct, or floats_ash_pct and sinks_ash_pct)",
                         source=sample.source)  # fmt: skip
    feed = points["feed_ash_pct"].to_numpy(float) if "feed_ash_pct" in points else np.full(len(points), np.nan)
    ashes = []
    for product in ("floats", "sinks"):
        column = f"{product}_ash_pct"
        ash = points[column].to_numpy(float) if column in points else np.full(len(points), np.nan)
        ash = np.where(np.isnan(ash), feed, ash)
        missing = np.flatnonzero(np.isnan(ash) & (points[product].to_numpy(float) > 0))
        if missing.size:
            raise InputError(f"test '{sample.test}': the {product} hold the fraction at {points['density'].iloc[missing[0]]:g} "
                             f"but no ash is given for it", source=sample.source, row=int(points["row"].iloc[missing[0]]),
                             column=column)  # fmt: skip
        ashes.append(np.nan_to_num(ash))
    return ashes[0], ashes[1]


def _evaluate_one(sample: DensitySample, curve: str) -> tuple[dict, pd.DataFrame]:
    points = sample.points
    floats_yield = float(sample.floats_yield)
    floats, sinks = points["floats"].to_numpy(float), points["sinks"].to_numpy(float)
    floats_ash, sinks_ash = _product_ash(sample)
    clean, reject = 100 * floats_yield * floats, 100 * (1 - floats_yield) * sinks  # per cent of the feed
    feed = clean + reject
    feed_ash = np.divide(clean * floats_ash + reject * sinks_ash, feed, out=np.zeros_like(feed), where=feed > 0)
    washability = washability_from_arrays(points["density_lower"], points["density_upper"], feed, feed_ash, test=sample.test)
    fit = fit_density_curve(sample, curve)
    rho50 = fit.indices.rho50 if fit.success else np.nan
    yield_pct, ash_pct = 100 * floats_yield, float(np.sum(floats * floats_ash))
    theoretical_yield = washability.theoretical_yield_pct(ash_pct)
    theoretical_ash = theoretical_ash_pct(washability, yield_pct)
    misplaced_floats, misplaced_sinks = _misplaced(washability, clean, reject, rho50)
    row = {"test": sample.test, "size_fraction": sample.size_fraction, "curve": fit.curve.id, "rho50": rho50,
           "ep": fit.indices.ep if fit.success else np.nan, "imperfection": fit.indices.imperfection if fit.success else np.nan,
           "feed_ash_pct": washability.feed_ash_pct, "clean_yield_pct": yield_pct, "clean_ash_pct": ash_pct,
           "reject_ash_pct": float(np.sum(sinks * sinks_ash)), "theoretical_yield_pct": theoretical_yield,
           "yield_error_pct": theoretical_yield - yield_pct, "theoretical_ash_pct": theoretical_ash,
           "ash_error_pct": ash_pct - theoretical_ash, "organic_efficiency_pct": 100 * yield_pct / theoretical_yield,
           "misplaced_floats_pct": misplaced_floats, "misplaced_sinks_pct": misplaced_sinks,
           "near_gravity_pct": washability.near_gravity_pct(rho50) if np.isfinite(rho50) else np.nan,
           "note": "; ".join((*sample.notes, *([fit.message] if not fit.success else fit.notes)))}  # fmt: skip
    part = pd.DataFrame({"test": sample.test, "size_fraction": sample.size_fraction, "density_lower": points["density_lower"],
                         "density_upper": points["density_upper"], "density": points["density"], "feed_pct": feed,
                         "feed_ash_pct": feed_ash, "clean_pct": clean, "reject_pct": reject,
                         "partition_sinks": points["partition_sinks"],
                         "fitted_partition_sinks": fit.partition(points["density"].to_numpy(float)) if fit.success else np.nan})  # fmt: skip
    return row, part


def theoretical_ash_pct(washability: Washability, yield_pct: float) -> float:
    """Ash of the ideal floats product of ``yield_pct`` (per cent of the feed): the lightest material up to that yield.

    The cumulative ash mass is linear in the yield within a fraction (each fraction of uniform ash).

    Examples
    --------
    >>> w = washability_from_arrays([np.nan, 1.4, 1.6], [1.4, 1.6, np.nan], [50, 25, 25], [10, 50, 50])
    >>> round(theoretical_ash_pct(w, 60.0), 6)  # all of -1.4 and 10 of 1.4-1.6: (500 + 500) / 60
    16.666667
    """
    if not 0 < yield_pct <= 100:
        return np.nan
    mass = np.append(0.0, np.cumsum(washability.mass_pct))
    ash_mass = np.append(0.0, np.cumsum(washability.mass_pct * washability.ash_pct))
    return float(np.interp(yield_pct, mass, ash_mass) / yield_pct)


def _misplaced(washability: Washability, clean: np.ndarray, reject: np.ndarray, rho50: float) -> tuple[float, float]:
    if not np.isfinite(rho50):
        return np.nan, np.nan
    width = washability.closed_upper - washability.closed_lower
    below = np.clip((rho50 - washability.closed_lower) / width, 0.0, 1.0)
    return float(np.sum(reject * below)), float(np.sum(clean * (1.0 - below)))
