"""Readable views of fit and batch results: short reprs, HTML, summaries, text reports, saving.

:class:`~tromplab.curves.curve_fit.CurveFit` and :class:`~tromplab.workbench.Workbench` call these
functions from their methods (``repr(fit)``, ``fit.summary()``, ``fit.report()``,
``bench.save(dir)``, ...); they are views of the same recorded fields as ``fits.csv``, in
the spirit of lmfit's ``fit_report`` and statsmodels' ``summary()``.
"""

from __future__ import annotations

import html
import json
import pickle
from pathlib import Path

import numpy as np
import pandas as pd

from .._version import __version__
from ..errors import InputError

#: Files of a saved batch (:func:`save_workbench`).
SAVED_FILES = ("workbench.pkl", "manifest.json", "fits.csv", "ranking.csv", "points.csv")
_INDEX_LINES = (
    ("eta", "classifier efficiency eta (recovery of fines, 0..1)"),
    ("epsilon", "misplacement eps of coarse particles into the fines (0..1)"),
    ("slope", "slope d phi/dx at the cut (< 0)"),
    ("d25", "d25, partition to coarse 0.25 [size]"),
    ("d75", "d75, partition to coarse 0.75 [size]"),
    ("ep", "Ecart probable Ep = (d75 - d25)/2 [size]"),
    ("imperfection", "imperfection Ep/d_cut (> 0)"),
)


def _g(value, digits: int = 5) -> str:
    return "nan" if value is None or not np.isfinite(value) else f"{value:.{digits}g}"


# --- one fit -------------------------------------------------------------------------------
def fit_repr(fit) -> str:
    """``<CurveFit plitt (7) on 'run1': d_cut=31.2, ks=3.1, F=123 > F_crit=3.8 (adequate), n=8>``."""
    head = f"<CurveFit {fit.formula.id} ({fit.formula.equation}) on {fit.experiment!r}"
    if not fit.success:
        return f"{head}: failed: {fit.message}>"
    values = ", ".join(f"{name}={_g(value, 4)}" for name, value in fit.fit.values.items())
    screen = fit.screen
    verdict = (
        f"F={_g(screen.F, 4)} {'>' if screen.adequate else '<='} F_crit={_g(screen.F_crit, 3)} "
        f"({'adequate' if screen.adequate else 'inadequate'})"
        if screen
        else "not screened"
    )
    warned = f", {len(fit.warnings)} warning(s)" if fit.warnings else ""
    return f"{head}: {values}, {verdict}, n={fit.points.n}{warned}>"


def fit_summary(fit) -> pd.DataFrame:
    """One-row DataFrame: the columns of ``fits.csv`` (README, "What the main job writes") but ``rank``."""
    from ..workbench import FIT_COLUMNS

    return pd.DataFrame([fit.row()]).reindex(columns=[c for c in FIT_COLUMNS if c != "rank"])


def fit_html(fit) -> str:
    """HTML for Jupyter: the repr line, parameters with standard errors, screen and indices."""
    rows = "".join(
        f"<tr><td>{html.escape(name)}</td><td>{_g(value)}</td><td>{_g(fit.fit.stderr[name])}</td></tr>"
        for name, value in fit.fit.values.items()
    )
    parts = [
        f"<p><b>{html.escape(fit_repr(fit))}</b></p>",
        f"<table><tr><th>parameter</th><th>value</th><th>stderr</th></tr>{rows}</table>",
    ]
    if fit.indices is not None:
        cells = "".join(f"<td>{_g(getattr(fit.indices, name), 4)}</td>" for name, _ in _INDEX_LINES)
        heads = "".join(f"<th>{name}</th>" for name, _ in _INDEX_LINES)
        parts.append(f"<table><tr>{heads}</tr><tr>{cells}</tr></table>")
    parts += [f"<p style='color:#a60'>warning: {html.escape(w)}</p>" for w in fit.warnings]
    return "\n".join(parts)


