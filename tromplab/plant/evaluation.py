r"""A tested separation evaluated in the standard form: :func:`evaluate` and :class:`SeparationEvaluation`.

Three kinds of test, after ISO 923 and Wills & Finch (2016, ch. 11):

- a **two-product float-sink test**: the analyses of the clean coal (floats) and the reject
  (sinks) - and of the feed - by density fraction, with the ash of each
  (:func:`tromplab.density.read_density`, the float-sink layout with ``feed_ash_pct`` or
  ``floats_ash_pct`` and ``sinks_ash_pct``).  The feed's washability is what the products
  recombine: fraction :math:`i` holds :math:`m_i = Y f_i + (1 - Y) s_i` of the feed with ash
  :math:`(Y f_i a^F_i + (1 - Y) s_i a^S_i)/m_i`; the clean coal is measured;
- a **tracer test** (tracer counts by density, as ``density fit`` reads them) with the washability
  of the feed it separated (``washability``, :func:`tromplab.density.read_washability`): the
  partition curve fitted to the counts (binomial maximum likelihood) applied to the washability
  gives the products, :math:`c_i = m_i (1 - \hat P(\rho_i))`, :math:`r_i = m_i \hat P(\rho_i)`;
- a **three-product test** (clean coal, middlings, reject; :mod:`tromplab.plant.three_products`):
  each of its two cuts is evaluated as the two-product test of its own feed, the primary on the
  feed, the secondary on the primary's sinks.

For each cut:

- the partition coefficient of each density fraction (the reader's mass balance, or the tracer
  counts) and the cut density, probable error and imperfection of the curve fitted to them
  (:func:`tromplab.density.fitting.fit_density_curve`);
- the clean coal: yield :math:`Y` and ash :math:`A`;
- the theoretical yield at the actual ash :math:`Y_T(A)` and the theoretical ash at the actual
  yield :math:`A_T(Y)`, read off the cumulative floats curve of the washability (an ideal cut
  inside a fraction takes part of it, each fraction of uniform ash);
- yield error :math:`Y_T(A) - Y`, ash error :math:`A - A_T(Y)`, organic efficiency
  :math:`100\,Y / Y_T(A)`;
- misplaced material at the cut density (floats in the reject, sinks in the clean coal, per
  cent of the cut's feed, a fraction cut by the cut density counting with the share of its range
  on each side) and the near-gravity material within +/- 0.1 of it.

``tromplab plant evaluate FILE -o DIR`` writes :meth:`SeparationEvaluation.save`:
``evaluation.csv`` (one row per test and cut), ``fractions.csv`` (one row per test, cut and
density fraction), ``tracers.csv`` (tracer tests: one row per test and tracer density) and
``summary.txt``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from ..density.fitting import DensityCurveFit, fit_density_curve
from ..density.readers import DensitySample, read_density
from ..density.registry import get_density_curve
from ..density.washability import Washability, read_washability, washability_from_arrays
from ..errors import InputError, OptionError
from ..loading.tables import read_table
from ..options import DEFAULT_SUM_TOLERANCE_PCT
from ..results_contract import ResultContract
from ..validation import check_non_negative
from .three_products import ThreeProductTest, is_three_product, read_three_product_tests

#: The columns of ``evaluation.csv``.
EVALUATION_COLUMNS = ("test", "size_fraction", "cut", "cut_feed_pct", "curve", "rho50", "ep", "imperfection", "feed_ash_pct",
                      "clean_yield_pct", "clean_ash_pct", "reject_ash_pct", "theoretical_yield_pct", "yield_error_pct",
                      "theoretical_ash_pct", "ash_error_pct", "organic_efficiency_pct", "misplaced_floats_pct",
                      "misplaced_sinks_pct", "near_gravity_pct", "note")  # fmt: skip
#: The columns of ``tracers.csv``.
TRACER_COLUMNS = ("test", "size_fraction", "density", "placed", "recovered", "sinks", "floats", "partition_sinks",
                  "fitted_partition_sinks")  # fmt: skip
#: The names of the cuts in the ``cut`` column: a two-product test's one cut, a three-product test's two.
CUTS = ("single", "primary", "secondary")


@dataclass(frozen=True)
class SeparationEvaluation(ResultContract):
    """The evaluation of tested separations in the standard form (ISO 923).

    Attributes
    ----------
    evaluation : pandas.DataFrame
        ``evaluation.csv``: one row per test and cut (columns in ``docs/plant.md``).
    fractions : pandas.DataFrame
        ``fractions.csv``: one row per test, cut and density fraction: the cut's feed, its ash,
        each product's share of the cut's feed and the partition coefficient, measured and fitted.
    samples : list of DensitySample
        The tests as read (a three-product test: its two cuts, as two-product tests of their feeds).
    tracers : pandas.DataFrame
        ``tracers.csv``: one row per tracer test and tracer density, the counts and the partition
        measured and fitted (no rows without tracer tests; the file is then not written).
    """

    evaluation: pd.DataFrame
    fractions: pd.DataFrame
    samples: list
    tracers: pd.DataFrame = None

    def summary(self) -> pd.DataFrame:
        """``evaluation.csv``: one row per test and cut."""
        return self.evaluation

    def _result_context(self) -> str:
        tests = list(dict.fromkeys(self.evaluation["test"]))
        return f"Evaluation of {len(tests)} tested separation(s) ({', '.join(tests)}), {len(self.evaluation)} cut(s)"

    def save(self, outdir) -> dict:
        """Write ``evaluation.csv``, ``fractions.csv``, ``tracers.csv`` (with tracer tests) and ``summary.txt``
        (what ``tromplab plant evaluate`` writes).

        Returns
        -------
        dict
            File name -> written path.
        """
        from ..output.csv_parts import file_writers
        from ..output.outputs import replace_folder

        tables = {"evaluation": self.evaluation, "fractions": self.fractions}
        if self.tracers is not None and len(self.tracers):
            tables["tracers"] = self.tracers
        writers = file_writers(tables, texts={"summary.txt": self.report() + "\n"})
        return replace_folder(writers, outdir)


def evaluate(
    data, *, curve: str = "normal", floats_yield: float | None = None, washability=None,
    sum_tolerance_pct: float = DEFAULT_SUM_TOLERANCE_PCT, sheet=None, sep=None, decimal=None,
) -> SeparationEvaluation:  # fmt: skip
    """Evaluate every tested separation of a table in the standard form: two-product float-sink, tracer or three-product tests.

    What ``tromplab plant evaluate`` does, with its options as keywords of the same names.

    Parameters
    ----------
    data : path or DataFrame
        Float-sink analyses of the two products with ash, or tracer counts
        (:func:`tromplab.density.read_density`), or the analyses of three products with ash
        (:mod:`tromplab.plant.three_products`).
    curve : str
        The partition curve fitted for rho50, Ep and the imperfection (default ``normal``).
    floats_yield : float, optional
        As for :func:`tromplab.density.read_density` (two-product float-sink tests only).
    washability : path, DataFrame, Washability or list of Washability, optional
        The washability of the feed of the tracer tests (:func:`tromplab.density.read_washability`):
        one table for every test, or one per test named after the test or its size fraction.
        Needed by tracer tests, refused with float-sink tests (their products give the feed's).
    sum_tolerance_pct, sheet, sep, decimal
        As for :func:`tromplab.density.read_density`.

    Returns
    -------
    SeparationEvaluation

    Raises
    ------
    InputError
        Naming the file, row and column: not a density table, no ash for a product that holds
        material, a tracer test without a washability of its feed.
    """
    try:
        get_density_curve(curve)
    except KeyError as error:
        raise OptionError("curve", str(error.args[0])) from None
    sum_tolerance_pct = check_non_negative(sum_tolerance_pct, "sum_tolerance_pct")
    read = {"sheet": sheet, "sep": sep, "decimal": decimal}
    if is_three_product(read_table(data, **read).frame.columns):
        if floats_yield is not None:
            raise OptionError("floats_yield", "is for two-product tests: give a three-product test's yields in its columns "
                              "clean_yield and middlings_yield")  # fmt: skip
        _refuse_washability(washability, "a three-product test's products give the feed's washability")
        tests = read_three_product_tests(data, sum_tolerance_pct=sum_tolerance_pct, **read)
        return _evaluated([part for test in tests for part in _three_product_parts(test, curve, sum_tolerance_pct)])
    samples = read_density(data, floats_yield=floats_yield, sum_tolerance_pct=sum_tolerance_pct, **read)
    layouts = {sample.layout for sample in samples}
    if "partition" in layouts or layouts == {"tracers", "float-sink"}:
        raise InputError("an evaluation needs float-sink analyses of the products with ash, or tracer counts with "
                         f"the feed's washability, not {' and '.join(sorted(layouts))}", source=samples[0].source)  # fmt: skip
    if layouts == {"float-sink"}:
        _refuse_washability(washability, "a float-sink test's products give the feed's washability")
        return _evaluated([_evaluate_one(sample, curve) for sample in samples])
    if washability is None:
        raise OptionError("washability", "is needed to evaluate a tracer test: give the float-sink analysis with ash of "
                          "the feed it separated")  # fmt: skip
    tables = _washabilities(washability, sum_tolerance_pct)
    return _evaluated([_evaluate_tracers(sample, _washability_for(sample, tables), curve) for sample in samples])


def _refuse_washability(washability, why: str) -> None:
    if washability is not None:
        raise OptionError("washability", f"is for tracer tests: {why}")


def _evaluated(parts: list) -> SeparationEvaluation:
    rows, fractions, samples, tracers = zip(*parts)
    evaluation = pd.DataFrame(list(rows)).reindex(columns=list(EVALUATION_COLUMNS))
    counted = [table for table in tracers if table is not None]
    tracer_table = pd.concat(counted, ignore_index=True) if counted else pd.DataFrame(columns=list(TRACER_COLUMNS))
    return SeparationEvaluation(evaluation, pd.concat(fractions, ignore_index=True), list(samples), tracer_table)


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


def _evaluate_one(sample: DensitySample, curve: str, *, cut: str = "single", cut_feed_pct: float = 100.0, notes=()):
    """A two-product float-sink test (or a cut of a three-product one): its row, its fractions, the sample, no tracers."""
    points = sample.points
    floats_yield = float(sample.floats_yield)
    floats, sinks = points["floats"].to_numpy(float), points["sinks"].to_numpy(float)
    floats_ash, sinks_ash = _product_ash(sample)
    clean, reject = 100 * floats_yield * floats, 100 * (1 - floats_yield) * sinks  # per cent of the cut's feed
    feed = clean + reject
    feed_ash = np.divide(clean * floats_ash + reject * sinks_ash, feed, out=np.zeros_like(feed), where=feed > 0)
    washability = washability_from_arrays(points["density_lower"], points["density_upper"], feed, feed_ash, test=sample.test)
    fit = fit_density_curve(sample, curve)
    ashes = (float(np.sum(floats * floats_ash)), float(np.sum(sinks * sinks_ash)))
    row = {"test": sample.test, "size_fraction": sample.size_fraction, "cut": cut, "cut_feed_pct": cut_feed_pct,
           **_standard_form(washability, fit, clean, reject, *ashes, yield_pct=100 * floats_yield),
           "note": "; ".join((*notes, *sample.notes, *([fit.message] if not fit.success else fit.notes)))}  # fmt: skip
    part = _fractions_table(sample, cut, washability, points["density"], clean, reject, points["partition_sinks"], fit)
    return row, part, sample, None


def _standard_form(
    washability: Washability, fit: DensityCurveFit, clean, reject, clean_ash: float, reject_ash: float, yield_pct: float
) -> dict:
    """The cut's indices and performance from its products by density fraction (per cent of its feed), their ash and
    the clean coal's yield (per cent of the cut's feed)."""
    rho50 = fit.indices.rho50 if fit.success else np.nan
    theoretical_yield = washability.theoretical_yield_pct(clean_ash)
    theoretical_ash = theoretical_ash_pct(washability, yield_pct)
    misplaced_floats, misplaced_sinks = _misplaced(washability, clean, reject, rho50)
    return {"curve": fit.curve.id, "rho50": rho50, "ep": fit.indices.ep if fit.success else np.nan,
            "imperfection": fit.indices.imperfection if fit.success else np.nan, "feed_ash_pct": washability.feed_ash_pct,
            "clean_yield_pct": yield_pct, "clean_ash_pct": clean_ash, "reject_ash_pct": reject_ash,
            "theoretical_yield_pct": theoretical_yield, "yield_error_pct": theoretical_yield - yield_pct,
            "theoretical_ash_pct": theoretical_ash, "ash_error_pct": clean_ash - theoretical_ash,
            "organic_efficiency_pct": 100 * yield_pct / theoretical_yield, "misplaced_floats_pct": misplaced_floats,
            "misplaced_sinks_pct": misplaced_sinks,
            "near_gravity_pct": washability.near_gravity_pct(rho50) if np.isfinite(rho50) else np.nan}  # fmt: skip


def _fractions_table(sample, cut, washability: Washability, density, clean, reject, measured, fit) -> pd.DataFrame:
    """``fractions.csv``'s rows of one cut; ``density`` where each fraction's partition is read."""
    density = np.asarray(density, dtype=float)
    fitted = fit.partition(density) if fit.success else np.nan
    return pd.DataFrame({"test": sample.test, "size_fraction": sample.size_fraction, "cut": cut,
                         "density_lower": washability.density_lower, "density_upper": washability.density_upper,
                         "density": density, "feed_pct": clean + reject, "feed_ash_pct": washability.ash_pct,
                         "clean_pct": clean, "reject_pct": reject, "partition_sinks": measured,
                         "fitted_partition_sinks": fitted})  # fmt: skip


def _three_product_parts(test: ThreeProductTest, curve: str, tolerance: float) -> list:
    """The primary and the secondary cut of a three-product test, each a two-product test of its own feed."""
    clean, middlings, reject = test.yields
    parts = []
    for cut, table, floats_yield, feed_pct in (("primary", test.primary, clean, 100.0),
                                               ("secondary", test.secondary, middlings / (middlings + reject),
                                                100.0 * (middlings + reject))):  # fmt: skip
        (sample,) = read_density(table, floats_yield=floats_yield, sum_tolerance_pct=tolerance)
        sample = replace(sample, source=test.source)
        parts.append(_evaluate_one(sample, curve, cut=cut, cut_feed_pct=feed_pct, notes=(test.yield_note,)))
    return parts


# --- tracer tests ---------------------------------------------------------------------------
def _washabilities(washability, tolerance: float) -> list[Washability]:
    if isinstance(washability, Washability):
        return [washability]
    if isinstance(washability, list | tuple) and all(isinstance(item, Washability) for item in washability):
        return list(washability)
    return read_washability(washability, sum_tolerance_pct=tolerance)


def _washability_for(sample: DensitySample, tables: list[Washability]) -> Washability:
    """The washability of the feed of a tracer test: the only one, else the one named after its size fraction or test."""
    if len(tables) == 1:
        return tables[0]
    for name in (sample.size_fraction, sample.test):
        named = [table for table in tables if name and table.test == name]
        if named:
            return named[0]
    raise InputError(f"no washability for the tracer test {sample.label}: name a washability table after the test or its "
                     f"size fraction (tables: {', '.join(table.test for table in tables)})", source=tables[0].source,
                     column="test")  # fmt: skip


def _evaluate_tracers(sample: DensitySample, washability: Washability, curve: str):
    """A tracer test: the fitted curve applied to the feed's washability gives the products."""
    fit = fit_density_curve(sample, curve)
    feed = washability.mass_pct
    partition = fit.partition(washability.density) if fit.success else np.full(feed.size, np.nan)
    clean, reject = feed * (1.0 - partition), feed * partition
    ashes = (_ratio(clean @ washability.ash_pct, clean.sum()), _ratio(reject @ washability.ash_pct, reject.sum()))
    how = f"products predicted by the fitted curve on the washability '{washability.test}' ({washability.source})"
    row = {"test": sample.test, "size_fraction": sample.size_fraction, "cut": "single", "cut_feed_pct": 100.0,
           **_standard_form(washability, fit, clean, reject, *ashes, yield_pct=float(np.sum(clean))),
           "note": "; ".join((how, *sample.notes, *([fit.message] if not fit.success else fit.notes)))}  # fmt: skip
    part = _fractions_table(sample, "single", washability, washability.density, clean, reject, np.full(feed.size, np.nan), fit)
    points = sample.points
    tracers = pd.DataFrame({"test": sample.test, "size_fraction": sample.size_fraction, "density": points["density"],
                            "placed": points["placed"], "recovered": points["recovered"], "sinks": points["sinks"],
                            "floats": points["floats"], "partition_sinks": points["partition_sinks"],
                            "fitted_partition_sinks": fit.partition(points["density"].to_numpy(float)) if fit.success else np.nan})  # fmt: skip
    return row, part, sample, tracers


def _ratio(numerator: float, denominator: float) -> float:
    return float(numerator / denominator) if denominator > 0 else np.nan


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
