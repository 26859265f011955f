"""Batch fitting: every formula to every experiment, screened and ranked.

A failing formula gives a failed :class:`~tromplab.curves.curve_fit.CurveFit`; a failing
experiment (too few points, say) is recorded in ``failures`` and skipped by the
ranking.  Neither stops the batch.
"""

from __future__ import annotations

import contextlib
import functools
import gc
import importlib.util
import logging
import math
import os
import sys
from collections.abc import Callable, Iterable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import NamedTuple

import numpy as np
import pandas as pd
from scipy import stats

from .curves.curve_fit import (
    FIT_COLUMNS,
    CurveFit,
    as_failure_if_implausible,
    attach_diagnostics,
    attach_indices,
    check_delta_max,
    failed_fit,
    fit_formula,
)
from .curves.engine import check_bootstrap_request, fit_formula_batch, measured_start
from .curves.formulas import Formula, is_batchable, select_formulas
from .curves.measured import AMBIGUOUS_CUT_RATIO, CUT_BAND, CUT_WARNING, measured_cut_band, measured_efficiency, unbracketed_cut
from .curves.ranking import RANK_BY, add_delta_aicc, add_ranks, fit_verdicts, rank_formulas
from .curves.screening import DEFAULT_ALPHA
from .errors import InputError, OptionError, expect_kind
from .loading.lab import Experiments, MassBalance, read_experiments
from .loading.points import TrompPoints, points_from_frame
from .loading.surveys import with_survey_columns
from .output.csv_parts import CsvPart, csv_part
from .output.folder import write_results_folder
from .output.plotting import plot_tromp_fits
from .output.report import build_report, write_report
from .output.results import load_workbench, workbench_html, workbench_repr
from .output.views import check_partition_to, partition_view
from .statistics.compare import nested_tests
from .statistics.hydrocyclone import bypass_against_water_recovery
from .statistics.uncertainty import BOOTSTRAP_METHODS, averaged_rows, interval_columns
from .validation import (
    MAX_JOBS,
    check_bootstrap,
    check_count,
    check_optional,
    check_probability,
    check_seed,
    check_water_recovery,
)

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class Workbench:
    """All fits of a batch with their tables."""

    fits: tuple[CurveFit, ...]
    failures: dict[str, str] = field(default_factory=dict)
    formulas: tuple[Formula, ...] = ()
    rank_by: str = "F"
    alpha: float = DEFAULT_ALPHA
    rank_extended: bool = False
    notes: dict[str, tuple[str, ...]] = field(default_factory=dict)
    water_recovery: float | None = None
    ci: float | None = None
    bootstrap: int = 0
    bootstrap_method: str = "residuals"
    seed: int = 0
    partition_to: str = "fine"
    size_unit: str = ""
    inputs: tuple[TrompPoints, ...] = field(default=(), repr=False)
    balances: tuple[MassBalance, ...] = field(default=(), repr=False)
    intervals: pd.DataFrame | None = field(default=None, repr=False, compare=False)

    def fits_table(self) -> pd.DataFrame:
        """The table ``fits.csv`` holds: one row per experiment and formula (columns
        :data:`FIT_COLUMNS`; with a ``water_recovery`` also ``water_recovery`` and
        ``water_recovery_check``, the fitted bypass compared with it, see
        :mod:`tromplab.statistics.hydrocyclone`), with the interval columns when the batch
        was fitted with ``ci`` or ``bootstrap``, read as partition to ``partition_to``
        (:func:`tromplab.output.views.partition_view`)."""
        return self._output_frame.copy()

    @cached_property
    def _output_frame(self) -> pd.DataFrame:
        return output_view(self._fits_frame, self.intervals, self.inputs, self.partition_to)

    @cached_property
    def _fits_frame(self) -> pd.DataFrame:
        # built once: the ranking, the best fits, the CLI and the report all read it; the rows
        # of the fits were made by the workers that fitted them (_keep_fit_rows) where there were
        made = self.__dict__.pop("_fit_rows", None)
        settings = fit_row_settings(self.formulas, self.rank_extended, self.rank_by, self.water_recovery)
        return completed_fit_rows(
            fit_rows_frame(self.fits) if made is None else made, self.fits, **settings, failures=self.failures
        )

    @property
    def ranked_formulas(self) -> tuple[Formula, ...]:
        """The formulas the ranking covers: the paper's nine unless extended curves are ranked too."""
        return ranked_among(self.formulas, self.rank_extended)

    def best_fit(self, experiment: str) -> CurveFit | None:
        """The top-ranked successful fit of an experiment; among fits sharing the top rank
        (indistinguishable by the tie rule) the one with the lowest sum of squares."""
        best = self._best_formulas.get(experiment)
        if best is None:
            return None
        return next(f for f in self.fits_of(experiment) if f.formula.id == best)

    @cached_property
    def _best_formulas(self) -> dict[str, str]:
        # one pass over the table instead of a scan per experiment
        table = self._fits_frame
        rows = table[table["success"] & table["rank"].notna()].sort_values(["rank", "ssr", "equation"], kind="stable")
        return dict(rows.drop_duplicates("experiment")[["experiment", "formula"]].itertuples(index=False))

    def top_ranked(self, experiment: str) -> pd.DataFrame:
        """Rows of the fits table that share the top rank of ``experiment`` (several when tied)."""
        top = self._top_rows.get(experiment)
        return self._fits_frame.iloc[0:0] if top is None else top

    @cached_property
    def _top_rows(self) -> dict[str, pd.DataFrame]:
        # grouped once: a scan of the whole table per experiment is quadratic in the batch
        table = self._fits_frame
        rows = table[table["success"] & table["rank"].notna()]
        rows = rows[rows["rank"] == rows.groupby("experiment", sort=False)["rank"].transform("min")]
        return {experiment: group for experiment, group in rows.groupby("experiment", sort=False)}

    def ranking_table(self) -> pd.DataFrame:
        """Ranks per experiment, points and place per formula (failed experiments left out)."""
        return self._ranking_frame.copy()

    @cached_property
    def _ranking_frame(self) -> pd.DataFrame:
        # built once: the results folder, the console and the report all read it
        table = self._fits_frame
        table = table[~table["experiment"].isin(list(self.failures)) & table["rank"].notna()]
        if table.empty:
            return pd.DataFrame(columns=["equation", "formula", "points", "place"])
        ranking = rank_formulas(table, by=self.rank_by, key="formula")
        equation = {f.id: f.equation for f in self.formulas}
        ranking.insert(0, "equation", ranking["formula"].map(equation))
        return ranking.sort_values(["place", "equation"]).reset_index(drop=True)

    def verdicts(self, experiment: str) -> list[str]:
        """Plain-language statements on the fits of an experiment (:func:`tromplab.curves.ranking.fit_verdicts`)."""
        table = self._fits_frame
        fits = self.fits_of(experiment)
        sizes = (float(fits[0].points.size.min()), float(fits[0].points.size.max())) if fits else None
        return fit_verdicts(table[table["experiment"] == experiment], by=self.rank_by, measured_sizes=sizes)

    def fits_of(self, experiment: str) -> list[CurveFit]:
        return list(self.fits_by_experiment().get(experiment, []))

    def fits_by_experiment(self) -> dict[str, list[CurveFit]]:
        """The fits grouped by experiment, in batch order."""
        return self._by_experiment

    @cached_property
    def _by_experiment(self) -> dict[str, list[CurveFit]]:
        return by_experiment(self.fits)

    @property
    def experiments(self) -> list[str]:
        return list(self._by_experiment)

    # --- readable views and saving (tromplab.output.results) ---------------------------------------
    def __repr__(self) -> str:
        return workbench_repr(self)

    def _repr_html_(self) -> str:
        return workbench_html(self)

    def averages(self, *, level: float | None = None, jobs: int | None = 1, client=None) -> pd.DataFrame:
        """Akaike-weighted d_cut, Ep and eta per experiment (:func:`model_averages`), with
        intervals at ``level`` (default: the batch's ``ci``, else 0.95); the table of ``averages.csv``.

        Computed once per level and kept; ``jobs`` and ``client`` spread the first
        computation over workers (the table is the same whatever they are).
        """
        level = averages_level(self.ci) if level is None else check_probability(level, "level")
        check_optional(check_count, jobs, "jobs", minimum=0, maximum=MAX_JOBS)
        if level not in self._averages_by_level:
            self._keep_averages(level, model_averages(self, level=level, jobs=jobs, client=client))
        return self._averages_by_level[level].copy()

    @cached_property
    def _averages_by_level(self) -> dict[float, pd.DataFrame]:
        return {}  # a frozen dataclass keeps caches in __dict__

    def _keep_from_workers(self, found: ChunkResults) -> None:
        """What the workers made beside the fits: the rows of the fits (the table
        :func:`fit_rows_frame` makes) and, where they made them, the model averages at the
        batch's level and the CSV text of both tables (:meth:`formatted_parts`)."""
        self.__dict__["_fit_rows"] = found.rows
        if found.averages is not None:
            self._keep_averages(averages_level(self.ci), found.averages)
        if found.csv_parts:
            self.__dict__["_csv_parts"] = found.csv_parts

    def formatted_parts(self, table: str) -> list[CsvPart] | None:
        """The rows of ``fits.csv`` (``table="fits"``) or ``averages.csv`` (``"averages"``, at the
        batch's level) as the workers formatted them, chunk by chunk (None where they did not):
        the results folder joins them instead of formatting the whole table again
        (:func:`tromplab.output.csv_parts.csv_from_parts`)."""
        return self.__dict__.get("_csv_parts", {}).get(table)

    def __getstate__(self) -> dict:
        # the formatted text is for writing this run's folder; a saved batch formats again
        return {key: value for key, value in self.__dict__.items() if key != "_csv_parts"}

    def _keep_averages(self, level: float, table: pd.DataFrame) -> None:
        self._averages_by_level[level] = with_survey_columns(table, self.inputs)

    def failure_table(self) -> pd.DataFrame:
        """``experiment, formula, reason`` of every experiment or fit that failed (``failures.csv``)."""
        rows = [{"experiment": e, "formula": "", "reason": reason} for e, reason in self.failures.items()]
        rows += [
            {"experiment": fit.experiment, "formula": fit.formula.id, "reason": fit.fit.message or "the fit failed"}
            for fit in self.fits
            if not fit.success
        ]
        return pd.DataFrame(rows, columns=["experiment", "formula", "reason"])

    def check_fitted(self, source: str = "") -> None:
        """Raise :class:`~tromplab.errors.InputError` when no formula could be fitted to any
        experiment (the command line then writes nothing and exits 1)."""
        if any(fit.success for fit in self.fits):
            return
        reasons = dict(self.failures)
        for fit in self.fits:
            reasons.setdefault(fit.experiment, f"{fit.formula.id}: {fit.fit.message}")
        listed = "; ".join(f"{experiment}: {reason}" for experiment, reason in reasons.items())
        raise InputError(f"no formula could be fitted to any experiment ({listed})", source=str(source) or None)

    def plot(self, experiment: str | None = None, *, ax=None, **options):
        """Measured points and fitted curves of one experiment (the first by default),
        best fit thick with its band; ``options`` go to :func:`tromplab.output.plotting.plot_tromp_fits`.

        Returns the matplotlib Axes.
        """
        experiment = self.experiments[0] if experiment is None else experiment
        if experiment not in self.experiments:
            raise KeyError(f"no experiment {experiment!r}; experiments: {', '.join(self.experiments)}")
        return plot_tromp_fits(self.fits_of(experiment), ax=ax, best=self.best_fit(experiment), **options)

    def report(
        self,
        path,
        *,
        balances=None,
        level: float | None = None,
        size_unit: str | None = None,
        title: str = "tromplab report",
        jobs: int | None = 1,
    ):
        """Write the HTML report (and its Markdown twin) to ``path``, as ``tromplab report`` does.

        ``balances`` (default: those the batch was read with, :func:`tromplab.read_experiments`),
        ``level`` (default: the batch's ``ci``, else 0.95) and ``size_unit`` (default: the
        batch's) as for the command; ``jobs`` worker processes draw the per-experiment
        figures (None or 0: all cores; the report is the same for any number).  Returns
        ``{file name: path}`` of the written files.
        """
        check_optional(check_probability, level, "level")
        check_optional(check_count, jobs, "jobs", minimum=0, maximum=MAX_JOBS)
        sources = dict.fromkeys(fit.points.source for fit in self.fits if fit.points.source)
        built = build_report(
            self,
            list(self.balances if balances is None else balances),
            source=", ".join(sources) or "data given in Python",
            level=(self.ci or 0.95) if level is None else level,
            size_unit=self.size_unit if size_unit is None else size_unit,
            title=title,
            partition_to=self.partition_to,
            map_work=functools.partial(_map_work, jobs=jobs or None, client=None),
        )
        return write_report(built, path)

    def save(
        self,
        directory,
        *,
        figures: str = "auto",
        format: str = "csv",
        excel: bool = False,
        reloadable: bool = False,
        jobs: int | None = 1,
    ):
        """Write the results folder, the same files as ``tromplab fit ... -o DIRECTORY``:
        ``fits``, ``ranking`` and ``averages`` tables, figures, ``failures.csv`` when fits
        failed, ``results.xlsx`` with ``excel`` (only the workbook when ``directory`` ends in
        ``.xlsx``); with ``reloadable`` also the pickled batch, so :func:`load` reads it back.
        ``jobs`` worker processes draw the per-experiment figures (None or 0: all cores; the
        files are the same for any number).  See
        :func:`tromplab.output.folder.write_results_folder`.  Returns ``{file name: path}``.
        """
        check_optional(check_count, jobs, "jobs", minimum=0, maximum=MAX_JOBS)
        return write_results_folder(
            self,
            directory,
            figures=figures,
            format=format,
            excel=excel,
            reloadable=reloadable,
            map_work=functools.partial(_map_work, jobs=jobs or None, client=None),
        )


