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

from ..errors import OptionError
from ..options import DEFAULT_PCT_SOLIDS_SD
from . import linear_algebra as linalg  # numpy's LAPACK: a design does not import scipy.linalg
from .measurements import SHARE_COLUMNS, STREAM_VALUE_COLUMNS, ErrorModel, Survey
from .problem import RANK_TOL, TESTABLE_SHARE

#: Columns of :func:`design_table` (``DIR/design.csv``).
#: A relative change of a result's sd smaller than this is the rounding of the low-rank updates
#: (the bundled surveys show up to 3e-14 either way), not an effect of the candidate.
REDUCTION_ROUNDING = 1e-12
DESIGN_COLUMNS = ["rank", "stream", "measurement", "quantity", "sd_before", "sd_after", "reduction", "makes_testable",
                  "n_made_testable", "testable", "stated_error"]  # fmt: skip
#: The measurements one could add, as :func:`candidates` and :func:`survey_with` name them.
CANDIDATE_KINDS = ("solids flow", "size analysis", "repeat size analysis", "per cent solids")


@dataclasses.dataclass(frozen=True)
class Candidate:
    """A measurement one could add: its whitened rows in the unknowns and how to write it."""

    stream: str
    measurement: str  # one of CANDIDATE_KINDS
    rows: np.ndarray  # whitened prediction rows (pieces x unknowns)
    stated_error: str  # the error the prediction assumes, in words


def candidates(balance, errors: ErrorModel | None = None, at: np.ndarray | None = None) -> list[Candidate]:
    """Every measurement one could add to the survey of ``balance``, with the error model
    ``errors`` (default :class:`~tromplab.circuit.measurements.ErrorModel`) evaluated at the
    reconciled values: a solids flow on each stream without one, a size analysis of each
    unsampled stream, a repeat size analysis of each sampled one, and (when water is
    balanced) a per cent solids of each stream without one.  ``at``: the unknowns at which the
    rows are linearised (default: the unbounded least-squares solution, as the covariance)."""
    errors = errors or ErrorModel()
    sheet, survey = balance.flowsheet, balance.survey
    S, n = balance.class_flows.shape
    at = _design_point(balance) if at is None else at
    m = at[: S * n].reshape(S, n)
    size = balance.covariance.shape[0]
    flows = m.sum(axis=1)
    measured_flows, analysed = set(survey.flows["stream"]), set(survey.shares["stream"])
    measured_pct = set(survey.pct_solids["stream"])
    found = []
    for s, stream in enumerate(sheet.stream_names):
        if stream not in measured_flows:
            row = np.zeros((1, size))
            row[0, s * n : (s + 1) * n] = 1.0 / (errors.flow_relative_error * flows[s])
            found.append(Candidate(stream, "solids flow", row, f"{100 * errors.flow_relative_error:g} % relative"))
        if n > 1:
            relative, absolute = errors.streams.get(stream, (errors.relative_error, errors.absolute_error))
            word = "repeat size analysis" if stream in analysed else "size analysis"
            stated = f"each share {100 * relative:g} % relative and {100 * absolute:g} percentage point absolute, closed"
            found.append(Candidate(stream, word, _analysis_rows(m[s], flows[s], s, size, relative, absolute), stated))
        if balance.balances_water and stream not in measured_pct:
            water = at[S * n + s]
            total = flows[s] + water
            row = np.zeros((1, size))
            row[0, s * n : (s + 1) * n] = 100.0 * water / total**2 / errors.pct_solids_sd
            row[0, S * n + s] = -100.0 * flows[s] / total**2 / errors.pct_solids_sd
            found.append(Candidate(stream, "per cent solids", row, f"sd {errors.pct_solids_sd:g} percentage points"))
    return found


def _analysis_rows(class_flows: np.ndarray, flow: float, s: int, size: int, relative: float, absolute: float) -> np.ndarray:
    """Whitened rows of a closed size analysis of stream ``s``: its shares' covariance P D P^T
    (n - 1 pieces), D from the error model at the reconciled shares."""
    n = class_flows.size
    x = class_flows / flow
    gradient = np.zeros((n, size))
    gradient[:, s * n : (s + 1) * n] = (np.eye(n) - np.outer(x, np.ones(n))) / flow  # d(x_i)/d(m_s,j)
    sd = np.sqrt((relative * x) ** 2 + absolute**2)
    P = np.eye(n) - np.outer(x, np.ones(n))
    eigenvalues, vectors = np.linalg.eigh(P @ np.diag(sd**2) @ P.T)
    keep = eigenvalues > 1e-12 * eigenvalues.max()
    return (vectors[:, keep] / np.sqrt(eigenvalues[keep])).T @ gradient


