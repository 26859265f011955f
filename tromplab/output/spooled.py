"""CSV tables written unit by unit: each unit of a batch formats its own rows (:func:`unit_table`,
on a worker), the main process spools the texts to a scratch folder beside the output folder
(:class:`SpooledTables`) and at the end joins them into each table's file, holding one unit at
a time, never the table.

The joined file is the text :func:`~tromplab.output.csv_parts.write_csv` writes for the whole
table (the units' frames concatenated), byte for byte.  A row's text depends on its values, its
column's type and the order of the columns only (:mod:`tromplab.output.csv_parts`), so when
every unit's rows were typed alike the texts are joined as they are.  When they were not (an
integer column that a failed fit's empty cell turns into floats in one unit only), the whole
table's columns and types are those pandas gives the concatenation of one row of each layout
met (:func:`pandas.concat` takes the common type of each column's types, whatever their
rows), and each unit of another layout is concatenated after those rows, cast alike, and
formatted again: still one unit at a time.  A text cell holding a carriage return, which makes
:func:`~tromplab.output.csv_parts.write_csv` quote every text cell of the file, is handled the
same way.

The scratch folder is named as the output layer names its staging folders
(``.OUT.tmp-<pid>-<random>``), so a run that dies leaves nothing that looks like a results
folder and the next run into the same place removes it
(:func:`tromplab.output.outputs.clean_stale`).
"""

from __future__ import annotations

import csv
import pickle
import shutil
from pathlib import Path
from typing import NamedTuple

import pandas as pd

from .csv_parts import csv_part, defended_frame, holds_carriage_return
from .outputs import staging_folder_beside


class UnitTable(NamedTuple):
    """A unit's rows of one table: ``text`` (the rows as CSV, no header, UTF-8), ``frame`` (the
    rows pickled, for a unit typed otherwise than the table), ``header`` (the header line the
    unit's columns give), ``layout`` (its columns and their types), ``rows`` and
    ``carriage_return`` (a text cell holds one)."""

    text: bytes
    frame: bytes
    header: bytes
    layout: tuple
    rows: int
    carriage_return: bool


def unit_table(frame: pd.DataFrame) -> UnitTable:
    """The :class:`UnitTable` of a unit's rows ``frame`` (made where the unit was fitted)."""
    part = csv_part(frame)
    header = defended_frame(frame.iloc[:0]).to_csv(index=False).encode("utf-8")
    return UnitTable(
        part.text.encode("utf-8"),
        pickle.dumps(frame, protocol=pickle.HIGHEST_PROTOCOL),
        header,
        (part.columns, part.dtypes),
        part.rows,
        holds_carriage_return(frame),
    )


class _Kept(NamedTuple):
    number: int
    layout: tuple
    rows: int
    carriage_return: bool


class SpooledTables:
    """The main process's side of tables written unit by unit: the scratch folder beside
    ``outdir`` and, for each table, what each unit's rows were (:meth:`keep`); :meth:`writer`
    joins them into the table's file.

    Use as a context manager: the scratch folder is removed on leaving, whatever happened.
    """

    def __init__(self, outdir):
        self.scratch = staging_folder_beside(outdir)
        self._kept: dict[str, list[_Kept]] = {}
        self._headers: dict[str, bytes] = {}
        self._empty_headers: dict[str, bytes] = {}

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        shutil.rmtree(self.scratch, ignore_errors=True)
        return False

    def keep(self, name: str, number: int, unit: UnitTable) -> None:
        """Spool unit ``number``'s rows of table ``name`` (units are kept in order)."""
        if not unit.rows:
            self._empty_headers.setdefault(name, unit.header)  # the header of a table without rows
            return
        self._headers.setdefault(name, unit.header)
        (self.scratch / f"{name}-{number:07d}.csv").write_bytes(unit.text)
        (self.scratch / f"{name}-{number:07d}.pkl").write_bytes(unit.frame)
        self._kept.setdefault(name, []).append(_Kept(number, unit.layout, unit.rows, unit.carriage_return))

    def rows(self, name: str) -> int:
        """Rows of table ``name`` kept so far."""
        return sum(kept.rows for kept in self._kept.get(name, ()))

    def writer(self, name: str):
        """Writer (taking a path) of table ``name``: the text of the whole table, joined unit by
        unit (the module's docstring); a table without rows is its header."""
        kept = self._kept.get(name, [])
        layouts = list(dict.fromkeys(unit.layout for unit in kept))
        quoted = any(unit.carriage_return for unit in kept)

        def write(path):
            with open(path, "wb") as file:
                if not kept:
                    file.write(self._empty_headers.get(name, b""))
                elif len(layouts) == 1 and not quoted:
                    file.write(self._headers[name])
                    for unit in kept:
                        with open(self._path(name, unit, "csv"), "rb") as part:
                            shutil.copyfileobj(part, file)
                else:
                    self._write_recast(name, kept, layouts, quoted, file)

        return write

    def _path(self, name: str, unit: _Kept, kind: str) -> Path:
        return self.scratch / f"{name}-{unit.number:07d}.{kind}"

    def _write_recast(self, name: str, kept: list[_Kept], layouts: list, quoted: bool, file) -> None:
        """The table's text when its units were typed differently (or a cell holds a carriage
        return): each unit cast to the whole table's columns and types and formatted again."""
        firsts = {}
        for unit in kept:  # one row of each layout, in the order the layouts were met
            if unit.layout not in firsts:
                firsts[unit.layout] = pd.read_pickle(self._path(name, unit, "pkl")).iloc[:1]
        probes = pd.concat(list(firsts.values()), ignore_index=True)
        whole = (tuple(probes.columns), tuple(str(dtype) for dtype in probes.dtypes))
        options = {"quoting": csv.QUOTE_NONNUMERIC} if quoted else {}
        file.write(defended_frame(probes.iloc[:0]).to_csv(index=False, **options).encode("utf-8"))
        for unit in kept:
            if unit.layout == whole and not quoted:
                with open(self._path(name, unit, "csv"), "rb") as part:
                    shutil.copyfileobj(part, file)
                continue
            frame = pd.read_pickle(self._path(name, unit, "pkl"))
            if unit.layout != whole:
                frame = pd.concat([probes, frame], ignore_index=True).iloc[len(probes) :]
            file.write(defended_frame(frame).to_csv(index=False, header=False, **options).encode("utf-8"))