#: Experiments per unit of work: at least ``CHUNK_SIZE`` (progress, and balance over the
#: workers), at most ``MAX_CHUNK_SIZE`` (memory), in between two units per worker.  The
#: numbers do not depend on the cut: every chunk is padded to the widest experiment of the
#: batch (:class:`~tromplab.curves.batched.PaddedPoints`), and the fits of one experiment
#: use its own rows only.  Large units matter: the engine's cost per call is mostly
#: interpreter overhead that a larger batch shares (1,024 experiments on one worker, chunks
#: of 64 against 512: 7.5 s against 4.3 s; 10,000 experiments on two workers, at most 1,024
#: against at most 512: the workers' CPU 47.1-49.0 s against 49.7-55.0 s in six alternating
#: runs, 20 MiB more at the peak; docs/performance.md).
CHUNK_SIZE = 64
MAX_CHUNK_SIZE = 1024


def chunked(items: Sequence, *, workers: int) -> list:
    """``items`` cut into consecutive units of work for ``workers`` (see :data:`CHUNK_SIZE`)."""
    size = min(MAX_CHUNK_SIZE, max(CHUNK_SIZE, math.ceil(len(items) / (2 * max(workers, 1)))))
    return [items[i : i + size] for i in range(0, len(items), size)]


def _worker_count(jobs, client) -> int:
    """Workers the chunks will run on: the Dask cluster's threads, else ``jobs`` (None or 0: all cores)."""
    if client is not None:
        return max(1, sum(client.nthreads().values()))
    return jobs or os.cpu_count() or 1


