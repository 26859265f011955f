"""Survey and date columns: which experiments were measured when.

A table of Tromp points or lab data may carry a ``date`` and a ``survey`` column (the
monitoring files of ``tromplab trend``).  ``tromplab fit`` reads the same file as it is: the
survey (or, without one, the date) names each experiment when the table has no
``experiment`` column, the date and survey travel with the points (``TrompPoints.meta``) into
``fits.csv`` and ``averages.csv``, and the experiments are ordered by date.  Columns named
``<parameter>_true`` hold the values a synthetic series was drawn with; they are set aside,
not read as data.
"""

from __future__ import annotations

from dataclasses import replace

import pandas as pd

from .points import TrompPoints
from .tables import Table

#: Columns that say when an experiment was measured (kept as metadata, not read as data).
SURVEY_COLUMNS = ("date", "survey")


def has_survey_columns(table: Table) -> bool:
    """True when the table has a ``date`` or ``survey`` column."""
    return any(column in table.frame.columns for column in SURVEY_COLUMNS)


def split_survey_columns(table: Table) -> tuple[Table, dict[str, dict]]:
    """The table without its survey, date and ``_true`` columns, and each experiment's survey and date.

    Without an ``experiment`` column the survey (else the date, as ``YYYY-MM-DD``) names the
    experiments.  Without a ``date`` column the surveys are dated one day apart in file order
    (from 2000-01-01), so that they keep that order.

    Returns
    -------
    (Table, dict)
        The table with an ``experiment`` column, and ``{experiment: {"date": Timestamp,
        "survey": str}}`` (``survey`` only where the table has the column).

    Raises
    ------
    InputError
        Naming file, row and column: a date that cannot be read, or an experiment (survey)
        with two dates.
    """
    frame = table.frame.copy()
    dates = _dates(table) if "date" in frame.columns else None
    surveys = pd.Series(table.names("survey", what="survey")) if "survey" in frame.columns else None
    what = "experiment" if "experiment" in frame.columns else "survey"
    if "experiment" in frame.columns:
        labels = pd.Series(table.names("experiment", what="experiment"))
    else:
        labels = surveys if surveys is not None else dates.dt.strftime("%Y-%m-%d")
        frame["experiment"] = labels.to_numpy()
    if dates is None:
        order = {name: i for i, name in enumerate(dict.fromkeys(labels))}
        dates = pd.Series(pd.Timestamp("2000-01-01") + pd.to_timedelta([order[n] for n in labels], unit="D"))
    found: dict[str, dict] = {}
    for i, (label, date) in enumerate(zip(labels, dates)):
        known = found.setdefault(label, {"date": date})
        if known["date"] != date:
            raise table.error(
                f"{what} {label} has two dates ({known['date']:%Y-%m-%d} and {date:%Y-%m-%d})", index=i, column="date"
            )
        if surveys is not None:
            if known.setdefault("survey", surveys.iloc[i]) != surveys.iloc[i]:
                raise table.error(
                    f"{what} {label} has two surveys ({known['survey']} and {surveys.iloc[i]})", index=i, column="survey"
                )
    set_aside = [c for c in frame.columns if c in SURVEY_COLUMNS or str(c).endswith("_true")]
    return Table(frame.drop(columns=set_aside), table.rows, table.source), found


def with_survey_meta(experiments: list[TrompPoints], found: dict[str, dict], *, dated: bool) -> list[TrompPoints]:
    """The experiments with their survey and date in ``meta`` (the date only when the table
    had one), ordered by date."""
    marked = []
    for points in experiments:
        meta = dict(found.get(points.experiment, {}))
        date = meta.pop("date", None)
        if dated and date is not None:
            meta["date"] = f"{date:%Y-%m-%d}"
        marked.append(replace(points, meta={**points.meta, **meta}))
    order = {name: found[name]["date"] for name in found}
    return sorted(marked, key=lambda p: order.get(p.experiment, pd.Timestamp.max))


def with_survey_columns(table: pd.DataFrame, experiments: list[TrompPoints]) -> pd.DataFrame:
    """``table`` (one or more rows per experiment) with the ``date`` and ``survey`` of each
    experiment inserted after its ``experiment`` column; unchanged when no experiment has them."""
    columns = [c for c in SURVEY_COLUMNS if any(c in p.meta for p in experiments)]
    if not columns or "experiment" not in table.columns:
        return table
    known = {p.experiment: p.meta for p in experiments}
    table = table.copy()
    at = table.columns.get_loc("experiment") + 1
    for offset, column in enumerate(columns):
        table.insert(at + offset, column, table["experiment"].map(lambda e, c=column: known.get(e, {}).get(c, "")))
    return table


def _dates(table: Table) -> pd.Series:
    dates = pd.to_datetime(table.frame["date"].astype(str).str.strip(), errors="coerce", format="mixed")
    table.refuse_where(
        dates.isna().to_numpy(), "date", lambda i: f"'{table.frame['date'].iloc[i]}' is not a date (use YYYY-MM-DD)"
    )
    return dates.reset_index(drop=True)
