"""Monitoring a classifier over time: one fit per survey, control charts and change flags.

A *survey* is one measured separation curve with a date (a plant survey or a lab test of
the same classifier).  :func:`monitor_surveys` fits every survey with one formula and
follows four quantities against the date:

``d_cut``
    the cut size (the corrected cut ``d50c`` when the formula has a bypass), size unit;
``ep``
    Ecart probable ``(d75 - d25)/2`` of the fitted curve, size unit;
``eta``
    classifier efficiency (recovery of fines, area under the curve on ``0 < x < 1``), 0..1;
``bypass``
    share of every size sent to the coarse product unclassified, 0..1 (formulas with a
    bypass only).

Each has its interval at ``level`` (Wald for parameters, delta method for indices), an
EWMA line ``z_i = lambda x_i + (1 - lambda) z_(i-1)`` over the surveys after the
baseline, started at the baseline mean ``mu0``, and its limits
``mu0 +- L sigma sqrt(lambda/(2 - lambda) (1 - (1 - lambda)^(2i)) + (1 - (1 - lambda)^i)^2/m)``
(Montgomery, *Introduction to Statistical Quality Control*, 6th ed., sec. 9.2; the last
term accounts for ``mu0`` being estimated from ``m`` baseline surveys), with ``sigma``
the standard deviation of the quantity over the baseline surveys: it holds the
survey-to-survey variation of the classifier as well as the scatter of each fit.

Two joint-fit equality tests (the extra-sum-of-squares test of :mod:`tromplab.statistics.compare`,
on the whole curve: one curve through both data sets against one curve each) are run
for every survey: against the previous survey (``p_previous``) and against the pooled
baseline surveys (``p_baseline``).

**Monitoring rule.**  A survey after the baseline is flagged ``changed`` when the EWMA of
at least one quantity lies outside its limits *and* the equality test against the
baseline rejects at ``alpha``.  A ``change_point`` is a flagged survey that starts a run of
flagged surveys or brings a quantity into alarm that was not in alarm at the survey before
(a second change on top of a first, such as a drifting cut after a bypass step).  The false-alarm rate and detection delay of this rule are measured by
``benchmarks/trend_false_alarms.py`` on series from :func:`simulate_surveys` and stated
in ``docs/trend.md``.
"""

from __future__ import annotations

import functools
import gc
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from .curves.curve_fit import CurveFit, fit_formula
from .curves.engine import fit_formula_batch
from .curves.fitting import ParameterFit, least_squares
from .curves.formulas import get_formula, is_batchable
from .curves.intervals import batched_delta_indices, interval_rows
from .curves.measured import measured_cut_size, measured_efficiency, measured_slope, normalised_weights
from .errors import InputError
from .loading.lab import LabOptions, balances_from_table, is_lab_table, read_renamed
from .loading.points import TrompPoints, points_from_table
from .loading.surveys import has_survey_columns, split_survey_columns
from .notices import Notice, notice_table
from .output.csv_parts import write_csv
from .output.outputs import write_files
from .output.plotting import figure_pngs, offscreen_axes, plot_control_chart
from .output.report import Report, figure_png
from .results_contract import ResultContract
from .statistics.compare import ExtraSumOfSquares
from .validation import check_probability
from .workbench import fit_chunk, fit_experiments

EWMA_LAMBDA = 0.2
EWMA_L = 3.5
DEFAULT_ALPHA = 0.01
#: Resolution of the chart files ``trend_<quantity>.png`` and of the charts the report embeds (dpi).
CHART_DPI, REPORT_DPI = 120, 100
QUANTITY_UNITS = {"d_cut": "size", "ep": "size", "eta": "fraction", "bypass": "fraction"}
TREND_COLUMNS = (
    "survey",
    "date",
    "formula",
    "quantity",
    "value",
    "low",
    "high",
    "unit",
    "baseline",
    "ewma",
    "ewma_low",
    "ewma_high",
    "ewma_alarm",
    "p_previous",
    "p_baseline",
    "changed",
    "change_point",
)


@dataclass(frozen=True)
class Survey:
    """One dated separation curve."""

    name: str
    date: pd.Timestamp
    points: TrompPoints


