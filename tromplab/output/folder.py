"""The results folder of a fitted batch: what ``tromplab fit -o DIR`` and ``Workbench.save(DIR)`` write.

One function builds the folder, so the command line and the Python API write the same
files byte for byte: ``fits``, ``ranking`` and ``averages`` tables (CSV or Parquet), the
figures with ``figures.csv`` mapping experiments to files, ``failures.csv`` when some fits
failed, ``left_out.csv`` when the loader left classes of lab input out, and the Excel
workbook when asked (or only the workbook, when the target is a ``.xlsx`` file).  With ``reloadable`` the pickled batch and its manifest are added, so
:func:`tromplab.load` can read the folder back.  The folder is replaced as a whole only
when every file is written (:func:`tromplab.output.outputs.replace_folder`).
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from ..errors import OptionError
from ..options import AUTO_FIGURE_LIMIT, FIGURE_CHOICES, TABLE_FORMATS
from .csv_parts import csv_pieces, write_csv
from .outputs import figure_file_names, replace_folder, write_files
from .plotting import figure_png, offscreen_axes, plot_batch_overview, plot_tromp_fits
from .results import batch_files
from .views import partition_view
from .workbook import write_workbook


def check_folder_options(*, figures: str, format: str) -> None:
    """Refuse an unknown ``figures`` or ``format`` choice (:class:`~tromplab.errors.OptionError`)."""
    if figures not in FIGURE_CHOICES:
        raise OptionError("figures", f"must be one of {', '.join(FIGURE_CHOICES)}, got {figures!r}")
    if format not in TABLE_FORMATS:
        raise OptionError("format", f"must be one of {', '.join(TABLE_FORMATS)}, got {format!r}")


def write_results_folder(
    bench,
    outdir,
    *,
    figures: str = "auto",
    format: str = "csv",
    excel: bool = False,
    reloadable: bool = False,
    map_work=None,
) -> dict[str, Path]:
    """Write the tables and figures of ``bench`` into ``outdir`` (or only the workbook,
    when ``outdir`` names a ``.xlsx`` file).

    Parameters
    ----------
    bench : Workbench
    outdir : str or path-like
        The folder, replaced as a whole when everything is written, or a ``.xlsx`` file.
    figures : {"auto", "all", "best", "none"}
        Per-experiment figures with every fit (``all``) or the top-ranked one (``best``);
        ``auto``: ``all`` up to :data:`AUTO_FIGURE_LIMIT` experiments, then one overview.
    format : {"csv", "parquet"}
        Format of the tables.
    excel : bool
        Also write every table and figure as one workbook, ``results.xlsx``.
    reloadable : bool
        Also write ``workbench.pkl``, ``manifest.json`` and ``points.csv``, so that
        :func:`tromplab.load` reads the batch back.
    map_work : callable, optional
        ``map_work(function, chunks, argument)`` yields ``function(argument, chunk)`` for each
        chunk in order: the batch's workers, which draw the per-experiment figures; default
        in this process.  The files are the same either way.

    Returns
    -------
    dict
        File name -> written path.
    """
    check_folder_options(figures=figures, format=format)
    outdir = Path(outdir)
    fits = bench.fits_table()
    tables = {"fits": fits, "ranking": bench.ranking_table(), "averages": bench.averages()}
    drawn, figure_names = _figures(bench, fits, figures, map_work or _map_here)
    only_workbook = outdir.suffix.lower() == ".xlsx"
    if only_workbook or excel:
        sheets = {**tables, **_input_sheets(bench)}
        if not (said := bench.warnings_table()).empty:  # what warnings.csv holds beside the tables
            sheets["warnings"] = said
        notes = {
            "balance": "no mass balance: the input holds Tromp points, not a lab table",
            "averages": "no model average: no experiment has a successful fit",
        }

        def workbook(path):
            write_workbook(path, sheets, figures=drawn, size_unit=bench.size_unit, notes=notes)

        if only_workbook:
            return write_files({outdir.name: workbook}, outdir.parent)
    outputs = {f"{name}.{format}": _table_writer(table, format, bench.formatted_parts(name)) for name, table in tables.items()}
    outputs.update({name: (lambda p, png=png: p.write_bytes(png)) for name, png in drawn.items()})
    if figure_names:
        mapping = pd.DataFrame({"experiment": list(figure_names), "file": list(figure_names.values())})
        outputs["figures.csv"] = lambda p: write_csv(mapping, p)
    outputs.update(_failure_files(bench))
    if excel:
        outputs["results.xlsx"] = workbook
    if reloadable:
        outputs.update(batch_files(bench))
    return replace_folder(outputs, outdir)


def write_streamed_folder(bench, outdir, tables: dict, *, overview: pd.DataFrame | None = None) -> dict[str, Path]:
    """Write the results folder of a batch whose tables were streamed to disk: the files
    :func:`write_results_folder` writes with ``format="csv"`` and ``figures`` ``"none"`` (or
    ``"auto"`` above :data:`AUTO_FIGURE_LIMIT` experiments, when ``overview`` holds the
    columns of the overview figure of each experiment's top-ranked fit, None when no fit is
    ranked), byte for byte: its tables come from ``tables``, written as joined on disk.

    Parameters
    ----------
    bench : Workbench
        The streamed batch: its ranking, failures and mass balances.
    outdir : str or path-like
        The folder, replaced as a whole when everything is written.
    tables : dict
        Writers (taking a path) of ``fits.csv``, ``ranking.csv`` and ``averages.csv``.
    overview : pandas.DataFrame, optional
        Columns ``experiment, formula, rank, d_cut, ep, eta`` of each experiment's top-ranked
        fit (:func:`~tromplab.output.plotting.plot_batch_overview`).

    Returns
    -------
    dict
        File name -> written path.
    """
    outputs = {name: tables[name] for name in ("fits.csv", "ranking.csv", "averages.csv")}
    if overview is not None:
        png = _overview_png(overview)
        outputs["overview.png"] = lambda p: p.write_bytes(png)
    outputs.update(_failure_files(bench))
    return replace_folder(outputs, Path(outdir))


def _failure_files(bench) -> dict:
    """Writers of ``failures.csv`` (when fits failed), ``warnings.csv`` (when the batch has
    warnings: every occurrence of what the console groups by kind) and ``left_out.csv`` (when
    the loader left classes of lab input out)."""
    outputs = {}
    failures = bench.failure_table()
    if not failures.empty:
        outputs["failures.csv"] = lambda p: write_csv(failures, p)
    said = bench.warnings_table()
    if not said.empty:
        outputs["warnings.csv"] = lambda p: write_csv(said, p)
    left_out = [b.left_out_table() for b in bench.balances]
    if any(not table.empty for table in left_out):  # the classes the console summarises in one line per experiment
        listed = pd.concat([table for table in left_out if not table.empty], ignore_index=True)
        outputs["left_out.csv"] = lambda p: write_csv(listed, p)
    return outputs


def _overview_png(fits: pd.DataFrame) -> bytes:
    return figure_png(plot_batch_overview(fits, axes=offscreen_axes(2, 2, figsize=(9, 6.5)))[0])


#: Experiments whose figures one worker draws at a time.
FIGURE_CHUNK = 16


def _figures(bench, fits: pd.DataFrame, mode: str, map_work) -> tuple[dict[str, bytes], dict[str, str]]:
    """PNG bytes by file name, and the experiment -> file mapping of per-experiment figures
    (drawn by ``map_work``'s workers, :data:`FIGURE_CHUNK` experiments at a time)."""
    if mode == "auto":
        mode = "all" if len(bench.experiments) <= AUTO_FIGURE_LIMIT else "overview"
    if mode == "overview":
        return ({"overview.png": _overview_png(fits)} if fits["rank"].notna().any() else {}), {}
    if mode not in ("all", "best"):
        return {}, {}
    names = figure_file_names(bench.experiments)
    work = []
    for experiment in names:
        best = bench.best_fit(experiment)
        work.append((bench.fits_of(experiment) if mode == "all" or best is None else [best], best))
    chunks = [work[i : i + FIGURE_CHUNK] for i in range(0, len(work), FIGURE_CHUNK)]
    options = {"size_unit": bench.size_unit, "partition_to": bench.partition_to}
    pictures = [png for drawn in map_work(tromp_figures, chunks, options) for png in drawn]
    return dict(zip(names.values(), pictures)), names


def tromp_figures(options: dict, chunk) -> list[bytes]:
    """PNG of the Tromp curves of each ``(fits shown, best fit)`` of ``chunk`` (``options``:
    ``size_unit``, ``partition_to``): a unit of work for the workers."""
    return [figure_png(plot_tromp_fits(shown, best=best, ax=offscreen_axes(), **options)) for shown, best in chunk]


def _map_here(function, chunks, argument):
    return (function(argument, chunk) for chunk in chunks)


def _input_sheets(bench) -> dict[str, pd.DataFrame]:
    """The ``balance`` and ``points`` sheets: the mass balances of lab input, else the points."""
    if bench.balances:
        # the loader weights lab points only with weight_by_feed_share, so the weights tell it
        weighted = any(fit.points.weight is not None for fit in bench.fits)
        balance = pd.concat([b.classes for b in bench.balances], ignore_index=True)
        points = pd.concat([b.points_table(weight_by_feed_share=weighted) for b in bench.balances], ignore_index=True)
    else:
        balance, points = pd.DataFrame(), pd.concat([p.to_frame() for p in bench.inputs], ignore_index=True)
    return {"balance": partition_view(balance, bench.partition_to), "points": partition_view(points, bench.partition_to)}


def _table_writer(table: pd.DataFrame, format: str, parts=None):
    """Writer of ``table`` in ``format``; a CSV joins the rows the workers formatted
    (``parts``, :mod:`tromplab.output.csv_parts`) where they match the table."""
    if format == "parquet":
        return lambda p: table.to_parquet(p, index=False)

    def write_table_csv(path):
        pieces = csv_pieces(table, parts)
        if pieces is None:
            write_csv(table, path)
            return
        with open(path, "w", encoding="utf-8", newline="") as file:  # as to_csv opens it
            file.writelines(pieces)

    return write_table_csv
