"""Console tables shared by the commands: the ranked fits (:func:`format_fits`), the balance
notes of lab tables and the list of failed fits."""

from __future__ import annotations

import re
import sys
import textwrap
from typing import TYPE_CHECKING

from .startup import EXIT_OK, EXIT_PARTIAL, cli_words

if TYPE_CHECKING:
    import pandas as pd

TERMINAL_COLUMNS = ["rank", "equation", "formula", "d50", "shape_name", "shape", "F", "F_crit", "adequate", "eta", "ep"]
#: Said under an experiment's table when a curve with bypass is shown: the two cuts told apart.
CUT_LEGEND = "d50: actual cut (partition 1/2) of every curve; d50c: corrected cut (of the classified part) of a curve with bypass"


#: Console words for the residual verdict (fits.csv column ``residuals``).
RESIDUAL_WORDS = {
    "random": "random",
    "exact": "exact",
    "systematic": "SYSTEMATIC",
    "not normal": "NOT NORMAL",
    "systematic, not normal": "SYST.+NOT NORM.",
}


def format_fits(fits: pd.DataFrame, verdicts: dict[str, list[str]] | None = None, *, rank_by: str = "F") -> str:
    """The ranked fits, one block per experiment, readable in a 100-column terminal.

    The criterion of the ranking is shown: ``F`` and ``F_crit`` when ranking by F,
    ``aicc`` (beside F) when ranking by AICc.  When the table has interval columns
    (``--ci``, else ``--bootstrap``), a second table per experiment gives the intervals
    of d_cut, the shape parameter and Ep.  ``verdicts`` (experiment -> statements,
    :meth:`Workbench.verdicts`) are printed under each table: indistinguishable formulas,
    shared ranks, adequate fits with systematic or non-normal residuals, extrapolated
    indices.  An adequate fit whose residuals fail a test is marked ``yes*`` in the
    adequacy column.
    """
    import numpy as np

    from ..curves.diagnostics import RESIDUAL_WARNING
    from ..curves.measured import CUT_WARNING

    columns = list(TERMINAL_COLUMNS)
    if rank_by == "aicc":
        columns[columns.index("F_crit")] = "aicc"
    kind = "" if "d_cut_low" in fits.columns else "_boot"  # --ci intervals, else the bootstrap's
    intervals = [
        f"{q}{kind}_{end}" for q in ("d_cut", "shape", "ep") for end in ("low", "high") if f"{q}{kind}_{end}" in fits.columns
    ]
    blocks = []
    for experiment, group in fits.groupby("experiment", sort=False):
        if not group["success"].any():
            continue  # experiments that could not be fitted are listed separately
        ordered = group.sort_values("rank", na_position="last")
        corrected = _has_bypass(ordered)
        shown = [*columns[:4], "d50c", *columns[4:]] if corrected else columns
        view = ordered[shown].copy()
        flagged = ordered["residuals"].fillna("").str.contains("systematic|not normal")
        view["adequate"] = np.where(ordered["adequate"], np.where(flagged, "yes*", "yes"), "NO")
        view.loc[~ordered["success"], "adequate"] = "failed"
        view["residuals"] = ordered["residuals"].map(RESIDUAL_WORDS).fillna("-")
        view = view.rename(columns={"equation": "eq", "shape_name": "par", "adequate": "adequ."})
        text = view.to_string(index=False, float_format=lambda v: f"{v:.4g}", na_rep="-")
        n = int(group["n"].dropna().iloc[0]) if group["n"].notna().any() else 0
        ranked_by = "AICc (lowest first)" if rank_by == "aicc" else "F (highest first)"
        blocks.append(f"Experiment {experiment} (n = {n}), ranked by {ranked_by}:\n{text}")
        if corrected:
            blocks.append(textwrap.fill(CUT_LEGEND, width=98, initial_indent="  ", subsequent_indent="    "))
        for statement in (verdicts or {}).get(experiment, []):
            blocks.append(textwrap.fill(statement, width=98, initial_indent="  ! ", subsequent_indent="    "))
        if intervals:
            cut = "d50c" if corrected else "d50"  # the fitted cut parameter: the actual cut of the nine formulas
            named = ["shape_name"] if "shape_name" in ordered else []  # which parameter "shape" is, as in the table above
            bounds = ordered[["formula", *named, "d_cut", *intervals]].rename(
                columns=lambda c, cut=cut: re.sub(r"^d_cut", cut, re.sub(r"(_boot)?_(low|high)$", r" \2", c))
            )
            bounds = bounds.rename(columns={"shape_name": "par"})
            title = "  intervals:" if kind == "" else "  bootstrap intervals:"
            blocks.append(f"{title}\n" + bounds.to_string(index=False, float_format=lambda v: f"{v:.4g}", na_rep="-"))
        for formula, success, message, warned in group[["formula", "success", "message", "warnings"]].itertuples(index=False):
            note = warned if success else f"fit failed: {message}"
            if success and isinstance(
                note, str
            ):  # residual and cut warnings are stated once per experiment (verdicts, data notes)
                note = "; ".join(w for w in note.split("; ") if not w.startswith((RESIDUAL_WARNING, CUT_WARNING)))
            if isinstance(note, str) and note:
                blocks.append(textwrap.fill(f"note {formula}: {note}", width=98, initial_indent="  ", subsequent_indent="    "))
    return "\n".join(blocks)


def _has_bypass(fits: pd.DataFrame) -> bool:
    """Whether some fit of the table is a curve with bypass (its d50c differs from its d50)."""
    return bool("bypass" in fits.columns and fits["bypass"].notna().any())


def print_balance_notes(balances, *, listed_in: str = "") -> None:
    """The balance warnings, and one line per experiment for the classes left out (where
    the full list is, when it is written: ``listed_in``)."""
    for balance in balances:
        for note in balance.notes:
            print(textwrap.fill(f"warning ({balance.experiment}): {cli_words(note)}", width=98), file=sys.stderr)
        if summary := balance.left_out_summary():
            where = f"; the list is in {listed_in}" if listed_in else ""
            print(textwrap.fill(f"note ({balance.experiment}): {summary}{where}", width=98), file=sys.stderr)


def print_notices(notices, *, total: int, quiet: bool, verbose: int, noun: str = "experiments", intervals: bool = False,
                  listed_in: str = "warnings.csv") -> None:  # fmt: skip
    """The warnings of a run on standard error: one line per kind with its count and the first
    names (:func:`tromplab.notices.grouped_lines`), every occurrence with ``-v``, none with
    ``--quiet`` (every one is in ``listed_in``).  ``intervals``: the run makes intervals, so a
    kind's words may speak of them."""
    from ..notices import grouped_lines, occurrence_line

    if quiet:
        return
    if verbose:
        lines = [occurrence_line(notice) for notice in notices]
    else:
        lines = grouped_lines(notices, total=total, noun=noun, intervals=intervals, listed_in=listed_in, labelled=True)
    for line in lines:
        print(textwrap.fill(cli_words(line), width=98, break_on_hyphens=False), file=sys.stderr)


def report_failures(failures: pd.DataFrame, *, listed_in: str = "failures.csv") -> int:
    """Exit code 3 with the failures on standard error when some fits failed, else 0."""
    if failures.empty:
        return EXIT_OK
    print(f"tromplab: partial result: {len(failures)} experiment(s) or fit(s) failed (listed in {listed_in}):", file=sys.stderr)
    for row in failures.itertuples(index=False):
        what = f"{row.experiment} / {row.formula}" if row.formula else row.experiment
        print("  " + textwrap.shorten(f"{what}: {row.reason}", width=160), file=sys.stderr)
    return EXIT_PARTIAL
