r"""Survey design advice: which measurement to add, predicted from the linearised covariance.

A candidate measurement :math:`c` (a solids flow on a stream, a size analysis of an unsampled
stream, a repeat size analysis, a per cent solids) has the rows :math:`H_c` of its predictions
in the unknowns and the whitening :math:`W_c` of its error model, both at the reconciled
values; added to the survey, the covariance of the free unknowns becomes
:math:`(J^T J + (W_c H_c N)^T (W_c H_c N))^+` (the same rank decision as the
reconciliation's), and the standard deviation of a result :math:`r` follows by the delta
method.  The results by default are each separator's partition in the class nearest its cut
and each circulating load.  The prediction is that of a linear model at the reconciled
values; the suite checks it by adding the top candidate to the survey at its reconciled value
and reconciling again.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from ..options import DEFAULT_ABSOLUTE_ERROR, DEFAULT_FLOW_RELATIVE_ERROR, DEFAULT_PCT_SOLIDS_SD, DEFAULT_RELATIVE_ERROR
from .measurements import SHARE_COLUMNS, STREAM_VALUE_COLUMNS, Survey
from .problem import RANK_TOL
from .worth import results

#: Columns of :func:`design_table` (``DIR/design.csv``).
DESIGN_COLUMNS = ["rank", "stream", "measurement", "quantity", "sd_before", "sd_after", "reduction"]


@dataclasses.dataclass(frozen=True)
class Candidate:
    """A measurement one could add: its whitened rows in the unknowns and how to write it."""

    stream: str
    measurement: str  # "solids flow", "size analysis", "repeat size analysis", "per cent solids"
    rows: np.ndarray  # whitened prediction rows (pieces x unknowns)


def candidates(balance) -> list[Candidate]:
    """Every measurement one could add to the survey of ``balance``, with the default error model
    (:mod:`tromplab.options`) evaluated at the reconciled values."""
    sheet, survey = balance.flowsheet, balance.survey
    m = balance.class_flows
    S, n = m.shape
    size = balance.covariance.shape[0]
    flows = balance.flows
    measured_flows, analysed = set(survey.flows["stream"]), set(survey.shares["stream"])
    measured_pct = set(survey.pct_solids["stream"])
    found = []
    for s, stream in enumerate(sheet.stream_names):
        if stream not in measured_flows:
            row = np.zeros((1, size))
            row[0, s * n : (s + 1) * n] = 1.0 / (DEFAULT_FLOW_RELATIVE_ERROR * flows[s])
            found.append(Candidate(stream, "solids flow", row))
        if n > 1:
            word = "repeat size analysis" if stream in analysed else "size analysis"
            found.append(Candidate(stream, word, _analysis_rows(m[s], flows[s], s, size)))
        if balance.balances_water and stream not in measured_pct:
            water = balance.water_flows[s]
            total = flows[s] + water
            row = np.zeros((1, size))
            row[0, s * n : (s + 1) * n] = 100.0 * water / total**2 / DEFAULT_PCT_SOLIDS_SD
            row[0, S * n + s] = -100.0 * flows[s] / total**2 / DEFAULT_PCT_SOLIDS_SD
            found.append(Candidate(stream, "per cent solids", row))
    return found


def _analysis_rows(class_flows: np.ndarray, flow: float, s: int, size: int) -> np.ndarray:
    """Whitened rows of a closed size analysis of stream ``s``: its shares' covariance P D P^T
    (n - 1 pieces), D from the default error model at the reconciled shares."""
    n = class_flows.size
    x = class_flows / flow
    gradient = np.zeros((n, size))
    gradient[:, s * n : (s + 1) * n] = (np.eye(n) - np.outer(x, np.ones(n))) / flow  # d(x_i)/d(m_s,j)
    sd = np.sqrt((DEFAULT_RELATIVE_ERROR * x) ** 2 + DEFAULT_ABSOLUTE_ERROR**2)
    P = np.eye(n) - np.outer(x, np.ones(n))
    eigenvalues, vectors = np.linalg.eigh(P @ np.diag(sd**2) @ P.T)
    keep = eigenvalues > 1e-12 * eigenvalues.max()
    return (vectors[:, keep] / np.sqrt(eigenvalues[keep])).T @ gradient


def default_quantities(balance) -> list[tuple[str, np.ndarray]]:
    """Each separator's partition in the class nearest its cut (0.5) and each circulating load."""
    chosen, nearest = [], {}
    for name, value, gradient in results(balance):
        if name.startswith("circulating load"):
            chosen.append((name, gradient))
        elif name.startswith("partition"):
            node = name.split(" ")[1]
            if node not in nearest or abs(value - 0.5) < nearest[node][0]:
                nearest[node] = (abs(value - 0.5), name, gradient)
    return [(name, gradient) for _, name, gradient in nearest.values()] + chosen


