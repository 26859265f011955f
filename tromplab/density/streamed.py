"""``tromplab density fit FILE -o DIR`` in one go (:func:`fit_density_to_folder`): a large
campaign streams its results to disk unit by unit, so the main process holds neither the fits
nor the samples of the whole file and its memory does not grow with the campaign.

When it streams is the batch's one rule (:func:`tromplab.parallel.streams`): from
:data:`~tromplab.parallel.STREAM_THRESHOLD` tests and size fractions (or ``stream=True``), with
CSV outputs only (no workbook, no report) and no per-test figure (``figures`` ``"none"``, or
``"auto"`` above :data:`~tromplab.options.AUTO_FIGURE_LIMIT`, which draws one overview).  A
table with size fractions is held in memory: its tables by size join each test's fractions,
which units of :data:`~tromplab.density.results.TESTS_PER_UNIT` may cut apart.

A streamed run reads and checks the table as a whole (:func:`~tromplab.density.readers.density_table`:
its rows, about a hundred bytes each) and makes each unit's samples as the workers can start on
them.  Each worker fits its unit (:func:`stream_unit`), as :func:`~tromplab.density.results.fit_density`
fits it, and formats the unit's rows of ``fits.csv``, ``partition.csv``, ``covariance.csv`` and
``warnings.csv`` and its lines of ``summary.txt``; the main process spools them to a scratch
folder beside the output folder (:class:`~tromplab.output.spooled.SpooledTables`), keeps the
overview figure's six numbers per test, the labels of the tests without a fitted curve and
the counts, then joins the files and swaps the folder into place as a whole
(:func:`~tromplab.output.outputs.replace_folder`): byte for byte the files of
:meth:`DensityResult.save <tromplab.density.results.DensityResult.save>`.  An error or an
interrupt leaves the output folder as it was and removes the scratch folder.  With ``ci`` and
more than one unit the file is fitted twice, as in memory: first without intervals, the workers
sending back each fit's Pearson dispersion (:func:`~tromplab.density.results.file_dispersions`),
then with intervals floored by the file's pooled dispersion, streamed; the samples of the
first pass are pickled into the scratch folder and read back for the second.
"""

from __future__ import annotations

import math
import pickle
import shutil
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..notices import Notice
from ..options import AUTO_FIGURE_LIMIT
from ..output.spooled import SpooledTables, unit_table
from ..parallel import chunks_of, dask_client, map_on_workers, streams
from . import results
from .readers import DensityTable, density_table
from .results import (
    DEFAULT_DENSITY_CURVES,
    DensityResult,
    UnitOptions,
    check_figures,
    check_fit_options,
    check_samples,
    file_dispersions,
    fit_density,
    fit_unit,
)

#: The tables each unit writes rows of, in the order the folder lists them.
STREAMED_TABLES = ("fits", "partition", "covariance", "warnings")
#: What the overview figure shows of each test's best curve (:func:`~tromplab.density.plotting.plot_density_overview`).
OVERVIEW_VALUES = ("rho50", "rho50_low", "rho50_high", "ep", "ep_low", "ep_high")


@dataclass(frozen=True)
class DensityFolder:
    """The result of a streamed ``density fit``: its folder, and what the console says of it.

    Attributes
    ----------
    outdir : Path
        The results folder.
    files : dict
        File name -> written path.
    tests : int
        Tests (and size fractions) fitted.
    unfitted_tests : tuple of str
        The labels of those no curve could be fitted to (:meth:`unfitted`).
    notes : int
        Notes of the tests and curves (the rows of ``warnings.csv``).
    ci : float or None
        Level of the profile-likelihood intervals.
    method : str or None
        The fitting method asked.
    """

    outdir: Path
    files: dict
    tests: int
    unfitted_tests: tuple[str, ...]
    notes: int
    ci: float | None = None
    method: str | None = None

    def __repr__(self) -> str:
        return f"<DensityFolder: {self.tests} test(s) in {self.outdir}, {len(self.unfitted_tests)} without a curve, ci={self.ci}>"

    def unfitted(self) -> list[str]:
        """The labels of the tests (and size fractions) no curve could be fitted to."""
        return list(self.unfitted_tests)

    def report(self) -> str:
        """The best curve of every test, as text (``summary.txt``, read from the folder)."""
        return (self.outdir / "summary.txt").read_text(encoding="utf-8")[:-1]

    def write_report(self, stream) -> None:
        """Copy :meth:`report` and a line end to the text ``stream`` (as ``print`` would), a piece at a time."""
        with open(self.outdir / "summary.txt", encoding="utf-8") as file:
            shutil.copyfileobj(file, stream)

    def fits_table(self):
        """``fits.csv`` read from the folder (pandas' reading of the written text)."""
        import pandas as pd

        return pd.read_csv(self.outdir / "fits.csv")

    def notices(self) -> Iterator[Notice]:
        """Every note of ``warnings.csv``, read from the folder a piece at a time."""
        import pandas as pd

        from ..loading.names import undefended

        path = self.outdir / "warnings.csv"
        if not path.exists():
            return
        with pd.read_csv(path, dtype=str, keep_default_na=False, chunksize=10_000) as pieces:
            for piece in pieces:
                for test, curve, code, message in piece.itertuples(index=False):
                    yield Notice(undefended(test), undefended(message), curve=undefended(curve), code=code)