def fit_experiments(
    experiments,
    *,
    formulas=None,
    extended: bool = False,
    alpha: float = DEFAULT_ALPHA,
    delta_max: float | None = None,
    rank_by: str = "F",
    rank_extended: bool = False,
    size_unit: str = "",
    water_recovery: float | None = None,
    partition_to: str = "fine",
    ci: float | None = None,
    bootstrap: int = 0,
    bootstrap_method: str = "residuals",
    seed: int = 0,
    jobs: int | None = 1,
    scheduler: str | None = None,
    dask: str | None = None,
    client=None,
    single_fits: bool = False,
    progress: Callable[[int, int, str], None] | None = None,
) -> Workbench:
    """Fit, screen and rank ``formulas`` (default: all nine) on each experiment: what
    ``tromplab fit`` does, with its options as keywords of the same names.

    Parameters
    ----------
    experiments : path, DataFrame, Experiments, mapping or iterable of TrompPoints
        A points file or lab table (path) or a pandas DataFrame of one, read by
        :func:`tromplab.read_experiments` with its defaults; what that function returns (its mass
        balances kept for the report and workbook); a Dask DataFrame of points (columns
        ``experiment, size, partition_fine[, weight]``); a mapping of experiment name (str) to
        its ``TrompPoints`` (renamed to the key), to a DataFrame of its points or to a
        ``(sizes, partitions)`` pair; or an iterable of ``TrompPoints``.  Two experiments of one
        name, or none at all, are an :class:`~tromplab.errors.InputError`; anything else is a
        ``TypeError`` saying what is accepted.
    formulas : str or iterable of ids or equation numbers, optional
        ``"paper"``: the nine; ``"extended"``: the bypass and fish-hook curves; ``"other"``: other tools' curves.
    extended, rank_extended : bool
        Also fit the extended curves (reported, kept out of the ranking); rank them with the nine.
    alpha : float
        Significance level of the Fisher screen, in (0, 1).
    delta_max : float, optional
        Largest feed size for the misplacement index (default per experiment: its
        ``delta_max`` if known, else its largest size).
    rank_by : {"F", "aicc"}
    size_unit : str
        Unit of the sizes, for labels and records (the unit the loader found in the column names wins
        when all experiments share one).
    water_recovery : float, optional
        Hydrocyclones: share of the feed water reporting to the underflow, in [0, 1).  The formulas are
        still fitted to the actual partition; the fits table gains ``water_recovery`` and ``water_recovery_check``
        (the fitted bypass against it, :func:`tromplab.statistics.hydrocyclone.bypass_against_water_recovery`).
    partition_to : {"fine", "coarse"}
        Product whose partition the tables and figures show (the fits are the same).
    ci : float, optional
        Add interval columns at this level (profile likelihood for the parameters, the
        delta method for the indices); also the level of the model averages (default 0.95).
    bootstrap, seed : int
        Add bootstrap percentile intervals from ``bootstrap`` resamples (0: none), drawn by
        ``bootstrap_method`` from ``seed`` (the same seed gives the same intervals).
    bootstrap_method : {"residuals", "cases"}
    jobs : int or None
        Worker processes (None or 0: all cores).  The experiments are cut into chunks
        (:func:`chunked`) that are padded alike, so the results are identical for any number.
    scheduler, dask, client : optional
        Run the chunks on Dask: on the scheduler at ``scheduler`` (``tcp://host:8786``), on a
        local cluster of two workers (``dask="local"``) or on ``client`` (a ``dask.distributed.Client``).
    single_fits : bool
        Fit one experiment and formula at a time with lmfit
        (:func:`tromplab.curves.curve_fit.fit_formula`) instead of the batched engine.
    progress : callable, optional
        Called as ``progress(done, total, label)`` as experiments are fitted, then (with
        ``ci`` or ``bootstrap``) as fits get their intervals (labels ``"intervals: ..."``).

    Returns
    -------
    Workbench
        Every fit, with the fits, ranking and averages tables; never raises for a failing
        fit.  ``bench.save(DIR)`` writes what ``tromplab fit ... -o DIR`` writes.

    Examples
    --------
    >>> points = TrompPoints("run", [10, 20, 40, 80, 160], [0.98, 0.91, 0.62, 0.21, 0.04])
    >>> bench = fit_experiments([points], formulas=["plitt", "lognormal", "molerus"])
    >>> bench.ranking_table()[["formula", "place"]].values.tolist()
    [['plitt', 1], ['lognormal', 2], ['molerus', 3]]
    """
    experiments, balances = _points_and_balances(experiments)
    chosen = select_formulas(check_formula_selection(formulas, extended))
    n_fits = len(experiments) * len(chosen)
    settings = _checked_settings(locals(), n_fits=n_fits, size_unit=_data_size_unit(experiments, size_unit))
    with dask_client(scheduler=scheduler, dask=dask, client=client) as cluster:
        failures, fittable = _screenable(experiments)
        wanted = {"level": ci, "n_bootstrap": bootstrap, "method": bootstrap_method, "seed": seed} if ci or bootstrap else None
        averaged = {"level": averages_level(ci), "ranked": ranked_among(chosen, rank_extended)}
        tables = {**fit_row_settings(chosen, rank_extended, rank_by, settings["water_recovery"]), "partition_to": partition_to}
        found = _fit_in_chunks(
            fittable,
            chosen,
            settings,
            jobs=jobs,
            client=cluster,
            progress=progress,
            intervals=wanted,
            averages=averaged,
            tables=tables,
        )
        bench = Workbench(
            tuple(found.fits), failures, chosen, rank_by, alpha, rank_extended, found.notes, settings["water_recovery"], ci,
            bootstrap, bootstrap_method, seed, partition_to, settings["size_unit"], tuple(experiments), balances, found.intervals,
        )  # fmt: skip
        bench._keep_from_workers(found)
    return bench