@dataclass(frozen=True)
class TrendResult(ResultContract):
    """Fits, control charts and flags of a series of surveys.

    ``table`` has one row per survey and quantity (columns :data:`TREND_COLUMNS`).
    :meth:`summary` has one row per survey (:meth:`survey_flags`), :meth:`report` is what
    ``tromplab trend`` prints, :meth:`save` writes what it writes.

    Attributes
    ----------
    formula_id : str
        The formula fitted to every survey.
    surveys : tuple of Survey
        The surveys, in date order.
    fits : tuple of CurveFit
        The fit of each survey.
    baseline : tuple of int
        Positions of the baseline surveys.
    table : pandas.DataFrame
        One row per survey and quantity (``trend.csv``).
    alpha : float
        Level of the equality tests.
    level : float
        Confidence level of the intervals.
    failures : dict
        Survey -> why it could not be fitted.
    quantities : list of str
        The quantities charted, in table order.
    """

    formula_id: str
    surveys: tuple[Survey, ...]
    fits: tuple[CurveFit, ...]
    baseline: tuple[int, ...]
    table: pd.DataFrame
    alpha: float
    level: float
    failures: dict[str, str] = field(default_factory=dict)

    @property
    def quantities(self) -> list[str]:
        return list(dict.fromkeys(self.table["quantity"]))

    def survey_flags(self) -> pd.DataFrame:
        """One row per survey: date, p-values, the EWMA alarms by quantity, changed, change_point."""
        first = self.table.drop_duplicates("survey").set_index("survey")
        in_alarm = self.table[self.table["ewma_alarm"]].groupby("survey", sort=False)["quantity"].agg(", ".join)
        out = pd.DataFrame(
            {
                "survey": first.index,
                "date": first["date"].to_numpy(),
                "baseline": first["baseline"].to_numpy(),
                "p_previous": first["p_previous"].to_numpy(),
                "p_baseline": first["p_baseline"].to_numpy(),
                "alarms": in_alarm.reindex(first.index).fillna("").to_numpy(),
                "changed": first["changed"].to_numpy(),
                "change_point": first["change_point"].to_numpy(),
            }
        )
        return out.reset_index(drop=True)

    def change_points(self) -> list[str]:
        """Surveys where a run of flagged surveys starts."""
        flags = self.survey_flags()
        return list(flags.loc[flags["change_point"], "survey"])

    def summary(self) -> pd.DataFrame:
        """One row per survey: date, p-values, alarms and change points (:meth:`survey_flags`)."""
        return self.survey_flags()

    def to_frame(self) -> pd.DataFrame:
        """The main table, ``trend.csv``: one row per survey and quantity."""
        return self.table.copy()

    def _result_context(self) -> str:
        return f"Trend of {len(self.surveys)} surveys fitted with {self.formula_id}"

    def save(self, directory, *, size_unit: str = "", figures: bool = True, progress=None) -> dict[str, Path]:
        """Write what ``tromplab trend ... -o DIRECTORY`` writes (:func:`write_trend`), all or nothing.

        Returns ``{file name: path}``.
        """
        return write_trend(self, directory, size_unit=size_unit, figures=figures, progress=progress)

    def notices(self) -> list[Notice]:
        """The warnings of each survey's fit, survey by survey (:class:`~tromplab.notices.Notice`)."""
        return [Notice(fit.experiment, warning, curve=self.formula_id) for fit in self.fits for warning in fit.warnings]

    def warnings_table(self) -> pd.DataFrame:
        """``survey, formula, code, message`` of every warning (``warnings.csv``)."""
        return notice_table(self.notices(), subject="survey")

    def report(self) -> str:
        """What ``tromplab trend`` prints: the settings, one line per survey and the change points."""
        flags = self.survey_flags()
        base = [self.surveys[i].name for i in self.baseline]
        lines = [
            f"Formula {self.formula_id}; {len(self.surveys)} surveys; baseline {base[0]} .. {base[-1]} ({len(base)} surveys); "
            f"EWMA lambda {EWMA_LAMBDA:g}, L {EWMA_L:g}; equality tests at alpha {self.alpha:g}"
        ]
        view = flags.assign(date=flags["date"].dt.strftime("%Y-%m-%d"))
        lines.append(view.to_string(index=False, float_format=lambda v: f"{v:.3g}", na_rep="-"))
        points = self.change_points()
        lines.append("Change points: " + (", ".join(points) if points else "none"))
        for name, reason in self.failures.items():
            lines.append(f"not fitted: {name}: {reason}")
        return "\n".join(lines)


def read_surveys(path, options=None) -> list[Survey]:
    """Surveys from Tromp points or a lab table with a ``date`` (or ``survey``) column.

    Rows sharing a ``survey`` name (or, without that column, a ``date``) form one survey;
    with both columns each survey must have one date.  Without a ``date`` column the
    surveys are numbered in file order.  Columns named ``<parameter>_true`` (the values a
    synthetic series was drawn with) are ignored; any other unknown column is refused.

    Raises
    ------
    InputError
        Naming file, row and column: no date/survey column, a date that cannot be read,
        a survey with two dates, and every error of the points or lab schema.
    """
    options = options or LabOptions()
    table = read_renamed(path, options)
    if not has_survey_columns(table):
        raise InputError("a trend needs a 'date' or 'survey' column (one survey per date)", source=table.source)
    table, found = split_survey_columns(table)
    if is_lab_table(table.frame.columns):
        experiments = [
            b.to_points(weight_by_feed_share=options.weight_by_feed_share) for b in balances_from_table(table, options)
        ]
    else:
        experiments = points_from_table(table)
    surveys = [Survey(p.experiment, pd.Timestamp(found[p.experiment]["date"]), p) for p in experiments]
    return sorted(surveys, key=lambda s: s.date)