#: The kinds of result :func:`select_quantities` takes for every separator at once.
QUANTITY_WORDS = ("partition at cut", "partition", "fine yield", "circulating load")


def default_quantities(balance) -> list[tuple[str, np.ndarray]]:
    """Each separator's partition in the class nearest its cut (0.5) and each circulating load."""
    chosen, nearest = [], {}
    for name, value, gradient in balance._results:
        if name.startswith("circulating load"):
            chosen.append((name, gradient))
        elif name.startswith("partition"):
            node = name.split(" ")[1]
            if node not in nearest or abs(value - 0.5) < nearest[node][0]:
                nearest[node] = (abs(value - 0.5), name, gradient)
    return [(name, gradient) for _, name, gradient in nearest.values()] + chosen


def select_quantities(balance, names, option: str = "quantity") -> list[tuple[str, np.ndarray]]:
    """The results named in ``names``: a result as :func:`~tromplab.circuit.worth.results`
    names it (``"partition cyclone -150+75"``, ``"fine yield cyclone"``, ``"circulating load
    cyclone"``) or one of :data:`QUANTITY_WORDS` for every separator (``"partition at cut"``:
    the class nearest the cut).  ``None`` or empty: :func:`default_quantities`.

    Raises
    ------
    OptionError
        A name that is neither (naming ``option`` and listing the results of the survey).
    """
    if names is None or (isinstance(names, str) and not names.strip()):
        return default_quantities(balance)
    names = [names] if isinstance(names, str) else list(names)
    everything = [(name, gradient) for name, _, gradient in balance._results]
    chosen: dict[str, np.ndarray] = {}
    for name in (str(n).strip() for n in names):
        if name == "partition at cut":
            matched = default_quantities(balance)
            matched = [item for item in matched if item[0].startswith("partition")]
        elif name in QUANTITY_WORDS:
            matched = [item for item in everything if item[0].startswith(name + " ")]
        else:
            matched = [item for item in everything if item[0] == name]
        if not matched:
            kinds = {n.split(" ")[0]: n for n, _ in everything}  # one result of each kind as an example
            known = ", ".join(repr(n) for n in kinds.values())
            raise OptionError(option, f"names {name!r}, not a result of this survey: use one of {', '.join(QUANTITY_WORDS)}, "
                              f"or a result such as {known}")  # fmt: skip
        chosen.update(matched)
    return list(chosen.items())


def _rounding_cleared(before: float, after: float) -> tuple[float, float]:
    """The predicted sd and its relative reduction, a change within the arithmetic's rounding
    (:data:`REDUCTION_ROUNDING`) written as none: an added measurement cannot raise an sd, and a
    reduction of 1e-16 would rank a candidate that changes nothing above others that do neither."""
    reduction = 1.0 - after / before if before > 0 else 0.0
    if abs(reduction) < REDUCTION_ROUNDING:
        return before, 0.0
    return after, reduction