def design_table(balance, quantities=None) -> pd.DataFrame:
    """One row per candidate measurement and result, ranked by the relative reduction of the
    result's sd (:data:`DESIGN_COLUMNS`).

    Parameters
    ----------
    balance : CircuitBalance
    quantities : list of (name, gradient), optional
        Results and their gradients in the unknowns (default :func:`default_quantities`).
    """
    problem, decomposition = balance.problem, balance.decomposition
    if problem is None or decomposition is None or not problem.y.size:
        return pd.DataFrame(columns=DESIGN_COLUMNS)
    quantities = default_quantities(balance) if quantities is None else quantities
    v = balance.fitted if balance.fitted is not None else balance._unknowns
    J = problem.W @ problem.jacobian(v) @ problem.N
    before = {name: float(np.sqrt(max(g @ balance.covariance @ g, 0.0))) for name, g in quantities}
    rows = []
    for candidate in candidates(balance):
        covariance = problem.N @ _pseudo_inverse(J, candidate.rows @ problem.N) @ problem.N.T
        for name, g in quantities:
            after = float(np.sqrt(max(g @ covariance @ g, 0.0)))
            rows.append({"stream": candidate.stream, "measurement": candidate.measurement, "quantity": name,
                         "sd_before": before[name], "sd_after": after,
                         "reduction": 1.0 - after / before[name] if before[name] > 0 else 0.0})  # fmt: skip
    table = pd.DataFrame(rows, columns=DESIGN_COLUMNS[1:])
    table = table.sort_values(["reduction", "quantity"], ascending=[False, True], kind="stable").reset_index(drop=True)
    table.insert(0, "rank", np.arange(1, len(table) + 1))
    return table


def _pseudo_inverse(J: np.ndarray, extra: np.ndarray) -> np.ndarray:
    """:math:`(J^T J + E^T E)^+` with the reconciliation's rank decision (:data:`RANK_TOL`)."""
    stacked = np.vstack([J, extra])
    _, singular, Vt = np.linalg.svd(stacked, full_matrices=False)
    rank = int(np.sum(singular > RANK_TOL * singular.max(initial=0.0)))
    return (Vt[:rank].T / singular[:rank] ** 2) @ Vt[:rank]


def water_determined_by(balance, gradients: np.ndarray, tolerance: float) -> list[list[str]]:
    """For each row of ``gradients`` (a water flow the survey leaves free, as a gradient in the
    unknowns): the solids streams whose per cent solids, measured as well, would determine it."""
    problem, v = balance.problem, balance._test_point
    S, n = problem.n_streams, problem.n_classes
    J = problem.W @ problem.jacobian(v) @ problem.N
    flows = v[: S * n].reshape(S, n).sum(axis=1)
    measured = set(balance.survey.pct_solids["stream"])
    found = [[] for _ in range(len(gradients))]
    for s, stream in enumerate(balance.flowsheet.stream_names):
        if stream in measured:
            continue
        water, total = v[S * n + s], flows[s] + v[S * n + s]
        row = np.zeros(v.size)
        row[s * n : (s + 1) * n], row[S * n + s] = 100.0 * water / total**2, -100.0 * flows[s] / total**2
        stacked = np.vstack([J, row @ problem.N / DEFAULT_PCT_SOLIDS_SD])
        _, singular, Vt = np.linalg.svd(stacked, full_matrices=True)
        rank = int(np.sum(singular > RANK_TOL * singular.max(initial=0.0)))
        unseen = problem.N @ Vt[rank:].T
        for j in np.flatnonzero(np.abs(gradients @ unseen).max(axis=1, initial=0.0) < tolerance):
            found[j].append(stream)
    return found


def survey_with(balance, stream: str, measurement: str) -> Survey:
    """The survey of ``balance`` with a candidate added at its reconciled value (a solids flow
    or a size analysis, default error model): what the design's prediction is checked against."""
    survey, s = balance.survey, balance.flowsheet.stream_index[stream]
    if measurement == "solids flow":
        value = float(balance.flows[s])
        added = pd.DataFrame([{"stream": stream, "value": value, "sd": DEFAULT_FLOW_RELATIVE_ERROR * value, "row": None,
                               "relative": DEFAULT_FLOW_RELATIVE_ERROR}], columns=STREAM_VALUE_COLUMNS)  # fmt: skip
        return dataclasses.replace(survey, flows=pd.concat([survey.flows, added], ignore_index=True))
    if measurement == "size analysis":
        x = balance.shares[s]
        added = pd.DataFrame({"stream": stream, "class_index": np.arange(x.size), "value": x,
                              "sd": np.sqrt((DEFAULT_RELATIVE_ERROR * x) ** 2 + DEFAULT_ABSOLUTE_ERROR**2), "row": None,
                              "relative": DEFAULT_RELATIVE_ERROR, "absolute": DEFAULT_ABSOLUTE_ERROR}, columns=SHARE_COLUMNS)  # fmt: skip
        return dataclasses.replace(survey, shares=pd.concat([survey.shares, added], ignore_index=True),
                                   closed_streams=(*survey.closed_streams, stream))  # fmt: skip
    raise ValueError(f"survey_with adds a 'solids flow' or a 'size analysis', not {measurement!r}")