def joint_fit(groups: Sequence[TrompPoints], formula, starts: Sequence[dict]) -> ParameterFit:
    """One curve of ``formula`` through several data sets at once.

    Each data set keeps its own normalised weights (so the sums of squares share one scale
    with the separate fits) and, for formula (11), its own measured efficiency.  ``starts``
    are parameter mappings (the groups' own optima are good ones); when empty, the
    data-driven start of the first group is used.
    """
    formula = get_formula(formula)
    specs = list(formula.parameters(np.concatenate([g.size for g in groups])))
    contexts = [{"measured_efficiency": measured_efficiency(g)} if formula.context_from_efficiency else {} for g in groups]
    roots = [np.sqrt(normalised_weights(g)) for g in groups]
    curves = _joint_curves(formula, groups, contexts)

    def residual(values):
        return np.concatenate([root * (curve - g.partition_fine) for g, root, curve in zip(groups, roots, curves(values))])

    if not starts:
        cut = measured_cut_size(groups[0])
        starts = [
            {
                "d_cut": cut,
                formula.shape_name: formula.shape_for_slope(measured_slope(groups[0], cut)),
                **{extra.name: extra.start for extra in formula.extras},
            }
        ]
    return least_squares(residual, specs, starts)


def _joint_curves(formula, groups: Sequence[TrompPoints], contexts: list[dict]):
    """``curves(values)``: the curve of ``formula`` at each group's sizes, each group with its own
    context.  A moving break that depends on each group's measured efficiency (formula (11)) is
    solved for all groups at once (``MovingBreak.at_shape``: the same break points as one by one,
    with one root search per group at every step of the optimiser otherwise)."""
    moving = formula.moving_break
    if moving is None or moving.at_shape is None or not formula.context_from_efficiency or formula.extras:

        def one_by_one(values):
            extras = {extra.name: values[extra.name] for extra in formula.extras}
            shape = values[formula.shape_name]
            return [formula(g.size, values["d_cut"], shape, **context, **extras) for g, context in zip(groups, contexts)]

        return one_by_one
    efficiencies = [context["measured_efficiency"] for context in contexts]

    def side_by_side(values):
        shape = values[formula.shape_name]
        breaks = moving.at_shape(shape, efficiencies)
        # formula(size, d_cut, shape, ...) is phi(size / d_cut, ...): the same arithmetic
        return [
            moving.phi(np.asarray(g.size, dtype=float) / values["d_cut"], shape, x_break) for g, x_break in zip(groups, breaks)
        ]

    return side_by_side


def equality_test(first: Sequence[TrompPoints], second: Sequence[TrompPoints], formula, fits=None) -> ExtraSumOfSquares:
    """Extra-sum-of-squares test: one curve through both groups against one curve per group.

    ``first`` and ``second`` are groups of surveys (each group fitted with one curve).
    The reduced model has ``p`` parameters, the full one ``2p``; the test has
    ``(p, N - 2p)`` degrees of freedom.  ``fits`` may give the two groups' own fits
    (:class:`~tromplab.curves.curve_fit.CurveFit` or :class:`~tromplab.curves.fitting.ParameterFit`).
    """
    formula = get_formula(formula)
    groups = [list(first), list(second)]
    if fits is None:
        fits = [fit_formula(g[0], formula) if len(g) == 1 else _group_fit(g, formula) for g in groups]
    own = [f.fit if isinstance(f, CurveFit) else f for f in fits]
    # the common optimum lies near the groups' own: start there
    together = joint_fit(groups[0] + groups[1], formula, [dict(f.values) for f in own if f.success])
    p = formula.n_params
    n = sum(g.n for g in groups[0] + groups[1])
    if not (together.success and all(f.success for f in own)):
        return ExtraSumOfSquares(np.nan, np.nan, p, n - 2 * p)
    return ExtraSumOfSquares(together.ssr, sum(f.ssr for f in own), p, n - 2 * p)


def _group_fit(points: Sequence[TrompPoints], formula) -> ParameterFit:
    """One curve through several surveys, started from each survey's own fit."""
    own = [fit_formula(p, formula) for p in points]
    return joint_fit(points, formula, [dict(f.fit.values) for f in own if f.success])


