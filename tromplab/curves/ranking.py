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

Tie rule
--------
Scores that differ by less than the data could ever resolve share their rank (the
average of the places they occupy):

* by F: relative difference ``|F_a - F_b| <= 1e-4 * F_best_of_group`` (:data:`F_TIE_RTOL`).
  For curves with the same number of parameters the ratio of F values is the inverse
  ratio of the sums of squares, and ``n ln(SSR_b / SSR_a)`` is their AICc difference: a
  relative 1e-4 is an AICc difference below ``1e-4 n`` (0.0013 at n = 13), an evidence
  ratio within 0.1 % of one for any realistic n.  Differences this small are set by the
  solver's stopping rule and by floating-point rounding (scaling the sizes by a unit
  factor moves F by up to about 1e-5 relative), not by the data;
* by AICc: absolute difference below 1e-3 (:data:`AICC_TIE_ATOL`), the same scale.

A group is anchored at its best member, so ties do not chain: a value joins a group when it
lies within the tolerance of the group's first (best) value.  The published F values of
Table 2 (2-4 digits) differ by at least a relative 1.7e-3 where they differ at all, so
the rule ties only values printed equal, and Table 3 is reproduced as before.

Separately, :data:`INDISTINGUISHABLE_DELTA_AICC` marks formulas the data cannot tell
apart: those whose AICc lies within 2 of the lowest of the experiment (Burnham & Anderson
2002, section 2.6: such models have substantial support).  Their ranks stay as computed,
but the console and the report say in words that the order among them is not evidence.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy import stats

from ..errors import InputError, expect_kind
from ..loading.tables import read_table
from ..options import RANK_BY
from .screening import DEFAULT_ALPHA, EXACT_FIT_RMS, critical_f

#: Relative difference of F below which two formulas share their rank.
F_TIE_RTOL = 1e-4
#: Absolute AICc difference below which two formulas share their rank.
AICC_TIE_ATOL = 1e-3
#: AICc difference from the best below which the data cannot tell a formula from the best.
INDISTINGUISHABLE_DELTA_AICC = 2.0
TIE_TOLERANCE = {"F": {"rtol": F_TIE_RTOL, "atol": 0.0}, "aicc": {"rtol": 0.0, "atol": AICC_TIE_ATOL}}


def ranks_within(scores, *, lower_is_better: bool = False, rtol: float = 0.0, atol: float = 0.0) -> np.ndarray:
    """Ranks 1..n, tied scores sharing their average rank; missing scores rank after all others.

    Parameters
    ----------
    scores : array_like
        One score per formula (nan for a failed fit).
    lower_is_better : bool
        True for AICc, False for F.
    rtol, atol : float
        Tie tolerance: a score ties with the best score of its group when they differ by
        at most ``atol + rtol * |best|`` (0, 0: only equal scores tie).

    Examples
    --------
    >>> ranks_within([5.0, 9.0, 9.0, 1.0]).tolist()
    [3.0, 1.5, 1.5, 4.0]
    >>> ranks_within([28.3858, 28.3856, 28.31, 16.0], rtol=1e-4).tolist()
    [1.5, 1.5, 3.0, 4.0]
    """
    scores = np.asarray(scores, dtype=float)
    key = scores if lower_is_better else -scores
    key = np.where(np.isnan(key), np.inf, key)
    order = np.argsort(key, kind="stable")
    ranks = np.empty(key.size)
    start = 0
    while start < key.size:
        leader = key[order[start]]
        stop = start + 1
        while stop < key.size and _ties(key[order[stop]], leader, rtol, atol):
            stop += 1
        ranks[order[start:stop]] = (start + 1 + stop) / 2.0  # average of places start+1 .. stop
        start = stop
    return ranks


def _ties(value: float, leader: float, rtol: float, atol: float) -> bool:
    if value == leader:  # also inf == inf: failed fits share the last places
        return True
    return bool(np.isfinite(value) and np.isfinite(leader) and value - leader <= atol + rtol * abs(leader))


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
    expect_kind(table, pd.DataFrame, "table", f"a pandas DataFrame with columns experiment, {key}, adequate and {by}")
    missing = [c for c in ("experiment", key, "adequate", by) if c not in table.columns]
    if missing:
        raise InputError(f"the table has no column(s) {', '.join(missing)}", source="table")
    ranked = add_ranks(table, by=by)
    ranked["counted"] = ranked["rank"] * np.where(ranked["adequate"].astype(bool), 1, 2)
    wide = ranked.pivot(index=key, columns="experiment", values="rank")
    wide = wide.reindex(index=list(dict.fromkeys(ranked[key])), columns=list(dict.fromkeys(ranked["experiment"])))
    wide.columns = [str(c) for c in wide.columns]
    wide["points"] = ranked.groupby(key, sort=False)["counted"].sum()
    wide["place"] = stats.rankdata(wide["points"].to_numpy(), method="min").astype(int)
    return wide.reset_index()