@dataclass(frozen=True)
class StreamOptions:
    """What every worker of a streamed run needs beside its unit: the fit's :class:`UnitOptions`
    and whether to send back the overview figure's values."""

    unit: UnitOptions
    overview: bool


class UnitOutput(NamedTuple):
    """What a worker sends back of a unit: its ``tables`` (:data:`STREAMED_TABLES` ->
    :class:`~tromplab.output.spooled.UnitTable`), its lines of ``summary.txt`` (``lines``),
    the ``unfitted`` labels, the ``overview`` values (tests x :data:`OVERVIEW_VALUES`, of those
    with a best curve; None when not asked), its size and the label of its last test."""

    tables: dict
    lines: str
    unfitted: tuple
    overview: np.ndarray | None
    size: int
    last: str


def stream_unit(options: StreamOptions, unit: list) -> UnitOutput:
    """Fit a unit of samples as :func:`~tromplab.density.results.fit_unit` does and format its
    rows of the folder's tables (what a worker does)."""
    from .covariance import covariance_table

    fits = fit_unit(options.unit, unit)
    result = DensityResult(unit, fits, options.unit.ci, options.unit.method)
    frames = {
        "fits": result.fits_table(),
        "partition": result.partition_table(),
        "covariance": covariance_table(fits, sizes=False),
        "warnings": result.warnings_table(),
    }
    overview = None
    if options.overview:
        rows = result.overview_rows()
        overview = np.array([[row[name] for name in OVERVIEW_VALUES] for row in rows], dtype=float).reshape(-1, 6)
    tables = {name: unit_table(frame) for name, frame in frames.items()}
    return UnitOutput(tables, result.report(), tuple(result.unfitted()), overview, len(unit), unit[-1].label)


def fit_density_to_folder(data, outdir, *, figures: str = "auto", excel: bool = False, report: bool = False,
                          stream: bool | None = None, ci: float | None = None, curves=DEFAULT_DENSITY_CURVES,
                          method: str | None = None, floats_yield: float | None = None, sheet=None, sep: str | None = None,
                          decimal: str | None = None, jobs: int | None = 1, scheduler: str | None = None,
                          dask: str | None = None, client=None, progress=None):  # fmt: skip
    """Fit density curves to every test of ``data`` and write the folder ``outdir``: what
    ``tromplab density fit FILE -o DIR`` does.

    Parameters
    ----------
    data, ci, curves, method, floats_yield, sheet, sep, decimal, jobs, scheduler, dask, client, progress
        As for :func:`~tromplab.density.results.fit_density`.
    outdir : str or path-like
        The results folder, replaced as a whole when every file is written.
    figures, excel, report
        As for :meth:`DensityResult.save <tromplab.density.results.DensityResult.save>`.
    stream : bool, optional
        Stream the results to disk unit by unit (True), or keep every fit in memory and save
        them afterwards (False).  Default: stream from
        :data:`~tromplab.parallel.STREAM_THRESHOLD` tests and size fractions.  Streaming needs
        CSV outputs only (no ``excel``, no ``report``), no per-test figure and no size
        fractions; otherwise the fits are kept in memory whatever ``stream`` says (the rule:
        :func:`tromplab.parallel.streams`).  The files are the same either way.

    Returns
    -------
    tuple
        The :class:`~tromplab.density.results.DensityResult` (kept in memory) or
        :class:`DensityFolder` (streamed), and ``{file name: path}`` of the written files.
    """
    ci, chosen, jobs = check_fit_options(ci=ci, method=method, curves=curves, jobs=jobs)
    check_figures(figures)
    if isinstance(data, (list, DensityTable)):
        source = data
    else:
        source = density_table(data, sheet=sheet, sep=sep, decimal=decimal, floats_yield=floats_yield)
    check_samples(source, method=method)
    sized = source.has_size if isinstance(source, DensityTable) else any(sample.has_size for sample in source)
    keywords = {"ci": ci, "method": method, "jobs": jobs, "progress": progress}
    if not streams(len(source), tables_only=not (excel or report or sized), figures=figures, stream=stream):
        result = fit_density(source, curves=curves, scheduler=scheduler, dask=dask, client=client, **keywords)
        return result, result.save(outdir, excel=excel, report=report, figures=figures, progress=progress)
    with dask_client(scheduler=scheduler, dask=dask, client=client) as cluster:
        return _streamed(source, outdir, figures=figures, curves=chosen, client=cluster, **keywords)


