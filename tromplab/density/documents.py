"""The density fits as one Excel workbook and as a report (HTML with a Markdown twin).

``tromplab density fit FILE -o DIR --excel`` adds ``DIR/results.xlsx`` and ``--report`` adds
``DIR/report.html`` and ``DIR/report.md``; ``DensityResult.save(DIR, excel=True,
report=True)`` writes the same.  Both are made of the tables and figures the folder already
holds (``fits.csv``, ``partition.csv``, ``by_size.csv``, ``ep_trend.csv``, the figures), through
the shared machinery: :func:`tromplab.output.workbook.write_workbook` (every name a text
cell, never a formula; a unit in each header) and :class:`tromplab.output.report.Report`
(every text escaped).  The Markdown report links the figures written beside it in the folder.
"""

from __future__ import annotations

import pandas as pd

from ..output.report import Report
from ..output.workbook import write_workbook

#: The workbook's file name in the output folder.
WORKBOOK_NAME = "results.xlsx"
#: The report's file names in the output folder.
REPORT_HTML, REPORT_MARKDOWN = "report.html", "report.md"
#: The sections of the density report, in order (headings in :mod:`tromplab.output.report`).
REPORT_SECTIONS = ("summary", "fits", "partition", "by_size", "figures")
#: Headings of the density report's own: its unit is the test (and size fraction), not the experiment.
REPORT_HEADINGS = {"fits": "Ranked fits per test"}

_DENSITY_STEMS = ("rho50", "rho25", "rho75", "rho_c", "ep", "ep_c", "density", "density_lower", "density_upper", "ep_at_1mm")
_SHARE_STEMS = ("partition_sinks", "partition", "light_limit", "heavy_limit", "feed_share", "floats_share", "sinks_share",
                "weight", "feed_measured", "gof_p", "limits_p")  # fmt: skip
_PERCENT_STEMS = ("feed_ash_pct", "floats_ash_pct", "sinks_ash_pct")
_DIMENSIONLESS_STEMS = ("imperfection", "deviance", "ssr", "dispersion", "aic", "balance_residual", "exponent")
_SUFFIXES = ("_low", "_high")

#: The columns of the fits shown in the report (the full table is fits.csv).
REPORT_FIT_COLUMNS = ("test", "size_fraction", "method", "curve", "rank", "rho50", "rho50_low", "rho50_high", "ep", "ep_low",
                      "ep_high", "imperfection", "imperfection_low", "imperfection_high", "gof_p", "limits_p", "aic", "notes")  # fmt: skip
#: The columns of the measured partition shown in the report (the full table is partition.csv).
REPORT_PARTITION_COLUMNS = ("test", "size_fraction", "density", "partition_sinks", "partition_low", "partition_high",
                            "placed", "sinks", "floats", "lost", "feed_share", "floats_share", "sinks_share")  # fmt: skip


def density_column_unit(column: str, size_unit: str = "") -> str:
    """Unit of a density output column for a workbook header (``"g/cm3"``, ``"0..1"``, ``"%"``, ``"-"``, the size unit or "").

    Examples
    --------
    >>> density_column_unit("rho50_low"), density_column_unit("partition_sinks"), density_column_unit("curve")
    ('g/cm3', '0..1', '')
    """
    stem = next((column[: -len(s)] for s in _SUFFIXES if column.endswith(s)), column)
    if stem in _DENSITY_STEMS:
        return "g/cm3"
    if stem in _SHARE_STEMS:
        return "0..1"
    if stem in _PERCENT_STEMS:
        return "%"
    if stem in _DIMENSIONLESS_STEMS:
        return "-"
    if stem in ("size_lower", "size_upper", "size"):
        return size_unit or "size unit"
    return ""


def write_density_workbook(path, tables: dict[str, pd.DataFrame], figures: dict[str, bytes], *, size_unit: str = "") -> None:
    """Write the sheets ``fits``, ``partition`` (and ``by_size``, ``ep_trend`` when present) and ``figures``."""
    write_workbook(
        path,
        {name: table for name, table in tables.items() if table is not None},
        figures=figures,
        column_units=lambda column: density_column_unit(column, size_unit),
    )


def density_report(result, tables: dict[str, pd.DataFrame], figures: dict[str, bytes]) -> Report:
    """The report of a :class:`~tromplab.density.results.DensityResult`: summary, fits, partition, by size, figures."""
    source = ", ".join(dict.fromkeys(sample.source for sample in result.samples if sample.source)) or "table"
    report = Report("tromplab density report", source, order=REPORT_SECTIONS, headings=REPORT_HEADINGS)
    level = f"{result.ci:g}" if result.ci is not None else "none (no --ci)"
    for sample in result.samples:
        report.add("summary", "text", f"{sample.label}: {sample.layout}, {sample.used.shape[0]} points.")
        for note in sample.notes:
            report.add("summary", "warning", f"{sample.label}: {note}")
    report.add("summary", "text", f"Interval level of rho50, Ep and the imperfection: {level}. Units: densities in g/cm3, "
               "partitions to the sinks as shares 0..1. Every column is defined in docs/density_columns.md.")  # fmt: skip
    fits = tables["fits"]
    report.add("fits", "table", fits[[c for c in REPORT_FIT_COLUMNS if c in fits.columns]], "Fits, ranked by AIC per test")
    partition = tables["partition"]
    shown = partition[[c for c in REPORT_PARTITION_COLUMNS if c in partition.columns]]
    report.add("partition", "table", shown, "Measured partition to sinks (Wilson intervals for tracers)")
    if "by_size" in tables:
        report.add("by_size", "table", tables["by_size"], "rho50, Ep and I per size fraction")
        report.add("by_size", "table", tables["ep_trend"], "The trend Ep = a d^-b")
    for name, png in figures.items():
        report.add("figures", "figure", png, name)
    return report
