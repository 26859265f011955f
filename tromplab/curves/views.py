"""Readable views of one fit: the short repr, HTML for notebooks and the text report.

:class:`~tromplab.curves.curve_fit.CurveFit` calls these from its methods (``repr(fit)``,
``fit._repr_html_()``, ``fit.report()``); they are views of the same recorded fields as a
row of ``fits.csv``, in the spirit of lmfit's ``fit_report`` and statsmodels' ``summary()``.
They sit below the result they render, as statsmodels' ``iolib`` sits below its results.
"""

from __future__ import annotations

import html

import numpy as np

from .intervals import interval_table

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


def _interval_text(row, *, method: bool = True) -> str:
    """``[low, high] (method)``, or the words of an interval withheld because the data do not
    determine the quantity (see [[Warnings]])."""
    if row.method == "none":
        return "no interval: not determined by the data (see [[Warnings]])"
    return f"[{_g(row.low)}, {_g(row.high)}]" + (f" ({row.method})" if method else "")


def fit_report(fit, *, level: float = 0.95, profile: bool = True) -> str:
    """Text report of one fit: parameters with standard errors and intervals, F screen,
    indices with delta-method standard errors, residual diagnostics and warnings."""
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
            f"{_interval_text(row)}; {parameter.unit}, bounds "
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
        spread = f" +/- {_g(row.stderr)} {_interval_text(row, method=False)}" if row is not None else ""
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
