r"""What each measurement of a survey is worth: its solvability class, its redundancy and its
influence on the results a metallurgist reads.

With :math:`J = W H N` the whitened Jacobian in the free unknowns, the reconciled unknowns
move with the measurements as :math:`\partial m / \partial y = N (J^T J)^+ J^T W`; a raw
error :math:`\varepsilon_j` of measurement :math:`j` (standard deviation :math:`\sigma_j`,
spread over its closed analysis by :math:`P e_j`) moves a result :math:`r(m)` by
:math:`s_{rj} = \nabla r^T\,\partial m/\partial y\,P e_j\,\sigma_j` per standard deviation, and
:math:`\sum_j s_{rj}^2` is the result's linearised variance; :math:`s_{rj}^2` over that sum is
the share of it that measurement :math:`j` carries.  A measurement is *redundant* when the
balances also determine it (its adjustment has a variance; its *redundancy* is that variance
over its own, 0..1, Crowe, Garcia Campos & Hrymak 1983), otherwise *just determined*: it is
returned unchanged and no test can check it.

References
----------
Crowe, C. M., Garcia Campos, Y. A. & Hrymak, A. (1983). Reconciliation of process flow rates
by matrix projection. Part I: linear case. *AIChE Journal* 29(6), 881-888.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .problem import TESTABLE_SHARE

#: Columns of :func:`worth_table` (``DIR/worth.csv``).
WORTH_COLUMNS = ["measurement", "stream", "kind", "solvability", "redundancy", "result", "result_value", "result_sd",
                 "shift_per_sd", "variance_share"]  # fmt: skip


def results(balance) -> list[tuple[str, float, np.ndarray]]:
    """``(name, value, gradient in the unknowns)`` of the results read from a survey: each
    separator's fine yield and partition in each class with enough feed, and the circulating
    load (coarse over fine product) of each separator whose coarse product returns to a node."""
    sheet, flows, m = balance.flowsheet, balance.flows, balance.class_flows
    n = m.shape[1]
    size = balance.covariance.shape[0]
    found = []
    partition = balance.partition_table()
    partition = partition[partition["component"] == "solids"]  # the whole solids' curves; components have their own
    for node in sheet.separators:
        f, c = sheet.stream_index[node.fine], sheet.stream_index[node.coarse]
        Ff, Fc = flows[f], flows[c]
        gradient = np.zeros(size)
        gradient[f * n : (f + 1) * n], gradient[c * n : (c + 1) * n] = Fc / (Ff + Fc) ** 2, -Ff / (Ff + Fc) ** 2
        found.append((f"fine yield {node.name}", Ff / (Ff + Fc), gradient))
        if sheet.stream(node.coarse).target:
            gradient = np.zeros(size)
            gradient[c * n : (c + 1) * n], gradient[f * n : (f + 1) * n] = 1.0 / Ff, -Fc / Ff**2
            found.append((f"circulating load {node.name}", Fc / Ff, gradient))
        classes = partition[partition["experiment"] == node.name]
        lower, upper = classes["size_lower"].to_numpy(float), classes["size_upper"].to_numpy(float)
        for i in np.flatnonzero(classes["used"].astype(bool).to_numpy()):
            total = m[f, i] + m[c, i]
            gradient = np.zeros(size)
            gradient[f * n + i], gradient[c * n + i] = m[c, i] / total**2, -m[f, i] / total**2
            found.append((f"partition {node.name} {_label(lower[i], upper[i])}", m[f, i] / total, gradient))
    return found


def _label(lower: float, upper: float) -> str:
    if not np.isfinite(upper):
        return f"+{lower:g}"
    return f"-{upper:g}" if not np.isfinite(lower) else f"-{upper:g}+{lower:g}"


def worth_table(balance) -> pd.DataFrame:
    """One row per measurement and result (:data:`WORTH_COLUMNS`): the measurement's
    solvability class and redundancy, and how far the result moves per standard deviation of
    the measurement's raw error (``shift_per_sd``) and the share of the result's variance it
    carries (``variance_share``, summing to 1 over the measurements of a result)."""
    problem, decomposition = balance.problem, balance.decomposition
    if problem is None or decomposition is None or not problem.y.size:
        return pd.DataFrame(columns=WORTH_COLUMNS)
    if getattr(problem, "is_sparse", False):  # a large flowsheet: the shifts of every result by sparse products
        from .sparse_tables import raw_error_sensitivities

        gradients = np.array([gradient for _, _, gradient in balance._results]).reshape(len(balance._results), -1)
        shifts = raw_error_sensitivities(balance, gradients)
    else:
        v = balance.fitted if balance.fitted is not None else problem.m0
        W = problem.W
        J = W @ problem.jacobian(v) @ problem.N
        sensitivity = problem.N @ decomposition.covariance() @ J.T @ W  # d(unknowns)/d(measurements)
        raw = sensitivity @ problem.effects * problem.sd  # columns: what one sd of each raw error moves
    adjustments = balance.adjustments_table()
    redundancy = np.clip((adjustments["adjustment_sd"].to_numpy(float) / adjustments["sd"].to_numpy(float)) ** 2, 0.0, 1.0)
    redundant = np.isfinite(redundancy) & (redundancy > TESTABLE_SHARE)
    kinds = np.where(adjustments["class_index"] >= 0, "share", np.where(adjustments["class_index"] == -1, "flow", "pct_solids"))
    if "component" in adjustments.columns:  # a per-class assay
        kinds = np.where(adjustments["component"].astype(bool), "assay", kinds)
    found = balance._results
    if not found:
        return pd.DataFrame(columns=WORTH_COLUMNS)
    # one product per result (a matrix product would round otherwise), the table built at once
    if getattr(problem, "is_sparse", False):
        shift = shifts
    else:
        shift = np.array([gradient @ raw for _, _, gradient in found])
    variance = np.array([float(row @ row) for row in shift])
    k, p = shift.shape
    with np.errstate(invalid="ignore", divide="ignore"):
        share = np.where(variance[:, None] > 0, shift**2 / variance[:, None], np.nan)
    each_measurement, each_result = np.tile(np.arange(p), k), np.repeat(np.arange(k), p)
    return pd.DataFrame({
        "measurement": _taken(adjustments["measurement"].to_numpy(), each_measurement),
        "stream": _taken(adjustments["stream"].to_numpy(), each_measurement), "kind": _taken(kinds, each_measurement),
        "solvability": _taken(np.where(redundant, "redundant", "just determined"), each_measurement),
        "redundancy": np.tile(np.where(redundant, redundancy, 0.0), k),
        "result": _taken(np.array([name for name, _, _ in found]), each_result),
        "result_value": np.repeat([value for _, value, _ in found], p), "result_sd": np.repeat(np.sqrt(variance), p),
        "shift_per_sd": shift.ravel(), "variance_share": share.ravel(),
    }, columns=WORTH_COLUMNS)  # fmt: skip


def _taken(labels: np.ndarray, positions: np.ndarray):
    """The column of ``labels[positions]`` as pandas makes it of the array (its string dtype
    inferred from ``labels``), each label converted once: the 30-node plant's table has 416,585
    rows, whose strings one by one took 0.3 s."""
    return pd.Series(labels).array.take(positions)