def baseline_indices(surveys: Sequence[Survey], baseline=None) -> tuple[int, ...]:
    """Positions of the baseline surveys: the first ``N`` (int or digits), a date range
    ``"FROM:TO"`` (inclusive), or by default the first half of the series (3 to 8 surveys)."""
    n = len(surveys)
    if baseline is None:
        count = int(np.clip(n // 2, 3, 8))
    elif isinstance(baseline, (int, np.integer)) or str(baseline).strip().isdigit():
        count = int(baseline)
    else:
        start, sep, stop = str(baseline).partition(":")
        if not sep:
            raise InputError(f"--baseline takes a number of surveys or a date range FROM:TO, got {baseline!r}")
        try:
            low, high = pd.Timestamp(start.strip()), pd.Timestamp(stop.strip())
        except ValueError:
            raise InputError(f"--baseline: cannot read the dates of {baseline!r} (use YYYY-MM-DD:YYYY-MM-DD)") from None
        chosen = tuple(i for i, s in enumerate(surveys) if low <= s.date <= high)
        if len(chosen) < 3:
            raise InputError(f"--baseline {baseline}: {len(chosen)} survey(s) in that range; at least 3 are needed")
        return chosen
    if not 3 <= count < n:
        raise InputError(f"the baseline needs at least 3 surveys and at least one survey after it; got {count} of {n}")
    return tuple(range(count))


def ewma_chart(values, baseline: Sequence[int], *, lam: float = EWMA_LAMBDA, width: float = EWMA_L):
    """EWMA line and limits of ``values`` after the baseline, with centre and sigma from the baseline.

    The EWMA starts at the baseline mean ``mu0`` at the first survey after the baseline
    (a phase-II chart; nan before).  Its limits at the ``i``-th survey after the baseline
    are ``mu0 +- width * sigma * sqrt(lam/(2 - lam) (1 - (1 - lam)^(2i)) + (1 - (1 - lam)^i)^2 / m)``,
    where the last term is the variance of ``mu0`` estimated from ``m`` baseline values and
    ``sigma`` is their sample standard deviation.  A missing value (failed fit) carries
    the EWMA over.

    Returns ``(ewma, low, high, centre, sigma)``.

    Examples
    --------
    >>> z, low, high, centre, sigma = ewma_chart([1.0, 1.2, 0.9, 1.1, 2.5], [0, 1, 2, 3])
    >>> round(centre, 3), round(sigma, 4), bool(z[-1] > high[-1]), bool(np.isnan(z[0]))
    (1.05, 0.1291, True, True)
    """
    values = np.asarray(values, dtype=float)
    base = values[list(baseline)]
    base = base[np.isfinite(base)]
    m = base.size
    centre = float(np.mean(base)) if m else np.nan
    sigma = float(np.std(base, ddof=1)) if m > 1 else np.nan
    ewma, low, high = (np.full(values.size, np.nan) for _ in range(3))
    level = centre
    for step, i in enumerate(range(max(baseline) + 1, values.size), start=1):
        if np.isfinite(values[i]):
            level = lam * values[i] + (1.0 - lam) * level
        ewma[i] = level
        decay = (1.0 - lam) ** step
        half = width * sigma * np.sqrt(lam / (2.0 - lam) * (1.0 - decay**2) + (1.0 - decay) ** 2 / m)
        low[i], high[i] = centre - half, centre + half
    return ewma, low, high, centre, sigma


def flag_changes(
    values: dict,
    p_baseline,
    baseline: Sequence[int],
    *,
    alpha: float = DEFAULT_ALPHA,
    lam: float = EWMA_LAMBDA,
    width: float = EWMA_L,
):
    """The monitoring rule (module docstring) on charted ``values`` (quantity -> per-survey array).

    Returns ``(charts, alarms, changed, change_point)``: the :func:`ewma_chart` of each
    quantity, its alarms (EWMA outside the limits) and the per-survey flags.
    """
    charts = {q: ewma_chart(v, baseline, lam=lam, width=width) for q, v in values.items()}
    with np.errstate(invalid="ignore"):
        alarms = {q: (c[0] < c[1]) | (c[0] > c[2]) for q, c in charts.items()}
    any_alarm = np.any(list(alarms.values()), axis=0)
    changed = any_alarm & (np.asarray(p_baseline) < alpha)
    # a change point starts a run of flagged surveys, or brings a quantity into alarm that was not before
    newly = np.any([a & ~np.concatenate(([False], a[:-1])) for a in alarms.values()], axis=0)
    change_point = changed & (~np.concatenate(([False], changed[:-1])) | newly)
    return charts, alarms, changed, change_point


def _older_objects_frozen(function):
    """``function`` run with the objects alive before it (the imported libraries, the surveys)
    left out of Python's cyclic garbage collections (``gc.freeze``), then returned to them;
    reference counting frees what the function drops as before.  The fits of the nine formulas
    and the joint fits allocate enough for a full collection, which traversed every object of
    numpy, scipy, pandas and matplotlib: 0.13 s of a 2.6 s ``tromplab trend``.  Where objects
    are frozen already (by the caller, or a server before forking) nothing is changed."""

    @functools.wraps(function)
    def run(*args, **kwargs):
        if gc.get_freeze_count():
            return function(*args, **kwargs)
        gc.freeze()
        try:
            return function(*args, **kwargs)
        finally:
            gc.unfreeze()

    return run


@_older_objects_frozen
def monitor_surveys(
    surveys: Sequence[Survey] | str | os.PathLike,
    *,
    formula=None,
    baseline=None,
    alpha: float = DEFAULT_ALPHA,
    level: float = 0.95,
    lam: float = EWMA_LAMBDA,
    width: float = EWMA_L,
    consecutive: bool = True,
    progress=None,
) -> TrendResult:
    """Fit each survey, chart d_cut, Ep, eta (and bypass), flag the surveys where the classifier changed.

    Parameters
    ----------
    surveys : sequence of Survey, or path
        In date order (:func:`read_surveys` sorts them); four or more.  A path is read by
        :func:`read_surveys` with the default :class:`~tromplab.loading.lab.LabOptions` (what
        ``tromplab trend INPUT`` does without lab options).
    formula : str, optional
        Formula id; default the best-ranked of the nine over all surveys.
    baseline : int or str, optional
        See :func:`baseline_indices`.
    alpha : float
        Significance level of the equality tests.
    level : float
        Level of the intervals of the charted quantities.
    lam, width : float
        EWMA weight and limit width in sigmas.
    consecutive : bool
        Also test each survey against the previous one (``p_previous``; not used by the
        flag, so the benchmark turns it off).
    progress : callable, optional
        ``progress(done, total, label)`` as the surveys are fitted (``label`` a survey's name)
        and as the equality tests' joint fits are made (``"tests: ..."``).

    Returns
    -------
    TrendResult
        Its ``save(outdir, size_unit=..., figures=...)`` writes what ``tromplab trend`` writes.
    """
    if isinstance(surveys, (str, os.PathLike)):
        surveys = read_surveys(surveys)
    elif not isinstance(surveys, Sequence) or not all(isinstance(survey, Survey) for survey in surveys):
        raise TypeError(f"surveys must be a path or a sequence of Survey (read_surveys reads them), got {surveys!r:.80}")
    surveys = _checked_surveys(surveys, alpha)
    base = baseline_indices(surveys, baseline)
    formula, fits = _trend_fits(surveys, formula, progress)
    failures = {s.name: f.message for s, f in zip(surveys, fits) if not f.success}
    quantities = ["d_cut", "ep", "eta"] + (["bypass"] if any(e.name == "bypass" for e in formula.extras) else [])
    values, lows, highs = _charted_values(fits, quantities, level)
    p_previous, p_baseline = _equality_p_values(surveys, fits, formula, base, consecutive=consecutive, progress=progress)
    charts, alarms, changed, change_point = flag_changes(values, p_baseline, base, alpha=alpha, lam=lam, width=width)
    rows = []
    for i, survey in enumerate(surveys):
        for q in quantities:
            ewma, low, high, _, _ = charts[q]
            rows.append(
                {
                    "survey": survey.name,
                    "date": survey.date,
                    "formula": formula.id,
                    "quantity": q,
                    "value": values[q][i],
                    "low": lows[q][i],
                    "high": highs[q][i],
                    "unit": QUANTITY_UNITS[q],
                    "baseline": i in base,
                    "ewma": ewma[i],
                    "ewma_low": low[i],
                    "ewma_high": high[i],
                    "ewma_alarm": bool(alarms[q][i]),
                    "p_previous": p_previous[i],
                    "p_baseline": p_baseline[i],
                    "changed": bool(changed[i]),
                    "change_point": bool(change_point[i]),
                }
            )
    table = pd.DataFrame(rows, columns=list(TREND_COLUMNS))
    return TrendResult(formula.id, tuple(surveys), fits, base, table, alpha, level, failures)


def _trend_fits(surveys: Sequence[Survey], formula, progress=None) -> tuple:
    """The formula of the trend and its fit of every survey: by default the ranking's best
    formula over all surveys, whose fits are the ranking's."""
    if formula is None:
        return _best_formula(surveys, progress)
    formula = get_formula(formula)
    if progress is not None:  # one batched call fits them all
        progress(0, len(surveys), surveys[0].name)
    fits = tuple(fit_chunk([s.points for s in surveys], formulas=[formula.id], alpha=None, delta_max=None))
    if progress is not None:
        progress(len(surveys), len(surveys), surveys[-1].name)
    return formula, fits


def _checked_surveys(surveys: Sequence[Survey], alpha: float) -> list[Survey]:
    """The surveys in date order, refused (:class:`~tromplab.errors.InputError`) when fewer than
    four or when one has fewer than three points; an
    :class:`~tromplab.errors.OptionError` when ``alpha`` is not in (0, 1)."""
    check_probability(alpha, "alpha")
    surveys = sorted(surveys, key=lambda s: s.date)
    if len(surveys) < 4:
        raise InputError(f"a trend needs at least four surveys, got {len(surveys)}")
    for survey in surveys:  # a cut-short survey cannot be fitted and screened (found by benchmarks/fuzz_cli.py)
        if survey.points.n < 3:
            raise InputError(f"survey '{survey.name}' has {survey.points.n} point(s); each survey needs at least 3")
    return surveys


def _charted_values(fits, quantities: list[str], level: float) -> tuple[dict, dict, dict]:
    """``values, lows, highs``: per quantity, an array over the surveys of the estimate and its
    interval at ``level`` (nan where the fit failed)."""
    values = {q: np.full(len(fits), np.nan) for q in quantities}
    lows, highs = {q: values[q].copy() for q in quantities}, {q: values[q].copy() for q in quantities}
    known = batched_delta_indices([fit for fit in fits if fit.success])  # all surveys' index evaluations at once
    for i, fit in enumerate(fits):
        if not fit.success:
            continue
        for row in interval_rows(fit, level=level, profile=False, known=known):
            if row["quantity"] in values:
                q = row["quantity"]
                values[q][i], lows[q][i], highs[q][i] = row["value"], row["low"], row["high"]
    return values, lows, highs


def _equality_p_values(surveys, fits, formula, base, *, consecutive: bool, progress=None) -> tuple[np.ndarray, np.ndarray]:
    """``p_previous, p_baseline``: p-values of the equality test of each survey's curve against the
    previous survey's (with ``consecutive``) and against the joint fit of the baseline (nan where not tested);
    the joint fits of all tests in one batched call where the formula allows (:func:`_joint_fits`);
    ``progress`` as for :func:`monitor_surveys`, counting the joint fits made."""
    baseline_points = [surveys[i].points for i in base]
    baseline_fit = joint_fit(baseline_points, formula, [dict(fits[i].fit.values) for i in base if fits[i].success])
    tests = []  # (column, survey, groups, the groups' own fits)
    for i in range(len(surveys)):
        if not fits[i].success:
            continue
        if consecutive and i > 0 and fits[i - 1].success:
            tests.append((0, i, [surveys[i - 1].points, surveys[i].points], (fits[i - 1].fit, fits[i].fit)))
        if i not in base:
            tests.append((1, i, [*baseline_points, surveys[i].points], (baseline_fit, fits[i].fit)))
    # against the baseline, the pooled optimum lies next to the baseline's own (most of the points are
    # the baseline's): started there without the grid; consecutive pairs get the global search
    joint = [None] * len(tests)
    counted = _JointFitCount(len(tests) + 1, progress)
    counted.made(1, "the baseline")
    for column, start in ((0, None), (1, dict(baseline_fit.values) if baseline_fit.success else None)):
        chosen = [k for k, test in enumerate(tests) if test[0] == column]
        against = "the previous survey" if column == 0 else "the baseline"
        found = _joint_fits(
            [tests[k][2] for k in chosen], formula, [tests[k][3] for k in chosen], start=start,
            made=lambda count, against=against: counted.made(count, against),
        )  # fmt: skip
        for k, fit in zip(chosen, found):
            joint[k] = fit
    p_values = np.full((2, len(surveys)), np.nan)
    p = formula.n_params
    for (column, i, groups, own), together in zip(tests, joint):
        if together.success and all(f.success for f in own):
            n = sum(g.n for g in groups)
            p_values[column, i] = ExtraSumOfSquares(together.ssr, sum(f.ssr for f in own), p, n - 2 * p).p_value
    return p_values[0], p_values[1]


def _joint_fits(
    groups: Sequence[Sequence[TrompPoints]],
    formula,
    own: Sequence[Sequence[ParameterFit]],
    *,
    start: dict | None = None,
    made=None,
) -> list[ParameterFit]:
    """One :func:`joint_fit` per set of ``groups``: for a batchable formula without data-derived
    inputs, the pooled points of each set (each group keeping its normalised weights) fitted
    by the batched engine at once (from the data-driven start and ``start`` alone, without the
    grid, when ``start`` is given); otherwise one by one, started from the groups' ``own`` fits.
    ``made(count)`` is called as joint fits are done."""
    made = made or (lambda count: None)
    if not groups:
        return []
    if is_batchable(formula) and not formula.context_from_efficiency:
        pooled = [_pooled(points) for points in groups]
        found = [fit.fit for fit in fit_formula_batch(pooled, formula, global_search=start is None, start=start)]
        made(len(found))
        return found
    found = []
    for points, fits in zip(groups, own):
        found.append(joint_fit(points, formula, [dict(f.values) for f in fits if f.success]))
        made(1)
    return found


class _JointFitCount:
    """The joint fits of the equality tests made so far, told to ``progress`` as ``"tests: ..."``."""

    def __init__(self, total: int, progress=None):
        self.total, self.done, self.progress = total, 0, progress

    def made(self, count: int, against: str) -> None:
        self.done += count
        if self.progress is not None:
            self.progress(self.done, self.total, f"tests: against {against}")


def _pooled(groups: Sequence[TrompPoints]) -> TrompPoints:
    """Several surveys' points as one data set, each survey keeping its normalised weights
    (their mean is then 1 over the pool, so the engine leaves them as they are)."""
    return TrompPoints(
        groups[0].experiment,
        np.concatenate([g.size for g in groups]),
        np.concatenate([g.partition_fine for g in groups]),
        np.concatenate([normalised_weights(g) for g in groups]),
        resampled=True,  # a size measured in two surveys appears twice
    )


def _best_formula(surveys, progress=None) -> tuple:
    """The best-ranked of the nine formulas over all surveys and its fit of each survey."""
    bench = fit_experiments([s.points for s in surveys], progress=progress)
    ranking = bench.ranking_table()
    if ranking.empty:
        raise InputError("no formula could be fitted to the surveys; give one with --formula")
    formula = get_formula(ranking.iloc[0]["formula"])
    by_experiment = bench.fits_by_experiment()
    fits = []
    for survey in surveys:  # a survey the batch could not fit (a flat one) gets its own failed fit
        found = next((f for f in by_experiment.get(survey.name, ()) if f.formula.id == formula.id), None)
        fits.append(found or fit_chunk([survey.points], formulas=[formula.id], alpha=None, delta_max=None)[0])
    return formula, tuple(fits)


@_older_objects_frozen
def write_trend(result: TrendResult, outdir, *, size_unit: str = "", figures: bool = True, progress=None) -> dict[str, Path]:
    """Write ``trend.csv`` (tidy), ``trend_surveys.csv`` (one row per survey), ``warnings.csv``
    (when a survey's fit has a warning), the charts ``trend_<quantity>.png`` and
    ``trend_report.html`` (+ ``.md``), all or nothing.

    ``size_unit`` labels the figures and replaces the unit ``size`` in ``trend.csv``;
    ``progress(done, total, label)`` is called as each chart is drawn (``"charts: <quantity>"``).
    """
    table = result.table.replace({"unit": {"size": size_unit}}) if size_unit else result.table
    outputs = {
        "trend.csv": lambda p: write_csv(table, p, date_format="%Y-%m-%d"),
        "trend_surveys.csv": lambda p: write_csv(result.survey_flags(), p, date_format="%Y-%m-%d"),
    }
    if not (said := result.warnings_table()).empty:
        outputs["warnings.csv"] = lambda p: write_csv(said, p)
    charts = control_chart_pngs(result, size_unit=size_unit, progress=progress) if figures else {}
    for quantity, (picture, _) in charts.items():
        outputs[f"trend_{quantity}.png"] = lambda p, picture=picture: p.write_bytes(picture)
    report = Report("tromplab trend report", ", ".join(dict.fromkeys(s.points.source for s in result.surveys)), order=("trend",))
    add_trend_section(report, result, size_unit=size_unit, figures=figures, charts={q: c[1] for q, c in charts.items()})
    names = {
        f"Control chart of {q}": f"trend_{q}.png" for q in result.quantities
    }  # the Markdown links the PNGs written beside it
    outputs["trend_report.html"] = lambda p: p.write_text(report.html(), encoding="utf-8")
    outputs["trend_report.md"] = lambda p: p.write_text(report.markdown(names), encoding="utf-8")
    return write_files(outputs, outdir)


# --- a documented generator of survey series --------------------------------------------------
@dataclass(frozen=True)
class SeriesDesign:
    """What :func:`simulate_surveys` draws: a Plitt-with-bypass classifier surveyed regularly.

    Sizes in micrometres.  Until ``bypass_step_at`` the classifier is steady (cut
    ``d_cut``, sharpness ``ks``, bypass ``bypass``); from survey ``bypass_step_at`` the
    bypass rises by ``bypass_step`` (a worn apex, a torn panel); from ``drift_from`` the
    cut grows by ``drift_per_survey`` (relative) per survey.  Each survey has its own small
    jitter of cut and bypass (``jitter_cut``, ``jitter_bypass``: standard deviations) and
    measurement noise on every partition number (``noise``).  ``None`` switches a change off.
    """

    n_surveys: int = 24
    start: str = "2025-01-06"
    days_between: int = 7
    sizes: tuple[float, ...] = tuple(np.round(np.geomspace(38, 850, 12), 1))
    d_cut: float = 150.0
    ks: float = 2.5
    bypass: float = 0.10
    bypass_step_at: int | None = 12
    bypass_step: float = 0.08
    drift_from: int | None = 18
    drift_per_survey: float = 0.04
    jitter_cut: float = 0.015
    jitter_bypass: float = 0.005
    noise: float = 0.012

    @property
    def change_points(self) -> tuple[int, ...]:
        return tuple(i for i in (self.bypass_step_at, self.drift_from) if i is not None)


def simulate_surveys(design: SeriesDesign = SeriesDesign(), *, seed: int = 0) -> pd.DataFrame:
    """A series of dated surveys (Tromp-points schema with ``date``, ``survey``) from ``design``.

    Returns columns ``survey, date, size, partition_fine, d_cut_true, bypass_true``.
    """
    rng = np.random.default_rng(seed)
    formula = get_formula("plitt_bypass")
    sizes = np.asarray(design.sizes, dtype=float)
    rows = []
    for i in range(design.n_surveys):
        d_cut, bypass = design.d_cut, design.bypass
        if design.bypass_step_at is not None and i >= design.bypass_step_at:
            bypass += design.bypass_step
        if design.drift_from is not None and i >= design.drift_from:
            d_cut *= 1.0 + design.drift_per_survey * (i - design.drift_from + 1)
        d_true = d_cut * (1.0 + design.jitter_cut * rng.standard_normal())
        b_true = float(np.clip(bypass + design.jitter_bypass * rng.standard_normal(), 0.0, 0.9))
        phi = formula(sizes, d_true, design.ks, bypass=b_true) + design.noise * rng.standard_normal(sizes.size)
        date = pd.Timestamp(design.start) + pd.Timedelta(days=design.days_between * i)
        for size, value in zip(sizes, np.clip(phi, 0.0, 1.0)):
            rows.append(
                {
                    "survey": f"S{i + 1:02d}",
                    "date": date.strftime("%Y-%m-%d"),
                    "size": size,
                    "partition_fine": round(float(value), 5),
                    "d_cut_true": round(d_true, 3),
                    "bypass_true": round(b_true, 5),
                }
            )
    return pd.DataFrame(rows)


def surveys_from_frame(frame: pd.DataFrame) -> list[Survey]:
    """Surveys from a frame with ``survey, date, size, partition_fine`` (as :func:`simulate_surveys` makes)."""
    surveys = []
    for name, group in frame.groupby("survey", sort=False):
        points = TrompPoints(
            str(name), group["size"].to_numpy(float), group["partition_fine"].to_numpy(float), source="simulated"
        )
        surveys.append(Survey(str(name), pd.Timestamp(group["date"].iloc[0]), points))
    return sorted(surveys, key=lambda s: s.date)


def control_chart_pngs(result, *, size_unit: str = "", progress=None) -> dict[str, tuple[bytes, bytes]]:
    """Quantity -> its control chart as PNG bytes at the file's resolution (``trend_<quantity>.png``,
    :data:`CHART_DPI`) and at the report's (:data:`REPORT_DPI`): each chart drawn and laid out
    once, then saved at both (the same bytes as drawing it anew for each)."""
    charts = {}
    for done, quantity in enumerate(result.quantities):
        if progress is not None:
            progress(done, len(result.quantities), f"charts: {quantity}")
        ax = plot_control_chart(result, quantity, size_unit=size_unit, ax=offscreen_axes())
        charts[quantity] = tuple(figure_pngs(ax, (CHART_DPI, REPORT_DPI)))
    if progress is not None and charts:
        progress(len(charts), len(charts), "charts: done")
    return charts


def add_trend_section(
    report: Report, result, *, size_unit: str = "", figures: bool = True, charts: dict[str, bytes] | None = None
) -> None:
    """Add the monitoring section of a :class:`~tromplab.trend.TrendResult` to ``report``.

    The survey flags, the rule, the tidy table of the charted quantities and (with
    ``figures``) one control chart per quantity captioned ``Control chart of <quantity>``
    (``charts``: quantity -> the chart as PNG bytes at the report's resolution, drawn
    beforehand by :func:`control_chart_pngs`; drawn here otherwise).
    """
    if "trend" not in report.order:
        report.order = (*report.order, "trend")
    base = [result.surveys[i].name for i in result.baseline]
    report.add(
        "trend",
        "text",
        f"Formula {result.formula_id} fitted to each of {len(result.surveys)} surveys; baseline "
        f"{base[0]} to {base[-1]} ({len(base)} surveys). EWMA with lambda = {EWMA_LAMBDA:g} and limits at "
        f"{EWMA_L:g} sigma (centre and standard deviation from the baseline surveys). A survey after the baseline is "
        f"flagged 'changed' when an EWMA leaves its limits and the joint-fit equality test against the baseline "
        f"rejects at alpha = {result.alpha:g}; intervals at {result.level:.0%}. Sizes in {size_unit or 'the unit of the input'}.",
    )
    for name, reason in result.failures.items():
        report.add("trend", "warning", f"survey {name} not fitted: {reason}")
    points = result.change_points()
    report.add("trend", "text", "Change points: " + (", ".join(points) if points else "none") + ".")
    flags = result.survey_flags()
    report.add("trend", "table", flags.assign(date=flags["date"].dt.strftime("%Y-%m-%d")), caption="Surveys and flags")
    if figures:
        for quantity in result.quantities:
            report.add(
                "trend",
                "figure",
                charts[quantity]
                if charts and quantity in charts
                else figure_png(plot_control_chart(result, quantity, size_unit=size_unit, ax=offscreen_axes())),
                caption=f"Control chart of {quantity}",
            )
    table = result.table.drop(columns=["formula"])
    report.add("trend", "table", table.assign(date=table["date"].dt.strftime("%Y-%m-%d")), caption="Charted quantities")
