"""What the page shows of a fitted batch, as JSON-ready data: the points and the fitted
curves of each experiment, the ranked fits with their intervals and what the data cannot
tell, the ranking across experiments and the warnings grouped by what they say.

Every number comes from the :class:`~tromplab.workbench.Workbench` the run made (the one
whose folder is offered for download); nothing is recomputed here but the curves drawn
through the fitted parameters (:meth:`CurveFit.predict`) and the best fit's band
(:func:`tromplab.output.plotting.curve_band`, as the figures of the results folder draw it).
"""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np

#: Columns of the fits table the page shows, in its order (those present in the run's table).
FIT_COLUMNS = ("rank", "equation", "formula", "d50", "d50c", "shape_name", "shape", "F", "F_crit", "adequate",
               "eta", "ep", "aicc", "delta_aicc", "residuals")  # fmt: skip
#: Quantities whose interval the page shows when the run has interval columns (``--ci``, ``--bootstrap``).
INTERVAL_QUANTITIES = ("d50", "d_cut", "shape", "ep", "eta")
#: Columns of ``tromplab density fit``'s fits table the page shows (its notes are grouped as warnings).
DENSITY_COLUMNS = ("rank", "curve", "method", "rho50", "ep", "imperfection", "rho50_low", "rho50_high", "ep_low", "ep_high",
                   "imperfection_low", "imperfection_high", "gof_p", "dispersion", "overdispersed", "aic", "qaic")  # fmt: skip
#: Points on each drawn curve, spaced evenly in log size (in density for density curves).
CURVE_POINTS = 120


#: Settings of a batch fit that decide its intervals and where the work runs, not its fits: two
#: batches fitted with settings that differ only in these have the same fits.
INTERVAL_AND_MACHINE_SETTINGS = frozenset({"ci", "bootstrap", "bootstrap_method", "seed", "jobs", "scheduler", "dask"})


def report_bench(bench, settings):
    """The batch ``tromplab report`` fits with ``settings``, made from ``bench``'s fits (the
    page's ``tromplab fit``), or None when ``settings`` change the fits themselves.

    ``tromplab report`` fits without interval columns (its ``--ci`` is the level of its own
    tables) and without a bootstrap. Where the two sets of settings differ only in
    :data:`INTERVAL_AND_MACHINE_SETTINGS`, the fits are the same, so the report's batch is the
    fit's with the report's settings, no interval columns and the notes on the data as a
    batch without intervals words them (its tables and averages made afresh from those
    settings): ``write_report`` then writes the file the command writes
    (tests/test_app.py compares them byte for byte). Another difference (an option of ``fit``
    the report does not take, such as ``--single-fits``) changes the fits: None, and the caller
    fits again as the command does.
    """
    import dataclasses

    same_fits = all(getattr(bench.settings, setting.name) == getattr(settings, setting.name)
                    for setting in dataclasses.fields(settings) if setting.name not in INTERVAL_AND_MACHINE_SETTINGS)  # fmt: skip
    if not same_fits:
        return None
    from ..workbench import data_notes

    intervals = bool(settings.ci or settings.bootstrap)  # the note on a cut not bracketed says whether intervals are withheld
    notes = {points.experiment: found for points in bench.inputs
             if points.experiment not in bench.failures and (found := data_notes(points, intervals=intervals))}  # fmt: skip
    return dataclasses.replace(bench, settings=settings, notes=notes, intervals=None, store=None)


def page_payload(bench, experiments, args) -> dict:
    """The page's data of a fit run: ``bench`` fitted from ``experiments`` with the options ``args``."""
    fits = bench.fits_table()
    unit = args.size_unit or "size unit"
    return {
        "view": "fit",
        "axes": {
            "x": f"size ({unit})",
            "y": f"partition to the {args.partition_to} product",
            "log_x": True,
            "best": "best formula",
            "cut": "cut size d50",
            "unit": args.size_unit,
        },  # fmt: skip
        "experiments": [_experiment(bench, name, fits, args.partition_to) for name in bench.experiments],
        "ranking": records(bench.ranking_table()),
        "failures": records(bench.failure_table()),
        "warnings": grouped_warnings(bench, experiments),
    }


