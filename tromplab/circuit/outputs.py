"""The files of a reconciled survey: what ``tromplab circuit`` writes and
:meth:`CircuitBalance.save <tromplab.circuit.CircuitBalance.save>` writes, from one place.

Tables ``flows.csv``, ``distributions.csv``, ``adjustments.csv``, ``gross_errors.csv``,
``elimination.csv``, ``nodal_tests.csv``, ``worth.csv``, ``observability.csv``, ``design.csv``, ``chi_square.csv``,
``degrees_of_freedom.csv``, ``partition.csv``, ``points.csv``, ``flowsheet.csv`` (and
``water.csv`` with per cent solids measured, ``components.csv`` with per-class assays, ``warnings.csv``
when a separator's points or fits have a warning), ``summary.txt`` (:meth:`CircuitBalance.report`)
and the figures ``flowsheet.png``, ``adjustments.png``, ``distributions.png`` (and
``partition.png`` with per-class assays).
"""

from __future__ import annotations

import io
from collections.abc import Callable
from pathlib import Path

import pandas as pd

from ..loading.weights import weight_notes, weight_notices
from ..notices import Notice, notice_table
from ..output.csv_parts import file_writers
from .elimination import exclusion_name
from .plotting import figure_size


def balance_tables(balance, errors=None, *, weighting: str = "error-model") -> dict[str, pd.DataFrame]:
    """Name (without ``.csv``) -> table of every table of the reconciled survey ``balance``
    (``errors``: the error model the survey was read with, for the design advice and the
    observability table; default :class:`~tromplab.circuit.measurements.ErrorModel`;
    ``weighting``: the weights of ``points.csv``, :meth:`CircuitBalance.points_table`)."""
    from .design import design_table, observability_table
    from .measurements import ErrorModel

    # the report (summary.txt) reads the balance's own design table, of the default error model:
    # with that model the file is the same table, computed once
    default = errors is None or errors == ErrorModel()
    design = balance.design_table() if default else design_table(balance, errors=errors, progress=balance.progress)
    tables = {
        "flows": balance.flows_table(),
        "distributions": balance.distributions_table(),
        "adjustments": balance.adjustments_table(),
        "gross_errors": balance.gross_errors_table(),
        "elimination": balance.elimination_table(),
        "nodal_tests": balance.nodal_tests_table(),
        "worth": balance.worth_table(),
        "observability": observability_table(balance, errors),
        "design": design,
        "chi_square": balance.chi_square_table(),
        "degrees_of_freedom": balance.degrees_of_freedom_table(),
        "partition": balance.partition_table(),
        "points": balance.points_table(weighting=weighting),
        "flowsheet": balance.flowsheet.to_frame(),
    }
    if balance.balances_water:
        tables["water"] = balance.water_table()
    if balance.survey.components:
        tables["components"] = balance.components_table()
    return tables


def balance_next_steps(balance, tables: dict) -> tuple[str, ...]:
    """The one or two things to do next (:func:`next_steps`) from the tables of :func:`balance_tables`."""
    return tuple(next_steps(balance, observability=tables["observability"], design=tables["design"]))


def balance_summary(balance, tables: dict, steps=()) -> str:
    """``summary.txt``: the report, the notes on the weights of the points and the next steps."""
    lines = [balance.report(), *weight_notes(tables["points"]), *(f"next: {step}" for step in steps)]
    return "\n".join(lines) + "\n"


def balance_notices(tables: dict, bench=None) -> list[Notice]:
    """Every warning of a reconciled survey's separators, one :class:`~tromplab.notices.Notice`
    per separator (and assayed component) and kind: the weights of its points concentrated on a
    few classes (``points.csv``, :func:`~tromplab.loading.weights.weight_notices`), then, with
    the fits of ``--fit`` (``bench``), the notes on its points (:meth:`Workbench.notices`)."""
    notices = [Notice(name, note) for name, note in weight_notices(tables["points"])]
    return notices + (list(bench.notices()) if bench is not None else [])


def balance_outputs(
    balance, *, figures: bool = True, tables: dict | None = None, steps=None, notices=None
) -> dict[str, Callable[[Path], None]]:
    """File name -> writer of every file of ``balance`` (``tables``: :func:`balance_tables` and any
    further tables, such as the fits of ``--fit``; ``steps``: :func:`balance_next_steps`;
    ``notices``: :func:`balance_notices`, written as ``warnings.csv`` when there is one), for
    :func:`tromplab.output.outputs.replace_folder`."""
    tables = balance_tables(balance) if tables is None else tables
    steps = balance_next_steps(balance, tables) if steps is None else steps
    notices = balance_notices(tables) if notices is None else notices
    if notices:  # every occurrence, as fit, trend and density fit write them
        tables = {**tables, "warnings": notice_table(notices, subject="separator")}
    pictures = {}
    if figures:
        kinds = ("flowsheet", "adjustments", "distributions") if balance.has_size_classes else ("flowsheet", "adjustments")
        pictures = {
            f"{kind}.png": balance_png(balance, kind) for kind in kinds + (("partition",) if balance.survey.components else ())
        }
    return file_writers(tables, texts={"summary.txt": balance_summary(balance, tables, steps)}, pictures=pictures)


def balance_png(balance, kind: str) -> bytes:
    """Figure ``kind`` drawn on a figure made without pyplot (no backend chosen, no figure left open)."""
    from ..output.plotting import offscreen_axes  # matplotlib only when a figure is drawn

    ax = offscreen_axes(figsize=figure_size(balance, kind))
    balance.plot(kind, ax=ax)
    buffer = io.BytesIO()
    ax.figure.savefig(buffer, format="png", dpi=120, bbox_inches="tight")
    return buffer.getvalue()


def next_steps(balance, *, observability=None, design=None, limit: int = 2) -> list[str]:
    """The one or two things to do next, most pressing first: act on the serial elimination's
    proposal when the global test rejects, measure what would determine a quantity the survey
    leaves free, and take the measurement that would lower a result's sd the most."""
    steps = []
    if balance.rejected and len(balance.elimination_table()) > 1:
        names = ",".join(
            exclusion_name(r.stream, r.kind, r.size_class) for r in balance.elimination_table().iloc[1:].itertuples()
        )
        steps.append(f"check the measurement(s) the serial elimination names ({names.replace(',', ', ')}; "
                     f"elimination.csv), then reconcile without them: --exclude {names}")  # fmt: skip
    if observability is None:
        from .design import observability_table

        observability = observability_table(balance)
    free = observability[observability["observable"] == "no"]
    if len(free):
        first = free.iloc[0]
        helper = first["made_observable_by"].split("; ")[0] if first["made_observable_by"] else ""
        listed = ", ".join(f"{r.quantity} of {r.stream}" for r in free.head(3).itertuples()) + (" ..." if len(free) > 3 else "")
        steps.append(f"the survey leaves {listed} undetermined"
                     + (f": measure the {helper} (observability.csv)" if helper else " (observability.csv)"))  # fmt: skip
    design = balance.design_table() if design is None else design
    if len(design) and design.iloc[0]["reduction"] > 0:
        top = design.iloc[0]
        steps.append(f"for the next survey, add the {top.measurement} of {top.stream} (sd of {top.quantity} "
                     f"{top.sd_before:.3g} -> {top.sd_after:.3g}, predicted; design.csv)")  # fmt: skip
    return steps[:limit]
