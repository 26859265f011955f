"""Ranking formulas within and across experiments (Shuvalov et al. 2018, Table 3).

Within an experiment the formulas are ranked by Fisher's F, highest = rank 1, ties
sharing the average rank.  Across experiments each formula collects points = the sum of
its ranks, where the rank of an inadequate cell (F <= F_crit) counts twice; the place
is the order of points, lowest first (tied points share the better place).

``by="aicc"`` ranks by the small-sample Akaike criterion instead (lowest = rank 1).  For
the nine two-parameter formulas fitted to the same points, F, the residual sum of
squares and AICc order the formulas identically, so the two rankings coincide; they
differ once models with another number of parameters (bypass, fish-hook) are ranked
together.  Adequacy (and so the double counting) always comes from the F screen.
A failed fit ranks last in its experiment and counts as inadequate.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy import stats

from .errors import InputError
from .screening import DEFAULT_ALPHA, critical_f
from .tables import read_table

RANK_BY = {"F": False, "aicc": True}  # criterion -> lower is better


def ranks_within(scores, *, lower_is_better: bool = False) -> np.ndarray:
    """Ranks 1..n with ties averaged; missing scores rank after all others.

    Examples
    --------
    >>> ranks_within([5.0, 9.0, 9.0, 1.0]).tolist()
    [3.0, 1.5, 1.5, 4.0]
    """
    scores = np.asarray(scores, dtype=float)
    key = scores if lower_is_better else -scores
    key = np.where(np.isnan(key), np.inf, key)
    return stats.rankdata(key, method="average")


def rank_formulas(table: pd.DataFrame, *, by: str = "F", key: str = "equation") -> pd.DataFrame:
    """Ranking table from a tidy table of per-experiment scores.

    Parameters
    ----------
    table : DataFrame
        Columns ``experiment``, ``key`` (the formula label), ``adequate`` (bool) and the
        criterion column ``by`` (``F`` or ``aicc``).
    by : {"F", "aicc"}
        Criterion to rank by within each experiment.
    key : str
        Column naming the formula.

    Returns
    -------
    DataFrame
        One row per formula: ``key``, one rank column per experiment (named by the
        experiment, in order of appearance), ``points`` and ``place``.
    """
    ranked = add_ranks(table, by=by)
    ranked["counted"] = ranked["rank"] * np.where(ranked["adequate"].astype(bool), 1, 2)
    wide = ranked.pivot(index=key, columns="experiment", values="rank")
    wide = wide.reindex(index=list(dict.fromkeys(ranked[key])), columns=list(dict.fromkeys(ranked["experiment"])))
    wide.columns = [str(c) for c in wide.columns]
    wide["points"] = ranked.groupby(key, sort=False)["counted"].sum()
    wide["place"] = stats.rankdata(wide["points"].to_numpy(), method="min").astype(int)
    return wide.reset_index()


def add_ranks(fits: pd.DataFrame, *, by: str = "F") -> pd.DataFrame:
    """Copy of a ``fits`` table with a ``rank`` column (within each experiment)."""
    if by not in RANK_BY:
        raise ValueError(f"unknown ranking criterion {by!r}; choose one of {', '.join(RANK_BY)}")
    out = fits.copy()
    out["rank"] = out.groupby("experiment", sort=False)[by].transform(
        lambda s: ranks_within(s.to_numpy(), lower_is_better=RANK_BY[by])
    )
    return out


def read_f_table(path, *, alpha: float = DEFAULT_ALPHA, use_given_marks: bool = True) -> pd.DataFrame:
    """Read a tidy table of F values for :func:`rank_formulas`.

    Columns ``experiment``, ``equation``, ``F`` and either ``n`` (number of points; the
    critical value is computed at ``alpha``) or ``F_crit``; optionally ``adequate``
    (true/false, 1/0, yes/no) to use given adequacy marks instead of ``F > F_crit``.
    """
    table = read_table(path)
    table.require("experiment", "equation", "F")
    frame = pd.DataFrame({"experiment": table.experiment_labels(), "equation": _labels(table, "equation")})
    frame["F"] = _non_negative(table, "F")
    if "F_crit" in table.frame.columns:
        frame["F_crit"] = _non_negative(table, "F_crit")
    elif "n" in table.frame.columns:
        n = table.numeric("n")
        for i, value in enumerate(n):
            if not np.isfinite(value) or value != int(value) or value <= 2:
                raise table.error(f"n must be a whole number above 2, got {value:g}", index=i, column="n")
        frame["F_crit"] = [critical_f(int(v), alpha=alpha) for v in n]
    else:
        raise InputError("give either an 'n' or an 'F_crit' column", source=table.source)
    if use_given_marks and "adequate" in table.frame.columns:
        frame["adequate"] = table.boolean("adequate")
    else:
        frame["adequate"] = frame["F"] > frame["F_crit"]
    duplicated = frame.duplicated(["experiment", "equation"]).to_numpy()
    if duplicated.any():
        raise table.error("the same experiment and equation appear twice", index=int(np.flatnonzero(duplicated)[0]), column="equation")
    present = set(zip(frame["experiment"], frame["equation"]))
    for experiment in dict.fromkeys(frame["experiment"]):
        missing = [e for e in dict.fromkeys(frame["equation"]) if (experiment, e) not in present]
        if missing:  # a formula without a rank in one experiment would collect fewer points and win
            raise InputError(f"experiment '{experiment}' has no row for equation(s) {', '.join(missing)}: every formula "
                             "needs an F value in every experiment", source=table.source, column="equation")  # fmt: skip
    return frame


def _labels(table, column: str) -> np.ndarray:
    """A label column as stripped text; a blank cell is an error (not the text 'nan')."""
    labels = table.frame[column]
    text = labels.astype(str).str.strip()
    blank = (labels.isna() | (text == "")).to_numpy()
    if blank.any():
        raise table.error(f"{column} is blank", index=int(np.flatnonzero(blank)[0]), column=column)
    return text.to_numpy(dtype=object)


def _non_negative(table, column: str) -> np.ndarray:
    """A column of F values: numbers >= 0 (F = inf, a perfect fit, is allowed)."""
    values = table.numeric(column)
    bad = np.flatnonzero(~(values >= 0))
    if bad.size:
        raise table.error(f"{column} must be a number >= 0, got {values[bad[0]]:g}", index=int(bad[0]), column=column)
    return values