def averages_level(ci: float | None) -> float:
    """Confidence level of the model averages' intervals: the batch's ``ci``, else 0.95."""
    return ci or 0.95


def by_experiment(fits) -> dict[str, list[CurveFit]]:
    """``fits`` grouped by experiment, in their order."""
    grouped: dict[str, list[CurveFit]] = {}
    for fit in fits:
        grouped.setdefault(fit.experiment, []).append(fit)
    return grouped


def fit_rows_frame(fits) -> pd.DataFrame:
    """One row per fit (``CurveFit.row``) in the columns of ``fits.csv`` before ranking."""
    return pd.DataFrame([fit.row() for fit in fits]).reindex(columns=[c for c in FIT_COLUMNS if c != "rank"])


def completed_fit_rows(
    table: pd.DataFrame, fits, *, failures: dict, formulas, ranked, rank_by: str, water_recovery
) -> pd.DataFrame:
    """The fits table of :meth:`Workbench.fits_table` before its intervals and view: ``table``
    (:func:`fit_rows_frame` of ``fits``) with a row per failed experiment and formula, the
    ranks among the ``ranked`` formula ids and ``delta_aicc``, the check against the
    ``water_recovery`` and the nested tests.  Every step works experiment by experiment, so a
    worker completes the rows of its chunk (without ``failures``) as the whole batch's are.
    Columns are added to ``table`` itself: pass a copy of a table that is used again."""
    chosen = select_formulas(formulas)
    failed = [
        {
            "experiment": experiment,
            "equation": formula.equation,
            "formula": formula.id,
            "shape_name": formula.shape_name,
            "adequate": False,
            "success": False,
            "message": reason,
        }
        for experiment, reason in failures.items()
        for formula in chosen
    ]
    if failed and table.empty:  # no fit: the columns take their types from the failures alone
        table = pd.DataFrame(failed).reindex(columns=table.columns)
    elif failed:
        table = pd.concat([table, pd.DataFrame(failed).reindex(columns=table.columns)], ignore_index=True)
    table["adequate"] = table["adequate"].astype(bool)
    table["success"] = table["success"].astype(bool)
    in_ranking = table["formula"].isin(ranked)
    table["rank"] = add_ranks(table[in_ranking], by=rank_by)["rank"]  # curves kept out of the ranking get no rank
    table.loc[table["experiment"].isin(list(failures)), "rank"] = np.nan
    table["delta_aicc"] = add_delta_aicc(table)
    table = table.reindex(columns=list(FIT_COLUMNS))
    if water_recovery is not None:
        checks = bypass_against_water_recovery(fits, water_recovery)
        table = table.merge(checks, on=["experiment", "formula"], how="left")
        table["water_recovery"] = water_recovery  # failed experiments too
        table["water_recovery_check"] = table["water_recovery_check"].fillna("")
    fitted = {f.id for f in chosen}
    if any(f.nests in fitted for f in chosen):  # is the bypass (fish-hook) needed? the nested F test
        table = table.merge(nested_tests(fits), on=["experiment", "formula"], how="left")
    return table


def fit_row_settings(formulas, rank_extended: bool, rank_by: str, water_recovery) -> dict:
    """The settings of :func:`completed_fit_rows` of a batch of ``formulas``."""
    return {
        "formulas": tuple(f.id for f in formulas),
        "ranked": tuple(f.id for f in ranked_among(formulas, rank_extended)),
        "rank_by": rank_by,
        "water_recovery": water_recovery,
    }


