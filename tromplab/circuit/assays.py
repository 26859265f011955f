r"""Per-class assays of a survey: the mass share of each component in each size class of a stream.

An assay column ``assay_<name>_pct`` gives, on the row of a stream and size class, the mass
per cent of component ``<name>`` (a mineral, an element reported as such) in the solids of
that class of that stream.  Any number of components; a stream, or a class of it, may lack
the assay of some or all components (a blank cell: not measured).  An assay has the standard
deviation of the error model of the shares,

.. math:: \sigma = \sqrt{(r\,a)^2 + b^2}

with :math:`a` the assay as a fraction, the relative error :math:`r`
(:data:`~tromplab.options.DEFAULT_ASSAY_RELATIVE_ERROR`) and the absolute error :math:`b`
(:data:`~tromplab.options.DEFAULT_ASSAY_ABSOLUTE_ERROR`, a fraction of the class's solids),
overridden per component by :class:`~tromplab.circuit.measurements.ErrorModel` ``components``.
Assays of different streams, classes and components are independent (components are not
normalised: they need not sum to 100 %).  Hodouin & Everell (1980) balance size and assay
data of mineral circuits in the same way.

References
----------
Hodouin, D. & Everell, M. D. (1980). A hierarchical procedure for adjustment and material
balancing of mineral processes data. *International Journal of Mineral Processing* 7(2),
91-116.
"""

from __future__ import annotations

import re

import numpy as np
import pandas as pd

from ..errors import OptionError
from ..loading.tables import Table

#: An assay column: the mass per cent of the component named between ``assay_`` and ``_pct``.
ASSAY_COLUMN = re.compile(r"^assay_(?P<component>.+)_pct$")
#: The name of the whole solids in the ``component`` columns of the outputs (not a component).
SOLIDS = "solids"
#: Columns of :attr:`~tromplab.circuit.measurements.Survey.assays`: ``value`` a fraction (0..1)
#: of the class's solids, ``relative``/``absolute`` the error model's errors (NaN where not modelled).
ASSAY_COLUMNS = ["stream", "class_index", "component", "value", "sd", "row", "relative", "absolute"]


#: An assay of a class holding less than this share of its stream (as measured) is set aside:
#: too little material to assay, and its prediction (component flow over a class flow near 0)
#: would dominate the Jacobian by orders of magnitude and blur the rank decision.
MIN_ASSAYED_SHARE = 0.001


def empty_assays() -> pd.DataFrame:
    return pd.DataFrame(columns=ASSAY_COLUMNS)


def assay_columns(table: Table) -> dict[str, str]:
    """``{component: column}`` of the table's assay columns, in the table's order."""
    found = {}
    for column in table.frame.columns:
        match = ASSAY_COLUMN.match(str(column))
        if match is None:
            continue
        name = match["component"].strip()
        if not name or name == SOLIDS:
            raise table.error(
                f"assay column '{column}' needs a component name other than '{SOLIDS}' (the whole solids)", column=column
            )
        found[name] = column
    return found


def read_assays(table: Table, names, has_class, class_of_row, errors) -> pd.DataFrame:
    """The assays of the table (:data:`ASSAY_COLUMNS`), checked, with their standard deviations.

    Raises
    ------
    InputError
        Naming the row and column: an assay below 0 or above 100 %, an assay on a row without a
        size class, a stream giving one class's assay twice.
    OptionError
        An :class:`~tromplab.circuit.measurements.ErrorModel` ``components`` override naming a
        component the table does not assay.
    """
    columns = assay_columns(table)
    unknown = [name for name in errors.components if name not in columns]
    if unknown:
        assayed = ", ".join(columns) or "none: no assay_<name>_pct column"
        raise OptionError(
            "components",
            f"of the error model names {', '.join(repr(n) for n in unknown)}, not a component the survey "
            f"{table.source} assays ({assayed})",
        )
    frames = [_component_assays(table, names, has_class, class_of_row, errors, name, column) for name, column in columns.items()]
    frames = [frame for frame in frames if len(frame)]
    return pd.concat(frames, ignore_index=True) if frames else empty_assays()


def _component_assays(table: Table, names, has_class, class_of_row, errors, component: str, column: str) -> pd.DataFrame:
    values = table.numeric(column, allow_blank=True)
    given = np.isfinite(values)
    for bad, what in ((values < 0, "negative assay"), (values > 100, "assay above 100 % of the class's solids")):
        where = np.flatnonzero(bad)
        if where.size:
            raise table.error(f"{what} {values[where[0]]:g}", index=int(where[0]), column=column)
    where = np.flatnonzero(given & ~has_class)
    if where.size:
        raise table.error("an assay without a size class: assays are per class of a stream", index=int(where[0]), column=column)
    seen = {}
    for i in np.flatnonzero(given):
        key = (names[i], int(class_of_row[i]))
        if key in seen:
            raise table.error(
                f"stream '{names[i]}' gives the {component} assay of size class {key[1] + 1} (coarse to fine) twice "
                f"(also at row {table.rows[seen[key]]})",
                index=int(i),
                column=column,
            )
        seen[key] = i
    rows = np.flatnonzero(given)
    value = values[rows] / 100.0
    relative, absolute = errors.assay_errors(component)
    return pd.DataFrame(
        {
            "stream": names[rows],
            "class_index": class_of_row[rows].astype(int),
            "component": component,
            "value": value,
            "sd": np.sqrt((relative * value) ** 2 + absolute**2),
            "row": np.asarray(table.rows)[rows].astype(int),
            "relative": relative,
            "absolute": absolute,
        },
        columns=ASSAY_COLUMNS,
    )


def assays_at(assays: pd.DataFrame, grades: np.ndarray, stream_index: dict, components: tuple[str, ...]) -> pd.DataFrame:
    """``assays`` with the error model evaluated at ``grades`` (components x streams x classes,
    fractions, clipped to 0..1, NaN read as 0) instead of the measured values; given sds stay."""
    table = assays.copy()
    if not len(table):
        return table
    k = table["component"].map({name: j for j, name in enumerate(components)}).to_numpy(int)
    s = table["stream"].map(stream_index).to_numpy(int)
    # an assay lies in 0..1: a reconciled grade outside (a class flow near 0 divides a component
    # flow the rounding leaves a little off) would make its sd follow the last digits of the solver
    at = np.clip(np.nan_to_num(grades[k, s, table["class_index"].to_numpy(int)], nan=0.0), 0.0, 1.0)
    modelled = table["relative"].notna().to_numpy()
    sd = np.sqrt((table["relative"].to_numpy(float) * at) ** 2 + table["absolute"].to_numpy(float) ** 2)
    table["sd"] = np.where(modelled, sd, table["sd"].to_numpy(float))
    return table


def set_aside(assays: pd.DataFrame, shares: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:
    """``(used, set_aside)``: the assays of classes whose measured share of their stream is below
    :data:`MIN_ASSAYED_SHARE` are set aside (an assay of a class not size-analysed is used)."""
    measured = {(r.stream, r.class_index): r.value for r in shares.itertuples()}
    scarce = np.array([measured.get((s, i), np.inf) < MIN_ASSAYED_SHARE for s, i in zip(assays["stream"], assays["class_index"])],
                      dtype=bool)  # fmt: skip
    return assays[~scarce].reset_index(drop=True), assays[scarce].reset_index(drop=True)