def add_ranks(fits: pd.DataFrame, *, by: str = "F") -> pd.DataFrame:
    """Copy of a ``fits`` table with a ``rank`` column (within each experiment, tie rule of the module)."""
    if by not in RANK_BY:
        raise ValueError(f"unknown ranking criterion {by!r}; choose one of {', '.join(RANK_BY)}")
    out = fits.copy()
    scores = out[by].to_numpy(dtype=float)
    exact = _exact_to_rounding(out)
    ranks = np.full(len(out), np.nan)
    # positions per experiment, ranked on plain arrays: a pandas transform with a Python
    # function cost about 0.5 ms per experiment, seconds for a batch of thousands
    for rows in out.groupby("experiment", sort=False).indices.values():
        ranks[rows] = ranks_within(_tie_exact(scores[rows], exact[rows], by), lower_is_better=RANK_BY[by], **TIE_TOLERANCE[by])
    out["rank"] = ranks
    return out


def _exact_to_rounding(fits: pd.DataFrame) -> np.ndarray:
    """Fits whose root-mean-square residual lies below the rounding floor
    (:data:`~tromplab.curves.screening.EXACT_FIT_RMS`, the floor of the runs test too)."""
    if not {"ssr", "n"} <= set(fits.columns):
        return np.zeros(len(fits), dtype=bool)
    with np.errstate(invalid="ignore", divide="ignore"):
        rms = np.sqrt(fits["ssr"].to_numpy(dtype=float) / fits["n"].to_numpy(dtype=float))
    return rms < EXACT_FIT_RMS


def _tie_exact(scores: np.ndarray, exact: np.ndarray, by: str) -> np.ndarray:
    """Scores with the fits exact to rounding given the best score among them: their sums of
    squares differ by rounding only (4.7e-18 against 7.5e-18), so F (or AICc) cannot tell them apart."""
    if exact.sum() < 2:
        return scores
    tied = scores.copy()
    tied[exact] = np.nanmin(scores[exact]) if RANK_BY[by] else np.nanmax(scores[exact])
    return tied


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
    table.refuse_where(duplicated, "equation", "the same experiment and equation appear twice")
    present = set(zip(frame["experiment"], frame["equation"]))
    for experiment in dict.fromkeys(frame["experiment"]):
        missing = [e for e in dict.fromkeys(frame["equation"]) if (experiment, e) not in present]
        if missing:  # a formula without a rank in one experiment would collect fewer points and win
            raise InputError(
                f"experiment '{experiment}' has no row for equation(s) {', '.join(missing)}: every formula "
                "needs an F value in every experiment",
                source=table.source,
                column="equation",
            )
    return frame


def top_ranked(fits: pd.DataFrame) -> pd.DataFrame:
    """Each experiment's best-ranked fit, one row per experiment in the table's order, with
    ``tied``: how many formulas share that first place (1 when none does).

    The best rank is the lowest of the experiment, not 1: formulas tied at the first place
    share a rank such as 1.5 (or 4.5 for eight), and the first of them in the table's order
    stands for the experiment.

    Examples
    --------
    >>> fits = pd.DataFrame({"experiment": ["A", "A", "B", "B"], "formula": ["plitt", "lognormal"] * 2,
    ...                      "rank": [1.5, 1.5, 1.0, 2.0]})
    >>> top_ranked(fits)[["experiment", "formula", "tied"]].values.tolist()
    [['A', 'plitt', 2], ['B', 'plitt', 1]]
    """
    rank = pd.to_numeric(fits["rank"], errors="coerce")
    ranked = fits[rank.notna()]
    rank = rank[rank.notna()]
    first = rank == rank.groupby(ranked["experiment"], sort=False).transform("min")
    top = ranked[first.to_numpy()]
    tied = top.groupby("experiment", sort=False)["experiment"].transform("size").to_numpy()
    return top.assign(tied=tied).drop_duplicates("experiment")


def add_delta_aicc(fits: pd.DataFrame) -> pd.Series:
    """AICc minus the lowest AICc of the same experiment (0 for the best; nan for failed fits)."""
    return fits["aicc"] - fits.groupby("experiment", sort=False)["aicc"].transform("min")