def design_table(balance, quantities=None, *, errors: ErrorModel | None = None, progress=None) -> pd.DataFrame:
    """One row per candidate measurement and result (:data:`DESIGN_COLUMNS`), ranked by the
    relative reduction of the result's sd, then by the number of measurements it makes testable.

    Parameters
    ----------
    balance : CircuitBalance
    quantities : list of (name, gradient), optional
        Results and their gradients in the unknowns (default :func:`default_quantities`).
    errors : ErrorModel, optional
        The error model of the candidates (default: the library's defaults).
    progress : callable, optional
        ``progress(done, total, label)`` after each candidate (``"design: candidate i of n"``).

    Notes
    -----
    ``makes_testable`` lists the measurements of the survey that are just determined now and
    would become redundant (testable) with the candidate; ``testable`` says whether the
    candidate itself would be.  Both use the reconciliation's test of testability: the raw
    error of a measurement is testable when it is not in the range of the whitened Jacobian.

    The candidates are evaluated by a low-rank update of the reconciliation's factors
    (:class:`CandidateUpdates`), not by a fresh pseudo-inverse each.
    """
    problem, decomposition = balance.problem, balance.decomposition
    if problem is None or decomposition is None or not problem.y.size:
        return pd.DataFrame(columns=DESIGN_COLUMNS)
    quantities = default_quantities(balance) if quantities is None else quantities
    v = _design_point(balance)
    names = balance._measurement_names  # the adjustments table's, without its tests
    if getattr(problem, "is_sparse", False):  # a large flowsheet: the same updates in the unknowns, sparse products
        from .sparse_tables import SparseCandidateUpdates as Updates
    else:
        Updates = CandidateUpdates
    updates = Updates(balance, np.array([g for _, g in quantities]).reshape(len(quantities), -1), v)
    before = dict(zip((name for name, _ in quantities), updates.sd_before))
    rows = []
    found = candidates(balance, errors, v)
    for number, candidate in enumerate(found, start=1):
        sd_after, testable_after = updates.with_candidate(candidate)
        newly = names[testable_after[: names.size] & ~updates.testable_now]
        for (name, _), after in zip(quantities, sd_after):
            after, reduction = _rounding_cleared(before[name], after)
            rows.append({"stream": candidate.stream, "measurement": candidate.measurement, "quantity": name,
                         "sd_before": before[name], "sd_after": after, "reduction": reduction,
                         "makes_testable": "; ".join(newly), "n_made_testable": int(newly.size),
                         "testable": bool(testable_after[names.size :].any()), "stated_error": candidate.stated_error})  # fmt: skip
        if progress is not None:
            progress(number, len(found), f"design: candidate {number} of {len(found)}")
    table = pd.DataFrame(rows, columns=DESIGN_COLUMNS[1:])
    table = table.sort_values(["reduction", "n_made_testable", "quantity"], ascending=[False, False, True], kind="stable")
    table = table.reset_index(drop=True)
    table.insert(0, "rank", np.arange(1, len(table) + 1))
    return table


