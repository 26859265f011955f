"""The files of a reconciled survey: what ``tromplab circuit`` writes and
:meth:`CircuitBalance.save <tromplab.circuit.CircuitBalance.save>` writes, from one place.

Tables ``flows.csv``, ``distributions.csv``, ``adjustments.csv``, ``gross_errors.csv``,
``elimination.csv``, ``nodal_tests.csv``, ``worth.csv``, ``design.csv``, ``chi_square.csv``,
``degrees_of_freedom.csv``, ``partition.csv``, ``points.csv``, ``flowsheet.csv`` (and
``water.csv`` with per cent solids measured), ``summary.txt`` (:meth:`CircuitBalance.report`)
and the figures ``flowsheet.png``, ``adjustments.png`` and ``distributions.png``.
"""

from __future__ import annotations

import io
from collections.abc import Callable
from pathlib import Path

import pandas as pd

from ..loading.weights import weight_notes
from ..output.csv_parts import write_csv
from ..output.plotting import offscreen_axes
from .plotting import figure_size


def balance_tables(balance) -> dict[str, pd.DataFrame]:
    """Name (without ``.csv``) -> table of every table of the reconciled survey ``balance``."""
    tables = {
        "flows": balance.flows_table(),
        "distributions": balance.distributions_table(),
        "adjustments": balance.adjustments_table(),
        "gross_errors": balance.gross_errors_table(),
        "elimination": balance.elimination_table(),
        "nodal_tests": balance.nodal_tests_table(),
        "worth": balance.worth_table(),
        "design": balance.design_table(),
        "chi_square": balance.chi_square_table(),
        "degrees_of_freedom": balance.degrees_of_freedom_table(),
        "partition": balance.partition_table(),
        "points": balance.points_table(),
        "flowsheet": balance.flowsheet.to_frame(),
    }
    if balance.balances_water:
        tables["water"] = balance.water_table()
    return tables


def balance_outputs(balance, *, figures: bool = True, tables: dict | None = None) -> dict[str, Callable[[Path], None]]:
    """File name -> writer of every file of ``balance`` (``tables``: :func:`balance_tables` and any
    further tables, such as the fits of ``--fit``), for :func:`tromplab.output.outputs.replace_folder`."""
    tables = balance_tables(balance) if tables is None else tables
    outputs = {f"{name}.csv": (lambda path, table=table: write_csv(table, path)) for name, table in tables.items()}
    summary = "\n".join([balance.report(), *weight_notes(tables["points"])]) + "\n"
    outputs["summary.txt"] = lambda path: path.write_text(summary, encoding="utf-8")
    if figures:
        for kind in ("flowsheet", "adjustments", "distributions") if balance.has_size_classes else ("flowsheet", "adjustments"):
            png = balance_png(balance, kind)
            outputs[f"{kind}.png"] = lambda path, png=png: path.write_bytes(png)
    return outputs


def balance_png(balance, kind: str) -> bytes:
    """Figure ``kind`` drawn on a figure made without pyplot (no backend chosen, no figure left open)."""
    ax = offscreen_axes(figsize=figure_size(balance, kind))
    balance.plot(kind, ax=ax)
    buffer = io.BytesIO()
    ax.figure.savefig(buffer, format="png", dpi=120, bbox_inches="tight")
    return buffer.getvalue()
