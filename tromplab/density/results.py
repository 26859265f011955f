"""The result of fitting density curves to a table of tests, its tables, figures and folder.

:func:`fit_density` reads a tracer, float-sink or partition table
(:func:`~tromplab.density.readers.read_density`), fits the chosen curves to every test and
size fraction (:func:`~tromplab.density.fitting.fit_density_curve`), ranks them, and
returns a :class:`DensityResult`; ``result.save(DIR)`` writes what ``tromplab density fit
FILE -o DIR`` writes, byte for byte: ``fits.csv``, ``partition.csv``, ``summary.txt`` and one
figure per test and size fraction (``figures.csv`` maps them), ``covariance.csv`` (the covariance
of each fit's rho50 and Ep, :mod:`tromplab.density.covariance`); for tests with size fractions
also ``by_size.csv``, ``ep_trend.csv`` and ``by_size_<test>.png``
(:func:`tromplab.density.by_size.by_size_artifacts`); with ``excel=True`` the workbook
``results.xlsx`` and with ``report=True`` ``report.html`` and ``report.md``
(:mod:`tromplab.density.documents`); the folder replaced as a
whole (:func:`tromplab.output.outputs.replace_folder`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np
import pandas as pd

from ..errors import InputError, OptionError
from ..notices import Notice, notice_table
from ..options import AUTO_FIGURE_LIMIT, FIGURE_CHOICES
from ..output.csv_parts import file_writers, write_csv
from ..parallel import dask_client, map_on_workers
from ..results_contract import ResultContract
from ..validation import MAX_JOBS, check_count, check_probability
from .dispersion import PooledDispersion, pool_dispersion
from .fitting import METHODS, DensityCurveFit, fit_density_curves, limits_test_p, wilson_interval
from .ranking import quasi_aic, rank_fits, variance_inflation
from .readers import DensitySample, DensityTable, read_density
from .registry import select_density_curves

#: The curves fitted when none are named: the three plain curves and their variants with limits.
DEFAULT_DENSITY_CURVES = "all"
#: Level of the partitions' binomial intervals in ``partition.csv`` when no ``ci`` is given.
PARTITION_INTERVAL_LEVEL = 0.95
INTERVAL_QUANTITIES = ("rho50", "ep", "imperfection")


@dataclass(frozen=True)
class DensityResult(ResultContract):
    """Density curves fitted to every test (and size fraction) of one table.

    :meth:`summary` has one row per test and size fraction (its best curve),
    :meth:`to_frame` is ``fits.csv``, :meth:`report` what ``tromplab density fit`` prints
    (and writes as ``summary.txt``), :meth:`save` the folder it writes.

    Attributes
    ----------
    samples : list of DensitySample
        The data, one per test and size fraction.
    fits : list of DensityCurveFit
        One per sample and curve, samples in order, curves in the order asked.
    ci : float or None
        Level of the profile-likelihood intervals (None: no intervals).
    method : str or None
        The fitting method asked (None: binomial for tracer counts, the joint fit for
        float-sink tests with three analyses, least squares for other shares).
    """

    samples: list
    fits: list
    ci: float | None = None
    method: str | None = None

    def __repr__(self) -> str:
        done = sum(fit.success for fit in self.fits)
        return f"<DensityResult: {len(self.samples)} test(s), {len(self.fits)} fits ({done} succeeded), ci={self.ci}>"

    #: Caches keyed by the ids of samples and fits, which a pickle does not keep: made again after loading.
    _ID_CACHES = ("_by_sample", "_best", "_ranking_notes")

    def __getstate__(self):
        return {name: value for name, value in super().__getstate__().items() if name not in self._ID_CACHES}

    @cached_property
    def _by_sample(self) -> dict[int, list[DensityCurveFit]]:
        by_sample = {id(sample): [] for sample in self.samples}
        for fit in self.fits:
            by_sample.setdefault(id(fit.sample), []).append(fit)
        return by_sample

    @cached_property
    def _ranked(self) -> list[tuple[DensityCurveFit, int, str]]:
        ranked = []
        for sample in self.samples:
            ranked += rank_fits(self.fits_of(sample))
        return ranked

    def notices(self) -> list[Notice]:
        """Every note of the tests and of their fitted curves, test by test
        (:class:`~tromplab.notices.Notice`: the test's label, the curve, the code, the note)."""
        found = []
        for sample in self.samples:
            found += [Notice(sample.label, note) for note in sample.notes]
            found += [Notice(sample.label, note, curve=fit.curve.id) for fit in self.fits_of(sample) for note in fit.notes]
        return found

    def warnings_table(self) -> pd.DataFrame:
        """``test, curve, code, message`` of every note (``warnings.csv``)."""
        return notice_table(self.notices(), subject="test", curve="curve")

    @cached_property
    def _best(self) -> dict[int, DensityCurveFit]:
        best = {}
        for fit, rank, _ in self._ranked:
            if rank == 1:
                best.setdefault(id(fit.sample), fit)
        return best

    @cached_property
    def _ranking_notes(self) -> dict[int, str]:
        return {id(fit): note for fit, _, note in self._ranked if note}

    def unfitted(self) -> list[str]:
        """The labels of the tests (and size fractions) no curve could be fitted to."""
        return [sample.label for sample in self.samples if self.best(sample) is None]

    def fits_of(self, sample: DensitySample) -> list[DensityCurveFit]:
        """The fits of one sample."""
        return list(self._by_sample.get(id(sample), []))

    def best(self, sample: DensitySample) -> DensityCurveFit | None:
        """The curve ranked first on ``sample`` (None when every fit failed)."""
        return self._best.get(id(sample))

    def fits_table(self) -> pd.DataFrame:
        """One row per test, size fraction and curve (columns defined in ``docs/columns.md``)."""
        rows = [self._fit_row(fit, rank, note) for fit, rank, note in self._ranked]
        table = pd.DataFrame(rows)
        if not any(sample.has_size for sample in self.samples):
            table = table.drop(columns=["size_fraction", "size_lower", "size_upper"])
        return table

    def _fit_row(self, fit: DensityCurveFit, rank: int, ranking_note: str) -> dict:
        sample = fit.sample
        row = {
            "test": sample.test,
            "size_fraction": sample.size_fraction,
            "size_lower": sample.size_lower,
            "size_upper": sample.size_upper,
            "layout": sample.layout,
            "method": fit.method,
            "curve": fit.curve.id,
            "success": fit.success,
        }
        index = (
            fit.indices.as_dict() if fit.indices else dict.fromkeys(("rho25", "rho50", "rho75", "ep", "imperfection"), math.nan)
        )
        row.update({name: index[name] for name in ("rho50", "ep", "imperfection")})
        if self.ci is not None:
            for name in INTERVAL_QUANTITIES:
                low, high = fit.intervals.get(name, (math.nan, math.nan))
                row[f"{name}_low"], row[f"{name}_high"] = low, high
        row.update({"rho25": index["rho25"], "rho75": index["rho75"]})
        for name in ("rho_c", "ep_c", "light_limit", "heavy_limit"):
            row[name] = fit.params.get(name, math.nan)
        binomial = fit.method == "binomial"
        row["n_points"] = int(sample.used.shape[0])
        row["deviance"] = fit.objective if binomial else math.nan
        row["ssr"] = fit.objective if not binomial else math.nan
        row["df_resid"] = fit.df_resid
        row["gof_p"] = fit.gof_p
        row["dispersion"] = fit.dispersion
        row["overdispersed"] = fit.overdispersed
        row["limits_p"] = self._limits_p(fit)
        row["aic"] = fit.aic
        row["qaic"] = quasi_aic(fit, variance_inflation(self.fits_of(sample)))
        row["rank"] = rank
        row["notes"] = "; ".join(part for part in (fit.message, *fit.notes, ranking_note) if part)
        return row

    def _limits_p(self, fit: DensityCurveFit) -> float:
        if not (fit.success and fit.curve.has_limits):
            return math.nan
        plain = [other for other in self.fits_of(fit.sample) if other.curve is fit.curve.limits_of and other.success]
        return limits_test_p(plain[0], fit) if plain else math.nan

    def partition_table(self) -> pd.DataFrame:
        """The measured partition per density with its binomial interval (tracers), one row per point."""
        level = self.ci if self.ci is not None else PARTITION_INTERVAL_LEVEL
        # the samples' points stacked once and the test's columns put in front as whole columns: a
        # frame per sample joined to its points and the lot concatenated was a tenth of save()
        points = pd.concat([sample.points for sample in self.samples], ignore_index=True)
        bounds = [_partition_bounds(sample, level) for sample in self.samples]
        points.insert(2, "partition_low", np.concatenate([low for low, _ in bounds]))
        points.insert(3, "partition_high", np.concatenate([high for _, high in bounds]))
        rows = [len(sample.points) for sample in self.samples]
        front = {
            name: [value for sample, count in zip(self.samples, rows) for value in [getattr(sample, name)] * count]
            for name in ("test", "size_fraction", "size_lower", "size_upper")
        }
        table = pd.concat([pd.DataFrame(front, index=points.index), points], axis=1)
        if not any(sample.has_size for sample in self.samples):
            table = table.drop(columns=["size_fraction", "size_lower", "size_upper"])
        return table.rename(
            columns={"feed": "feed_share", "floats": "floats_share", "sinks": "sinks_share"}
            if self.samples[0].layout == "float-sink"
            else {}
        )

    def summary(self) -> pd.DataFrame:
        """One row per test and size fraction: its best curve (``curve``, ``method``, ``rho50``,
        ``ep``, ``imperfection``; empty and nan when no curve could be fitted) and ``notes``."""
        rows = []
        for sample in self.samples:
            best = self.best(sample)
            index = best.indices.as_dict() if best is not None and best.indices else {}
            notes = best.notes if best is not None else sorted({fit.message for fit in self.fits_of(sample)})
            rows.append(
                {
                    "test": sample.test,
                    "size_fraction": sample.size_fraction,
                    "layout": sample.layout,
                    "n_points": int(sample.used.shape[0]),
                    "curve": best.curve.id if best is not None else "",
                    "method": best.method if best is not None else "",
                    **{name: index.get(name, math.nan) for name in ("rho50", "ep", "imperfection")},
                    "notes": "; ".join(notes),
                }  # fmt: skip
            )
        table = pd.DataFrame(rows)
        return table if any(sample.has_size for sample in self.samples) else table.drop(columns=["size_fraction"])

    def to_frame(self) -> pd.DataFrame:
        """The main table, ``fits.csv`` (:meth:`fits_table`)."""
        return self.fits_table()

    def _result_context(self) -> str:
        return repr(self)

    def report(self) -> str:
        """The best curve of every test and size fraction, with its intervals and notes, as text."""
        lines = []
        for sample in self.samples:
            lines.append(
                f"{sample.label}: {sample.layout}, {sample.used.shape[0]} points"
                + (f"; {'; '.join(sample.notes)}" if sample.notes else "")
            )
            best = self.best(sample)
            if best is None:
                reasons = "; ".join(sorted({fit.message for fit in self.fits_of(sample)}))
                lines.append(f"  no curve fitted: {reasons}")
                continue
            lines.append(f"  best curve: {best.curve.id} ({best.method}) {_indices_text(best)}")
            tie = self._ranking_notes.get(id(best), "")
            if tie:
                lines.append(f"    {tie}")
        return "\n".join(lines)

    def plot(self, sample: DensitySample | int = 0, *, ax=None):
        """Figure of one sample (or its position): the points, every fitted curve and the band of the best."""
        sample = self.samples[sample] if isinstance(sample, int) else sample
        return self._plot(sample, self.fits_of(sample), self.best(sample), ax=ax)

    def _plot(self, sample: DensitySample, shown: list, best, *, ax=None):
        from .plotting import plot_density_fits

        return plot_density_fits(sample, shown, best, ax=ax, level=self.ci or PARTITION_INTERVAL_LEVEL)

    def save(self, outdir, *, excel: bool = False, report: bool = False, figures: str = "auto", progress=None) -> dict:
        """Write ``fits.csv``, ``partition.csv``, ``summary.txt``, ``figures.csv``, ``covariance.csv``,
        the figures and (when a test or curve has a note) ``warnings.csv`` into ``outdir``.

        The folder is replaced as a whole when everything is written; the same files as
        ``tromplab density fit`` with the same options.

        Parameters
        ----------
        outdir : path
            The output folder.
        figures : {"auto", "all", "best", "none"}
            One figure per test and size fraction with every fitted curve (``all``) or its
            best one (``best``); ``auto``: ``all`` up to
            :data:`~tromplab.options.AUTO_FIGURE_LIMIT` tests and size fractions, then one
            overview figure (``overview.png``: rho50 and Ep of each one's best curve); ``none``:
            no figure (nor ``figures.csv``, nor the figures by size).
        progress : callable, optional
            Called as ``progress(done, total, "figures: <test>")`` as the figures are drawn.
        excel : bool
            Also write ``results.xlsx``: the sheets ``fits``, ``partition`` (``by_size`` and
            ``ep_trend`` for tests with size fractions) and ``figures``
            (:mod:`tromplab.density.documents`).
        report : bool
            Also write ``report.html`` (figures embedded) and its Markdown twin ``report.md``
            (linking the figures in the folder).

        Returns
        -------
        dict
            File name -> written path.
        """
        from ..output.outputs import replace_folder
        from .covariance import covariance_table

        check_figures(figures)
        tables = {"fits": self.fits_table(), "partition": self.partition_table()}
        pictures, figure_table = self._figures(figures, progress)
        sized = any(sample.has_size for sample in self.samples)
        if sized:  # indices by size, the Ep trend and its figure (their module imported only for them)
            from .by_size import by_size_artifacts

            size_tables, size_figures = by_size_artifacts(
                self.fits, ci=self.ci or PARTITION_INTERVAL_LEVEL, figures=figures != "none"
            )
            tables.update(size_tables)
            pictures.update(size_figures)
        outputs = file_writers(tables, texts={"summary.txt": self.report() + "\n"}, pictures=pictures)
        if figure_table is not None:
            outputs["figures.csv"] = lambda path: write_csv(figure_table, path)
        covariance = covariance_table(self.fits, sizes=sized)
        outputs["covariance.csv"] = lambda path: write_csv(covariance, path)  # for `plant predict --curves-from`
        if not (said := self.warnings_table()).empty:
            outputs["warnings.csv"] = lambda path: write_csv(said, path)
        outputs.update(self._documents(tables, pictures, excel=excel, report=report))
        return replace_folder(outputs, outdir)

    def _figures(self, mode: str, progress=None) -> tuple[dict[str, bytes], pd.DataFrame | None]:
        """PNG bytes by file name, and the table of per-test figures (None when there are none)."""
        if mode == "none":
            return {}, None
        from ..output.outputs import figure_file_names
        from ..output.plotting import figure_png

        if mode == "auto":
            mode = "all" if len(self.samples) <= AUTO_FIGURE_LIMIT else "overview"
        if mode == "overview":
            from .plotting import plot_density_overview

            summary = self.overview_rows()
            if not summary:
                return {}, None
            axes = _offscreen(2, figsize=(9.0, 6.5))
            return {"overview.png": figure_png(plot_density_overview(summary, axes=axes)[0])}, None
        names = figure_file_names([sample.label for sample in self.samples], prefix="density_")
        pictures, rows = {}, []
        for sample in self.samples:
            best = self.best(sample)
            shown = self.fits_of(sample) if mode == "all" or best is None else [best]
            pictures[names[sample.label]] = figure_png(self._plot(sample, shown, best, ax=_offscreen()))
            rows.append({"test": sample.test, "size_fraction": sample.size_fraction, "file": names[sample.label]})
            if progress is not None:
                progress(len(rows), len(self.samples), f"figures: {sample.label}")
        return pictures, pd.DataFrame(rows)

    def overview_rows(self) -> list[dict]:
        """rho50 and Ep of each sample's best curve, with their intervals, for the overview figure."""
        rows = []
        for sample in self.samples:
            best = self.best(sample)
            if best is None:
                continue
            row = {"label": sample.label, "curve": best.curve.id}
            for name in ("rho50", "ep"):
                low, high = best.intervals.get(name, (math.nan, math.nan))
                row.update({name: getattr(best.indices, name), f"{name}_low": low, f"{name}_high": high})
            rows.append(row)
        return rows

    def _documents(self, tables: dict, figures: dict, *, excel: bool, report: bool) -> dict:
        if not (excel or report):
            return {}
        from .documents import REPORT_HTML, REPORT_MARKDOWN, WORKBOOK_NAME, density_report, write_density_workbook

        outputs = {}
        if excel:
            size_unit = next((sample.size_unit for sample in self.samples if sample.size_unit), "")
            outputs[WORKBOOK_NAME] = lambda path: write_density_workbook(path, tables, figures, size_unit=size_unit)
        if report:
            document = density_report(self, tables, figures)
            outputs[REPORT_HTML] = lambda path: path.write_text(document.html(), encoding="utf-8")
            links = {name: name for name in figures}
            outputs[REPORT_MARKDOWN] = lambda path: path.write_text(document.markdown(links), encoding="utf-8")
        return outputs


def _partition_bounds(sample: DensitySample, level: float) -> tuple[np.ndarray, np.ndarray]:
    """Wilson's interval of each point's partition (tracers; nan elsewhere and where no tracer was recovered)."""
    points = sample.points
    if sample.layout != "tracers":
        missing = np.full(len(points), np.nan)
        return missing, missing
    recovered = points["recovered"].to_numpy()
    with np.errstate(all="ignore"):
        low, high = wilson_interval(points["sinks"].to_numpy(), np.maximum(recovered, 1), level=level)
    share = points["partition_sinks"].to_numpy(float)
    # Wilson's limits at k = 0 and k = n are the share itself; rounding can put them a hair past it
    low = np.where(recovered > 0, np.minimum(low, share), np.nan)
    high = np.where(recovered > 0, np.maximum(high, share), np.nan)
    return low, high


def _indices_text(fit: DensityCurveFit) -> str:
    index = fit.indices
    parts = []
    for name, unit in (("rho50", " g/cm3"), ("ep", " g/cm3"), ("imperfection", "")):
        value = getattr(index, name)
        text = f"{name} = {value:.4g}{unit}" if math.isfinite(value) else f"{name} does not exist"
        low, high = fit.intervals.get(name, (math.nan, math.nan))
        if math.isfinite(low) or math.isfinite(high):
            text += f" [{low:.4g}, {high:.4g}]"
        parts.append(text)
    notes = f"\n    notes: {'; '.join(fit.notes)}" if fit.notes else ""
    return ", ".join(parts) + notes


def _offscreen(nrows: int = 1, *, figsize=(7.5, 5.0)):
    from ..output.plotting import offscreen_axes

    return offscreen_axes(nrows, 1, figsize=figsize)


def check_figures(figures) -> str:
    """``figures`` if it is one of :data:`~tromplab.options.FIGURE_CHOICES`, else an :class:`~tromplab.errors.OptionError`."""
    if figures not in FIGURE_CHOICES:
        raise OptionError("figures", f"must be one of {', '.join(FIGURE_CHOICES)}, got {figures!r}")
    return figures


def fit_density(
    data,
    *,
    ci: float | None = None,
    curves=DEFAULT_DENSITY_CURVES,
    method: str | None = None,
    floats_yield: float | None = None,
    sheet=None,
    sep: str | None = None,
    decimal: str | None = None,
    jobs: int | None = 1,
    scheduler: str | None = None,
    dask: str | None = None,
    client=None,
    progress=None,
) -> DensityResult:
    """Fit density partition curves to every test of a tracer, float-sink or partition table.

    What ``tromplab density fit`` does, with its options as keywords of the same names.

    Parameters
    ----------
    data : str, path-like, pandas.DataFrame or list of DensitySample
        The table (:func:`tromplab.density.readers.read_density` reads it), samples already read, or a
        :class:`~tromplab.density.readers.DensityTable` (:func:`~tromplab.density.readers.density_table`).
    ci : float, optional
        Level of the profile-likelihood intervals of rho50, Ep and the imperfection, in (0, 1).
    curves : str or iterable
        Curve ids or the groups ``plain``, ``limits``, ``all`` (default: all six).
    method : {"binomial", "least_squares"}, optional
        Force a method (``least_squares``: on the shares, as a spreadsheet does); default
        binomial for tracers, the joint fit of the three analyses for float-sink tests with a
        feed analysis (``joint_least_squares`` in ``fits.csv``), least squares otherwise.
    floats_yield : float, optional
        Mass share of the feed to the floats (float-sink tables).
    sheet, sep, decimal : optional
        How to read the file.
    jobs : int, optional
        Worker processes (0 or None: all cores).  The tests are fitted in units of
        :data:`TESTS_PER_UNIT`, so a file of fewer tests than that runs in this process
        whatever ``jobs`` says (starting a worker costs more than it saves).
    scheduler, dask, client : optional
        Run the units on a Dask cluster: the scheduler at this address (``--scheduler``), a
        local cluster of two workers (``dask="local"``, ``--dask local``), or this
        ``distributed.Client``; as ``tromplab fit`` does (:func:`tromplab.parallel.dask_client`).
        The fits are the same wherever they run.
    progress : callable, optional
        Called as ``progress(done, total, label)`` as the tests (and size fractions) are fitted.

    Returns
    -------
    DensityResult

    Examples
    --------
    >>> tracers = pd.DataFrame({"density": [1.45, 1.5, 1.55, 1.6, 1.65], "sinks": [1, 6, 15, 24, 29],
    ...                         "floats": [29, 24, 15, 6, 1]})
    >>> result = fit_density(tracers, curves="normal")
    >>> row = result.fits_table().iloc[0]
    >>> row["curve"], round(float(row["rho50"]), 3), round(float(row["ep"]), 4)
    ('normal', 1.55, 0.038)
    """
    ci, chosen, jobs = check_fit_options(ci=ci, method=method, curves=curves, jobs=jobs)
    if isinstance(data, list) and all(isinstance(item, DensitySample) for item in data):
        samples = data
    elif isinstance(data, DensityTable):
        samples = list(data.samples())
    else:
        samples = read_density(data, sheet=sheet, sep=sep, decimal=decimal, floats_yield=floats_yield)
    check_samples(samples, method=method)
    with dask_client(scheduler=scheduler, dask=dask, client=client) as cluster:
        fits = _fit_in_units(samples, chosen, ci=ci, method=method, jobs=jobs, client=cluster, progress=progress)
    return DensityResult(samples, fits, ci, method)


def check_fit_options(*, ci, method, curves, jobs) -> tuple:
    """``ci``, the curves and ``jobs`` of :func:`fit_density` checked (an
    :class:`~tromplab.errors.OptionError` naming the option): ``(ci, curves, jobs)``."""
    if ci is not None:
        ci = check_probability(ci, "ci")
    if method is not None and method not in METHODS:
        raise OptionError("method", f"must be one of {', '.join(METHODS)}, got {method!r}")
    try:
        chosen = select_density_curves(curves)
    except KeyError as error:
        raise OptionError("curves", error.args[0]) from None
    return ci, chosen, check_count(0 if jobs is None else jobs, "jobs", minimum=0, maximum=MAX_JOBS)


def check_samples(samples, *, method) -> None:
    """Refuse an empty list of samples, and ``method="binomial"`` for a table of shares."""
    if not len(samples):
        raise InputError("no test to fit: data is an empty list of samples")
    layouts = {samples.layout} if isinstance(samples, DensityTable) else {sample.layout for sample in samples}
    if method == "binomial" and layouts - {"tracers"}:
        raise OptionError("method", "binomial needs tracer counts (density, sinks, floats); the table gives shares")


#: Tests (and size fractions) fitted together in one unit of work: the batch's arrays are
#: efficient from a few dozen rows on, and the progress moves on after each unit.
TESTS_PER_UNIT = 128


@dataclass(frozen=True)
class UnitOptions:
    """What a worker needs besides its unit of samples: the curves' ids, ``ci``, ``method`` and the
    whole file's pooled dispersions (``pooled``, when the file is fitted in several units)."""

    curves: tuple[str, ...]
    ci: float | None
    method: str | None
    pooled: dict | None = None


def _fit_in_units(samples: list, curves, *, ci, method, jobs: int, client, progress) -> list[DensityCurveFit]:
    """The fits of every sample, :data:`TESTS_PER_UNIT` samples at a time, in this process, on
    ``jobs`` worker processes (0: all cores) or on the Dask ``client``, through the fan-out of
    :mod:`tromplab.parallel`; the same fits wherever they run, in the samples' order."""
    units = [samples[i : i + TESTS_PER_UNIT] for i in range(0, len(samples), TESTS_PER_UNIT)]
    options = UnitOptions(tuple(curve.id for curve in curves), ci, method)
    if ci is not None and len(units) > 1:  # the intervals' scale is floored by the whole file's dispersion: fit first
        options = replace(options, pooled=file_dispersions(units, options, jobs=jobs, client=client, count=len(units)))
    fits, done = [], 0
    for unit, unit_fits in zip(units, map_on_workers(fit_unit, units, options, jobs=jobs or None, client=client)):
        # a worker's fits hold copies of the samples: give them back the caller's (fits_of finds them by identity)
        per_sample = len(unit_fits) // len(unit)
        fits += [
            fit if fit.sample is sample else replace(fit, sample=sample)
            for position, sample in enumerate(unit)
            for fit in unit_fits[position * per_sample : (position + 1) * per_sample]
        ]
        done += len(unit)
        if progress is not None:
            progress(done, len(samples), unit[-1].label)
    return fits


def fit_unit(options: UnitOptions, unit: list) -> list[DensityCurveFit]:
    """The fits of one unit of samples (what a worker does)."""
    return fit_density_curves(unit, options.curves, ci=options.ci, method=options.method, pooled=options.pooled)


def unit_dispersions(options: UnitOptions, unit: list) -> dict[str, tuple[list, list]]:
    """The Pearson dispersions and residual degrees of freedom of the binomial fits of one unit
    of samples, by curve id, fitted without intervals (what a worker does for
    :func:`file_dispersions`): those :func:`~tromplab.density.fitting.pooled_dispersions` pools."""
    found: dict[str, tuple[list, list]] = {}
    for fit in fit_density_curves(unit, options.curves, ci=None, method=options.method):
        if fit.success and fit.method == "binomial":
            dispersions, dfs_resid = found.setdefault(fit.curve.id, ([], []))
            dispersions.append(fit.dispersion)
            dfs_resid.append(fit.df_resid)
    return found


def file_dispersions(units, options: UnitOptions, *, jobs: int, client, count: int) -> dict[str, PooledDispersion]:
    """The Pearson dispersion of each curve pooled over a whole file, its ``count`` ``units``
    fitted without intervals (an iterable: taken as the workers can start on them), as
    :func:`~tromplab.density.fitting.pooled_dispersions` pools the fits of the whole file: the
    workers send back two numbers per fit, not the fits."""
    by_curve: dict[str, tuple[list, list]] = {}
    for found in map_on_workers(unit_dispersions, units, options, jobs=jobs or None, client=client, count=count):
        for curve_id, (dispersions, dfs_resid) in found.items():
            kept = by_curve.setdefault(curve_id, ([], []))
            kept[0].extend(dispersions)
            kept[1].extend(dfs_resid)
    return {curve_id: pool_dispersion(*kept) for curve_id, kept in by_curve.items()}