def output_view(table: pd.DataFrame, intervals: pd.DataFrame | None, inputs, partition_to: str) -> pd.DataFrame:
    """:func:`completed_fit_rows` with the ``intervals`` columns, the survey columns of the
    ``inputs`` and read as partition to ``partition_to``: the table ``fits.csv`` holds."""
    if intervals is not None:
        table = table.merge(intervals, on=["experiment", "formula"], how="left")
    return partition_view(with_survey_columns(table, inputs), partition_to)


def ranked_among(formulas, rank_extended: bool) -> tuple[Formula, ...]:
    """The formulas a ranking covers: the paper's nine unless extended curves are ranked too."""
    return tuple(f for f in formulas if rank_extended or f.family == "paper")


def check_formula_selection(formulas=None, extended: bool = False):
    """The selection :func:`formula_keys` makes, refused with an
    :class:`~tromplab.errors.OptionError` naming ``formulas`` when it names an unknown formula."""
    if isinstance(formulas, (list, tuple, set, frozenset)) and not formulas:
        raise OptionError("formulas", "names no formula; leave it out (None) for the nine formulas")
    if isinstance(formulas, str) and not formulas.replace(",", "").strip():
        raise OptionError("formulas", f"names no formula, got {formulas!r}")
    keys = formula_keys(formulas, extended)
    try:
        select_formulas(keys)
    except KeyError as error:
        raise OptionError("formulas", f"names an {error.args[0]}") from None
    return keys


def formula_keys(formulas=None, extended: bool = False):
    """The formula selection of ``formulas`` plus the extended curves when ``extended``
    (``formulas`` default: the nine), as :func:`tromplab.curves.formulas.select_formulas` reads it."""
    if not extended:
        return formulas
    keys = formulas if formulas is not None else "paper"
    keys = keys if isinstance(keys, str) else ",".join(str(key) for key in keys)
    return keys if "extended" in keys else f"{keys},extended"


def _checked_settings(given: dict, *, n_fits: int, size_unit: str) -> dict:
    """The options of :func:`fit_experiments` checked (an :class:`~tromplab.errors.OptionError`
    names the option), before any fitting."""
    check_probability(given["alpha"], "alpha")
    if given["delta_max"] is not None:  # refused before any fitting, not in each fit
        check_delta_max(given["delta_max"], given["experiments"])
    check_optional(check_count, given["jobs"], "jobs", minimum=0, maximum=MAX_JOBS)
    check_partition_to(given["partition_to"])
    check_optional(check_probability, given["ci"], "ci")
    check_seed(given["seed"], "seed")
    if given["rank_by"] not in RANK_BY:
        raise OptionError("rank_by", f"must be one of {', '.join(sorted(RANK_BY))}, got {given['rank_by']!r}")
    if given["bootstrap_method"] not in BOOTSTRAP_METHODS:
        raise OptionError("bootstrap_method", f"must be one of {', '.join(BOOTSTRAP_METHODS)}, got {given['bootstrap_method']!r}")
    if check_bootstrap(given["bootstrap"], "bootstrap"):
        try:
            check_bootstrap_request(given["bootstrap"], n_fits=n_fits)
        except ValueError as error:  # too much work for these data, said before any fitting
            raise OptionError("bootstrap", str(error).removeprefix("--bootstrap ")) from None
    return {
        "alpha": given["alpha"],
        "delta_max": given["delta_max"],
        "engine": not given["single_fits"],
        "size_unit": size_unit,
        "water_recovery": check_optional(check_water_recovery, given["water_recovery"], "water_recovery"),
    }


def _data_size_unit(experiments: Sequence[TrompPoints], fallback: str) -> str:
    """The unit the loader found (column suffix) when all experiments share one, else ``fallback``."""
    units = {p.size_unit for p in experiments if p.size_unit}
    return units.pop() if len(units) == 1 else fallback


def _screenable(experiments: Sequence[TrompPoints]) -> tuple[dict[str, str], list[TrompPoints]]:
    """The experiments the Fisher screen cannot judge (with the reason), and the others."""
    failures, fittable = {}, []
    for points in experiments:
        if points.n <= 2:
            failures[points.experiment] = (
                f"experiment '{points.experiment}' has {points.n} points; the Fisher screen needs at least 3"
            )
        elif np.ptp(points.partition_fine) == 0:  # F = 0/0: no curve can be told from another
            failures[points.experiment] = (
                f"experiment '{points.experiment}' is flat: every partition equals {points.partition_fine[0]:g}, "
                "so there is no cut to fit and the Fisher screen is undefined (0/0)"
            )
        else:
            fittable.append(points)
    return failures, fittable


class ChunkResults(NamedTuple):
    """What :func:`_fit_in_chunks` gathers: the fits, the data notes, the interval columns and
    the model averages (None when not asked for), the rows of the fits, and the workers' CSV
    text of the tables (``{"fits": [CsvPart, ...], "averages": [...]}``, None in one process)."""

    fits: list[CurveFit]
    notes: dict
    intervals: pd.DataFrame | None
    averages: pd.DataFrame | None
    rows: pd.DataFrame
    csv_parts: dict[str, list[CsvPart]] | None = None


