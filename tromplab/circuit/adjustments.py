r"""The adjustments of a reconciled survey and the tests of its measurements.

The adjustments :math:`e = y - \hat y` have :math:`\mathrm{cov}(e) = \Sigma - \mathrm{cov}(\hat y)`;
the standardised adjustment is the measurement test of Mah & Tamhane (1982).  Because the
shares of a closed analysis share their errors, the gross-error test is the generalised
likelihood ratio of an error in one raw measurement, spread by the closure (Narasimhan & Mah
1987).  :class:`~tromplab.circuit.reconciliation.CircuitBalance` reads them from here.

References
----------
Mah, R. S. H. & Tamhane, A. C. (1982). Detection of gross errors in process data.
*AIChE Journal* 28(5), 828-830.

Narasimhan, S. & Mah, R. S. H. (1987). Generalized likelihood ratio method for gross error
identification. *AIChE Journal* 33(9), 1514-1521.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pandas as pd

from ..statistics.distributions import norm_sf
from .measurements import class_name
from .problem import TESTABLE_SHARE, decompose

#: Adjustments correlated beyond this are reported as indistinguishable: a gross error in one
#: of them moves the others' standardised adjustments alike, so no test can tell which it is.
EQUIVALENT_CORRELATION = 0.99
#: Columns of :meth:`CircuitBalance.adjustments_table`.
ADJUSTMENT_COLUMNS = [
    "measurement",
    "stream",
    "class_index",
    "size_lower",
    "size_upper",
    "row",
    "measured",
    "sd",
    "reconciled",
    "reconciled_sd",
    "adjustment",
    "adjustment_sd",
    "standardised",
    "gross_error",
    "gross_error_sd",
    "measurement_test",
    "p_value",
    "suspect",
    "indistinguishable_from",
]
_MEASURED_QUANTITY = {"flow": "flow", "pct": "per cent solids"}


class MeasurementTests(NamedTuple):
    """The generalised likelihood ratio test of a gross error in each raw measurement."""

    statistic: np.ndarray  # with the sign of the adjustment (reconciled - measured)
    estimate: np.ndarray  # the gross error that best explains the adjustments (measured - true)
    estimate_sd: np.ndarray
    testable: np.ndarray
    correlation: np.ndarray  # of the statistics: beyond EQUIVALENT_CORRELATION no test tells them apart


#: Measurement tests whose sizes agree to this share of the largest are a tie, ranked by the
#: measurement's row in the file: the assays of a stream reported as one value tie to 8 digits,
#: which the last bits of the solution (another BLAS, another machine) would otherwise order.
TEST_TIE = 1e-6


def ranked_by_test(table: pd.DataFrame) -> pd.DataFrame:
    """``table`` (rows of :meth:`CircuitBalance.adjustments_table` with a finite test), largest
    absolute measurement test first; tests within :data:`TEST_TIE` of each other by file row."""
    size = table["measurement_test"].abs().to_numpy(float)
    rows = pd.to_numeric(table["row"], errors="coerce").to_numpy(float)
    position = np.arange(len(table))
    by_size = np.lexsort((position, rows, -size))
    tie_group = np.empty(len(table), dtype=int)
    group, leader = -1, np.inf
    for k in by_size:  # a test joins the group of the largest test it is within TEST_TIE of
        if size[k] < leader * (1.0 - TEST_TIE):
            group, leader = group + 1, size[k]
        tie_group[k] = group
    return table.iloc[np.lexsort((position, rows, tie_group))]


def adjustments_frame(balance) -> pd.DataFrame:
    """The table of :meth:`CircuitBalance.adjustments_table` (computed once per balance)."""
    problem = balance.problem
    if problem is None or problem.y.size == 0:
        return pd.DataFrame(columns=ADJUSTMENT_COLUMNS)
    m = balance._test_point
    H = problem.jacobian(m)
    predicted = problem.predict(balance._unknowns)  # the reported values (bounded at 0)
    if getattr(problem, "is_sparse", False):  # a large flowsheet: the diagonal only, from sparse rows
        from .sparse_tables import prediction_variances

        predicted_var = prediction_variances(balance.covariance, H)
    else:
        predicted_var = np.diag(H @ balance.covariance @ H.T)
    adjustment = balance.measured_y - problem.predict(m)  # measured minus reconciled, without the bounds
    adjustment_var = problem.variance - predicted_var
    testable = adjustment_var > TESTABLE_SHARE * problem.sd**2
    adjustment_sd = np.where(testable, np.sqrt(np.clip(adjustment_var, 0.0, None)), np.nan)
    with np.errstate(invalid="ignore", divide="ignore"):
        standardised = np.where(testable, adjustment / adjustment_sd, np.nan)
    classes = balance.survey.classes
    rows_of = _measurement_rows(balance)
    lower, upper = (np.append(classes[column].to_numpy(float), np.nan) for column in ("size_lower", "size_upper"))
    sized = np.where(problem.klass >= 0, problem.klass, lower.size - 1)  # a flow or per cent solids: NaN
    table = pd.DataFrame(
        {
            "measurement": measurement_names(balance),
            "stream": [balance.streams[s] for s in problem.stream],
            "class_index": problem.klass,
            "size_lower": lower[sized],
            "size_upper": upper[sized],
            "row": rows_of,
            "measured": balance.measured_y,
            "sd": np.sqrt(problem.variance),
            "reconciled": predicted,
            "reconciled_sd": np.sqrt(np.clip(predicted_var, 0.0, None)),
            "adjustment": predicted - balance.measured_y,  # what was added to the measurement
            "adjustment_sd": adjustment_sd,
            "standardised": -standardised,
        }
    )
    if balance.survey.components:
        names = np.array(("",) + balance.survey.components, dtype=object)
        table.insert(table.columns.get_loc("class_index") + 1, "component", names[problem.component + 1])
    tests = balance._measurement_tests
    table["gross_error"] = tests.estimate
    table["gross_error_sd"] = tests.estimate_sd
    table["measurement_test"] = tests.statistic
    table["p_value"] = 2.0 * norm_sf(np.abs(tests.statistic))
    table["suspect"] = np.abs(table["measurement_test"]) > balance.measurement_test_critical
    names = table["measurement"].to_numpy()
    table["indistinguishable_from"] = [
        "; ".join(names[(np.abs(tests.correlation[j]) > EQUIVALENT_CORRELATION) & tests.testable & (np.arange(names.size) != j)])
        if tests.testable[j]
        else ""
        for j in range(names.size)
    ]
    return table


def measurement_names(balance) -> list[str]:
    """``STREAM class CLASS``, ``STREAM COMPONENT assay class CLASS``, ``STREAM flow``, ``STREAM per cent solids``."""
    problem, classes = balance.problem, balance.survey.classes
    class_names = [class_name(classes, i) for i in range(len(classes))]
    names = []
    for s, i, kind, k in zip(problem.stream, problem.klass, problem.kinds, problem.component):
        if kind == "share":
            names.append(f"{balance.streams[s]} class {class_names[i]}")
        elif kind == "assay":
            names.append(f"{balance.streams[s]} {balance.survey.components[k]} assay class {class_names[i]}")
        else:
            names.append(f"{balance.streams[s]} {_MEASURED_QUANTITY[kind]}")
    return names


def _measurement_rows(balance) -> list:
    survey = balance.survey
    shares, flows, pct, assays = survey.shares, survey.flows, survey.pct_solids, survey.assays
    order = {name: k for k, name in enumerate(survey.components)}
    rows = dict(zip(zip(shares["stream"], shares["class_index"], [-1] * len(shares)), shares["row"]))
    rows |= dict(zip(zip(flows["stream"], [-1] * len(flows), [-1] * len(flows)), flows["row"]))
    rows |= dict(zip(zip(pct["stream"], [-2] * len(pct), [-1] * len(pct)), pct["row"]))
    rows |= dict(zip(zip(assays["stream"], assays["class_index"], assays["component"].map(order)), assays["row"]))
    problem = balance.problem
    return [rows.get((balance.streams[s], i, k)) for s, i, k in zip(problem.stream, problem.klass, problem.component)]


def measurement_tests(balance) -> MeasurementTests:
    r"""The generalised likelihood ratio test of a gross error in each raw measurement.

    A gross error :math:`b` in raw measurement :math:`j` shifts the reported values by
    :math:`b f_j` (:math:`f_j` the column of :attr:`Problem.effects`: a unit vector, or
    in a closed analysis the shift of every share of the stream).  With the whitened
    residuals :math:`\rho` and :math:`g_j = W f_j`, its least-squares estimate is
    :math:`\hat b_j = g_j^T \rho / g_j^T Q g_j` with sd :math:`(g_j^T Q g_j)^{-1/2}`,
    :math:`Q` the projection off the range of the whitened Jacobian; the statistic
    :math:`\hat b_j / \mathrm{sd}` is the most powerful test of that error (Narasimhan &
    Mah 1987) and, for a measurement whose error is independent of the others, equals the
    standardised adjustment of Mah & Tamhane (1982) with the sign of the adjustment.
    """
    problem = balance.problem
    if problem is None or problem.y.size == 0:
        empty = np.zeros(0)
        return MeasurementTests(empty, empty, empty, empty.astype(bool), np.zeros((0, 0)))
    if getattr(problem, "is_sparse", False):  # a large flowsheet: from the covariance, by sparse products
        from .sparse_tables import tests_information

        G, own, information, residual, correlation = tests_information(balance)
        return _tests(G, own, information, residual, correlation)
    m = balance._test_point
    residual = problem.W @ (balance.measured_y - problem.predict(m))
    decomposition = balance.decomposition or decompose(problem, problem.N.T @ (m - problem.m0))
    basis = decomposition.range_basis
    G = problem.W @ problem.effects
    QG = G - basis @ (basis.T @ G)
    information = np.einsum("ij,ij->j", G, QG)
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.sqrt(np.clip(information, 1e-300, None))
        correlation = (QG.T @ QG) / np.outer(scale, scale)
    return _tests(G, np.einsum("ij,ij->j", G, G), information, residual, correlation)


def _tests(G, own: np.ndarray, information: np.ndarray, residual: np.ndarray, correlation: np.ndarray) -> MeasurementTests:
    """The tests from the whitened effects ``G``, their squared norms ``own``, their information
    off the range of the whitened Jacobian and the whitened residuals."""
    testable = information > TESTABLE_SHARE * own
    with np.errstate(invalid="ignore", divide="ignore"):
        estimate = np.where(testable, (G.T @ residual) / information, np.nan)
        estimate_sd = np.where(testable, 1.0 / np.sqrt(np.abs(information)), np.nan)
    return MeasurementTests(-estimate / estimate_sd, estimate, estimate_sd, testable, correlation)
