"""One Excel workbook with every table of a fit and its figures (``tromplab fit -o results.xlsx``).

Sheets ``fits``, ``ranking``, ``averages``, ``balance``, ``points`` and, when figures
are given, ``figures``.  Each table sheet holds the same values as the CSV of the same
name; the header row carries the unit of each column in brackets (``d_cut [mm]``),
is frozen, and the numbers have a display format (the stored values keep full
precision).  Written with openpyxl, readable in Excel and LibreOffice.

Every text cell is written as text, never as a formula: openpyxl would store a string that
starts with ``=`` as a formula, so a name such as ``=1+1`` taken from the data would run in
the reader's spreadsheet.  Text that starts as a formula would (``=``, ``+``, ``-``, ``@``, a
tab, a carriage return) is also given the spreadsheet's text mark (``quotePrefix``), so that
editing the cell keeps it text.  The cell holds the name exactly; control characters that a
workbook cannot hold, and a carriage return, are written in the workbook's own escape
(``_x0001_``, ``_x000D_``), which Excel shows as the character.

The same tables give the same file, byte for byte: the workbook's creation and modification
dates and the time stamps of the parts of its zip archive are :data:`WORKBOOK_DATE`, not the
time of writing (openpyxl would write the clock's).
"""

from __future__ import annotations

import datetime
import io
import zipfile
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from ..loading.names import FORMULA_STARTS

#: The date the workbook says it was created and modified (and its zip parts' time): fixed, so that
#: the same results give the same bytes (the zip format's earliest date).
WORKBOOK_DATE = datetime.datetime(1980, 1, 1)

#: The part of an xlsx archive that holds its creation and modification dates.
_CORE_PROPERTIES = "docProps/core.xml"

#: Sheets of the workbook, in order (``figures`` last, when there are figures).
SHEETS = ("fits", "ranking", "averages", "balance", "points")

# Columns measured in the unit of the particle sizes (with their interval and error columns).
_SIZE_STEMS = ("d_cut", "d50", "d50c", "d25", "d75", "ep", "ep_c", "size", "size_lower", "size_upper", "delta_max")
# Shares of a stream or of the feed, 0..1.
_FRACTION_STEMS = (
    "partition_fine",
    "partition_coarse",
    "eta",
    "bypass",
    "akaike_share",
    "water_recovery",
    "feed_share",
    "fine_yield",
    "coarse_yield",
    "feed",
    "fine",
    "coarse",
    "feed_adjusted",
    "fine_adjusted",
    "coarse_adjusted",
)
_COUNT_COLUMNS = ("n", "rank", "place", "points", "equation", "n_regimes", "bootstrap_failed")
_SUFFIXES = ("_stderr", "_se", "_low", "_high", "_boot_low", "_boot_high")

#: Display formats by kind of column.
NUMBER_FORMATS = {"size": "0.0000", "fraction": "0.0000", "count": "0", "other": "0.0000"}


def column_unit(column: str, size_unit: str = "") -> str:
    """Unit of a column for its header: the size unit, ``"0..1"`` for shares, ``"-"`` for
    other dimensionless numbers, or ``""`` for text, counts and flags.

    Examples
    --------
    >>> column_unit("d_cut_low", "mm"), column_unit("eta", "mm"), column_unit("formula")
    ('mm', '0..1', '')
    """
    stem = _stem(column)
    if stem in _SIZE_STEMS:
        return size_unit or "size unit"
    if stem in _FRACTION_STEMS or stem.startswith("weight_"):  # Akaike weights; a bare "weight" is a least-squares weight
        return "0..1"
    if stem in (
        "imperfection",
        "imperfection_c",
        "epsilon",  # an area in relative-size units, in [0, x_max - 1]
        "fishhook",
        "x_break",  # a relative size, size / d_cut
        "balance_residual",  # a difference of shares, negative as often as positive
        "partition_fine_corrected",  # Kelsall-corrected, above 1 where a class beat its water
        "partition_coarse_corrected",
        "shape",
        "F",
        "F_crit",
        "ssr",
        "aic",
        "aicc",
        "delta_aicc",
        "bic",
        "slope",
        "slope_coarse",
        "sharpness",
        "runs_p",
        "normality_p",
        "nested_F",
        "nested_p",
    ):
        return "-"
    return ""


def header_with_unit(column: str, size_unit: str = "") -> str:
    """``"d_cut [mm]"``; a column without a unit keeps its bare name."""
    unit = column_unit(column, size_unit)
    return f"{column} [{unit}]" if unit else column


def _stem(column: str) -> str:
    for suffix in sorted(_SUFFIXES, key=len, reverse=True):
        if column.endswith(suffix):
            return column[: -len(suffix)]
    return column


def _number_format(column: str) -> str:
    stem = _stem(column)
    if column in _COUNT_COLUMNS:
        return NUMBER_FORMATS["count"]
    if stem in _SIZE_STEMS:
        return NUMBER_FORMATS["size"]
    if stem in _FRACTION_STEMS:
        return NUMBER_FORMATS["fraction"]
    return NUMBER_FORMATS["other"]