def _fit_in_chunks(
    fittable,
    chosen,
    settings: dict,
    *,
    jobs,
    client,
    progress,
    intervals: dict | None = None,
    averages: dict | None = None,
    tables: dict | None = None,
) -> ChunkResults:
    """The fits, data notes, (with ``intervals``, the options of
    :func:`~tromplab.statistics.uncertainty.interval_columns``) the interval columns and (with
    ``averages``: ``level`` and the ``ranked`` formulas) the model averages of ``fittable``,
    chunk by chunk in order, wherever the chunks run (the averages only where there are
    workers: in one process they are made when first asked for).  Where there are workers,
    each also formats its rows of ``fits.csv`` and ``averages.csv`` (``tables``: the
    :func:`fit_row_settings` and ``partition_to``), which the main process only joins.

    A chunk's intervals are made by the worker that fitted it, right after the fits: the fits
    do not travel to the main process and back again, and each fit's intervals (its bootstrap
    seed included) depend on that fit only, so the table is the same for any number of workers.
    ``progress`` hears of each chunk twice: its fits, then (labels ``"intervals: ..."``) its intervals.
    """
    chunks = chunked(fittable, workers=_worker_count(jobs, client))
    options = {key: settings[key] for key in ("alpha", "delta_max", "engine", "size_unit")}
    options["formulas"] = tuple(f.id for f in chosen)
    options["intervals"] = intervals
    options["width"] = max((points.n for points in fittable), default=0)  # one padding for every chunk
    if jobs == 1 and client is None:  # one process: the model averages wait until they are asked for
        averages = tables = None
    options["averages"] = None if averages is None else (averages["level"], tuple(f.id for f in averages["ranked"]))
    options["tables"] = tables
    logger.info(
        "fitting %d experiment(s) x %d formula(s) in %d chunk(s) of up to %d (%s)",
        len(fittable),
        len(chosen),
        len(chunks),
        len(chunks[0]) if chunks else 0,
        "on a Dask cluster" if client is not None else f"jobs={jobs or 'all cores'}",
    )
    fits, notes, frames, averaged, rows, parts = [], {}, [], [], [], {}
    for number, (chunk, (chunk_fits, chunk_notes, frame, chunk_averages, chunk_rows, chunk_parts)) in enumerate(
        zip(chunks, _map_chunks(chunks, options, jobs=jobs, client=client)), 1
    ):
        fits += chunk_fits
        rows.append(chunk_rows)
        for name, part in (chunk_parts or {}).items():
            parts.setdefault(name, []).append(part)
        notes.update(chunk_notes)
        averaged += chunk_averages or []
        logger.debug(
            "chunk %d/%d fitted: %d fits, %d failed", number, len(chunks), len(chunk_fits), sum(not f.success for f in chunk_fits)
        )
        if progress is not None:
            progress(len(fits) // max(len(chosen), 1), len(fittable), chunk[-1].experiment)
        if frame is not None:
            frames.append(frame)
            if progress is not None:
                progress(len(fits) // max(len(chosen), 1), len(fittable), f"intervals: {chunk[-1].experiment}")
    return ChunkResults(
        fits,
        notes,
        pd.concat(frames, ignore_index=True) if frames else None,
        None if averages is None else _averages_table(averaged),
        pd.concat(rows, ignore_index=True) if rows else fit_rows_frame([]),
        parts if tables is not None else None,
    )


@contextlib.contextmanager
def dask_client(*, scheduler: str | None = None, dask: str | None = None, client=None):
    """The Dask client to run on: ``client`` as given, one connected to ``scheduler``, or
    one on a local cluster of two workers (``dask="local"``); None when none is asked for.
    A client made here is closed afterwards."""
    if client is not None or (scheduler is None and dask is None):
        yield client
        return
    if dask not in (None, "local"):
        raise OptionError("dask", f"must be 'local', got {dask!r}")
    if importlib.util.find_spec("distributed") is None:
        raise OptionError(
            "scheduler" if scheduler is not None else "dask", "needs the package distributed: pip install 'tromplab[dask]'"
        )
    from dask import config as dask_config
    from dask.distributed import Client, LocalCluster

    with contextlib.ExitStack() as stack:
        if scheduler is not None:
            made = stack.enter_context(Client(scheduler))
        else:
            # Dask's nanny starts its workers with MALLOC_TRIM_THRESHOLD_=65536, which makes
            # glibc map and unmap every numpy array above 64 KiB: the fits ran 1.5 x slower
            with dask_config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}):
                cluster = stack.enter_context(LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None))
            made = stack.enter_context(Client(cluster))
        yield made


def fit_chunk(
    experiments: Sequence[TrompPoints], *, formulas, alpha, delta_max, engine=True, size_unit="", width=None
) -> list[CurveFit]:
    """Fits of ``formulas`` to ``experiments``, experiment by experiment in formula order.

    Batchable formulas go through the engine for all experiments at once, padded to
    ``width`` points; the others (and a formula whose batch raised) are fitted one by one.
    """
    per_formula = []
    measured = [measured_start(points) for points in experiments] if engine else None  # shared by the formulas
    for formula in select_formulas(formulas):
        batch = None
        if engine and is_batchable(formula):
            try:
                batch = fit_formula_batch(
                    experiments, formula, alpha=alpha, delta_max=delta_max, size_unit=size_unit, width=width, measured=measured
                )
            except Exception as error:  # a broken batch falls back to single fits, which report per fit
                logger.warning(
                    "batched engine failed on formula %s for %d experiment(s) (%s: %s); fitting them one at a time instead",
                    formula.id,
                    len(experiments),
                    type(error).__name__,
                    error,
                )
        per_formula.append(batch or [_fit_guarded(points, formula, alpha, delta_max, size_unit) for points in experiments])
    fits = [fits[i] for i in range(len(experiments)) for fits in per_formula]
    attach_indices(fits)
    fits = [as_failure_if_implausible(fit) for fit in fits]  # a result out of its range is a failure
    attach_diagnostics(fits)
    reasons = {}  # unbracketed is a property of the points, which the formulas of an experiment share
    for fit in fits:
        if id(fit.points) not in reasons:
            reasons[id(fit.points)] = unbracketed_cut(fit.points)
        fit.__dict__["unbracketed"] = reasons[id(fit.points)]  # where functools.cached_property keeps it
    for fit in fits:
        derive(fit)
    return fits


def derive(fit: CurveFit) -> CurveFit:
    """Compute the cached screen, indices, diagnostics, break point and warnings of ``fit`` now.

    The chunk's worker does it, so that they travel back with the pickled fit instead of
    being computed one by one in the parent when the tables are built (the serial part
    that kept two workers from being twice as fast as one).
    """
    for name in ("screen", "indices", "diagnostics", "x_break", "warnings"):
        getattr(fit, name)
    return fit


def _map_chunks(chunks, options, *, jobs, client):
    """Yield the fits and the data notes of each chunk, in order: in process, in a process pool, or on Dask."""
    yield from _map_work(_fit_chunk_star, chunks, options, jobs=jobs, client=client)