def fit_verdicts(fits: pd.DataFrame, *, by: str = "F", measured_sizes: tuple[float, float] | None = None) -> list[str]:
    """Plain-language statements about the fits of one experiment, for the console and the report.

    Says when the data cannot tell formulas apart (AICc within
    :data:`INDISTINGUISHABLE_DELTA_AICC` of the lowest), which formulas share a rank by
    the tie rule, which formulas are adequate by F while their residuals are systematic or
    not normal, and which indices are extrapolated beyond the measured sizes.

    Parameters
    ----------
    fits : DataFrame
        Rows of ``fits.csv`` for one experiment (columns ``formula``, ``success``, ``rank``,
        ``adequate``, ``delta_aicc``, ``residuals``, ``extrapolated``).
    by : {"F", "aicc"}
        The ranking criterion (names the tie rule).
    measured_sizes : (float, float), optional
        Smallest and largest measured size, quoted in the extrapolation statement.
    """
    good = fits[fits["success"].astype(bool)]
    statements = []
    close = good[good["delta_aicc"] < INDISTINGUISHABLE_DELTA_AICC]
    if len(close) >= 2:
        if len(close) == len(good):
            statements.append(
                f"The data cannot tell the {len(good)} formulas apart: every AICc lies within "
                f"{INDISTINGUISHABLE_DELTA_AICC:g} of the lowest, so their order is no evidence for one formula."
            )
        else:
            statements.append(
                f"The data cannot tell apart {_names(close)}: their AICc lie within {INDISTINGUISHABLE_DELTA_AICC:g} "
                "of the lowest, so their order is no evidence."
            )
    statements += _shared_rank_statements(good, by)
    statements += _residual_statements(good)
    flags = good["extrapolated"].fillna("").astype(str)
    where = f" ({measured_sizes[0]:.4g} to {measured_sizes[1]:.4g})" if measured_sizes else ""
    parts = []
    for index in ("d25", "d75", "eta", "epsilon"):
        holders = good[flags.str.split(";").apply(lambda names, index=index: index in names)]
        if len(holders):
            parts.append(f"{index} of {_names(holders, of=len(good))}")
    if parts:
        statements.append(f"Extrapolated beyond the measured sizes{where}: {'; '.join(parts)}.")
    return statements


def _shared_rank_statements(good: pd.DataFrame, by: str) -> list[str]:
    """One sentence per rank shared by several fits, with the rule that tied them."""
    rule = f"F equal to within a relative {F_TIE_RTOL:.0e}" if by == "F" else f"AICc equal to within {AICC_TIE_ATOL:.0e}"
    ranked = good[good["rank"].notna()]
    exact = _exact_to_rounding(ranked)
    statements = []
    for rank, group in ranked.groupby("rank", sort=True):
        if len(group) > 1:
            if exact[ranked.index.get_indexer(group.index)].all():
                reason = f"exact to rounding: root-mean-square residuals below {EXACT_FIT_RMS:g}, where sums of squares differ by rounding only"
            else:
                reason = rule
            statements.append(f"Shared rank {rank:g}: {_names(group)} ({reason}).")
    return statements


def _residual_statements(good: pd.DataFrame) -> list[str]:
    """One sentence per residual verdict that makes 'adequate by F' overstate the fits holding it."""
    adequate = good[good["adequate"].astype(bool) & good["residuals"].fillna("").str.contains("systematic|not normal")]
    statements = []
    for verdict, group in adequate.groupby("residuals", sort=False):
        meaning = []
        if "systematic" in verdict:
            meaning.append("the curve misses the data in a pattern the F test does not see (runs test)")
        if "not normal" in verdict:
            meaning.append("the errors are not normal as the F test assumes (Shapiro-Wilk)")
        reason = "; ".join(meaning)
        statements.append(
            f"Adequate by F, but the residuals are {verdict}: {_names(group, of=len(good))}. "
            f"{reason[0].upper()}{reason[1:]}, so 'adequate' overstates these fits."
        )
    return statements


def _names(rows: pd.DataFrame, *, of: int | None = None) -> str:
    names = list(rows["formula"])
    if of is not None and len(names) == of and of > 2:
        return f"all {of} formulas"
    return ", ".join(names)


def _labels(table, column: str) -> np.ndarray:
    """A label column as stripped text; a blank cell is an error (not the text 'nan')."""
    labels = table.frame[column]
    text = labels.astype(str).str.strip()
    blank = (labels.isna() | (text == "")).to_numpy()
    table.refuse_where(blank, column, f"{column} is blank")
    return text.to_numpy(dtype=object)


def _non_negative(table, column: str) -> np.ndarray:
    """A column of F values: numbers >= 0 (F = inf, a perfect fit, is allowed)."""
    values = table.numeric(column)
    table.refuse_where(~(values >= 0), column, lambda i: f"{column} must be a number >= 0, got {values[i]:g}")
    return values