def _samples_of(source):
    return source.samples() if isinstance(source, DensityTable) else iter(source)


def _streamed(source, outdir, *, figures: str, ci, curves, method, jobs: int, client, progress):
    """Fit ``source`` unit by unit on the workers and write the folder from their rows."""
    from ..output.outputs import replace_folder

    count = len(source)
    size = results.TESTS_PER_UNIT  # the units of fit_density: the same fits
    n_units = math.ceil(count / size)
    options = UnitOptions(tuple(curve.id for curve in curves), ci, method)
    overview = figures == "auto" and count > AUTO_FIGURE_LIMIT
    with SpooledTables(outdir) as spool:
        units = chunks_of(_samples_of(source), size)
        if ci is not None and n_units > 1:  # the intervals' scale is floored by the whole file's dispersion: fit first
            pooled = file_dispersions(_units_kept(units, spool.scratch), options, jobs=jobs, client=client, count=n_units)
            options = UnitOptions(options.curves, ci, method, pooled)
            units = _units_read(spool.scratch, n_units)
        reports, unfitted, values, done = [], [], [], 0
        outputs = map_on_workers(
            stream_unit, units, StreamOptions(options, overview), jobs=jobs or None, client=client, count=n_units
        )
        for number, output in enumerate(outputs):
            for name in STREAMED_TABLES:
                spool.keep(name, number, output.tables[name])
            reports.append(spool.scratch / f"summary-{number:07d}.txt")
            reports[-1].write_text(output.lines, encoding="utf-8")
            unfitted += output.unfitted
            if output.overview is not None:
                values.append(output.overview)
            done += output.size
            if progress is not None:
                progress(done, count, output.last)
        files = {"fits.csv": spool.writer("fits"), "partition.csv": spool.writer("partition")}
        files["summary.txt"] = lambda path: _join_reports(reports, path)
        if values and (picture := _overview_png(np.concatenate(values))) is not None:
            files["overview.png"] = lambda path: path.write_bytes(picture)
        files["covariance.csv"] = spool.writer("covariance")  # for `plant predict --curves-from`
        notes = spool.rows("warnings")
        if notes:
            files["warnings.csv"] = spool.writer("warnings")
        written = replace_folder(files, outdir)
    return DensityFolder(Path(outdir), written, count, tuple(unfitted), notes, ci, method), written


def _units_kept(units, scratch: Path):
    """``units`` as they pass, each also pickled into ``scratch`` for the second pass: reading
    a unit's samples back costs less than half of making them again from the table."""
    for number, unit in enumerate(units):
        (scratch / f"samples-{number:07d}.pkl").write_bytes(pickle.dumps(unit, protocol=pickle.HIGHEST_PROTOCOL))
        yield unit


def _units_read(scratch: Path, count: int):
    """The ``count`` units :func:`_units_kept` kept, read back one at a time (each file removed once read)."""
    for number in range(count):
        path = scratch / f"samples-{number:07d}.pkl"
        unit = pickle.loads(path.read_bytes())
        path.unlink()
        yield unit


def _join_reports(reports: list[Path], path: Path) -> None:
    """``summary.txt`` from the units' lines, as :meth:`DensityResult.report` joins them."""
    with open(path, "w", encoding="utf-8") as file:
        for position, part in enumerate(reports):
            file.write(("\n" if position else "") + part.read_text(encoding="utf-8"))
        file.write("\n")


def _overview_png(values: np.ndarray) -> bytes | None:
    """The overview figure of every test's best curve (None when no test has one)."""
    if not len(values):
        return None
    from ..output.plotting import figure_png, offscreen_axes
    from .plotting import plot_density_overview

    axes = offscreen_axes(2, 1, figsize=(9.0, 6.5))  # as DensityResult.save draws it
    return figure_png(plot_density_overview(_OverviewRows(values), axes=axes)[0])


class _OverviewRows:
    """The overview's rows made as they are read, one at a time, from its values (tests x :data:`OVERVIEW_VALUES`)."""

    def __init__(self, values: np.ndarray):
        self.values = values

    def __len__(self) -> int:
        return len(self.values)

    def __iter__(self):
        for line in self.values:
            yield dict(zip(OVERVIEW_VALUES, line))
