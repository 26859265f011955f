"""What an uploaded table holds, told from its columns as the commands tell it, and the
command that reads it.

Only the column names are read here (the header row, past the ``#`` comment lines); the
command then reads the whole file with its own reader and checks, so a bad file gets the
command's own message.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

#: Suffixes the page accepts: what the readers of :mod:`tromplab.loading.tables` read.
ACCEPTED_SUFFIXES = (".csv", ".txt", ".xlsx", ".xlsm")


@dataclass(frozen=True)
class TableKind:
    """The kind of an uploaded table.

    Attributes
    ----------
    kind : str
        ``"points"``, ``"lab"``, ``"trend"``, ``"density"``, ``"flowsheet"``, ``"survey"`` or ``"unknown"``.
    label : str
        What the page says the file holds.
    command : tuple of str
        The ``tromplab`` command that reads it (``("fit",)``), empty when none does.
    runs_here : bool
        Whether the page runs that command (else it says which command to run).
    alternatives : tuple of tuple of str
        Other commands that read it too, which the page offers beside ``command`` (dated
        surveys: ``tromplab trend`` beside ``tromplab fit``).
    """

    kind: str
    label: str
    command: tuple[str, ...]
    runs_here: bool
    alternatives: tuple[tuple[str, ...], ...] = ()

    @property
    def commands(self) -> tuple[tuple[str, ...], ...]:
        """The command and its alternatives, the default first."""
        return (self.command, *self.alternatives)

    def as_dict(self) -> dict:
        return {"kind": self.kind, "label": self.label, "command": command_name(self.command),
                "runs_here": self.runs_here, "commands": [command_name(c) for c in self.commands]}  # fmt: skip


def command_name(command: tuple[str, ...]) -> str:
    """``"tromplab density fit"`` of ``("density", "fit")``."""
    return " ".join(("tromplab", *command))


#: The two files of ``tromplab circuit``, in the order the command takes them.
CIRCUIT_ROLES = ("flowsheet", "survey")
#: ``tromplab circuit design``: the flowsheet, and the survey when one was dropped too.
CIRCUIT_DESIGN = ("circuit", "design")


def sheet_names(path: Path) -> list[str]:
    """The sheets of a workbook, in order (empty for a CSV file)."""
    if path.suffix.lower() not in (".xlsx", ".xlsm"):
        return []
    from openpyxl import load_workbook

    workbook = load_workbook(path, read_only=True)
    try:
        return list(workbook.sheetnames)
    finally:
        workbook.close()


def table_kind(path: Path, sheet: str | None = None) -> TableKind:
    """The kind of the table in ``path`` (its ``sheet``), told from its column names.

    Raises
    ------
    tromplab.errors.InputError
        When the file cannot be read as a table (the reader's own message).
    """
    return kind_of_columns(_column_names(path, sheet))


def kind_of_columns(columns) -> TableKind:
    """The kind of a table with these column names (see :func:`table_kind`)."""
    from ..loading.lab_streams import is_lab_table

    names = {str(column).strip().lower() for column in columns}
    if {"from", "to", "stream"} <= names:
        return TableKind("flowsheet", "a circuit flowsheet", ("circuit",), True, (CIRCUIT_DESIGN,))
    if "stream" in names:
        return TableKind("survey", "a plant survey of a circuit", ("circuit",), True, (CIRCUIT_DESIGN,))
    if "density" in names or "density_lower" in names or "density_upper" in names:
        return TableKind("density", "density tracers, a float-sink table or a density partition", ("density", "fit"), True)
    has_partition = any(name.startswith("partition") for name in names)
    if has_partition and ("survey" in names or "date" in names):
        return TableKind("trend", "Tromp points of dated surveys (tromplab fit ranks the formulas per survey; tromplab trend charts them)",
                         ("fit",), True, (("trend",),))  # fmt: skip
    if has_partition:
        return TableKind("points", "Tromp points", ("fit",), True)
    if is_lab_table(list(columns)) and ("survey" in names or "date" in names):
        return TableKind("trend", "a lab table of dated surveys (tromplab fit ranks the formulas per survey; tromplab trend charts them)",
                         ("fit",), True, (("trend",),))  # fmt: skip
    if is_lab_table(list(columns)):
        return TableKind("lab", "a lab table (feed and product size analyses)", ("fit",), True)
    return TableKind("unknown", "no table a command reads", ("fit",), True)  # fit's reader says what is missing


def _column_names(path: Path, sheet: str | None) -> list[str]:
    from ..loading.tables import read_table

    return [str(column) for column in read_table(path, sheet=sheet).frame.columns]