def _map_work(function, chunks, argument, *, jobs, client):
    """Yield ``function(argument, chunk)`` for each chunk, in order: in process, in a
    process pool of ``jobs`` workers (None: all cores), or on a Dask client."""
    work = functools.partial(_with_older_objects_frozen, function, argument)
    with _results_kept_out_of_collections() as keep:
        if client is not None:
            for future in client.map(work, chunks, pure=False):
                yield future.result()
                keep()
            return
        workers = min(jobs or os.cpu_count() or 1, len(chunks))
        if workers <= 1:
            for result in map(work, chunks):
                yield result
                keep()
            return
        with ProcessPoolExecutor(max_workers=workers) as pool:
            for result in pool.map(work, chunks):
                yield result
                keep()


def _with_older_objects_frozen(function, argument, chunk):
    """``function(argument, chunk)`` with the objects alive before it (the imported modules, in
    process the earlier chunks' results) left out of the cyclic garbage collections it
    triggers; the chunk's own garbage is collected as usual.  Where objects are frozen
    already (in process by the batch itself, or by the process's owner), nothing is changed."""
    if gc.get_freeze_count():
        return function(argument, chunk)
    gc.freeze()
    try:
        return function(argument, chunk)
    finally:
        gc.unfreeze()


@contextlib.contextmanager
def _results_kept_out_of_collections():
    """The chunks' results left out of Python's cyclic garbage collections while more arrive:
    yields the function to call after each chunk.

    Each chunk's results are tens of thousands of objects (fits, their dicts and arrays);
    every collection triggered while later chunks are unpickled or built traversed all of
    them again: at 10,000 experiments on two workers, about 3 s of the main process's CPU.
    ``gc.freeze`` after each chunk moves the objects alive to a generation collections
    skip (reference counting still frees them); ``gc.unfreeze`` at the end returns them to
    the collector, so no garbage outlives the batch.  A process with objects frozen before
    the batch (a server that froze them before forking its workers) is left as it is: its
    freezing is its own to undo.
    """
    if gc.get_freeze_count():
        yield lambda: None
        return
    try:
        yield gc.freeze
    finally:
        gc.unfreeze()


def _fit_chunk_star(options, chunk):
    # the notes on the points are made in the worker too: in the parent they were a serial
    # Spearman test per experiment (seconds at 10,000 experiments)
    notes = {points.experiment: found for points in chunk if (found := data_notes(points))}
    options = dict(options)
    intervals, averages, tables = options.pop("intervals", None), options.pop("averages", None), options.pop("tables", None)
    fits = fit_chunk(chunk, **options)
    columns = interval_columns(fits, **intervals, width=options["width"]) if intervals else None
    rows = fit_rows_frame(fits)  # the rows of fits.csv too: a serial 40 us per fit in the main process
    averaged = None
    if averages is not None:
        level, ranked = averages
        averaged = _averages_of_chunk(level, _averaged_groups(by_experiment(fits).values(), ranked))
    parts = None
    if tables is not None:  # the text of the chunk's rows: 2.2 s of serial formatting at 10,000 experiments
        tables = dict(tables)
        partition_to = tables.pop("partition_to")
        parts = {
            "fits": csv_part(
                output_view(completed_fit_rows(rows.copy(), fits, failures={}, **tables), columns, chunk, partition_to)
            )
        }
        if averaged:
            parts["averages"] = csv_part(with_survey_columns(_averages_table(averaged), chunk))
    return fits, notes, columns, averaged, rows, parts


#: What :func:`fit_experiments` takes as its experiments, for the message refusing anything else.
ACCEPTED_EXPERIMENTS = (
    "a path to a points file or lab table, a pandas or Dask DataFrame, what read_experiments returns, "
    "a mapping of experiment name to TrompPoints (or to a DataFrame of its points, or to a (sizes, "
    "partitions) pair), or an iterable of TrompPoints"
)


def _points_and_balances(experiments) -> tuple[list[TrompPoints], tuple[MassBalance, ...]]:
    """Points (and the mass balances of lab input) from any of :data:`ACCEPTED_EXPERIMENTS`;
    an empty input, or two experiments of one name, is an :class:`InputError`."""
    balances = ()
    if isinstance(experiments, (str, os.PathLike, pd.DataFrame)):
        experiments = read_experiments(experiments)
    if isinstance(experiments, Experiments):
        points, balances = list(experiments.points), tuple(experiments.balances)
    elif hasattr(experiments, "dask") and hasattr(experiments, "compute"):
        points = points_from_frame(experiments.compute(), source="dask dataframe")
    elif isinstance(experiments, Mapping):
        points = [_named_points(name, value) for name, value in experiments.items()]
    elif isinstance(experiments, Iterable) and not isinstance(experiments, (bytes, bytearray)):
        points = list(experiments)
        for position, item in enumerate(points):
            if not isinstance(item, TrompPoints):
                raise TypeError(
                    f"experiments[{position}] is a {type(item).__name__}, not a TrompPoints; experiments must be "
                    f"{ACCEPTED_EXPERIMENTS}"
                )
    else:
        raise TypeError(f"experiments must be {ACCEPTED_EXPERIMENTS}; got {type(experiments).__name__}")
    if not points:
        raise InputError("no experiment to fit: the input is empty", source="experiments")
    seen = set()
    for item in points:
        if item.experiment in seen:
            raise InputError(
                f"two experiments are named '{item.experiment}': give each experiment its own name", source="experiments"
            )
        seen.add(item.experiment)
    return points, balances


def _named_points(name, value) -> TrompPoints:
    """The points of experiment ``name`` of a mapping: a TrompPoints (renamed to the key), a
    DataFrame of one experiment's points (the file schema, its own experiment column ignored)
    or a ``(sizes, partitions)`` pair."""
    if not isinstance(name, str):
        raise TypeError(
            f"the names of a mapping of experiments are text (str), got {type(name).__name__} {name!r}: map each "
            "name (str) to its TrompPoints, a DataFrame of its points or a (sizes, partitions) pair"
        )
    source = f"experiments['{name}']"
    if isinstance(value, TrompPoints):
        return value if value.experiment == name else replace(value, experiment=name)
    if isinstance(value, pd.DataFrame):
        found = points_from_frame(value.drop(columns=["experiment"], errors="ignore"), source=source)
        return replace(found[0], experiment=name)
    if isinstance(value, (tuple, list)) and len(value) == 2:
        return TrompPoints(name, value[0], value[1], source=source)
    raise TypeError(
        f"{source} is a {type(value).__name__}; give a TrompPoints, a DataFrame of its points or a (sizes, partitions) pair"
    )