class CandidateUpdates:
    r"""The reconciliation's factors, taken once, that evaluate every candidate by a low-rank update.

    With :math:`C = (J^T J)^+` the covariance of the free unknowns (the reconciliation's rank
    decision) and :math:`E` the candidate's whitened rows in them, a candidate inside the
    directions the survey sees changes the covariance by the Sherman-Morrison-Woodbury identity

    .. math:: C' = C - C E^T (I + E C E^T)^{-1} E C,

    a solve of the candidate's few pieces, so the sd of a result with gradient :math:`q` is
    :math:`q^T C' q` and the information of a raw error :math:`g` (whitened) off the range of
    :math:`[J; E]` grows by :math:`\|(I + E C E^T)^{-1/2} E C J^T g\|^2`; a piece of the
    candidate itself keeps :math:`[(I + E C E^T)^{-1}]_{ii}` of its own.  A candidate that
    reaches a direction no measurement sees (it would change the rank), or whose update
    cancels more than :data:`UPDATE_CANCELLATION` of a variance, is evaluated by a fresh
    pseudo-inverse instead (:meth:`_refactored`), as the update would not be exact there.
    """

    def __init__(self, balance, gradients: np.ndarray, v: np.ndarray):
        problem, decomposition = balance.problem, balance.decomposition
        self.balance, self.problem = balance, problem
        self.J = problem.W @ problem.jacobian(v) @ problem.N
        self.G = problem.W @ problem.effects
        self.C = decomposition.covariance()
        self.unseen = decomposition.unseen
        self.Q = gradients[:, : problem.N.shape[0]] @ problem.N if len(gradients) else np.zeros((0, problem.N.shape[1]))
        self.CQ = self.C @ self.Q.T
        variance = np.einsum("ij,jk,ik->i", gradients, balance.covariance, gradients) if len(gradients) else np.zeros(0)
        self.sd_before = np.sqrt(np.clip(variance, 0.0, None))
        self.variance_before = np.einsum("ij,ji->i", self.Q, self.CQ)
        self.information, self.testable_now = _information(self.J, self.G)
        self.CJG = self.C @ (self.J.T @ self.G)
        self.largest = float(np.linalg.norm(self.J, 2)) if self.J.size else 0.0

    def with_candidate(self, candidate: Candidate) -> tuple[np.ndarray, np.ndarray]:
        """``(sd after of each result, testable)``: which raw errors (the survey's, then the
        candidate's pieces) would be testable with the candidate added.

        A survey without a measured flow is scaled by a basis (a feed of 100); the first flow
        measured replaces it: it sets the scale and nothing else, so it changes no sd of a
        result relative to the flows (partitions, yields, circulating loads) and is not testable.
        """
        E = candidate.rows @ self.problem.N
        if self.balance.basis and candidate.measurement == "solids flow":
            return self.sd_before, np.concatenate([self.testable_now, np.zeros(E.shape[0], dtype=bool)])
        if not self._within_seen(E):
            return self._refactored(E)
        EC = E @ self.C
        inner = np.eye(E.shape[0]) + EC @ E.T
        factor = linalg.cho_factor(inner)
        ECQ = EC @ self.Q.T
        variance = self.variance_before - np.einsum("ij,ij->j", ECQ, linalg.cho_solve(factor, ECQ))
        if np.any(variance < UPDATE_CANCELLATION * self.variance_before):
            return self._refactored(E)
        ECJG = E @ self.CJG
        information = self.information + np.einsum("ij,ij->j", ECJG, linalg.cho_solve(factor, ECJG))
        survey_testable = information > TESTABLE_SHARE * np.einsum("ij,ij->j", self.G, self.G)
        own = np.diag(linalg.cho_solve(factor, np.eye(E.shape[0])))
        return np.sqrt(np.clip(variance, 0.0, None)), np.concatenate([survey_testable, own > TESTABLE_SHARE])

    def _within_seen(self, E: np.ndarray) -> bool:
        """Whether the candidate's rows lie in the directions the survey sees (the rank stays)."""
        if not self.unseen.shape[1]:
            return True
        return bool(np.linalg.norm(E @ self.unseen) <= RANK_TOL * 1e-3 * max(self.largest, np.linalg.norm(E)))

    def _refactored(self, E: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The candidate by a fresh pseudo-inverse of the stacked Jacobian (its own rank decision)."""
        covariance = _pseudo_inverse(self.J, E)
        pieces = E.shape[0]
        stacked_effects = np.block(
            [[self.G, np.zeros((self.G.shape[0], pieces))], [np.zeros((pieces, self.G.shape[1])), np.eye(pieces)]]
        )
        variance = np.einsum("ij,jk,ik->i", self.Q, covariance, self.Q)
        return np.sqrt(np.clip(variance, 0.0, None)), _testable(np.vstack([self.J, E]), stacked_effects)


#: A low-rank update that removes more than all but this share of a variance loses digits to
#: cancellation: such a candidate is evaluated by a fresh pseudo-inverse.
UPDATE_CANCELLATION = 1e-4


def _information(J: np.ndarray, G: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The information of each raw error (columns of the whitened effects ``G``) off the range of
    ``J`` (the rank decision of :data:`RANK_TOL`), and whether it is testable (more than :data:`~tromplab.circuit.problem.TESTABLE_SHARE` of
    it, as in the measurement test)."""
    U, singular, _ = np.linalg.svd(J, full_matrices=False)
    rank = int(np.sum(singular > RANK_TOL * singular.max(initial=0.0)))
    basis = U[:, :rank]
    information = np.einsum("ij,ij->j", G, G - basis @ (basis.T @ G))
    return information, information > TESTABLE_SHARE * np.einsum("ij,ij->j", G, G)


def _design_point(balance) -> np.ndarray:
    """The unknowns at which the design is linearised: those of the covariance (the unbounded
    least-squares solution), so that a candidate's rows and the Jacobian share one point."""
    return balance.fitted if balance.fitted is not None else balance._unknowns


def _testable(J: np.ndarray, G: np.ndarray) -> np.ndarray:
    """Which raw errors (columns of the whitened effects ``G``) a reconciliation with the whitened
    Jacobian ``J`` can test: their part off the range of ``J`` (the rank decision of
    :data:`RANK_TOL`) carries more than TESTABLE_SHARE of them, as in the measurement test."""
    return _information(J, G)[1]


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


def survey_with(balance, stream: str, measurement: str, errors: ErrorModel | None = None) -> Survey:
    r"""The survey of ``balance`` with a candidate added at its reconciled value, with the error
    of ``errors`` (default :class:`~tromplab.circuit.measurements.ErrorModel`): what the
    design's prediction is checked against.

    A repeat size analysis averages with the analysis already there: the stream's shares
    become the mean of the measured and the reconciled ones, with the variance of a mean of
    two (relative and absolute errors over :math:`\sqrt 2`).
    """
    errors = errors or ErrorModel()
    survey, s = balance.survey, balance.flowsheet.stream_index[stream]
    if measurement == "solids flow":
        value = float(balance.flows[s])
        added = pd.DataFrame([{"stream": stream, "value": value, "sd": errors.flow_relative_error * value, "row": None,
                               "relative": errors.flow_relative_error}], columns=STREAM_VALUE_COLUMNS)  # fmt: skip
        return dataclasses.replace(survey, flows=pd.concat([survey.flows, added], ignore_index=True))
    if measurement == "per cent solids":
        water = float(balance.water_flows[s])
        value = 100.0 * float(balance.flows[s]) / (float(balance.flows[s]) + water)
        added = pd.DataFrame([{"stream": stream, "value": value, "sd": errors.pct_solids_sd, "row": None,
                               "relative": np.nan}], columns=STREAM_VALUE_COLUMNS)  # fmt: skip
        return dataclasses.replace(survey, pct_solids=pd.concat([survey.pct_solids, added], ignore_index=True))
    relative, absolute = errors.streams.get(stream, (errors.relative_error, errors.absolute_error))
    x = balance.shares[s]
    if measurement == "size analysis":
        added = pd.DataFrame({"stream": stream, "class_index": np.arange(x.size), "value": x,
                              "sd": np.sqrt((relative * x) ** 2 + absolute**2), "row": None,
                              "relative": relative, "absolute": absolute}, columns=SHARE_COLUMNS)  # fmt: skip
        return dataclasses.replace(survey, shares=pd.concat([survey.shares, added], ignore_index=True),
                                   closed_streams=(*survey.closed_streams, stream))  # fmt: skip
    if measurement == "repeat size analysis":
        shares = survey.shares.copy()
        here = (shares["stream"] == stream).to_numpy()
        shares.loc[here, "value"] = (
            shares.loc[here, "value"].to_numpy(float) + x[shares.loc[here, "class_index"].to_numpy(int)]
        ) / 2
        shares.loc[here, ["relative", "absolute"]] = np.array([relative, absolute]) / np.sqrt(2.0)
        shares.loc[here, "sd"] = np.hypot(shares.loc[here, "relative"] * shares.loc[here, "value"], shares.loc[here, "absolute"])
        return dataclasses.replace(survey, shares=shares)
    raise ValueError(f"survey_with adds one of {', '.join(CANDIDATE_KINDS)}, not {measurement!r}")


#: Columns of :func:`observability_table` (``DIR/observability.csv``).
OBSERVABILITY_COLUMNS = ["stream", "quantity", "observable", "reconciled", "reconciled_sd", "made_observable_by"]


def observability_table(balance, errors: ErrorModel | None = None) -> pd.DataFrame:
    """Every quantity the survey does not measure (:data:`OBSERVABILITY_COLUMNS`): the solids
    flow of a stream without a flow measurement, the size distribution of an unsampled stream,
    a class left blank, and with water balanced the per cent solids and water flow of each
    stream; whether the balances determine it (``observable``: ``yes``, ``relative to the
    basis`` when no flow is measured, or ``no``), its reconciled value and sd when they do, and
    otherwise the candidate measurements (:func:`candidates`) that would each make it observable.

    Notes
    -----
    A quantity with gradient :math:`g` in the unknowns is observable when :math:`g` is
    orthogonal to every direction of the free unknowns that no measurement sees (the null
    space of the whitened Jacobian, with the reconciliation's rank decision; Crowe, Garcia
    Campos & Hrymak 1983).  A survey that leaves a solids flow or distribution unobservable is
    refused by the reconciliation, so ``no`` appears for water flows and per cent solids.
    """
    problem = balance.problem
    large = getattr(problem, "is_sparse", False)  # a large flowsheet: the sparse path's unseen directions
    if problem is None or not (problem.free if large else problem.N.shape[1]):
        return pd.DataFrame(columns=OBSERVABILITY_COLUMNS)
    v = _design_point(balance)
    if large:
        from .sparse_tables import prediction_variances

        J, unseen = None, balance.decomposition.unseen_unknowns
    else:
        J = problem.W @ problem.jacobian(v) @ problem.N if problem.y.size else np.zeros((0, problem.N.shape[1]))
        unseen = problem.N @ _unseen(J)
    tolerance = 1e-7 * max(1.0, float(np.abs(v).max()))
    reported = balance._unknowns  # the reported values (bounded at 0), as in flows.csv and water.csv
    options = None
    rows = []
    for stream, quantity, gradients in _unmeasured_quantities(balance, reported):
        observable = bool(np.abs(gradients @ unseen).max(initial=0.0) < tolerance)
        variance = (prediction_variances(balance.covariance, gradients) if large
                    else np.einsum("ij,jk,ik->i", gradients, balance.covariance, gradients))  # fmt: skip
        sd = np.sqrt(np.clip(variance, 0.0, None))
        value = float(gradients[0] @ reported) if quantity in ("solids flow", "water flow") else np.nan
        if quantity == "per cent solids":
            s = balance.flowsheet.stream_index[stream]
            value = 100.0 * balance.flows[s] / (balance.flows[s] + balance.water_flows[s])
        helpers = ""
        if not observable and not large:  # on the sparse path only component flows go unseen, none listed here
            options = options if options is not None else candidates(balance, errors, v)
            helpers = "; ".join(f"{c.measurement} of {c.stream}" for c in options
                                if np.abs(gradients @ problem.N @ _unseen(np.vstack([J, c.rows @ problem.N]))).max(initial=0.0) < tolerance)  # fmt: skip
        word = "yes" if observable else "no"
        if observable and balance.basis and quantity == "solids flow":
            word, helpers = "relative to the basis", "a solids flow of any stream"
        rows.append({"stream": stream, "quantity": quantity, "observable": word,
                     "reconciled": value if observable else np.nan, "reconciled_sd": float(sd.max()) if observable else np.nan,
                     "made_observable_by": helpers})  # fmt: skip
    return pd.DataFrame(rows, columns=OBSERVABILITY_COLUMNS)


def _unseen(J: np.ndarray) -> np.ndarray:
    """Columns: the directions of the free unknowns that ``J`` does not see (rank decision :data:`RANK_TOL`)."""
    _, singular, Vt = np.linalg.svd(J, full_matrices=True)
    rank = int(np.sum(singular > RANK_TOL * singular.max(initial=0.0)))
    return Vt[rank:].T


def _unmeasured_quantities(balance, v: np.ndarray):
    """``(stream, quantity, gradients)`` of every quantity the survey does not measure."""
    survey, sheet = balance.survey, balance.flowsheet
    S, n = balance.class_flows.shape
    size = v.size
    flows = v[: S * n].reshape(S, n).sum(axis=1)
    measured_flows, analysed = set(survey.flows["stream"]), set(survey.shares["stream"])
    blank = survey.unmeasured.groupby("stream")["class_index"].apply(list).to_dict() if len(survey.unmeasured) else {}
    for s, stream in enumerate(sheet.stream_names):
        if stream not in measured_flows:
            gradient = np.zeros((1, size))
            gradient[0, s * n : (s + 1) * n] = 1.0
            yield stream, "solids flow", gradient
        classes = range(n) if stream not in analysed else [int(i) for i in blank.get(stream, [])]
        if n > 1 and len(classes):
            x = v[s * n : (s + 1) * n] / flows[s]
            gradient = np.zeros((n, size))
            gradient[:, s * n : (s + 1) * n] = (np.eye(n) - np.outer(x, np.ones(n))) / flows[s]
            yield stream, "size distribution" if stream not in analysed else "blank classes", gradient[list(classes)]
    if balance.balances_water:
        measured_pct = set(survey.pct_solids["stream"])
        for s, stream in enumerate(sheet.stream_names):
            if stream not in measured_pct:
                gradient = np.zeros((1, size))
                total = flows[s] + v[S * n + s]
                gradient[0, s * n : (s + 1) * n] = 100.0 * v[S * n + s] / total**2
                gradient[0, S * n + s] = -100.0 * flows[s] / total**2
                yield stream, "per cent solids", gradient
        for k, stream in enumerate(sheet.streams + sheet.water_streams):
            gradient = np.zeros((1, size))
            gradient[0, S * n + k] = 1.0
            yield stream.name, "water flow", gradient