def fit_report(fit, *, level: float = 0.95, profile: bool = True) -> str:
    """Text report of one fit: parameters with standard errors and intervals, F screen,
    indices with delta-method standard errors, residual diagnostics and warnings."""
    from ..statistics.uncertainty import interval_table

    formula = fit.formula
    lines = [
        f"[[Fit]] {formula.id} ({formula.equation}), {formula.title}, experiment {fit.experiment!r}",
        f"    phi(x) = {formula.expression}, x = size/d_cut",
        f"    points = {fit.points.n}, parameters = {formula.n_params}, starts = {fit.fit.n_starts}, "
        f"function evaluations = {fit.fit.nfev}",
        f"    success = {fit.success}: {fit.message}",
    ]
    if not fit.success:
        return "\n".join(lines)
    table = interval_table(fit, level=level, profile=profile).set_index("quantity")
    lines.append(f"[[Parameters]] value +/- standard error, {level:.0%} interval (method)")
    for parameter in formula.parameters(fit.points.size):
        row = table.loc[parameter.name]
        lines.append(
            f"    {parameter.name:<9} = {_g(row.value):>11} +/- {_g(row.stderr):<10} "
            f"[{_g(row.low)}, {_g(row.high)}] ({row.method}); {parameter.unit}, bounds "
            f"[{parameter.lower:g}, {parameter.upper:g}]"
        )
    screen = fit.screen
    lines += [
        f"[[Fisher screen]] alpha = {screen.alpha:g}",
        f"    F = s0^2/s_res^2 = {_g(screen.s0_sq)}/{_g(screen.s_res_sq)} = {_g(screen.F)}; "
        f"F_crit = {_g(screen.F_crit)}; {'adequate' if screen.adequate else 'inadequate'} (F > F_crit)",
        f"[[Indices]] value +/- delta-method standard error, {level:.0%} interval",
    ]
    for name, meaning in _INDEX_LINES:
        row = table.loc[name] if name in table.index else None
        value = getattr(fit.indices, name)
        spread = f" +/- {_g(row.stderr)} [{_g(row.low)}, {_g(row.high)}]" if row is not None else ""
        lines.append(f"    {name:<12} = {_g(value):>11}{spread}  {meaning}")
    criteria = fit.fit.information_criteria()
    diag = fit.diagnostics
    lines += [
        "[[Diagnostics]]",
        f"    SSR = {_g(fit.fit.ssr)}; AIC = {_g(criteria['aic'])}, AICc = {_g(criteria['aicc'])}, BIC = {_g(criteria['bic'])}",
        f"    runs test p = {_g(diag.runs_p, 3)} ({diag.n_runs} runs of signs), normality p = {_g(diag.normality_p, 3)}",
    ]
    lines.append("[[Warnings]]")
    lines += [f"    {warning}" for warning in fit.warnings] or ["    none"]
    return "\n".join(lines)


# --- a batch -------------------------------------------------------------------------------
def workbench_repr(bench) -> str:
    """``<Workbench: 2 experiments x 9 formulas, 18 fits (18 successful), ranked by F ...>``."""
    n_ok = sum(fit.success for fit in bench.fits)
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


def workbench_html(bench) -> str:
    """HTML for Jupyter: the repr line and the ranking table."""
    return f"<p><b>{html.escape(workbench_repr(bench))}</b></p>\n" + bench.ranking_table().to_html(index=False)


def _major(version: str) -> str:
    return str(version).split(".")[0]


def save_workbench(bench, directory) -> dict[str, Path]:
    """Write a batch into ``directory``: the pickled batch with its inputs and options, and
    readable tables (``fits.csv``, ``ranking.csv``, ``points.csv``) and ``manifest.json``.

    Written atomically (all files or none).  Load with :func:`load_workbench`.
    """
    from ..workbench import write_atomically

    points = pd.concat([p.to_frame() for p in _inputs(bench)], ignore_index=True) if bench.fits else pd.DataFrame()
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
    outputs = {
        "workbench.pkl": lambda p: p.write_bytes(pickle.dumps(bench, protocol=pickle.HIGHEST_PROTOCOL)),
        "manifest.json": lambda p: p.write_text(json.dumps(manifest, indent=2) + "\n", encoding="utf-8"),
        "fits.csv": lambda p: bench.fits_table().to_csv(p, index=False),
        "ranking.csv": lambda p: bench.ranking_table().to_csv(p, index=False),
        "points.csv": lambda p: points.to_csv(p, index=False),
    }
    return write_atomically(outputs, directory)


def _inputs(bench):
    return list({fit.experiment: fit.points for fit in bench.fits}.values())


def load_workbench(directory):
    """A batch saved by :func:`save_workbench` (only load directories you trust: it unpickles).

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
