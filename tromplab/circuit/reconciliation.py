r"""Reconciliation of a circuit survey: weighted least squares under the node balances.

The unknowns are the solids flows :math:`F_s` of the streams and their size distributions
:math:`x_{s,i}` (share of stream :math:`s` in class :math:`i`).  The reconciled values
minimise the weighted sum of squared adjustments of every measurement

.. math:: S = \sum_j \left(\frac{y_j - h_j}{\sigma_j}\right)^2

subject to the balance of every size class at every separator and junction and of the
total solids at every mill,

.. math:: \sum_s M_{ks} F_s x_{s,i} = 0, \qquad \sum_s M_{ks} F_s = 0,

with :math:`M` the node-stream incidence (+1 in, -1 out); the total solids balance of a
separator or junction is the sum of its class balances.  The problem is bilinear in flows
and fractions (Smith & Ichiyen 1973; Hodouin & Everell 1980).  It is solved exactly, not
by alternating flows and fractions, in the class flows :math:`m_{s,i} = F_s x_{s,i}`:
there the balances are linear, :math:`F_s = \sum_i m_{s,i}` and :math:`x_{s,i} =
m_{s,i}/F_s`, so the feasible set is :math:`m = m_0 + N z` (:math:`N` an orthonormal basis
of the null space of the constraints) and :math:`z` is found without constraints by
Gauss-Newton steps (:func:`~tromplab.circuit.problem.gauss_newton`; the same bits in every run).  Flows
given with a standard deviation of 0 (and the basis of 100 on the first feed when no flow
is measured) join the linear constraints.

Uncertainty is linearised at the solution (Kuehn & Davidson 1961; Hodouin & Everell
1980): with :math:`J` the weighted Jacobian of the measurements in :math:`z`,
:math:`\mathrm{cov}(z) = (J^T J)^{-1}`, :math:`\mathrm{cov}(m) = N\,\mathrm{cov}(z) N^T`,
and every reconciled quantity (flows, shares, partition numbers) gets its standard deviation
by the delta method.  Adjustments :math:`e = y - \hat y` have :math:`\mathrm{cov}(e) =
\Sigma - \mathrm{cov}(\hat y)`; the standardised adjustment :math:`e_j /
\sqrt{\mathrm{cov}(e)_{jj}}` is the measurement test of Mah & Tamhane (1982).  Because the
shares of a closed analysis share their errors, the gross-error test is the generalised
likelihood ratio of an error in one raw measurement, spread by the closure (Narasimhan &
Mah 1987), which reduces to the standardised adjustment for an independent measurement;
it is compared with the Sidak-corrected normal quantile over the testable measurements.  The global test
compares :math:`S` with the chi-square distribution with as many degrees of freedom as
the redundancy (measurements minus the rank of :math:`J`) (Almasy & Sztano 1975).

References
----------
Almasy, G. A. & Sztano, T. (1975). Checking and correction of measurements on the basis of
linear system model. *Problems of Control and Information Theory* 4, 57-69.

Hodouin, D. & Everell, M. D. (1980). A hierarchical procedure for adjustment and material
balancing of mineral processes data. *International Journal of Mineral Processing* 7(2), 91-116.

Kuehn, D. R. & Davidson, H. (1961). Computer control II. Mathematics of control.
*Chemical Engineering Progress* 57(6), 44-47.

Mah, R. S. H. & Tamhane, A. C. (1982). Detection of gross errors in process data.
*AIChE Journal* 28(5), 828-830.

Narasimhan, S. & Mah, R. S. H. (1987). Generalized likelihood ratio method for gross error
identification. *AIChE Journal* 33(9), 1514-1521.

Smith, H. W. & Ichiyen, N. (1973). Computer adjustment of metallurgical balances.
*CIM Bulletin* 66(737), 97-100.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import pandas as pd

from ..loading.points import TrompPoints
from ..loading.weights import partition_weights, stream_error
from ..options import DEFAULT_ALPHA
from ..results_contract import ResultContract
from ..statistics.distributions import chi2_ppf, chi2_sf, norm_isf
from ..validation import check_probability
from . import plotting
from .adjustments import (
    ADJUSTMENT_COLUMNS,
    EQUIVALENT_CORRELATION,
    MeasurementTests,
    adjustments_frame,
    measurement_names,
    measurement_tests,
    ranked_by_test,
)
from .assays import MIN_ASSAYED_SHARE
from .design import design_table, water_determined_by
from .elimination import nodal_tests, proposal, serial_elimination, without
from .flowsheet import Flowsheet, read_flowsheet
from .linear_algebra import sparse  # scipy.sparse, imported when a large flowsheet first uses it
from .measurements import ErrorModel, Survey, class_name, read_survey
from .path_choice import takes_sparse_path
from .problem import (
    GAUSS_NEWTON_XTOL,
    SPARSE_UNKNOWNS,
    Decomposition,
    Problem,
    SurveyErrors,
    bounded_solution,
    build_problem,
    check_observable,
    check_positive_flows,
    decompose,
    error_model_point,
    gauss_newton_step,
    held_against_multipliers,
    linearised,
    solids_first_start,
    solve,
    starting_point,
    with_errors,
)
from .separators import MIN_FEED_SHARE, PARTITION_COLUMNS, components_table, curve_names, partition_table, plot_partitions
from .worth import results, worth_table

__all__ = ["ADJUSTMENT_COLUMNS", "EQUIVALENT_CORRELATION", "MIN_FEED_SHARE", "PARTITION_COLUMNS", "CircuitBalance", "reconcile"]

#: The error model at the reconciled values has settled when no sd moves by more than this share of
#: itself: tight enough that the reported values are those of the fixed point to about 1e-13, not of
#: the path the rounds took to it (at 1e-6 the last round's stop moved them by 1e-9).
ERROR_MODEL_TOLERANCE = 1e-10
MAX_ERROR_MODEL_ITERATIONS = 50
#: Serial elimination on a large flowsheet (the sparse path) stops after this many steps, said in
#: the summary: each step is a whole reconciliation again (seconds to minutes at that size).
LARGE_ELIMINATION_STEPS = 3
#: The solutions of the rounds before the error model settles stop at this share of ``z`` at most.
EARLY_ROUND_XTOL = 1e-6
DISTRIBUTION_COLUMNS = ["stream", "size_lower", "size_upper", "size", "measured", "measured_sd", "reconciled",
                        "reconciled_sd"]  # fmt: skip


@dataclass(frozen=True)
class CircuitBalance(ResultContract):
    """A reconciled survey: flows and size distributions that close every balance.

    Built by :func:`reconcile`.  Tables (pandas, fixed columns):

    * :meth:`flows_table` - one row per stream: measured and reconciled solids flow, sd;
    * :meth:`distributions_table` - one row per stream and class: measured and reconciled share;
    * :meth:`adjustments_table` - one row per measurement: adjustment, its sd, the
      standardised adjustment and the measurement test;
    * :meth:`gross_errors_table` - the measurements whose measurement test fails;
    * :meth:`partition_table` - per separator and class: partition to the fine product and sd;
    * :meth:`chi_square_table` - the global test;
    * :meth:`degrees_of_freedom_table` - counts of unknowns, constraints and measurements.

    :meth:`to_points` gives the separators' partition curves as
    :class:`~tromplab.loading.points.TrompPoints` with weights, :meth:`points_table` the same
    in the Tromp-points file schema.  :meth:`summary` has one row per stream, :meth:`report`
    is the text ``tromplab circuit`` prints first (and writes as ``summary.txt``).

    Attributes
    ----------
    flowsheet : Flowsheet
        The circuit balanced.
    survey : Survey
        The measurements, with their standard deviations.
    class_flows : numpy.ndarray
        Reconciled solids flow of every stream (rows) and size class (columns).
    covariance : numpy.ndarray
        Covariance of the flattened class flows, then the water flows.
    chi_square : float
        The global test statistic (sum of squared standardised adjustments).
    dof : int
        Its degrees of freedom (the redundancy).
    alpha : float
        Level of the chi-square and measurement tests.
    success, message
        Whether the reconciliation converged, and the solver's message.
    basis : str
        The stream the flows are relative to ("" when flows are measured).
    problem : Problem or None
        The linear constraints and measurements the reconciliation solved.
    measured_y : numpy.ndarray or None
        The measurement vector.
    water_flows : numpy.ndarray or None
        Water flows of the solids streams, then of the water streams (None: water not balanced).
    fitted : numpy.ndarray or None
        The unknowns of the least squares without the bounds at 0.
    at_bound : tuple of int
        Unknowns the bounds hold at 0.
    decomposition : Decomposition, SparseLinearisation or None
        The whitened Jacobian split by the reconciliation's rank decision (on a large flowsheet
        the sparse path's :class:`~tromplab.circuit.sparse_tables.SparseLinearisation`, and
        ``problem`` a :class:`~tromplab.circuit.sparse_solve.SparseProblem`).
    excluded : tuple of str
        The measurements left out on request.
    component_flows : numpy.ndarray or None
        Class flows of every assayed component (components x streams x classes; None: no assay).
    raisable_held : int or None
        A large flowsheet's count of ``held_against_multipliers``, made by its bounds; None on
        the dense path (counted from the multipliers when asked).
    progress : callable or None
        ``progress(done, total, label)`` of the run that made the balance: the serial
        elimination and the design advice report their steps to it when first computed.
    has_size_classes : bool
        False for a survey of flows and per cent solids only.
    held_at_zero : list of tuple
        ``(stream, class index)`` of the class flows held at 0.
    held_against_multipliers : int
        How many of the unknowns held at 0 would lower the sum of squares if raised: on the dense
        path those of a wrong-sign multiplier (the active set holds them for good), on a large
        flowsheet the class flows held with their class and its assays: 0 when the bounds' end is a minimum.
    p_value, chi_square_critical : float
        The chi-square test's p-value and critical value at ``alpha``.
    rejected : bool
        True when the chi-square test rejects the measurements as a whole.
    streams : tuple of str
        The solids streams, in flowsheet order.
    flows, flow_sd : numpy.ndarray
        Reconciled solids flow per stream and its standard deviation.
    shares, share_sd : numpy.ndarray
        Reconciled class shares per stream and class, and their standard deviations.
    balances_water : bool
        True when per cent solids were measured and water is balanced too.
    measurement_test_critical : float
        Critical value of the measurement tests (Sidak-corrected at ``alpha``).
    """

    flowsheet: Flowsheet
    survey: Survey
    class_flows: np.ndarray = field(repr=False)  # streams x classes
    covariance: np.ndarray = field(repr=False)  # of the flattened class flows, then the water flows
    chi_square: float
    dof: int
    alpha: float
    success: bool
    message: str
    basis: str = ""
    problem: Problem | None = field(default=None, repr=False, compare=False)
    measured_y: np.ndarray | None = field(default=None, repr=False, compare=False)
    #: Water flows of the solids streams, then of the water streams (None: water not balanced).
    water_flows: np.ndarray | None = field(default=None, repr=False, compare=False)
    #: The unknowns of the least squares without the bounds at 0 (class flows, then water flows):
    #: the point of the tests and of the covariance (None: the reported values themselves).
    fitted: np.ndarray | None = field(default=None, repr=False, compare=False)
    #: Unknowns (indices into ``fitted``) that the bounds hold at 0 in the reported values.
    at_bound: tuple[int, ...] = field(default=(), repr=False, compare=False)
    #: The whitened Jacobian at ``fitted`` split by the reconciliation's one rank decision.
    decomposition: Decomposition | None = field(default=None, repr=False, compare=False)
    #: The measurements left out on request (``exclude=`` of :func:`reconcile`).
    excluded: tuple[str, ...] = field(default=(), compare=False)
    #: Class flows of every assayed component (components x streams x classes; None: no assay).
    component_flows: np.ndarray | None = field(default=None, repr=False, compare=False)
    #: The large flowsheet's count of :attr:`held_against_multipliers`, made by its bounds
    #: (:func:`tromplab.circuit.sparse_solve.bounded_sparse`); None on the dense path.
    raisable_held: int | None = field(default=None, repr=False, compare=False)
    #: ``progress(done, total, label)`` of the run that made the balance (``reconcile(progress=)``):
    #: the serial elimination and the design advice, computed when first asked for, report to it.
    progress: Callable[[int, int, str], None] | None = field(default=None, repr=False, compare=False)

    @property
    def has_size_classes(self) -> bool:
        """False for a survey of flows and per cent solids only: no distribution, no partition."""
        return self.survey.n_classes > 0

    @property
    def held_at_zero(self) -> list[tuple[str, int]]:
        """``(stream, class index)`` of the class flows held at their bound 0 (class index -1: a
        water flow): the unbounded least squares would have made them negative."""
        S, n = self.class_flows.shape
        names = self.flowsheet.stream_names + tuple(w.name for w in self.flowsheet.water_streams)
        solids_and_water = S * n + len(names) if self.balances_water else S * n  # a component's flow is flagged per curve
        return [(names[k // n], k % n) if k < S * n else (names[k - S * n], -1) for k in self.at_bound if k < solids_and_water]

    @cached_property
    def held_against_multipliers(self) -> int:
        """How many of the flows held at 0 would lower the sum of squares if raised.  On the dense
        path, those whose Lagrange multiplier has the wrong sign: the active set holds them for
        good (each was released once and came back negative).  On a large flowsheet the bounds
        counted them (:attr:`raisable_held`): the class flows that reached 0, emptied their class
        and took its assays out, and that the linearised problem would raise.  0 when the
        bounds' end is a minimum."""
        if not self.at_bound or self.problem is None:
            return 0
        if self.raisable_held is not None:  # a large flowsheet: its bounds counted them
            return self.raisable_held
        return held_against_multipliers(self.problem, self._unknowns, self.at_bound)

    @property
    def _unknowns(self) -> np.ndarray:
        water = self.water_flows if self.water_flows is not None else np.zeros(0)
        components = self.component_flows.ravel() if self.component_flows is not None else np.zeros(0)
        return np.concatenate([self.class_flows.ravel(), water, components])

    @property
    def _test_point(self) -> np.ndarray:
        """The unbounded least-squares solution: the tests' distributions hold there."""
        return self.fitted if self.fitted is not None else self._unknowns

    # --- the global test -------------------------------------------------------------
    @property
    def p_value(self) -> float:
        """Probability of a chi-square at least as large under the error model (NaN without redundancy)."""
        return float(chi2_sf(self.chi_square, self.dof)) if self.dof > 0 else float("nan")

    @property
    def chi_square_critical(self) -> float:
        return float(chi2_ppf(1.0 - self.alpha, self.dof)) if self.dof > 0 else float("nan")

    @property
    def rejected(self) -> bool:
        """True when the chi-square test rejects the error model (or a gross error is present) at ``alpha``."""
        return bool(self.dof > 0 and self.chi_square > self.chi_square_critical)

    def chi_square_table(self) -> pd.DataFrame:
        """``statistic, dof, critical, alpha, p_value, rejected, verdict``."""
        verdict = (
            "no redundancy: nothing to test"
            if self.dof <= 0
            else (
                f"rejected at {self.alpha:g}: the adjustments are larger than the error model allows (a gross error or "
                "standard deviations too small)"
                if self.rejected
                else f"consistent with the error model at {self.alpha:g}"
            )
        )
        return pd.DataFrame(
            [
                {
                    "statistic": self.chi_square,
                    "dof": self.dof,
                    "critical": self.chi_square_critical,
                    "alpha": self.alpha,
                    "p_value": self.p_value,
                    "rejected": self.rejected,
                    "verdict": verdict,
                }
            ]
        )

    # --- reconciled quantities ---------------------------------------------------------
    @property
    def streams(self) -> tuple[str, ...]:
        return self.flowsheet.stream_names

    @property
    def flows(self) -> np.ndarray:
        return self.class_flows.sum(axis=1)

    @property
    def shares(self) -> np.ndarray:
        """Reconciled size distributions, streams x classes (fractions)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.class_flows / self.flows[:, None]

    def _sd(self, gradients: np.ndarray) -> np.ndarray:
        """Delta-method standard deviations of quantities with these gradients in the class flows."""
        k = gradients.shape[1]  # the class flows lead the unknowns: a gradient in them alone is shorter
        if k < SPARSE_UNKNOWNS:
            variance = np.einsum("ij,jk,ik->i", gradients, self.covariance[:k, :k], gradients)
        else:  # a large flowsheet: each gradient touches one or two streams (the three-operand einsum runs no BLAS)
            variance = np.einsum("ij,ij->i", sparse.csr_matrix(gradients) @ self.covariance[:k, :k], gradients)
        return np.sqrt(np.clip(variance, 0.0, None))

    @cached_property
    def flow_sd(self) -> np.ndarray:
        S, n = self.class_flows.shape
        G = np.zeros((S, S * n))
        for s in range(S):
            G[s, s * n : (s + 1) * n] = 1.0
        return self._sd(G)

    @cached_property
    def share_sd(self) -> np.ndarray:
        S, n = self.class_flows.shape
        G = np.zeros((S * n, S * n))
        for s in range(S):
            F, x = self.flows[s], self.shares[s]
            for i in range(n):
                G[s * n + i, s * n : (s + 1) * n] = -x[i] / F
                G[s * n + i, s * n + i] += 1.0 / F
        return self._sd(G).reshape(S, n)

    def flows_table(self) -> pd.DataFrame:
        """``stream, from, to, product, measured, measured_sd, reconciled, reconciled_sd, adjustment``."""
        measured = self.survey.flows.set_index("stream")
        rows = []
        for s, stream in enumerate(self.flowsheet.streams):
            given = stream.name in measured.index
            value = float(measured.loc[stream.name, "value"]) if given else np.nan
            rows.append(
                {
                    "stream": stream.name,
                    "from": stream.source,
                    "to": stream.target,
                    "product": stream.product,
                    "measured": value,
                    "measured_sd": float(measured.loc[stream.name, "sd"]) if given else np.nan,
                    "reconciled": self.flows[s],
                    "reconciled_sd": self.flow_sd[s],
                    "adjustment": self.flows[s] - value,
                }
            )
        return pd.DataFrame(rows)

    @property
    def balances_water(self) -> bool:
        """True when per cent solids were measured: the water flows are then unknowns balanced at every node."""
        return self.water_flows is not None

    def water_table(self) -> pd.DataFrame:
        """One row per stream (water streams last), empty unless :attr:`balances_water`.

        Columns ``stream, from, to, product, measured_pct_solids, measured_sd,
        pct_solids, pct_solids_sd`` (per cent solids by mass, 0-100; NaN for a water stream),
        ``water_flow, water_flow_sd`` (in the unit of the solids flows), ``determined`` and
        ``note``: a water flow the survey cannot determine (e.g. two additions at one node,
        or a feed whose per cent solids was not measured) is NaN, said in words.
        """
        columns = ["stream", "from", "to", "product", "measured_pct_solids", "measured_sd", "pct_solids",
                   "pct_solids_sd", "water_flow", "water_flow_sd", "determined", "note"]  # fmt: skip
        if not self.balances_water:
            return pd.DataFrame(columns=columns)
        S, n = self.class_flows.shape
        streams = self.flowsheet.streams + self.flowsheet.water_streams
        k = self.water_flows.size
        water_gradient = np.hstack([np.zeros((k, S * n)), np.eye(k)])
        pct_gradient = np.zeros((S, S * n + k))
        total = self.flows + self.water_flows[:S]
        for s in range(S):
            pct_gradient[s, s * n : (s + 1) * n] = 100.0 * self.water_flows[s] / total[s] ** 2
            pct_gradient[s, S * n + s] = -100.0 * self.flows[s] / total[s] ** 2
        decomposition = self.decomposition or decompose(self.problem, self.problem.N.T @ (self._test_point - self.problem.m0))
        unseen = self.problem.N @ decomposition.unseen
        tolerance = 1e-7 * max(1.0, float(np.abs(self._test_point).max()))
        water_determined = np.abs(water_gradient @ unseen).max(axis=1, initial=0.0) < tolerance
        pct_determined = np.abs(pct_gradient @ unseen).max(axis=1, initial=0.0) < tolerance
        water_sd, pct_sd = self._sd(water_gradient), self._sd(pct_gradient)
        helpers = water_determined_by(self, water_gradient, tolerance) if not water_determined.all() else [[]] * k
        pct = 100.0 * self.flows / total
        measured = self.survey.pct_solids.set_index("stream")
        rows = []
        for j, stream in enumerate(streams):
            solids = j < S
            given = solids and stream.name in measured.index
            determined = bool(water_determined[j])
            rows.append({
                "stream": stream.name, "from": stream.source, "to": stream.target, "product": stream.product,
                "measured_pct_solids": float(measured.loc[stream.name, "value"]) if given else np.nan,
                "measured_sd": float(measured.loc[stream.name, "sd"]) if given else np.nan,
                "pct_solids": pct[j] if solids and pct_determined[j] else np.nan,
                "pct_solids_sd": pct_sd[j] if solids and pct_determined[j] else np.nan,
                "water_flow": self.water_flows[j] if determined else np.nan,
                "water_flow_sd": water_sd[j] if determined else np.nan,
                "determined": determined,
                "note": "" if determined else _undetermined_water_note(helpers[j]),
            })  # fmt: skip
        return pd.DataFrame(rows, columns=columns)

    def distributions_table(self) -> pd.DataFrame:
        """``stream, size_lower, size_upper, size, measured, measured_sd, reconciled, reconciled_sd``
        (shares as fractions; measured NaN where the class was not measured in that stream)."""
        classes, shares = self.survey.classes, self.survey.shares
        S, n = len(self.streams), len(classes)
        value, sd = np.full((S, n), np.nan), np.full((S, n), np.nan)
        index = self.flowsheet.stream_index
        where = (shares["stream"].map(index).to_numpy(int), shares["class_index"].to_numpy(int))
        value[where], sd[where] = shares["value"].to_numpy(float), shares["sd"].to_numpy(float)
        return pd.DataFrame({
            "stream": np.repeat(np.array(self.streams, dtype=object), n),
            **{column: np.tile(classes[column].to_numpy(), S) for column in ("size_lower", "size_upper", "size")},
            "measured": value.ravel(), "measured_sd": sd.ravel(), "reconciled": self.shares[:, :n].ravel(),
            "reconciled_sd": self.share_sd[:, :n].ravel(),  # a survey without size classes: no row
        }, columns=DISTRIBUTION_COLUMNS)  # fmt: skip

    @cached_property
    def _adjustments(self) -> pd.DataFrame:
        return adjustments_frame(self)

    @cached_property
    def _measurement_names(self) -> np.ndarray:
        # the adjustments table's first column without its tests: a design of a flowsheet
        # without a survey computes no test, and imports no scipy.special for one
        return np.array(measurement_names(self), dtype=object)

    @cached_property
    def _measurement_tests(self) -> MeasurementTests:
        return measurement_tests(self)

    @property
    def measurement_test_critical(self) -> float:
        """Critical absolute value of the measurement test: the normal quantile at the
        Sidak-corrected level ``1 - (1 - alpha) ** (1 / p)`` over the p testable measurements."""
        p = int(self._measurement_tests.testable.sum())
        if p == 0:
            return float("nan")
        level = 1.0 - (1.0 - self.alpha) ** (1.0 / p)
        return float(norm_isf(level / 2.0))

    def adjustments_table(self) -> pd.DataFrame:
        """One row per measurement (flows given with sd 0 are constraints, not listed).

        Columns ``measurement, stream, class_index, size_lower, size_upper, row`` (file row),
        ``measured, sd, reconciled, reconciled_sd, adjustment`` (reconciled - measured),
        ``adjustment_sd``, ``standardised`` (adjustment / adjustment_sd; NaN for a measurement
        without redundancy, which the balances cannot check), ``gross_error`` and
        ``gross_error_sd`` (the error in the raw measurement, before the closure of its
        analysis, that best explains all adjustments: measured - true), ``measurement_test``
        (gross_error / its sd, with the sign of the adjustment: the most powerful test of a
        gross error there, equal to ``standardised`` when the measurement's error is
        independent of the others'), ``p_value`` (two-sided normal), ``suspect`` (absolute
        ``measurement_test`` above :attr:`measurement_test_critical`) and
        ``indistinguishable_from`` (the measurements whose tests are correlated with this one
        beyond :data:`~tromplab.circuit.adjustments.EQUIVALENT_CORRELATION`: a gross error in any of them looks the same,
        e.g. the only two flowmeters of a loop, or one class of the three streams of a
        separator whose split is free).
        """
        return self._adjustments.copy()

    def gross_errors_table(self) -> pd.DataFrame:
        """The measurements suspected of gross error, largest absolute measurement test first
        (tests equal to :data:`~tromplab.circuit.adjustments.TEST_TIE` by file row); ``rank`` 1
        is the first candidate."""
        table = self._adjustments
        suspects = table.loc[table["suspect"].astype(bool)].copy()  # an empty object column would select columns
        suspects = ranked_by_test(suspects)
        suspects.insert(0, "rank", np.arange(1, len(suspects) + 1))
        return suspects.reset_index(drop=True)

    @cached_property
    def _elimination(self) -> pd.DataFrame:
        # on a large flowsheet each step is a whole reconciliation again: a few steps at most
        large = getattr(self.problem, "is_sparse", False)
        return serial_elimination(
            self, _reconciled_for_elimination, progress=self.progress, max_steps=LARGE_ELIMINATION_STEPS if large else None
        )

    @property
    def _elimination_cut_short(self) -> bool:
        """True when the serial elimination of a large flowsheet stopped at :data:`LARGE_ELIMINATION_STEPS`
        with redundancy left and the global test still rejecting."""
        table = self._elimination
        steps = len(table) - 1
        return bool(getattr(self.problem, "is_sparse", False) and steps == LARGE_ELIMINATION_STEPS < self.dof
                    and table["p_value"].iloc[-1] <= self.alpha)  # fmt: skip

    def elimination_table(self) -> pd.DataFrame:
        """Serial elimination with compensation (:func:`~tromplab.circuit.elimination.serial_elimination`):
        row 0 the survey as reconciled, then one row per measurement compensated, with the
        global test after the step.  A proposal: nothing in this balance is changed."""
        return self._elimination.copy()

    def nodal_tests_table(self) -> pd.DataFrame:
        """The nodal test of every node and class balance in the raw data (:func:`~tromplab.circuit.elimination.nodal_tests`)."""
        return nodal_tests(self)

    def worth_table(self) -> pd.DataFrame:
        """What each measurement is worth (:func:`~tromplab.circuit.worth.worth_table`): its
        solvability class and redundancy, and its influence on every separator's fine yield,
        partition per class and circulating load."""
        return self._worth.copy()

    @cached_property
    def _worth(self) -> pd.DataFrame:
        return worth_table(self)

    @cached_property
    def _design(self) -> pd.DataFrame:
        return design_table(self, progress=self.progress)

    def design_table(self) -> pd.DataFrame:
        """Survey design advice (:func:`~tromplab.circuit.design.design_table`): the measurements
        one could add, ranked by how much they would lower the sd of each separator's partition
        at its cut and of each circulating load, predicted from the linearised covariance."""
        return self._design.copy()

    def largest_adjustments(self, n: int = 5) -> pd.DataFrame:
        """The ``n`` measurements with the largest absolute measurement tests (suspect or not)."""
        table = self._adjustments.dropna(subset=["measurement_test"])
        return ranked_by_test(table).head(n).reset_index(drop=True)

    # --- separators -----------------------------------------------------------------------
    @cached_property
    def _results(self) -> list:
        return results(self)

    @cached_property
    def _partition(self) -> pd.DataFrame:
        return partition_table(self)

    def partition_table(self) -> pd.DataFrame:
        """Partition to the fine product of every separator and class, of the whole solids and of
        each assayed component (:func:`~tromplab.circuit.separators.partition_table`)."""
        return self._partition.copy()

    def components_table(self) -> pd.DataFrame:
        """Each assayed component at each separator: grades, fine yield and recovery with sds
        (:func:`~tromplab.circuit.separators.components_table`; empty without assays)."""
        return components_table(self)

    def points_table(self, *, unit_in_names: bool = True, weighting: str = "error-model") -> pd.DataFrame:
        """The separators' partition curves in the Tromp-points schema that ``tromplab fit`` reads.

        Columns ``experiment, size[_unit], partition_fine, weight, used, size_lower[_unit],
        size_upper[_unit], feed_share, flag, component``.  One curve per separator and
        component: ``experiment`` is the separator's node for the whole solids and
        ``NODE:COMPONENT`` for an assayed component.  ``weight`` follows ``weighting``
        (:func:`tromplab.loading.weights.partition_weights`, the function of the lab path): by
        default the inverse variance of each class's partition under the error model of the
        separator's products' size analyses at the shares the partition implies, with a floor
        relative to the feed share, scaled to a mean of 1 per curve over the used classes (a
        component's curve is weighted with the same model).
        """
        table = self.partition_table()
        table["node"] = table["experiment"]
        table["experiment"] = curve_names(table)
        unit = self.survey.size_unit
        suffix = f"_{unit}" if unit and unit_in_names else ""
        rows = []
        products = {node.name: (node.fine, node.coarse) for node in self.flowsheet.separators}
        errors = {}  # the error model of each product's analysis, shared by the curves of its separator
        for _curve, part in table.groupby("experiment", sort=False):
            used = part["used"].to_numpy()
            for stream in products[part["node"].iloc[0]]:
                if stream not in errors:
                    errors[stream] = stream_error(self.survey.shares, stream)
            fine, coarse = (errors[stream] for stream in products[part["node"].iloc[0]])
            weight = partition_weights(weighting, part["partition_fine"], part["feed_share"], part["fine_yield"].iloc[0],
                                       used, fine_error=fine, coarse_error=coarse)  # fmt: skip
            weight = np.where(used, 1.0, np.nan) if weight is None else weight
            rows.append(
                pd.DataFrame(
                    {
                        "experiment": part["experiment"].to_numpy(),
                        f"size{suffix}": part["size"].to_numpy(),
                        "partition_fine": np.where(used, part["partition_fine"].to_numpy(), np.nan),
                        "weight": np.where(used & np.isfinite(weight), weight, np.nan),
                        "used": np.where(used, "yes", "no"),
                        f"size_lower{suffix}": part["size_lower"].to_numpy(),
                        f"size_upper{suffix}": part["size_upper"].to_numpy(),
                        "feed_share": part["feed_share"].to_numpy(),
                        "flag": part["flag"].to_numpy(),
                        "component": part["component"].to_numpy(),
                    }
                )
            )
        if not rows:
            return pd.DataFrame(columns=["experiment", f"size{suffix}", "partition_fine", "weight", "used", "component"])
        return pd.concat(rows, ignore_index=True)

    def to_points(self, *, weighting: str = "error-model") -> list[TrompPoints]:
        """One :class:`~tromplab.loading.points.TrompPoints` per separator and component
        (experiment = node name, ``NODE:COMPONENT`` for an assayed component), the used classes
        only, weighted as :meth:`points_table` says."""
        table = self.points_table(unit_in_names=False, weighting=weighting)
        points = []
        for name, part in table.groupby("experiment", sort=False):
            part = part[part["used"] == "yes"]
            points.append(
                TrompPoints(
                    experiment=str(name),
                    size=part["size"].to_numpy(),
                    partition_fine=part["partition_fine"].to_numpy(),
                    weight=part["weight"].to_numpy(),
                    source=f"{self.survey.source} (reconciled)",
                    size_unit=self.survey.size_unit,
                )
            )
        return points

    # --- counts ---------------------------------------------------------------------------
    def degrees_of_freedom_table(self) -> pd.DataFrame:
        """``quantity, count`` of the unknowns, the constraints and the measurements."""
        problem = self.problem
        S, n = self.class_flows.shape
        free = (problem.free if getattr(problem, "is_sparse", False) else problem.N.shape[1]) if problem is not None else 0
        measurements = int(problem.y.size) if problem is not None else 0
        rows = [
            ("streams", S),
            ("nodes", len(self.flowsheet.nodes)),
            ("size classes", n),
            ("unknown class flows (streams x classes)", S * n),
            *([("unknown water flows (streams and water streams)", self.water_flows.size)] if self.balances_water else []),
            *(
                [("unknown component class flows (components x streams x classes)", self.component_flows.size)]
                if self.component_flows is not None
                else []
            ),  # fmt: skip
            ("independent linear constraints (balances, fixed flows, basis)", self._unknowns.size - free),
            ("free unknowns", free),
            ("measurements with a standard deviation", measurements),
            ("redundancy (degrees of freedom of the chi-square)", self.dof),
            (
                "flow degrees of freedom of the flowsheet (streams - independent solids balances)",
                self.flowsheet.flow_degrees_of_freedom,
            ),
        ]
        return pd.DataFrame(rows, columns=["quantity", "count"])

    def summary(self) -> pd.DataFrame:
        """One row per stream: measured and reconciled solids flow and its sd (:meth:`flows_table`)."""
        return self.flows_table()[["stream", "measured", "reconciled", "reconciled_sd"]]

    def to_frame(self) -> pd.DataFrame:
        """The main table, ``flows.csv`` (:meth:`flows_table`)."""
        return self.flows_table()

    def _result_context(self) -> str:
        return f"Circuit survey {self.survey.source}: {self.flowsheet.describe()}"

    def save(self, directory, *, figures: bool = True) -> dict:
        """Write what ``tromplab circuit FLOWSHEET MEASUREMENTS -o DIRECTORY`` writes (without
        ``--fit``), all or nothing (:mod:`tromplab.circuit.outputs`).  Returns ``{file name: path}``."""
        from ..output.outputs import replace_folder
        from .outputs import balance_outputs

        return replace_folder(balance_outputs(self, figures=figures), directory)

    def report(self) -> str:
        """A few lines: what was balanced, the chi-square test and the gross-error candidates."""
        return self._report

    @cached_property
    def _report(self) -> str:
        """The text of :meth:`report`, made once (``summary.txt`` and the console print it)."""
        lines = [
            self._result_context(),
            f"{self.problem.y.size if self.problem else 0} measurements, redundancy {self.dof}"
            + (f"; flows relative to {self.basis}" if self.basis else ""),
        ]
        lines += self._survey_notes()
        if self.excluded:
            lines.append(f"left out on request (exclude): {', '.join(self.excluded)}")
        if self.balances_water:
            water = self.water_table()
            free = water.loc[~water["determined"], "stream"].tolist()
            lines.append(
                f"water balanced at every node from the per cent solids of {len(self.survey.pct_solids)} stream(s)"
                + (f"; water flow not determined for {', '.join(free)}" if free else "")
            )
        chi = self.chi_square_table().iloc[0]
        if self.dof > 0:
            lines.append(
                f"chi-square {chi.statistic:.3g} on {self.dof} dof (critical {chi.critical:.3g} at {self.alpha:g}, "
                f"p = {chi.p_value:.3g}): {chi.verdict}"
            )
        suspects = self.gross_errors_table()
        if len(suspects):
            listed = "; ".join(
                f"{r.measurement} (test {r.measurement_test:+.2f}, gross error {r.gross_error:+.3g})"
                for r in suspects.head(5).itertuples()
            )
            lines.append(f"suspected gross errors (|measurement test| > {self.measurement_test_critical:.2f}): {listed}")
        design = self._design
        if len(design):
            top = design.iloc[0]
            lines.append(
                f"the measurement that would help most: {top.measurement} of {top.stream} (sd of {top.quantity} "
                f"{top.sd_before:.3g} -> {top.sd_after:.3g}, predicted; design.csv ranks them all)"
            )
        if self.rejected:
            words = proposal(self._elimination, self.alpha)
            lines.append(words or "serial elimination finds no testable measurement to compensate")
            if self._elimination_cut_short:
                lines.append(f"serial elimination stopped after {LARGE_ELIMINATION_STEPS} steps: on a flowsheet this large "
                             "each step reconciles the survey again; exclude the measurements named and run again to go on")  # fmt: skip
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.report()

    def _survey_notes(self) -> list[str]:
        """The summary's lines on what the survey lacks: size analyses, blank values, nothing to adjust, bounds."""
        classes = self.survey.classes
        lines = []
        if not self.has_size_classes:
            lines.append("no size analysis: flows and water only (no distribution, no partition curve)")
        blank = self.survey.unmeasured
        if len(blank):
            listed = "; ".join(
                f"{r.stream} class {class_name(classes, int(r.class_index))} (row {r.row})" for r in blank.head(8).itertuples()
            )
            more = f" and {len(blank) - 8} more" if len(blank) > 8 else ""
            lines.append(f"not measured (blank or NaN value in the table): {listed}{more}")
        if self.problem is not None and self.problem.y.size == 0:
            lines.append("every measurement is exact (standard deviation 0): nothing to adjust, nothing to test")
        lines += _assay_notes(self.survey)
        held = self.held_at_zero
        if held:
            listed = "; ".join(f"{stream} {'water' if i < 0 else 'class ' + class_name(classes, i)}" for stream, i in held[:8])
            lines.append(
                f"held at 0 (the least squares would make them negative; the tests and sds are those without the bound): {listed}"
            )
        if self.held_against_multipliers:
            why = (
                "each reached 0, emptied its class and took the class's assays out of the least squares"
                if self.raisable_held is not None
                else "their multipliers have the wrong sign; each was released once and came back negative, and the "
                "bounds' active set then holds it"
            )
            lines.append(
                f"{self.held_against_multipliers} of the flows held at 0 would lower the sum of squares if raised ({why}): "
                "the balance is not shown to be the least-squares minimum under the bounds"
            )
        if not self.success:
            lines.append(f"not converged: {self.message}")
        return lines

    # --- figures --------------------------------------------------------------------------
    def plot(self, kind: str = "distributions", ax=None):
        """``"distributions"``: reconciled against measured distributions per stream;
        ``"adjustments"``: standardised adjustments; ``"flowsheet"``: the flowsheet with the
        reconciled flows; ``"partition"``: the partition curves per separator and component.  Returns the Axes (or the array of Axes for distributions)."""
        figures = {
            "distributions": plotting.plot_distributions,
            "adjustments": plotting.plot_adjustments,
            "flowsheet": plotting.plot_flowsheet,
            "partition": plot_partitions,
        }
        if kind not in figures:
            raise ValueError(f"unknown kind {kind!r}; choose one of {', '.join(figures)}")
        return figures[kind](self, ax=ax)


def _errors_at_reconciled(
    flowsheet: Flowsheet, survey: Survey, problem: Problem, z: np.ndarray, progress=None, *, single_steps: bool = False
):
    """Evaluate the error model at the reconciled shares and flows and reconcile again, until
    no standard deviation moves by more than :data:`ERROR_MODEL_TOLERANCE` of itself.

    The rounds evaluate the error model on arrays (:class:`~tromplab.circuit.problem.SurveyErrors`)
    and change only the measurements' covariance of the problem; the survey's tables are made
    once, at the last point.  With ``single_steps``, each round before the one that settles the
    sds takes one Gauss-Newton step instead of a solution to a thousandth of their move (the
    solution and the error model then converge together; the same fixed point, reached by
    another path).  Returns ``(survey, problem, z, success, message)`` of the last
    reconciliation; the survey holds the standard deviations it used.
    """
    single_steps = single_steps and problem.m0.size < SPARSE_UNKNOWNS and bool(problem.N.shape[1] and problem.y.size)

    errors = SurveyErrors(survey, flowsheet.stream_index)
    before = errors.sd
    success, message = True, ""
    for round_number in range(2, MAX_ERROR_MODEL_ITERATIONS + 2):
        if progress is not None:
            progress(0, 1, f"reconciliation: round {round_number}")
        v = problem.m0 + problem.N @ z
        point = error_model_point(problem, v)
        after, share_at = errors.at(*point)
        if np.array_equal(after > 0, before > 0):
            problem = with_errors(problem, errors, after, share_at)
        else:  # an sd reached 0 (or left it): the measurement joins (or leaves) the constraints
            problem, _ = build_problem(flowsheet, survey.with_errors_at(*point[:2], flowsheet.stream_index, point[2]))
        moving = errors.movable
        moved = float(np.max(np.abs(after - before)[moving] / np.maximum(before[moving], 1e-300), initial=0.0))
        before = after
        if single_steps and moved > ERROR_MODEL_TOLERANCE:
            z = gauss_newton_step(problem, z)
            continue
        # while the sds still move, a solution to a thousandth of their move is enough (the next
        # round moves it again); the round that settles them solves to the solver's full tolerance
        z, success, message = solve(problem, v, xtol=min(EARLY_ROUND_XTOL, max(GAUSS_NEWTON_XTOL, 1e-3 * moved)))
        if moved <= ERROR_MODEL_TOLERANCE:
            break
    else:
        success, message = (
            False,
            f"the error model at the reconciled values did not settle in {MAX_ERROR_MODEL_ITERATIONS} rounds",
        )
    survey = survey.with_errors_at(*point[:2], flowsheet.stream_index, point[2])
    return survey, problem, z, success, message


def _assay_notes(survey: Survey) -> list[str]:
    """The summary's lines on the per-class assays: the components balanced, the assays set aside."""
    if not survey.components:
        return []
    lines = [f"per-class assays of {', '.join(survey.components)}: balanced per class at separators and junctions and in "
             "total at mills (partition curve per component in partition.csv, grades and recoveries in components.csv)"]  # fmt: skip
    scarce = survey.assays_set_aside
    if len(scarce):
        listed = "; ".join(f"{r.stream} {r.component} class {class_name(survey.classes, int(r.class_index))} (row {r.row})"
                           for r in scarce.head(6).itertuples())  # fmt: skip
        more = f" and {len(scarce) - 6} more" if len(scarce) > 6 else ""
        lines.append(f"assays set aside (the class holds less than {100 * MIN_ASSAYED_SHARE:g} % of its stream, too little "
                     f"material to assay): {listed}{more}")  # fmt: skip
    return lines


def _undetermined_water_note(streams: list[str]) -> str:
    if streams:
        return f"not determined by the survey: the water balances leave it free; the per cent solids of {' or '.join(streams)} would determine it"
    return "not determined by the survey: the water balances leave it free, and no single per cent solids more would determine it"


def reconcile(
    flowsheet,
    measurements,
    *,
    errors: ErrorModel | None = None,
    alpha: float = DEFAULT_ALPHA,
    size_unit: str | None = None,
    exclude=(),
    progress: Callable[[int, int, str], None] | None = None,
) -> CircuitBalance:
    """Reconcile a circuit survey: flows and size distributions that close every node balance.

    Parameters
    ----------
    flowsheet : Flowsheet, path or DataFrame
        The flowsheet (:func:`~tromplab.circuit.flowsheet.read_flowsheet` schema).
    measurements : Survey, path or DataFrame
        The measurement table (:func:`~tromplab.circuit.measurements.read_survey` schema).
    errors : ErrorModel, optional
        Standard deviations where the table gives none (default: 5 % relative, 0.1
        percentage point absolute for shares; 5 % for flows).
    alpha : float
        Significance level of the chi-square test and of the measurement test.
    size_unit : str, optional
        Unit of the sizes when the table's size columns carry none.
    exclude : iterable of str or str, optional
        Measurements left out: ``"STREAM"`` (all of the stream's), ``"STREAM:flow"``,
        ``"STREAM:pct_solids"`` or ``"STREAM:CLASS"`` (``"cyclone_feed:-150+75"``); a
        comma-separated string is split.  What :meth:`CircuitBalance.elimination_table`
        proposes, acted on.
    progress : callable, optional
        ``progress(done, total, label)`` at each stage: ``"reconciliation: round k"`` (the
        rounds of the error model at the reconciled values), then, when the balance's tables
        are first asked for, ``"elimination: step k"`` and ``"design: candidate i of n"``
        (kept by the balance).  The command line draws it as a bar on a terminal.

    Returns
    -------
    CircuitBalance

    Raises
    ------
    InputError
        Bad flowsheet or measurements (naming file, row, node or stream), flows fixed
        inconsistently, or a flow or distribution the survey cannot determine
        (unobservable: naming the streams; more measurements are needed there).

    Examples
    --------
    >>> sheet = pd.DataFrame({"stream": ["feed", "fine", "coarse"], "from": ["", "cyclone", "cyclone"],
    ...                       "to": ["cyclone", "", ""], "product": ["", "fine", "coarse"]})
    >>> feed, fine, coarse = [0.2, 0.3, 0.5], [0.05, 0.25, 0.7], [0.35, 0.35, 0.3]
    >>> table = pd.DataFrame({"stream": ["feed"] * 3 + ["fine"] * 3 + ["coarse"] * 3,
    ...                       "size_lower_um": [100, 50, 0] * 3, "size_upper_um": [200, 100, 50] * 3,
    ...                       "retained_frac": feed + fine + coarse})
    >>> balance = reconcile(sheet, table)
    >>> round(float(balance.flows[1]), 6), balance.dof   # the fine product per 100 of the feed; the redundancy
    (50.0, 1)
    """
    alpha = check_probability(alpha, "alpha")
    if not isinstance(flowsheet, Flowsheet):
        flowsheet = read_flowsheet(flowsheet)
    survey = (
        measurements
        if isinstance(measurements, Survey)
        else read_survey(measurements, flowsheet, errors=errors, size_unit=size_unit)
    )
    survey, excluded = _without_excluded(survey, flowsheet, exclude)
    return _balance(flowsheet, survey, alpha, excluded, progress)


def _without_excluded(survey: Survey, flowsheet: Flowsheet, exclude) -> tuple[Survey, tuple[str, ...]]:
    """The survey without the measurements ``exclude`` names, and the names as given."""
    entries = exclude.split(",") if isinstance(exclude, str) else exclude or ()
    excluded = tuple(str(entry).strip() for entry in entries if str(entry).strip())
    if excluded:
        names = [class_name(survey.classes, i) for i in range(survey.n_classes)]
        survey = without(survey, excluded, flowsheet.stream_names, names)
    return survey, excluded


def _reconciled_for_elimination(previous: CircuitBalance, survey: Survey) -> CircuitBalance:
    """The compensated ``survey`` of a step of the serial elimination, reconciled as far as the
    steps read it: the global test and the measurement tests.  Started from the solution of the
    step before (``previous``: the same constraints, one measurement moved), the error model's
    rounds by single Gauss-Newton steps, without the active set of the bounds at 0 (the tests
    hold at the unbounded least squares; its flows are those, clipped at 0)."""
    return _balance(previous.flowsheet, survey, previous.alpha, (), bounds=False, warm=previous._test_point)


def _balance(
    flowsheet: Flowsheet,
    survey: Survey,
    alpha: float,
    excluded: tuple[str, ...],
    progress=None,
    *,
    bounds: bool = True,
    warm: np.ndarray | None = None,
) -> CircuitBalance:
    """Reconcile ``survey``: solve, evaluate the error model at the reconciled values, linearise,
    bound at 0 (``bounds``; else the unbounded solution clipped at 0).  ``warm``: the unknowns
    of a reconciliation of a survey like it (observable, the same constraints), to start from."""
    if progress is not None:
        progress(0, 1, "reconciliation: round 1")
    if takes_sparse_path(flowsheet, survey):
        from .sparse_solve import DensePathNeeded

        try:
            return _sparse_balance(flowsheet, survey, alpha, excluded, progress)
        except DensePathNeeded:
            pass  # a direction no measurement sees or dependent constraints: the dense path decides
    problem, basis = build_problem(flowsheet, survey)
    if warm is not None:
        start = warm
    else:
        start = (
            solids_first_start(flowsheet, survey, problem) if problem.n_components else starting_point(flowsheet, survey, problem)
        )
        check_observable(flowsheet, survey, problem, start)
    rounds_follow = survey.evaluated_at == "reconciled"
    z, success, message = solve(problem, start, xtol=EARLY_ROUND_XTOL if rounds_follow else None)
    if rounds_follow:
        survey, problem, z, success, message = _errors_at_reconciled(
            flowsheet, survey, problem, z, progress, single_steps=warm is not None
        )
    fitted = problem.m0 + problem.N @ z
    chi, decomposition, covariance = linearised(problem, z)
    held, v = bounded_solution(problem, fitted) if bounds else ((), np.clip(fitted, 0.0, None))
    if held and not np.all(np.isfinite(v)):
        success, message = False, "the bounds on the flows did not settle (active-set iterations exhausted)"
    S, n = problem.n_streams, problem.n_classes
    check_positive_flows(flowsheet, survey, v[: S * n].reshape(S, n).sum(axis=1))
    water = v[S * n : problem.component_offset]
    return CircuitBalance(flowsheet=flowsheet, survey=survey, class_flows=v[: S * n].reshape(S, n), covariance=covariance,
                          chi_square=chi, dof=int(problem.W.shape[0] - decomposition.rank), alpha=alpha, success=success,
                          message=message, basis=basis, problem=problem, measured_y=problem.y.copy(),
                          water_flows=water if problem.n_water else None, fitted=fitted, at_bound=held,
                          decomposition=decomposition, excluded=excluded,
                          component_flows=v[problem.component_offset :].reshape(-1, S, n) if problem.n_components else None,
                          progress=progress)  # fmt: skip


def _sparse_balance(flowsheet: Flowsheet, survey: Survey, alpha: float, excluded: tuple[str, ...], progress=None):
    """:func:`_balance` of a large flowsheet, through sparse matrices (:mod:`tromplab.circuit.sparse_solve`)."""
    from .sparse_solve import reconcile_sparse

    result = reconcile_sparse(flowsheet, survey, early_xtol=EARLY_ROUND_XTOL, tolerance=ERROR_MODEL_TOLERANCE,
                              max_rounds=MAX_ERROR_MODEL_ITERATIONS, progress=progress)  # fmt: skip
    problem, v = result.problem, result.bounded.v
    S, n = problem.n_streams, problem.n_classes
    check_positive_flows(flowsheet, result.survey, v[: S * n].reshape(S, n).sum(axis=1))
    return CircuitBalance(flowsheet=flowsheet, survey=result.survey, class_flows=v[: S * n].reshape(S, n),
                          covariance=result.linearisation.C, chi_square=result.chi_square,
                          dof=int(problem.W.shape[0] - result.linearisation.rank), alpha=alpha, success=result.success,
                          message=result.message, basis=result.basis, problem=problem, measured_y=problem.y.copy(),
                          water_flows=v[S * n : problem.component_offset] if problem.n_water else None, fitted=result.fitted,
                          at_bound=result.bounded.held, decomposition=result.linearisation, excluded=excluded,
                          raisable_held=result.bounded.raisable,
                          component_flows=v[problem.component_offset :].reshape(-1, S, n) if problem.n_components else None,
                          progress=progress)  # fmt: skip
