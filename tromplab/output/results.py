"""Readable views of a batch (short repr, HTML) and the files that make a saved batch reloadable.

:class:`~tromplab.workbench.Workbench` calls these from its methods (``repr(bench)``,
``bench._repr_html_()``, ``bench.save(dir, reloadable=True)``, :func:`tromplab.load`); the
views of one fit are in :mod:`tromplab.curves.views`.
"""

from __future__ import annotations

import html
import json
import pickle
from pathlib import Path

import pandas as pd

from .._version import __version__
from ..errors import InputError
from .csv_parts import write_csv

#: Files that make a results folder reloadable (:func:`batch_files`).
SAVED_FILES = ("workbench.pkl", "manifest.json", "points.csv")


# --- a batch -------------------------------------------------------------------------------
def workbench_repr(bench) -> str:
    """``<Workbench: 2 experiments x 9 formulas, 18 fits (18 successful), ranked by F ...>``."""
    n_ok = bench.n_successful
    best = []
    for experiment in bench.experiments[:4]:
        fit = bench.best_fit(experiment)
        tied = len(bench.top_ranked(experiment)) - 1
        best.append(f"{experiment}: {fit.formula.id if fit else 'none'}" + (f" (tied with {tied} more)" if tied > 0 else ""))
    more = ", ..." if len(bench.experiments) > 4 else ""
    failed = f", {len(bench.failures)} experiment(s) not fitted" if bench.failures else ""
    return (
        f"<Workbench: {len(bench.experiments)} experiments x {len(bench.formulas)} formulas, {len(bench.fits)} fits "
        f"({n_ok} successful){failed}, ranked by {bench.rank_by} at alpha={bench.alpha:g}; best: "
        f"{', '.join(best)}{more}>"
    )


#: Columns of :func:`experiment_summary` taken from ``fits.csv`` (those present in the batch's table).
SUMMARY_COLUMNS = ("experiment", "equation", "formula", "rank", "d_cut", "shape_name", "shape", "F", "F_crit", "adequate",
                   "eta", "ep", "aicc", "residuals")  # fmt: skip


def experiment_summary(bench) -> pd.DataFrame:
    """One row per experiment of ``bench``: the columns :data:`SUMMARY_COLUMNS` of its top-ranked
    fit (:meth:`~tromplab.workbench.Workbench.best_fit`), ``tied`` (fits sharing the top rank)
    and ``reason`` (why the experiment has no ranked fit; "" when it has one)."""
    table = bench.fits_table()
    columns = [column for column in SUMMARY_COLUMNS if column in table.columns]
    rows = []
    for experiment in dict.fromkeys([*bench.experiments, *bench.failures]):
        best = bench.best_fit(experiment)
        if best is None:
            reason = bench.failures.get(experiment, "no successful fit among the ranked formulas")
            rows.append({"experiment": experiment, "tied": 0, "reason": reason})
            continue
        row = table[(table["experiment"] == experiment) & (table["formula"] == best.formula.id)].iloc[0]
        rows.append({**row[columns].to_dict(), "tied": len(bench.top_ranked(experiment)), "reason": ""})
    return pd.DataFrame(rows, columns=[*columns, "tied", "reason"])


def summary_text(bench) -> str:
    """The text of :meth:`~tromplab.workbench.Workbench.report`: the batch in a line, the
    summary table, then the experiments that could not be fitted."""
    summary = experiment_summary(bench)
    shown = summary.drop(columns=["reason"]).to_string(index=False, float_format=lambda value: f"{value:.4g}", na_rep="-")
    lines = [workbench_repr(bench), "", "Top-ranked fit of each experiment (every fit: fits_table()):", shown]
    failed = summary[summary["reason"] != ""]
    lines += [f"not ranked: {row.experiment}: {row.reason}" for row in failed.itertuples(index=False)]
    return "\n".join(lines)


def workbench_html(bench) -> str:
    """HTML for Jupyter: the repr line and the ranking table."""
    return f"<p><b>{html.escape(workbench_repr(bench))}</b></p>\n" + bench.ranking_table().to_html(index=False)


def _major(version: str) -> str:
    return str(version).split(".")[0]


def batch_files(bench) -> dict:
    """Writers of the files that make a results folder reloadable (:func:`load_workbench`):
    the pickled batch with its inputs and options, ``manifest.json`` (version, options,
    files) and the input points as ``points.csv``."""
    points = pd.concat([p.to_frame() for p in bench.inputs], ignore_index=True) if bench.inputs else pd.DataFrame()
    manifest = {
        "tromplab_version": __version__,
        "experiments": bench.experiments,
        "failures": bench.failures,
        "formulas": [f.id for f in bench.formulas],
        "alpha": bench.alpha,
        "rank_by": bench.rank_by,
        "rank_extended": bench.rank_extended,
        "files": list(SAVED_FILES),
    }
    return {
        "workbench.pkl": lambda p: p.write_bytes(pickle.dumps(bench, protocol=pickle.HIGHEST_PROTOCOL)),
        "manifest.json": lambda p: p.write_text(json.dumps(manifest, indent=2) + "\n", encoding="utf-8"),
        "points.csv": lambda p: write_csv(points, p),
    }


def load_workbench(directory):
    """A batch saved with ``reloadable=True`` (:func:`batch_files`) (only load directories you trust: it unpickles).

    Raises
    ------
    InputError
        When the directory lacks the saved files, or was written by tromplab with another
        major version (whose records may not unpickle into this one).
    """
    directory = Path(directory)
    manifest_path = directory / "manifest.json"
    if not manifest_path.exists() or not (directory / "workbench.pkl").exists():
        raise InputError("not a saved tromplab batch: manifest.json or workbench.pkl is missing", source=str(directory))
    manifest = json.loads(manifest_path.read_text(encoding="utf-8"))
    saved = str(manifest.get("tromplab_version", "unknown"))
    if _major(saved) != _major(__version__):
        raise InputError(
            f"saved by tromplab {saved}, this is tromplab {__version__}: major versions differ, so the "
            f"saved results cannot be loaded; refit the inputs in points.csv, or install tromplab "
            f"{_major(saved)}.x to read them",
            source=str(directory),
        )
    return pickle.loads((directory / "workbench.pkl").read_bytes())
