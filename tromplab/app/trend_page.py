"""What the page shows of a ``tromplab trend`` run, as JSON-ready data: one control chart per
quantity (each survey's value with its interval, the EWMA line and its limits, the baseline,
the alarms and the change points), the table of the surveys and their flags, the tidy table of
the charted quantities and the warnings grouped by what they say.

Every number comes from the :class:`~tromplab.trend.TrendResult` the run made and wrote (the
folder offered for download); nothing is computed here.
"""

from __future__ import annotations

from .payload import notice_groups, numbers, records

#: What each charted quantity is, for the charts' titles (definitions: docs/trend.md).
QUANTITY_NAMES = {"d_cut": "cut size d_cut", "ep": "Ecart probable Ep", "eta": "classifier efficiency eta", "bypass": "bypass"}


def trend_payload(result, *, size_unit: str = "") -> dict:
    """The page's data of a trend run: ``result`` a :class:`~tromplab.trend.TrendResult`,
    ``size_unit`` the unit of the sizes (``--size-unit``)."""
    table = result.table
    names = [survey.name for survey in result.surveys]
    flags = result.survey_flags()
    charts = []
    for quantity in result.quantities:
        rows = table[table["quantity"] == quantity].set_index("survey").loc[names]
        unit = size_unit if rows["unit"].iloc[0] == "size" else ""
        charts.append({
            "quantity": quantity, "title": QUANTITY_NAMES.get(quantity, quantity), "unit": unit,
            "value": numbers(rows["value"]), "low": numbers(rows["low"]), "high": numbers(rows["high"]),
            "ewma": numbers(rows["ewma"]), "ewma_low": numbers(rows["ewma_low"]), "ewma_high": numbers(rows["ewma_high"]),
            "alarm": [bool(alarm) for alarm in rows["ewma_alarm"]],
        })  # fmt: skip
    shown = table.drop(columns=["formula"]).assign(date=table["date"].dt.strftime("%Y-%m-%d"))
    if size_unit:
        shown = shown.replace({"unit": {"size": size_unit}})
    return {
        "view": "trend",
        "formula": result.formula_id,
        "alpha": result.alpha,
        "level": result.level,
        "surveys": names,
        "dates": [survey.date.strftime("%Y-%m-%d") for survey in result.surveys],
        "baseline": [index in result.baseline for index in range(len(names))],
        "changed": [bool(changed) for changed in flags["changed"]],
        "change_points": result.change_points(),
        "charts": charts,
        "flags": records(flags.assign(date=flags["date"].dt.strftime("%Y-%m-%d"))),
        "table": records(shown),
        "warnings": trend_warnings(result),
    }


def trend_warnings(result) -> list[dict]:
    """The surveys not fitted, then the warnings of each survey's fit grouped (:func:`notice_groups`)."""
    failures = [{"kind": "failure", "text": f"not fitted: {reason}", "count": 1, "where": [name]}
                for name, reason in result.failures.items()]  # fmt: skip
    return failures + notice_groups(result.notices())