def density_payload(result) -> dict:
    """The page's data of a ``density fit`` run: a :class:`~tromplab.density.results.DensityResult`,
    each test (and size fraction) as an experiment, the curves over the measured partition to sinks."""
    table, start, experiments = result.fits_table(), 0, []
    warnings = defaultdict(list)
    for sample in result.samples:  # the table's rows are the samples' fits, sample by sample
        count = len(result.fits_of(sample))
        rows, start = table.iloc[start : start + count], start + count
        for curve, notes in zip(rows["curve"], rows["notes"].fillna("")):
            if notes:
                warnings[notes].append(f"{sample.label}: {curve}")
        experiments.append(_density_sample(result, sample, rows))
    return {
        "view": "fit",
        "axes": {
            "x": "relative density (g/cm3)",
            "y": "partition to sinks",
            "log_x": False,
            "best": "best curve",
            "cut": "rho50",
            "unit": "g/cm3",
        },  # fmt: skip
        "experiments": experiments,
        "ranking": None,
        "failures": None,
        "warnings": [{"kind": "fit", "text": text, "count": len(where), "where": where} for text, where in warnings.items()],
    }


def _density_sample(result, sample, rows) -> dict:
    from ..density.fitting import partition_band

    best = result.best(sample)
    density = sample.points["density"].to_numpy(float)
    grid = np.linspace(density.min() - 0.05, density.max() + 0.05, CURVE_POINTS)
    curves = []
    for fit in (fit for fit in result.fits_of(sample) if fit.success):
        curve = {"formula": fit.curve.id, "size": numbers(grid), "partition": numbers(fit.partition(grid)),
                 "best": fit is best, "adequate": None}  # fmt: skip
        if fit is best:
            low, high = partition_band(fit, grid)  # as the folder's figures draw it
            if np.isfinite(low).all() and np.isfinite(high).all():
                curve["band"] = {"low": numbers(low), "high": numbers(high), "level": 0.95}
        curves.append(curve)
    return {
        "name": sample.label,
        "table": records(rows[[column for column in DENSITY_COLUMNS if column in rows.columns]]),
        "intervals": None,  # in the ranked table: rho50_low, ..., ep_high
        "best": None
        if best is None
        else {
            "formula": best.curve.id,
            "d50": number(best.indices.rho50),
            "ep": number(best.indices.ep),
            "rank": 1,
            "tied": [],
        },  # fmt: skip
        "verdicts": [],
        "cannot_tell": None,
        "points": {"size": numbers(density), "partition": numbers(sample.points["partition_sinks"])},
        "curves": curves,
    }


def _experiment(bench, name: str, fits, partition_to: str) -> dict:
    own = fits[fits["experiment"] == name].sort_values(["rank", "equation"], na_position="last")
    shown = [column for column in FIT_COLUMNS if column in own.columns]
    intervals = _interval_columns(own.columns)
    curve_fits = bench.fits_of(name)
    best = bench.best_fit(name)
    points = curve_fits[0].points if curve_fits else None
    return {
        "name": name,
        "table": records(own[shown]),
        "intervals": records(own[["formula", *intervals]]) if intervals else None,
        "best": _best(bench, name, best),
        "verdicts": list(bench.verdicts(name)),
        "cannot_tell": _cannot_tell(curve_fits, own),
        "points": None if points is None else _points(points, partition_to),
        "curves": _curves(curve_fits, best, partition_to),
    }


def _best(bench, name: str, best) -> dict | None:
    """The top-ranked fit (the library's choice among tied fits: the lowest sum of squares) and the formulas tied with it."""
    if best is None:
        return None
    top = bench.top_ranked(name)
    tied = [
        {"formula": formula, "d50": number(d50)} for formula, d50 in zip(top["formula"], top["d50"]) if formula != best.formula.id
    ]
    rank = number(top["rank"].iloc[0]) if len(top) else None
    indices = best.indices
    return {"formula": best.formula.id, "d50": number(indices.d50) if indices else None,
            "ep": number(indices.ep) if indices else None, "rank": rank, "tied": tied}  # fmt: skip


def _interval_columns(columns) -> list[str]:
    found = []
    for quantity in INTERVAL_QUANTITIES:
        for kind in ("", "_boot"):
            low, high, method = f"{quantity}{kind}_low", f"{quantity}{kind}_high", f"{quantity}{kind}_method"
            found += [column for column in (low, high, method) if column in columns]
    return found


def _cannot_tell(curve_fits, rows) -> list[dict]:
    """What the data cannot tell, each statement once with the formulas it holds for: the
    intervals withheld (the fits table's ``interval_flags`` when the run made intervals, else
    the cut not bracketed) and the extra terms the data cannot determine."""
    said = defaultdict(list)
    flags = dict(zip(rows["formula"], rows["interval_flags"].fillna(""))) if "interval_flags" in rows else None
    for fit in curve_fits:
        if flags is not None and flags.get(fit.formula.id):
            said[flags[fit.formula.id]].append(fit.formula.id)
        elif flags is None and fit.success and fit.unbracketed:
            said[f"no interval for the cut, d25, d75 and Ep: {fit.unbracketed}"].append(fit.formula.id)
        for extra, reason in (fit.undetermined_extras if fit.success else {}).items():
            said[f"{extra}: {reason}"].append(fit.formula.id)
    return [{"formulas": formulas, "text": text} for text, formulas in said.items()]


