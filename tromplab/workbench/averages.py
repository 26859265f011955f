"""Akaike-weighted model averages of d_cut, Ep and eta per experiment, a chunk of
experiments at a time (:func:`tromplab.statistics.uncertainty.averaged_rows`).
"""

from __future__ import annotations

import pandas as pd

from ..curves.curve_fit import CurveFit
from ..statistics.uncertainty import averaged_rows


def averages_level(ci: float | None) -> float:
    """Confidence level of the model averages' intervals: the batch's ``ci``, else 0.95."""
    return ci or 0.95


def averaged_groups(fits_by_experiment, ranked) -> list[list[CurveFit]]:
    """The successful fits of the ``ranked`` formula ids, per experiment (experiments without any left out)."""
    ranked = set(ranked)
    groups = ([f for f in fits if f.success and f.formula.id in ranked] for fits in fits_by_experiment)
    return [chosen for chosen in groups if chosen]


def averages_table(frames: list[pd.DataFrame]) -> pd.DataFrame:
    """The chunks' tables of averages as one, the experiment first (empty without any)."""
    if not frames:
        return pd.DataFrame()
    table = pd.concat(frames, ignore_index=True)
    return table[["experiment", *[c for c in table.columns if c != "experiment"]]]


def averages_of_chunk(level, groups) -> list[pd.DataFrame]:
    """The averages of a chunk's ``groups`` of fits at confidence ``level``, as one table in a list."""
    # the whole chunk at once: the delta method in one call per formula, each quantity on arrays
    rows = [
        {**row, "experiment": fits[0].experiment}
        for fits, experiment_rows in zip(groups, averaged_rows(groups, level=level))
        for row in experiment_rows
    ]
    # one table per chunk, from all its experiments' rows: the main process then unpickles and
    # concatenates tens of tables, not thousands (about 3 s of serial work at 10,000
    # experiments), and the chunk builds one DataFrame instead of one per experiment
    return [pd.DataFrame(rows)]
