"""The fits table of a batch (``fits.csv``): rows of the fits, completed with the failed
experiments, ranks, ``delta_aicc``, the water-recovery check and the nested tests, then
read with its intervals as partition to one product.  Every step works experiment by
experiment, so a worker builds the rows of its chunk as the whole batch's are built.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..curves.curve_fit import FIT_COLUMNS, CurveFit
from ..curves.formulas import Formula, select_formulas
from ..curves.ranking import add_delta_aicc, add_ranks
from ..loading.surveys import with_survey_columns
from ..output.views import partition_view
from ..statistics.compare import nested_tests
from ..statistics.hydrocyclone import bypass_against_water_recovery


def by_experiment(fits) -> dict[str, list[CurveFit]]:
    """``fits`` grouped by experiment, in their order."""
    grouped: dict[str, list[CurveFit]] = {}
    for fit in fits:
        grouped.setdefault(fit.experiment, []).append(fit)
    return grouped


def fit_rows_frame(fits) -> pd.DataFrame:
    """One row per fit (``CurveFit.row``) in the columns of ``fits.csv`` before ranking."""
    return pd.DataFrame([fit.row() for fit in fits]).reindex(columns=[c for c in FIT_COLUMNS if c != "rank"])


def completed_fit_rows(
    table: pd.DataFrame, fits, *, failures: dict, formulas, ranked, rank_by: str, water_recovery
) -> pd.DataFrame:
    """The fits table of :meth:`Workbench.fits_table` before its intervals and view: ``table``
    (:func:`fit_rows_frame` of ``fits``) with a row per failed experiment and formula, the
    ranks among the ``ranked`` formula ids and ``delta_aicc``, the check against the
    ``water_recovery`` and the nested tests.  Every step works experiment by experiment, so a
    worker completes the rows of its chunk (without ``failures``) as the whole batch's are.
    Columns are added to ``table`` itself: pass a copy of a table that is used again."""
    chosen = select_formulas(formulas)
    failed = [
        {
            "experiment": experiment,
            "equation": formula.equation,
            "formula": formula.id,
            "shape_name": formula.shape_name,
            "adequate": False,
            "success": False,
            "message": reason,
        }
        for experiment, reason in failures.items()
        for formula in chosen
    ]
    if failed and table.empty:  # no fit: the columns take their types from the failures alone
        table = pd.DataFrame(failed).reindex(columns=table.columns)
    elif failed:
        table = pd.concat([table, pd.DataFrame(failed).reindex(columns=table.columns)], ignore_index=True)
    table["adequate"] = table["adequate"].astype(bool)
    table["success"] = table["success"].astype(bool)
    in_ranking = table["formula"].isin(ranked)
    table["rank"] = add_ranks(table[in_ranking], by=rank_by)["rank"]  # curves kept out of the ranking get no rank
    table.loc[table["experiment"].isin(list(failures)), "rank"] = np.nan
    table["delta_aicc"] = add_delta_aicc(table)
    table = table.reindex(columns=list(FIT_COLUMNS))
    if water_recovery is not None:
        checks = bypass_against_water_recovery(fits, water_recovery)
        table = table.merge(checks, on=["experiment", "formula"], how="left")
        table["water_recovery"] = water_recovery  # failed experiments too
        table["water_recovery_check"] = table["water_recovery_check"].fillna("")
    fitted = {f.id for f in chosen}
    if any(f.nests in fitted for f in chosen):  # is the bypass (fish-hook) needed? the nested F test
        table = table.merge(nested_tests(fits), on=["experiment", "formula"], how="left")
    return table


def fit_row_settings(formulas, rank_extended: bool, rank_by: str, water_recovery) -> dict:
    """The settings of :func:`completed_fit_rows` of a batch of ``formulas``."""
    return {
        "formulas": tuple(f.id for f in formulas),
        "ranked": tuple(f.id for f in ranked_among(formulas, rank_extended)),
        "rank_by": rank_by,
        "water_recovery": water_recovery,
    }


def output_view(table: pd.DataFrame, intervals: pd.DataFrame | None, inputs, partition_to: str) -> pd.DataFrame:
    """:func:`completed_fit_rows` with the ``intervals`` columns, the survey columns of the
    ``inputs`` and read as partition to ``partition_to``: the table ``fits.csv`` holds."""
    if intervals is not None:
        table = table.merge(intervals, on=["experiment", "formula"], how="left")
    return partition_view(with_survey_columns(table, inputs), partition_to)


def ranked_among(formulas, rank_extended: bool) -> tuple[Formula, ...]:
    """The formulas a ranking covers: the paper's nine unless extended curves are ranked too."""
    return tuple(f for f in formulas if rank_extended or f.family == "paper")