def write_workbook(
    path,
    tables: Mapping[str, pd.DataFrame],
    *,
    figures: Mapping[str, bytes] | None = None,
    size_unit: str = "",
    notes: Mapping[str, str] | None = None,
    column_units: Callable[[str], str] | None = None,
) -> Path:
    """Write ``tables`` (sheet name -> DataFrame) and PNG ``figures`` into one workbook.

    Parameters
    ----------
    path : path
        The ``.xlsx`` file.  Write it through :func:`tromplab.output.outputs.write_files`
        to make it all-or-nothing.
    tables : mapping
        Sheet name -> table, written in the given order; an empty table gets its
        ``notes`` entry (or "no rows") in cell A1 instead of a header.  A table with a
        ``quantity`` column (one row per quantity) gets a ``unit`` column beside it.
    figures : mapping, optional
        Figure name -> PNG bytes, embedded one below the other on a ``figures`` sheet,
        each under its name.
    size_unit : str
        Unit of the sizes, shown in the headers of size columns.
    notes : mapping, optional
        Sheet name -> sentence shown on a sheet with no rows (why it is empty).
    column_units : callable, optional
        Column name -> its unit for the header, in place of :func:`column_unit` (tables
        whose columns are not sizes and shares, as the density fits').
    """
    from openpyxl import Workbook

    book = Workbook()
    book.remove(book.active)
    for name, table in tables.items():
        sheet = book.create_sheet(name)
        if table is None or table.empty:
            _set_text(sheet["A1"], (notes or {}).get(name, "no rows"))
        else:
            _write_table(sheet, table, size_unit, column_units)
    if figures:
        _write_figures(book.create_sheet("figures"), figures)
    path = Path(path)
    _save_reproducibly(book, path)
    return path


def _save_reproducibly(book, path: Path) -> None:
    """Save ``book`` at ``path`` with :data:`WORKBOOK_DATE` in place of every clock time openpyxl writes."""
    from openpyxl.xml.functions import tostring

    written = io.BytesIO()
    book.save(written)  # sets the modification date to now: the document properties are written again below
    book.properties.created = book.properties.modified = WORKBOOK_DATE
    with zipfile.ZipFile(written) as source, zipfile.ZipFile(path, "w") as target:
        for part in source.infolist():
            stamped = zipfile.ZipInfo(part.filename, date_time=WORKBOOK_DATE.timetuple()[:6])
            stamped.compress_type, stamped.external_attr = part.compress_type, part.external_attr
            content = tostring(book.properties.to_tree()) if part.filename == _CORE_PROPERTIES else source.read(part)
            target.writestr(stamped, content)


def _write_table(sheet, table: pd.DataFrame, size_unit: str, column_units=None) -> None:
    """``table`` on ``sheet``: a bold header with units, the rows at full precision, a number format
    per numeric column and the header row frozen."""
    from openpyxl.styles import Font
    from openpyxl.utils import get_column_letter

    if "quantity" in table.columns and "unit" not in table.columns:
        # a long table (one row per quantity, as the model averages): the unit goes in a column
        table = table.copy()
        table.insert(
            table.columns.get_loc("quantity") + 1, "unit", table["quantity"].map(lambda q: column_unit(str(q), size_unit))
        )
    if column_units is None:
        headers = [header_with_unit(str(c), size_unit) for c in table.columns]
    else:
        headers = [f"{c} [{column_units(str(c))}]" if column_units(str(c)) else str(c) for c in table.columns]
    sheet.append([_storable(header) for header in headers])
    for row in table.itertuples(index=False):
        sheet.append([_cell_value(value) for value in row])
    for index, column in enumerate(table.columns, start=1):
        text_column = not pd.api.types.is_numeric_dtype(table[column]) or pd.api.types.is_bool_dtype(table[column])
        for cell in sheet[get_column_letter(index)] if text_column else sheet[get_column_letter(index)][:1]:
            if isinstance(cell.value, str):
                _mark_text(cell)
    for index, column in enumerate(table.columns, start=1):
        letter = get_column_letter(index)
        sheet.cell(row=1, column=index).font = Font(bold=True)
        sheet.column_dimensions[letter].width = max(10, min(40, len(headers[index - 1]) + 2))
        if pd.api.types.is_numeric_dtype(table[column]) and not pd.api.types.is_bool_dtype(table[column]):
            number_format = _number_format(str(column))
            for cell in sheet[letter][1:]:
                cell.number_format = number_format
    sheet.freeze_panes = "A2"


def _write_figures(sheet, figures: Mapping[str, bytes]) -> None:
    """The PNG ``figures`` on ``sheet``, one below the other, each under its name in bold."""
    from openpyxl.drawing.image import Image
    from openpyxl.styles import Font

    row = 1
    for name, png in figures.items():
        cell = sheet.cell(row=row, column=1)
        _set_text(cell, name)
        cell.font = Font(bold=True)
        image = Image(io.BytesIO(png))
        sheet.add_image(image, f"A{row + 1}")
        row += int(np.ceil(image.height / 20)) + 3  # default row height is 20 pixels


def _storable(text: str) -> str:
    """``text`` with the control characters a workbook cannot hold, and the carriage return
    (which XML reads as a line feed), in the workbook's escape ``_xHHHH_``, as Excel writes them."""
    from openpyxl.cell.cell import ILLEGAL_CHARACTERS_RE

    text = ILLEGAL_CHARACTERS_RE.sub(lambda found: f"_x{ord(found.group()):04X}_", text)
    return text.replace("\r", "_x000D_")


def _mark_text(cell) -> None:
    """Keep the text in ``cell`` a text cell, never a formula (module docstring)."""
    cell.data_type = "s"
    if cell.value.startswith(FORMULA_STARTS):
        cell.quotePrefix = True


def _set_text(cell, text: str) -> None:
    """Store ``text`` in ``cell`` as a text cell."""
    cell.value = _storable(text)
    _mark_text(cell)


def _cell_value(value):
    """A value openpyxl stores: numpy scalars as Python numbers, missing as an empty cell."""
    if value is None or (isinstance(value, float) and np.isnan(value)):
        return None
    if isinstance(value, np.generic):
        value = value.item()
        if isinstance(value, float) and np.isnan(value):
            return None
    if value is pd.NA or value is pd.NaT:
        return None
    return _storable(value) if isinstance(value, str) else value