def load(directory) -> Workbench:
    """A batch saved by :meth:`Workbench.save` (refused when saved by another major version).

    Only load directories you trust: the batch is unpickled.

    Parameters
    ----------
    directory : str or path-like
        A directory written by :meth:`Workbench.save` with ``reloadable=True`` (the
        pickled batch and its manifest are written only then).
    """
    expect_kind(directory, (str, os.PathLike), "directory", "a path (str or path-like) to a saved results folder")
    return load_workbench(directory)


def data_notes(points: TrompPoints) -> tuple[str, ...]:
    """Warnings about the measured points themselves, before any fit."""
    notes = []
    if points.n >= 3 and np.ptp(points.partition_fine) > 0:
        # Spearman's rho as Pearson's r of the ranks (the sizes are distinct and increasing, so
        # their ranks are 1..n): stats.spearmanr's checks cost 0.3 ms, 3 s at 10,000 experiments
        rho = float(np.corrcoef(np.arange(points.n), stats.rankdata(points.partition_fine))[0, 1])
        if rho > 0.5:
            notes.append(
                f"the partition to fines rises with size (Spearman {rho:.2f}): is the column the partition to the "
                "coarse product? (use partition_coarse)"
            )
    one_sided = np.all(points.partition_fine > 0.5) or np.all(points.partition_fine < 0.5)
    if unbracketed := unbracketed_cut(points):
        extrapolated = "the cut size is extrapolated beyond the measured sizes, and " if one_sided else ""
        notes.append(
            f"{CUT_WARNING} ({unbracketed}): {extrapolated}no interval is given for d_cut, d50, d50c, d25, d75 and Ep, "
            "which rest on the formula's shape, not on measurements"
        )
    elif (ambiguous := _ambiguous_measured_cut(points)) is not None:
        notes.append(ambiguous)
    return tuple(notes)


def _ambiguous_measured_cut(points: TrompPoints) -> str | None:
    """A note when the measured cut, and with it formula (11)'s measured efficiency, moves
    far with partitions changed within :data:`~tromplab.curves.measured.CUT_BAND` (a plateau at 1/2, or a
    curve crossing 1/2 more than once): the fit of (11) then hangs on the data's last digits."""
    low, high = measured_cut_band(points)
    if not high > AMBIGUOUS_CUT_RATIO * low:
        return None
    efficiencies = sorted(measured_efficiency(points, cut) for cut in (low, high))
    return (
        f"the measured cut is ambiguous: partitions within 1/2 +- {CUT_BAND:g} put it anywhere from "
        f"{low:.4g} to {high:.4g}; formula (11), whose measured efficiency rests on it "
        f"({efficiencies[0]:.3f} to {efficiencies[1]:.3f} over that range), may change with the data's "
        "last digits"
    )


def model_averages(bench: Workbench, *, level: float = 0.95, jobs: int | None = 1, client=None) -> pd.DataFrame:
    """Akaike-weighted d_cut, Ep and eta per experiment (the formulas ranked by the batch).

    Parameters
    ----------
    bench : Workbench
    level : float
        Confidence level of the intervals, 0..1.
    jobs, client
        Spread the experiments over worker processes or a Dask cluster as
        :func:`fit_experiments` does; the table is the same whatever they are.

    Returns
    -------
    pandas.DataFrame
        ``experiment, quantity, value, stderr, low, high`` and ``weight_<formula>`` columns.

    """
    expect_kind(bench, Workbench, "bench", "a Workbench (tromplab.fit_experiments)")
    check_probability(level, "level")
    check_optional(check_count, jobs, "jobs", minimum=0, maximum=MAX_JOBS)
    groups = _averaged_groups(bench.fits_by_experiment().values(), [f.id for f in bench.ranked_formulas])
    chunks = chunked(groups, workers=_worker_count(jobs, client))
    logger.info("model averages of %d experiment(s) at level %g", len(groups), level)
    return _averages_table(
        [frame for chunk in _map_work(_averages_of_chunk, chunks, level, jobs=jobs, client=client) for frame in chunk]
    )


def _averaged_groups(fits_by_experiment, ranked) -> list[list[CurveFit]]:
    """The successful fits of the ``ranked`` formula ids, per experiment (experiments without any left out)."""
    ranked = set(ranked)
    groups = ([f for f in fits if f.success and f.formula.id in ranked] for fits in fits_by_experiment)
    return [chosen for chosen in groups if chosen]


def _averages_table(frames: list[pd.DataFrame]) -> pd.DataFrame:
    if not frames:
        return pd.DataFrame()
    table = pd.concat(frames, ignore_index=True)
    return table[["experiment", *[c for c in table.columns if c != "experiment"]]]


def _averages_of_chunk(level, groups) -> list[pd.DataFrame]:
    # the whole chunk at once: the delta method in one call per formula, each quantity on arrays
    rows = [
        {**row, "experiment": fits[0].experiment}
        for fits, experiment_rows in zip(groups, averaged_rows(groups, level=level))
        for row in experiment_rows
    ]
    # one table per chunk, from all its experiments' rows: the main process then unpickles and
    # concatenates tens of tables, not thousands (about 3 s of serial work at 10,000
    # experiments), and the chunk builds one DataFrame instead of one per experiment
    return [pd.DataFrame(rows)]


def _fit_guarded(points, formula, alpha, delta_max, size_unit="") -> CurveFit:
    size_unit = size_unit or getattr(points, "size_unit", "")  # the unit the loader read from the column name
    try:
        return fit_formula(points, formula, alpha=alpha, delta_max=delta_max, size_unit=size_unit)
    except Exception as error:  # a batch reports a broken fit instead of stopping
        return failed_fit(
            points, formula, f"{type(error).__name__}: {error}", alpha=alpha, delta_max=delta_max, size_unit=size_unit
        )


def print_progress(i: int, total: int, experiment: str) -> None:
    """Progress line on standard error (for batches of more than one experiment)."""
    if total > 1:
        print(f"[{i}/{total}] fitting experiment {experiment}", file=sys.stderr, flush=True)