def _points(points, partition_to: str) -> dict:
    partition = np.asarray(points.partition_fine, dtype=float)
    return {"size": numbers(points.size), "partition": numbers(1.0 - partition if partition_to == "coarse" else partition)}


def _curves(curve_fits, best, partition_to: str) -> list[dict]:
    successful = [fit for fit in curve_fits if fit.success]
    if not successful:
        return []
    sizes = np.asarray(successful[0].points.size, dtype=float)
    grid = np.geomspace(sizes.min() / 1.5, sizes.max() * 1.5, CURVE_POINTS)

    def read(values):
        values = np.asarray(values, dtype=float)
        return 1.0 - values if partition_to == "coarse" else values

    curves = []
    for fit in successful:
        curve = {"formula": fit.formula.id, "size": numbers(grid), "partition": numbers(read(fit.predict(grid))),
                 "best": best is not None and fit is best, "adequate": bool(fit.screen.adequate) if fit.screen else None}  # fmt: skip
        if curve["best"] and not fit.unbracketed:
            from ..output.plotting import curve_band

            low, high = sorted((read(bound) for bound in curve_band(fit, grid)), key=np.sum)
            curve["band"] = {"low": numbers(low), "high": numbers(high), "level": 0.95}
        curves.append(curve)
    return curves


def grouped_warnings(bench, experiments) -> list[dict]:
    """Every warning of the run once: failures and notes on the data with how often and where
    they were said, then the fits' warnings grouped as the HTML report groups them
    (:func:`tromplab.output.display.grouped_warnings`: warnings that differ only in their
    numbers are one line, with every fit and its numbers)."""
    from ..output.display import grouped_warnings as report_lines

    where = defaultdict(list)
    for experiment, reason in bench.failures.items():
        where[("failure", str(reason))].append(experiment)
    for balance in experiments.balances:
        for note in getattr(balance, "notes", ()):
            where[("data", note)].append(balance.experiment)
    for experiment, notes in bench.notes.items():
        for note in notes:
            where[("data", note)].append(experiment)
    groups = [{"kind": kind, "text": text, "count": len(places), "where": list(dict.fromkeys(places))}
              for (kind, text), places in where.items()]  # fmt: skip
    fit_warnings = [(experiment, fit.formula.id, warning) for experiment in bench.experiments
                    for fit in bench.fits_of(experiment) if fit.success for warning in fit.warnings]  # fmt: skip
    return groups + [{"kind": "fit", "text": line, "count": None, "where": []} for line in report_lines(fit_warnings)]


def notice_groups(notices) -> list[dict]:
    """Notices (:class:`~tromplab.notices.Notice`) each kind once: the notes on the data with how
    often and where they were said, then the fits' warnings grouped as the HTML report groups
    them (:func:`tromplab.output.display.grouped_warnings`)."""
    from ..notices import level_of
    from ..output.display import grouped_warnings as report_lines

    where, fit_warnings = defaultdict(list), []
    for notice in notices:
        if notice.curve:
            fit_warnings.append((notice.subject, notice.curve, notice.message))
        else:
            where[(level_of(notice.code), notice.message)].append(notice.subject)
    groups = [{"kind": kind, "text": text, "count": len(places), "where": list(dict.fromkeys(places))}
              for (kind, text), places in where.items()]  # fmt: skip
    return groups + [{"kind": "fit", "text": line, "count": None, "where": []} for line in report_lines(fit_warnings)]


def number(value):
    value = float(value)
    return value if math.isfinite(value) else None


def numbers(values) -> list:
    return [number(value) for value in np.asarray(values, dtype=float)]


def records(table) -> dict:
    """``{"columns": [...], "rows": [[...], ...]}``, NaN as null, numpy scalars as Python ones."""
    rows = []
    for row in table.itertuples(index=False):
        rows.append([_plain(value) for value in row])
    return {"columns": [str(column) for column in table.columns], "rows": rows}


def _plain(value):
    if isinstance(value, bool | np.bool_):
        return bool(value)
    if isinstance(value, int | np.integer):
        return int(value)
    if isinstance(value, float | np.floating):
        return number(value)
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return None
    try:
        if value != value:  # pandas NA and NaT
            return None
    except (TypeError, ValueError):
        pass
    return str(value)
