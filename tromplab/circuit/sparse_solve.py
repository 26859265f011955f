r"""Large flowsheets: the reconciliation in sparse matrices, without a null-space basis.

The dense path (:mod:`tromplab.circuit.problem`) writes the feasible set as :math:`m = m_0 + N
z` with :math:`N` a dense orthonormal basis of the null space of the constraints :math:`A`.  A
plant of thirty nodes with four minerals assayed on every stream has 4,100 unknowns and 2,050
free ones: :math:`N` alone is 67 MB, its SVD 9 s, and every Gauss-Newton step and every table
multiplies through it.  Here the unknowns stay the class flows themselves and the constraints
stay rows of a sparse matrix.  Each Gauss-Newton step solves the equality-constrained linear
least squares by its augmented (KKT) system

.. math::
   \begin{pmatrix} I & J D^{-1} & 0 \\ D^{-1} J^T & 0 & D^{-1} A^T \\ 0 & A D^{-1} & 0
   \end{pmatrix}
   \begin{pmatrix} s \\ D\,\delta \\ \mu \end{pmatrix} =
   \begin{pmatrix} -\rho \\ 0 \\ 0 \end{pmatrix}

(:math:`J` the whitened Jacobian, :math:`\rho` the whitened residuals, :math:`D` the column
norms of :math:`J`: the scaling of the dense path's steps), by one sparse LU
(``scipy.sparse.linalg.splu``); the augmented form keeps the condition of :math:`J`, where the
normal equations :math:`J^T J` would square it.  The covariance of the unknowns,
:math:`N (N^T J^T J N)^{-1} N^T`, is the upper-left block of the inverse of
:math:`\begin{pmatrix} J^T J & A^T \\ A & 0 \end{pmatrix}` (Bjorck 1996, ch. 5): solves of that
one factor give it, and the delta-method sds, the measurement tests, the worth of each
measurement and the design candidates (Sherman-Morrison-Woodbury) follow from it by sparse
products (:class:`SparseLinearisation`).  The bounds (every flow at 0 or above, every
component's grade of a class at 1 or below) are met by Gauss-Newton steps under all of them at
once, each a convex quadratic programme (:mod:`tromplab.circuit.bounded_qp`), from a start where
the negative flows are held (the first half of the dense path's active set, Lawson & Hanson
1974): :func:`bounded_sparse`.

The path requires every free direction to be seen by a measurement (no water flow left
undetermined: surveys with per cent solids take the dense path) and the constraints to be
independent; when the factor says otherwise (a singular system), :func:`reconcile_sparse`
raises :class:`DensePathNeeded` and the reconciliation takes the dense path, which handles both.

References
----------
Bjorck, A. (1996). *Numerical Methods for Least Squares Problems*. SIAM.

Lawson, C. L. & Hanson, R. J. (1974). *Solving Least Squares Problems*. Prentice-Hall.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np
import pandas as pd

from .problem import (
    BOUND_TOL,
    GAUSS_NEWTON_ITERATIONS,
    GAUSS_NEWTON_ROUNDING,
    GAUSS_NEWTON_XTOL,
    WRONG_SIGN,
    Problem,
    closure_point,
    error_model_point,
    held_outcome,
    linear_constraints,
    measurement_arrays,
    start_components,
    starting_point,
)
from .sparse_factor import AugmentedFactor, DensePathNeeded
from .sparse_tables import SparseLinearisation


def is_sparse(problem) -> bool:
    """Whether ``problem`` is a :class:`SparseProblem` (its tables take this module's linear algebra)."""
    return bool(getattr(problem, "is_sparse", False))


@dataclass(frozen=True)
class SparseProblem(Problem):
    """A :class:`~tromplab.circuit.problem.Problem` whose constraints ``A``, whitening ``W``,
    measurement covariance ``cov`` and raw-error effects ``effects`` are ``scipy.sparse`` CSR
    matrices and which has no null-space basis (``N`` is None, ``m0`` a feasible point).
    ``held`` lists the unknowns fixed at 0 (taken out of the least squares)."""

    free: int = 0  # free unknowns: unknowns - rank of the constraints (- the held ones)
    held: tuple[int, ...] = ()
    is_sparse: ClassVar[bool] = True

    @property
    def variance(self) -> np.ndarray:
        return self.cov.diagonal()

    def jacobian(self, v: np.ndarray):
        """d(prediction)/d(v) as a sparse CSR matrix (the entries of :meth:`Problem.jacobian`)."""
        from scipy import sparse

        n, rows, cols, values = self.n_classes, [], [], []
        flows = self._flows(v)
        j_all = np.arange(self.y.size)
        share, pct, assay = self.kinds == "share", self.kinds == "pct", self.kinds == "assay"
        flow = ~share & ~pct & ~assay
        classes = np.arange(n)[None, :]

        def add(j, k, value):
            rows.append(np.broadcast_to(j, np.shape(k)).ravel())
            cols.append(np.asarray(k).ravel())
            values.append(np.broadcast_to(value, np.shape(k)).ravel())

        j, s = j_all[share], self.stream[share]
        own = s * n + self.klass[share]
        add(j[:, None], s[:, None] * n + classes, (-v[own] / flows[s] ** 2)[:, None])
        add(j, own, 1.0 / flows[s])
        j, s = j_all[pct], self.stream[pct]
        water = self.n_streams * n + s
        total = flows[s] + v[water]
        add(j[:, None], s[:, None] * n + classes, (100.0 * v[water] / total**2)[:, None])
        add(j, water, -100.0 * flows[s] / total**2)
        j, s = j_all[assay], self.stream[assay]
        own = s * n + self.klass[assay]
        component = self.component_index(self.component[assay], s, self.klass[assay])
        add(j, component, 1.0 / v[own])
        add(j, own, -v[component] / v[own] ** 2)
        j, s = j_all[flow], self.stream[flow]
        add(j[:, None], s[:, None] * n + classes, np.ones((1, 1)))
        matrix = sparse.coo_matrix((np.concatenate(values), (np.concatenate(rows), np.concatenate(cols))),
                                   shape=(self.y.size, v.size))  # fmt: skip
        return matrix.tocsr()  # duplicates (a share's own class) summed, as the dense += does

    def _measurements(self, keep: np.ndarray) -> SparseProblem:
        if keep.all():
            return self
        W = self.W[:, np.flatnonzero(keep)]
        W = W[np.flatnonzero(np.asarray(abs(W).sum(axis=1)).ravel() > 0)]
        index = np.flatnonzero(keep)
        return replace(self, kinds=self.kinds[keep], stream=self.stream[keep], klass=self.klass[keep], y=self.y[keep],
                       sd=self.sd[keep], cov=self.cov[index][:, index], W=W, effects=self.effects[index][:, index],
                       component=self.component[keep])  # fmt: skip


# --- the problem ----------------------------------------------------------------------------------


def build_sparse_problem(flowsheet, survey, constraints=None) -> tuple[SparseProblem, str]:
    """The :class:`SparseProblem` of ``survey`` and the basis of its flows ("" when a flow is
    measured); ``constraints``: ``(A, b, basis, free)`` of an earlier build with the same exact
    measurements (the rounds of the error model change only the sds)."""
    S = len(flowsheet.streams)
    n = max(survey.n_classes, 1)
    n_water = S + len(flowsheet.water_streams) if len(survey.pct_solids) else 0
    layout = SparseProblem(n_streams=S, n_classes=n, A=None, b=None, m0=None, N=None, kinds=None, stream=None, klass=None,
                           y=None, sd=None, cov=None, W=None, effects=None, n_water=n_water,
                           n_components=len(survey.components))  # fmt: skip
    A, b, basis, free = constraints if constraints is not None else _constraints(flowsheet, survey, layout)
    measured = measurement_arrays(survey, flowsheet.stream_index)
    shares = survey.shares[survey.shares["sd"] > 0]
    cov, W, effects = _sparse_measurement_covariance(shares, measured["sd"], survey.closed_streams)
    return replace(layout, A=A, b=b, m0=None, free=free, cov=cov, W=W, effects=effects, **measured), basis


def _constraints(flowsheet, survey, layout) -> tuple:
    """``(A, b, basis, free)``: the node balances and the exact measurements as a sparse matrix."""
    from scipy import sparse

    dense, b, basis = linear_constraints(flowsheet, survey, layout)
    A = sparse.csr_matrix(dense)
    return A, b, basis, dense.shape[1] - dense.shape[0]


def _sparse_measurement_covariance(shares: pd.DataFrame, sd: np.ndarray, closed):
    """``(cov, W, effects)`` of :func:`~tromplab.circuit.problem._measurement_covariance` as sparse
    matrices: the blocks of the closed analyses, the diagonal elsewhere."""
    from scipy import sparse

    streams, values = shares["stream"].to_numpy(), closure_point(shares)
    cov, effects, whitening = ([], [], []), ([], [], []), ([], [], [])  # (values, rows, columns) each
    done, pieces = np.zeros(sd.size, dtype=bool), 0

    def put(target, block, rows, columns):
        target[0].append(block.ravel())
        target[1].append(np.repeat(rows, columns.size))
        target[2].append(np.tile(columns, rows.size))

    for stream in closed:
        where = np.flatnonzero(streams == stream)
        if where.size == 0:
            continue
        x = values[where] / values[where].sum()
        P = np.eye(where.size) - np.outer(x, np.ones(where.size))
        block = P @ np.diag(sd[where] ** 2) @ P.T
        put(cov, block, where, where)
        put(effects, P, where, where)
        eigenvalues, vectors = np.linalg.eigh(block)
        keep = eigenvalues > 1e-12 * eigenvalues.max()
        rows = vectors[:, keep].T / np.sqrt(eigenvalues[keep])[:, None]
        put(whitening, rows, pieces + np.arange(rows.shape[0]), where)
        pieces += rows.shape[0]
        done[where] = True
    single = np.flatnonzero(~done)
    for target, diagonal in ((cov, sd[single] ** 2), (effects, np.ones(single.size))):
        target[0].append(diagonal)
        target[1].append(single)
        target[2].append(single)
    whitening[0].append(1.0 / sd[single])
    whitening[1].append(pieces + np.arange(single.size))
    whitening[2].append(single)
    pieces += single.size

    def matrix(parts, rows):
        return sparse.csr_matrix((np.concatenate(parts[0]), (np.concatenate(parts[1]), np.concatenate(parts[2]))),
                                 shape=(rows, sd.size))  # fmt: skip

    return matrix(cov, sd.size), matrix(whitening, pieces), matrix(effects, sd.size)


# --- the least squares ------------------------------------------------------------------------


def _whitened(problem: SparseProblem, v: np.ndarray):
    residual = problem.W @ (problem.predict(v) - problem.y)
    return residual


def projected(A, b: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``v`` moved orthogonally onto ``A v = b`` (``A`` of full row rank): the dense path's
    ``lstsq`` correction, by one sparse LU of :math:`A A^T`."""
    from scipy.sparse import linalg as sparse_linalg

    if not A.shape[0]:
        return v
    try:
        lu = sparse_linalg.splu((A @ A.T).tocsc())
    except RuntimeError as error:
        raise DensePathNeeded(str(error)) from None
    correction = A.T @ lu.solve(A @ v - b)
    moved = v - correction
    if not np.all(np.isfinite(moved)) or np.linalg.norm(A @ moved - b) > 1e-8 * max(1.0, np.linalg.norm(b)):
        raise DensePathNeeded("dependent constraints")
    return moved


def gauss_newton_sparse(problem: SparseProblem, v0: np.ndarray, xtol: float = GAUSS_NEWTON_XTOL, free=None, near=None):
    """The weighted least squares from the feasible ``v0`` by Gauss-Newton steps through the
    augmented system, shortened by halves until the sum of squares falls (the rules of
    :func:`~tromplab.circuit.problem.gauss_newton`).  ``free``: the unknowns that move (default:
    all).  Returns ``(v, success, message, factor)``, ``factor`` the last :class:`AugmentedFactor`.
    Each step after the first (and the first, given the factor ``near`` of an earlier solve of the
    same constraints) solves through the last LU, refined (:meth:`AugmentedFactor._refined`):
    the Jacobian moves little from one step to the next, and an LU costs as much as a dozen solves."""
    free = np.arange(v0.size) if free is None else free
    A = free_constraints(problem, free)[0]
    v = v0.copy()
    residual = _whitened(problem, v)
    cost, moved, factor = float(residual @ residual), np.inf, near
    for _ in range(GAUSS_NEWTON_ITERATIONS):
        factor = AugmentedFactor(problem.W @ problem.jacobian(v)[:, free], A, near=factor)
        step = np.zeros(v.size)
        step[free] = factor.step(residual)
        size = float(np.linalg.norm(step))
        if size <= xtol * (float(np.linalg.norm(v)) + xtol):
            return v, True, "Gauss-Newton converged", factor
        length = 1.0
        while True:
            trial = v + length * step
            trial_residual = _whitened(problem, trial)
            trial_cost = float(trial_residual @ trial_residual)
            if trial_cost <= cost or (trial_cost <= cost * (1.0 + GAUSS_NEWTON_ROUNDING) and length * size < moved):
                break
            length /= 2.0
            if length < 1e-12:
                return v, True, "Gauss-Newton converged (no step lowers the sum of squares)", factor
        v, residual, cost, moved = trial, trial_residual, trial_cost, length * size
    return v, False, f"Gauss-Newton did not converge in {GAUSS_NEWTON_ITERATIONS} steps", factor


def solve_sparse(problem: SparseProblem, start: np.ndarray, xtol: float | None = None, free=None, near=None):
    """:func:`~tromplab.circuit.problem.solve` of the sparse path: ``start`` projected onto the
    constraints (the held unknowns at 0), then :func:`gauss_newton_sparse` (``near``: the factor
    of an earlier solve, reused where it fits).  Returns ``(v, success, message, factor)``."""
    return _solve_from_projected(problem, projected_start(problem, start, free), xtol, free, near)


def _solve_from_projected(problem: SparseProblem, v0: np.ndarray, xtol: float | None = None, free=None, near=None):
    """:func:`solve_sparse` from ``v0``, the start already projected (:func:`projected_start`)."""
    if not problem.y.size:
        return v0, True, "nothing to adjust", None
    if not np.all(np.isfinite(_whitened(problem, v0))):
        raise DensePathNeeded("the predictions are not finite at the starting point")
    return gauss_newton_sparse(problem, v0, GAUSS_NEWTON_XTOL if xtol is None else xtol, free, near)


def projected_start(problem: SparseProblem, start: np.ndarray, free=None) -> np.ndarray:
    """``start`` with its assayed classes filled (:func:`~tromplab.circuit.problem.assayed_classes_filled`),
    the unknowns not in ``free`` at 0, projected onto the constraints."""
    from .problem import assayed_classes_filled

    v = assayed_classes_filled(replace(problem, at_bound=tuple(problem.held)), start).copy()
    if free is None:
        return projected(problem.A, problem.b, v)
    held = np.setdiff1d(np.arange(v.size), free)
    v[held] = 0.0
    A, b, _ = free_constraints(problem, free)
    moved = v.copy()
    moved[free] = projected(A, b, v[free])
    return moved


#: The constraints of the last sets of free unknowns (the active set returns to the same ones).
_FREE_CONSTRAINTS: dict[bytes, tuple] = {}


def _constraints_key(problem: SparseProblem, free: np.ndarray) -> bytes:
    return problem.A.indptr.tobytes() + problem.A.indices.tobytes() + problem.A.data.tobytes() + free.tobytes()


def free_constraints(problem: SparseProblem, free: np.ndarray) -> tuple:
    """``(A, b, rows)``: the constraints on the unknowns ``free`` (the others held at 0), their
    independent rows only.  A balance whose unknowns are all held says 0 = 0 and goes; holding
    unknowns can make further rows dependent (two balances left with the same unknown), found by
    a pivoted QR of each connected block of rows that lost an unknown."""
    if free.size == problem.A.shape[1]:
        return problem.A, problem.b, np.arange(problem.A.shape[0])
    key = _constraints_key(problem, free)
    if key not in _FREE_CONSTRAINTS:
        A = problem.A[:, free].tocsr()
        rows = np.flatnonzero(np.diff(A.indptr) > 0)
        dependent = _dependent_balances(A[rows])
        if dependent is not None:
            rows = np.delete(rows, dependent)
        elif not _full_row_rank(A[rows]):
            touched = np.asarray(abs(problem.A).sum(axis=1)).ravel() > np.asarray(abs(A).sum(axis=1)).ravel()
            rows = _independent_rows(A, rows, touched)
        if len(_FREE_CONSTRAINTS) >= 16:
            _FREE_CONSTRAINTS.pop(next(iter(_FREE_CONSTRAINTS)))
        _FREE_CONSTRAINTS[key] = A[rows], problem.b[rows], rows
    return _FREE_CONSTRAINTS[key]


def _with_rows_of(problem: SparseProblem, free: np.ndarray, balanced: SparseProblem, rows) -> None:
    """Remember :func:`free_constraints` of ``problem``, whose constraints are those of
    ``balanced`` and then ``rows`` (a grade at 1 each), as the independent rows of ``balanced``
    and all of ``rows`` when these are independent of them (one sparse LU says so), else leave it
    to :func:`free_constraints` (a pivoted QR of each block of balances they touch, a second each
    on the 30-node plant)."""
    from scipy import sparse

    A, b, kept = free_constraints(balanced, free)
    stacked = sparse.vstack([A, rows[:, free]]).tocsr()
    if _full_row_rank(stacked):
        key = _constraints_key(problem, free)
        everything = np.concatenate([kept, problem.A.shape[0] - rows.shape[0] + np.arange(rows.shape[0])])
        _FREE_CONSTRAINTS[key] = stacked, np.concatenate([b, np.zeros(rows.shape[0])]), everything


def _dependent_balances(A) -> np.ndarray | None:
    """The rows of ``A`` to drop for independent rows when ``A`` is the incidence matrix of a
    graph (each column one entry, or two of opposite sign and equal size: a flow leaving one
    balance and entering another, as the balances of a flowsheet are), else None.  The rows of a
    connected set that no column of one entry leaves sum to 0: one of them goes (the last); the
    others are independent (the rank of an incidence matrix).  A walk of the graph, where a
    pivoted QR of each block of rows took 0.1 s per block of the 30-node plant."""
    from scipy import sparse
    from scipy.sparse import csgraph

    columns = A.tocsc()
    counts = np.diff(columns.indptr)
    if counts.max(initial=0) > 2:
        return None
    pairs = columns.indptr[:-1][counts == 2]
    if np.any(columns.data[pairs] + columns.data[pairs + 1] != 0.0):
        return None
    rows = A.shape[0]
    edges = sparse.coo_matrix((np.ones(pairs.size), (columns.indices[pairs], columns.indices[pairs + 1])), shape=(rows, rows))
    _, labels = csgraph.connected_components(edges, directed=False)
    open_sets = np.zeros(labels.max(initial=-1) + 1, dtype=bool)
    open_sets[labels[columns.indices[columns.indptr[:-1][counts == 1]]]] = True
    last_rows = np.full(open_sets.size, -1)
    np.maximum.at(last_rows, labels, np.arange(rows))
    return last_rows[~open_sets]


def _full_row_rank(A) -> bool:
    """Whether the rows of ``A`` are independent: the sparse LU of :math:`A A^T` has no pivot at
    rounding (a dependence of balances with unit entries cancels exactly)."""
    from scipy.sparse import linalg as sparse_linalg

    try:
        pivots = np.abs(sparse_linalg.splu((A @ A.T).tocsc()).U.diagonal())
    except RuntimeError:  # exactly singular
        return False
    return bool(pivots.min(initial=np.inf) > 1e-12 * pivots.max(initial=0.0))


def _independent_rows(A, rows: np.ndarray, touched: np.ndarray) -> np.ndarray:
    """``rows`` of ``A`` without those dependent on the others: the rows of the original constraints
    were independent, so a dependence runs through a row that lost an unknown (``touched``)."""
    from scipy import sparse
    from scipy.sparse import csgraph

    sub = A[rows]
    graph = sparse.bmat([[None, sub], [sub.T, None]])
    _, labels = csgraph.connected_components(graph, directed=False)
    labels = labels[: rows.size]
    dropped = []
    for label in np.unique(labels[touched[rows]]):
        block_rows = np.flatnonzero(labels == label)
        block = sub[block_rows]
        block = block[:, np.flatnonzero(np.diff(block.tocsc().indptr) > 0)].tocsr()
        key = block.indptr.tobytes() + block.indices.tobytes() + block.data.tobytes() + bytes(str(block.shape), "ascii")
        if key not in _DEPENDENT_ROWS:
            if len(_DEPENDENT_ROWS) >= 256:
                _DEPENDENT_ROWS.pop(next(iter(_DEPENDENT_ROWS)))
            _DEPENDENT_ROWS[key] = _dependent_rows_of_block(block)
        dropped.extend(block_rows[_DEPENDENT_ROWS[key]])
    return np.delete(rows, dropped)


def _dependent_rows_of_block(block) -> np.ndarray:
    r"""The rows of ``block`` to drop for independent rows: none when one sparse LU of
    :math:`B B^T` says they are independent (most blocks a held set touches); else the rows of
    the pivots at the regularisation in a symmetric sparse LU of :math:`B B^T + \epsilon I`,
    once the rows kept are shown independent and every row dropped in their span (2 ms where a
    pivoted QR of the dense block of the 30-node plant's minerals took 0.7 s); failing that, those
    a pivoted QR leaves after its rank."""
    from scipy import linalg

    if _full_row_rank(block):
        return np.zeros(0, dtype=int)
    dropped = _dependent_by_regularised_lu(block)
    if dropped is not None:
        return dropped
    R, pivots = linalg.qr(block.toarray().T, mode="r", pivoting=True)
    diagonal = np.abs(np.diag(R))
    return pivots[int(np.sum(diagonal > 1e-10 * diagonal.max(initial=0.0))) :]


def _dependent_by_regularised_lu(block) -> np.ndarray | None:
    r"""The rows of ``block`` (entries of order 1) whose pivots in
    the symmetric LU of :math:`B B^T + \epsilon I` are at the size of :math:`\epsilon`, or None
    when the rows kept are not independent or a row dropped is not in their span."""
    from scipy import sparse
    from scipy.sparse import linalg as sparse_linalg

    gram = (block @ block.T).tocsc()
    largest = float(gram.diagonal().max(initial=0.0))
    try:
        lu = sparse_linalg.splu(gram + 1e-10 * largest * sparse.identity(gram.shape[0], format="csc"),
                                permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})  # fmt: skip
    except RuntimeError:
        return None
    small = np.abs(lu.U.diagonal()) < 1e-6 * largest
    if not np.array_equal(lu.perm_r, lu.perm_c):
        return None
    dropped = np.argsort(lu.perm_c)[small]
    kept = block[np.setdiff1d(np.arange(block.shape[0]), dropped)]
    if not _full_row_rank(kept):
        return None
    rows = block[dropped].toarray().T
    within = kept.T @ sparse_linalg.splu((kept @ kept.T).tocsc()).solve(kept @ rows)
    return dropped if np.all(np.abs(rows - within) <= 1e-9 * max(1.0, np.abs(rows).max(initial=0.0))) else None


#: The dependent rows of the blocks of constraints seen (by their matrix): a set of held flows
#: differs from the last in one flow or a few, so most blocks of rows recur unchanged, and a
#: block's pivoted QR is most of the cost of a set (0.1 s for the 410 rows of a mineral of the
#: 30-node plant).
_DEPENDENT_ROWS: dict[bytes, np.ndarray] = {}


# --- the bounds -------------------------------------------------------------------------------


#: At most this many steps of the bounded Gauss-Newton iteration (the plants of the tests take 3-6).
BOUNDED_STEPS = 40
#: After this many polishes that leave the bounds with the same bounds binding, the iterate stands.
UNPOLISHED = 2
#: A step that lowers the sum of squares by less than this share of it is polished even if a
#: bound changed (a flow at 0 with a multiplier at 0 changes sides from one programme to the next).
SETTLING = 1e-6
#: An assayed class flow that a step would shrink below this share of itself is taken to 0 with
#: its class: its assays, ratios of nearly nothing, are far from their linearisation there (a
#: class of the 30-node plant shrunk 2,500-fold by a step predicted a chi-square of 1,197 and
#: made one of 5e6, and the halvings crawled back for 8 steps).
EMPTYING = 1e-3


@dataclass(frozen=True)
class BoundedFlows:
    """The reconciled unknowns under the bounds: ``v``, the unknowns ``held`` at 0 (each flow at
    its bound and the component flows of a class held with it), whether the iteration settled
    (``settled``, else ``message`` says why) and ``raisable``: how many of the class flows held
    with their class (its assays out) would lower the sum of squares if raised
    (:func:`_raisable`; every other bound is shown binding by the last step's multipliers)."""

    v: np.ndarray
    held: tuple[int, ...]
    settled: bool = True
    message: str = ""
    raisable: int = 0


def bounded_sparse(problem: SparseProblem, fitted: np.ndarray, progress=None) -> BoundedFlows:
    r"""The least squares with every flow at least 0 and every component's grade of a class at
    most 1 (:math:`c_{k,s,i} \le m_{s,i}`), from the unbounded solution ``fitted``.

    From a start inside the bounds (:func:`_inside_the_bounds`), Gauss-Newton steps each of which
    solves the linearised problem under the bounds (:func:`~tromplab.circuit.bounded_qp.
    bounded_least_squares`), shortened by halves until the sum of squares falls: every iterate
    satisfies the balances and the bounds.  A class flow that reaches 0 empties its class (its
    component flows held at 0 with it, its assays out of the least squares, as on the dense
    path), and so does an assayed one a step would shrink below :data:`EMPTYING` of itself.  Each
    programme begins from the last one's multipliers.  When two steps in a row
    leave the same bounds binding (or a step gains less than :data:`SETTLING`), one
    equality-constrained solve with those bounds held and those grades at 1 (:func:`_polished`)
    converges the last digits; if it stays inside the bounds, that is the solution, and
    :func:`_raisable` counts the emptied classes that would lower the sum of squares if raised.
    ``progress``: called at each solve that
    holds negative flows ("reconciliation: bounds, N flows held") and at each step
    ("reconciliation: bounds, step K, N flows at 0")."""
    from .bounded_qp import bounded_least_squares

    scale = max(np.abs(fitted).max(initial=0.0), 1e-300)
    grades, _ = _grade_rows(problem, np.arange(fitted.size))
    if not np.any(fitted < -BOUND_TOL * scale) and not np.any(grades @ fitted < -BOUND_TOL * scale):
        return BoundedFlows(np.clip(fitted, 0.0, None), ())
    solids = problem.n_streams * problem.n_classes
    held, v = _inside_the_bounds(problem, fitted, progress)
    emptied = np.zeros(fitted.size, dtype=bool)  # class flows held with their class (and its assays out)
    emptied[:solids] = held[:solids] & _assayed_classes(problem)
    cost, binding, unpolished = np.inf, None, 0
    # the last programme's multipliers on every unknown and every grade (NaN: none), to begin the next from
    bound_multipliers, grade_multipliers = np.full(v.size, np.nan), np.full(problem.n_components * solids, np.nan)
    for step in range(1, BOUNDED_STEPS + 1):
        current = _held(problem, emptied)
        free = np.setdiff1d(np.arange(v.size), current.held)
        if progress is not None:
            progress(0, 1, f"reconciliation: bounds, step {step}, {int(np.sum(v == 0.0))} flows at 0")
        J = (current.W @ current.jacobian(v)).tocsc()[:, free].tocsr()
        residual = _whitened(current, v)
        A, b, _ = free_constraints(current, free)
        grades, pairs = _grade_rows(current, free)
        try:
            warm = None if step == 1 else (bound_multipliers[free], grade_multipliers[pairs])
            qp = bounded_least_squares(J, J @ v[free] - residual, A, b, grades, v[free], warm)
        except RuntimeError as error:  # SuperLU: "Factor is exactly singular"
            raise DensePathNeeded(f"the bounds' quadratic programme: {error}") from None
        if not qp.converged:
            return BoundedFlows(v, tuple(np.flatnonzero(emptied | (v == 0.0))), False,
                                "the bounds' quadratic programme did not converge")  # fmt: skip
        bound_multipliers[:], grade_multipliers[:] = np.nan, np.nan
        bound_multipliers[free], grade_multipliers[pairs] = qp.z, qp.w
        target = v.copy()
        target[free] = np.where(qp.at_zero, 0.0, np.clip(qp.x, 0.0, None))
        collapsing = np.zeros(v.size, dtype=bool)
        collapsing[:solids] = _assayed_classes(current) & (target[:solids] < EMPTYING * v[:solids])
        target[collapsing | problem.emptied(collapsing)] = 0.0
        now = np.zeros(v.size + problem.n_components * solids, dtype=bool)  # the bounds, then the grades, binding
        now[free[qp.at_zero]] = True
        now[v.size + pairs[qp.grade_at_one]] = True
        before = cost
        v, cost, newly_emptied = _shortened_bounded(problem, emptied, v, target, cost, solids)
        emptied |= newly_emptied
        settling = binding is not None and (np.array_equal(now, binding) or before - cost <= SETTLING * cost)
        if settling and not newly_emptied.any():
            polished = _polished(problem, v, emptied | now[: v.size], np.flatnonzero(now[v.size :]))
            unpolished += polished is None
            if polished is None and unpolished >= UNPOLISHED and np.array_equal(now, binding):
                # the binding bounds stay, the solve with them held leaves the bounds: degenerate
                # bounds (at 0 with a multiplier at 0); the iterate is the solution to the
                # interior point's accuracy, inside the bounds and on the balances
                polished = BoundedFlows(v, tuple(np.flatnonzero(emptied | now[: v.size] | problem.emptied(emptied))))
            if polished is not None:
                return replace(polished, raisable=_raisable(problem, polished.v, emptied))
        binding = now
    return BoundedFlows(v, tuple(np.flatnonzero(emptied | (v == 0.0))), False,
                        f"the bounds on the flows did not settle in {BOUNDED_STEPS} steps")  # fmt: skip


def _inside_the_bounds(problem: SparseProblem, fitted: np.ndarray, progress=None) -> tuple[np.ndarray, np.ndarray]:
    """``(held, v)``: the least squares with the negative flows of ``fitted`` held at 0, then those
    of that solution, until none is negative (the first half of the active set of the dense
    path): a start inside the bounds, near the bounded solution, where the linearisation holds."""
    active = fitted < -BOUND_TOL * max(np.abs(fitted).max(initial=0.0), 1e-300)
    start = np.clip(fitted, 0.0, None)
    for _ in range(fitted.size + 1):
        if progress is not None:
            progress(0, 1, f"reconciliation: bounds, {int(active.sum())} flows held")
        current = _held(problem, active)
        free = np.setdiff1d(np.arange(fitted.size), current.held)
        v0 = projected_start(current, start, free)
        emptied = _emptied_by_balances(current, v0)
        if emptied.any():
            active |= emptied
            continue
        v, _, _, _ = _solve_from_projected(current, v0, free=free)
        negative = (v < -BOUND_TOL * max(np.abs(v).max(), 1e-300)) & ~active
        if not negative.any():
            break
        active |= negative
        start = np.clip(v, 0.0, None)
    active |= problem.emptied(active)
    return active, np.where(active, 0.0, np.clip(v, 0.0, None))


def _assayed_classes(problem: SparseProblem) -> np.ndarray:
    """Whether each class flow (stream by class) has an assay among the measurements."""
    assayed = np.zeros(problem.n_streams * problem.n_classes, dtype=bool)
    assay = problem.kinds == "assay"
    assayed[problem.stream[assay] * problem.n_classes + problem.klass[assay]] = True
    return assayed


def _shortened_bounded(problem: SparseProblem, emptied: np.ndarray, v: np.ndarray, target: np.ndarray, cost: float, solids: int):
    """``(trial, its sum of squares, the class flows it empties)``: ``target`` if its sum of
    squares is below ``cost`` (or ``cost`` is inf: the first step, from outside the bounds),
    else the point halfway there, and so on; a class flow at 0 empties its class (its assays
    leave the sum of squares)."""
    length = 1.0
    while True:
        trial = target if length == 1.0 else np.clip(v + length * (target - v), 0.0, None)
        at_zero = np.zeros(v.size, dtype=bool)
        at_zero[:solids] = (trial[:solids] <= 0.0) & ~emptied[:solids]
        trial_cost = _cost(_held(problem, emptied | at_zero), trial)
        if (np.isfinite(trial_cost) and trial_cost <= cost) or not np.isfinite(cost):
            return trial, trial_cost, at_zero
        length /= 2.0
        if length < 1e-12:
            return v, cost, np.zeros(v.size, dtype=bool)


def _cost(problem: SparseProblem, v: np.ndarray) -> float:
    residual = _whitened(problem, v)
    return float(residual @ residual)


def _raisable(problem: SparseProblem, v: np.ndarray, emptied: np.ndarray) -> int:
    """How many class flows of the ``emptied`` classes (held at 0 with their components, their
    assays out of the least squares) the linearised problem at ``v`` would raise, every unknown
    free under the bounds, when that lowers the sum of squares by more than rounding: the held
    flows of the dense path's wrong-sign multipliers.  (Multipliers of the held flows from one
    factor are not unique where held flows and balances are dependent, as around a class the lab
    reports empty in several streams: a quadratic programme decides.)"""
    from .bounded_qp import bounded_least_squares

    solids = problem.n_streams * problem.n_classes
    if not emptied[:solids].any() or not problem.y.size:
        return 0
    current = replace(_held(problem, emptied), held=())
    everything = np.arange(v.size)
    J = (current.W @ current.jacobian(v)).tocsr()
    residual = _whitened(current, v)
    try:
        qp = bounded_least_squares(J, J @ v - residual, problem.A, problem.b, _grade_rows(current, everything)[0], v)
    except RuntimeError:  # a singular system: the multipliers of one factor count them instead
        return held_against_multipliers_sparse(problem, v, tuple(np.flatnonzero(emptied | problem.emptied(emptied))))
    model = J @ (qp.x - v) + residual
    if float(residual @ residual) - float(model @ model) <= WRONG_SIGN * float(residual @ residual):
        return 0
    return int(np.sum(emptied[:solids] & ~qp.at_zero[:solids]))


def _grade_rows(problem: SparseProblem, free: np.ndarray) -> tuple:
    """``(G, pairs)``: the rows :math:`m_{s,i} - c_{k,s,i}` (at least 0: a grade at most 1) over
    the unknowns ``free`` (columns), one for each class and component whose two flows are free,
    and which those are (``component * classes + class``, classes numbered stream by class)."""
    from scipy import sparse

    solids = problem.n_streams * problem.n_classes
    column = np.full(problem.component_offset + problem.n_components * solids, -1)
    column[free] = np.arange(free.size)
    component = column[problem.component_offset :].reshape(problem.n_components, solids)
    solid = np.broadcast_to(column[:solids][None, :], component.shape)
    keep = (component >= 0) & (solid >= 0)
    rows = np.arange(int(keep.sum()))
    G = sparse.csr_matrix((np.concatenate([np.ones(rows.size), -np.ones(rows.size)]),
                           (np.concatenate([rows, rows]), np.concatenate([solid[keep], component[keep]]))),
                          shape=(rows.size, free.size))  # fmt: skip
    return G, np.flatnonzero(keep.ravel())


def _polished(problem: SparseProblem, v: np.ndarray, held: np.ndarray, at_one: np.ndarray) -> BoundedFlows | None:
    """The bounded iteration's end ``v`` solved once more with the unknowns ``held`` at 0 and the
    grades ``at_one`` (:func:`_grade_rows`' pairs) at 1 as balances, or None when that solve
    leaves the bounds (beyond rounding: the bounds binding are not yet those of the solution)."""
    from scipy import sparse

    scale = max(np.abs(v).max(initial=0.0), 1e-300)
    balanced = _held(problem, held)
    free = np.setdiff1d(np.arange(v.size), balanced.held)
    everything = np.arange(v.size)
    grades, pairs = _grade_rows(problem, everything)
    rows = grades[np.searchsorted(pairs, at_one)]
    current = replace(balanced, A=sparse.vstack([problem.A, rows]).tocsr(), b=np.concatenate([problem.b, np.zeros(at_one.size)]))
    _with_rows_of(current, free, balanced, rows)
    polished, success, message, _ = _solve_from_projected(current, projected_start(current, v, free), free=free)
    if np.any(polished < -BOUND_TOL * scale) or np.any(grades @ polished < -BOUND_TOL * scale):
        return None
    return BoundedFlows(np.clip(polished, 0.0, None), current.held, success, "" if success else message)


def _held(problem: SparseProblem, active: np.ndarray) -> SparseProblem:
    """The problem with the unknowns ``active`` (and the component flows of their classes) held at
    0, the assays of the emptied classes left out (as :meth:`Problem.fixed_at_zero`)."""
    active = active | problem.emptied(active)
    current = replace(problem, held=tuple(int(k) for k in np.flatnonzero(active)), at_bound=())
    if not problem.n_components:
        return current
    empty_class = active[problem.stream * problem.n_classes + np.maximum(problem.klass, 0)]
    return current._measurements(~((problem.kinds == "assay") & empty_class))


def _emptied_by_balances(problem: SparseProblem, v0: np.ndarray) -> np.ndarray:
    """The assayed class flows that the balances put at 0 once the held flows are (a sump whose
    other streams of the class are held, say): 0 to rounding at the projected start ``v0``, where
    their assay is 0/0 or a ratio of rounding errors.  They are at the bound already; held, their class's assays leave the least squares as
    those of every class held at 0, where the solve could not start (the dense path's fallback
    took minutes on the 30-node four-mineral plant)."""
    emptied = np.zeros(v0.size, dtype=bool)
    if not problem.n_components or not problem.y.size:
        return emptied
    solids = problem.n_streams * problem.n_classes
    emptied[:solids] = _assayed_classes(problem)
    at_zero = np.abs(v0) <= BOUND_TOL * max(float(np.abs(v0[:solids]).max(initial=0.0)), 1e-300)
    return emptied & at_zero  # at 0 to rounding (the projection leaves 1e-15 where a balance says 0)


def _held_multipliers(problem: SparseProblem, v: np.ndarray, free: np.ndarray, factor) -> tuple:
    """:func:`~tromplab.circuit.problem.held_multipliers` of the sparse path, from the factor at
    the solution ``v`` of the unknowns ``free``."""
    held = np.array(problem.held, dtype=int)
    if held.size == 0 or not problem.y.size:
        return held[:0], np.zeros(0), 0.0
    gradient = (problem.W @ problem.jacobian(v)).T @ _whitened(problem, v)
    _, _, rows = free_constraints(problem, free)
    mu = factor.multipliers(gradient[free])
    return held_outcome(problem, held, gradient[held] - problem.A[rows][:, held].T @ mu, gradient)


def held_against_multipliers_sparse(problem: SparseProblem, v: np.ndarray, held: tuple[int, ...]) -> int:
    """:func:`~tromplab.circuit.problem.held_against_multipliers` of the sparse path (one factor
    of the held problem at ``v``)."""
    if not held:
        return 0
    active = np.zeros(v.size, dtype=bool)
    active[list(held)] = True
    current = _held(problem, active)
    free = np.setdiff1d(np.arange(v.size), current.held)
    factor = AugmentedFactor(current.W @ current.jacobian(v)[:, free], free_constraints(current, free)[0])
    _, multipliers, threshold = _held_multipliers(current, v, free, factor)
    return int(np.sum(multipliers < threshold))


# --- the reconciliation -----------------------------------------------------------------------


@dataclass(frozen=True)
class SparseReconciliation:
    """What :func:`reconcile_sparse` hands to the balance: the last round's survey and problem,
    the unbounded solution ``fitted`` and its linearisation, the ``bounded`` flows."""

    survey: object
    problem: SparseProblem
    basis: str
    fitted: np.ndarray
    chi_square: float
    linearisation: SparseLinearisation
    bounded: BoundedFlows
    success: bool
    message: str


def reconcile_sparse(flowsheet, survey, *, early_xtol: float, tolerance: float, max_rounds: int, progress=None):
    """The reconciliation of :func:`~tromplab.circuit.reconciliation.reconcile` through sparse
    matrices: the start, the rounds of the error model at the reconciled values (``tolerance``,
    ``max_rounds``, ``early_xtol`` as the dense path's), the linearisation and the bounds.

    Raises
    ------
    DensePathNeeded
        When the survey needs the dense path (a singular system).
    """
    problem, basis = build_sparse_problem(flowsheet, survey)
    start = (
        sparse_solids_first_start(flowsheet, survey, problem)
        if problem.n_components
        else sparse_starting_point(flowsheet, survey, problem)
    )
    rounds_follow = survey.evaluated_at == "reconciled"
    v, success, message, factor = solve_sparse(problem, start, xtol=early_xtol if rounds_follow else None)
    if rounds_follow:
        survey, problem, v, success, message, factor = _rounds(flowsheet, survey, problem, v, early_xtol, tolerance,
                                                               max_rounds, progress, factor)  # fmt: skip
    if factor is None:
        raise DensePathNeeded("nothing to adjust")
    residual = _whitened(problem, v)
    linearisation = SparseLinearisation.at(problem, v, factor.fresh())
    bounded = bounded_sparse(problem, v, progress)
    if not bounded.settled:
        success, message = False, bounded.message
    return SparseReconciliation(survey, problem, basis, v, float(residual @ residual), linearisation, bounded, success,
                                message)  # fmt: skip


def sparse_starting_point(flowsheet, survey, problem: SparseProblem) -> np.ndarray:
    """:func:`~tromplab.circuit.problem.starting_point` before its projection (done sparse here)."""
    unconstrained = replace(problem, A=np.zeros((0, problem.A.shape[1])))
    return projected(problem.A, problem.b, starting_point(flowsheet, survey, unconstrained))


def sparse_solids_first_start(flowsheet, survey, problem: SparseProblem) -> np.ndarray:
    """:func:`~tromplab.circuit.problem.solids_first_start` of the sparse path."""
    solids_survey = replace(survey, assays=survey.assays.iloc[:0], components=())
    solids_problem, _ = build_sparse_problem(flowsheet, solids_survey)
    solids, _, _, _ = solve_sparse(solids_problem, sparse_starting_point(flowsheet, solids_survey, solids_problem), xtol=1e-6)
    S, n = problem.n_streams, problem.n_classes
    v = np.concatenate([solids, start_components(survey, flowsheet.stream_index, solids[: S * n].reshape(S, n))])
    return projected(problem.A, problem.b, v)


def _rounds(flowsheet, survey, problem, v, early_xtol, tolerance, max_rounds, progress, factor=None):
    """The rounds of :func:`~tromplab.circuit.reconciliation._errors_at_reconciled`, the
    constraints built once (the rounds change the sds only), each round's steps through the last
    factor (``factor``: the first solve's) refined while it serves."""
    success, message = True, ""
    constraints = (problem.A, problem.b, "", problem.free)
    for round_number in range(2, max_rounds + 2):
        if progress is not None:
            progress(0, 1, f"reconciliation: round {round_number}")
        shares, flows, grades = error_model_point(problem, v)
        evaluated = survey.with_errors_at(shares, flows, flowsheet.stream_index, grades)
        before, after = (np.concatenate([s.shares["sd"].to_numpy(float), s.flows["sd"].to_numpy(float),
                                         s.assays["sd"].to_numpy(float)]) for s in (survey, evaluated))  # fmt: skip
        if not np.array_equal(before == 0, after == 0):
            raise DensePathNeeded("the exact measurements changed between rounds")
        survey = evaluated
        problem, _ = build_sparse_problem(flowsheet, survey, constraints)
        moved = float(np.max(np.abs(after - before) / np.maximum(before, 1e-300), initial=0.0))
        v, success, message, factor = solve_sparse(problem, v, xtol=min(early_xtol, max(GAUSS_NEWTON_XTOL, 1e-3 * moved)),
                                                   near=factor)  # fmt: skip
        if moved <= tolerance:
            return survey, problem, v, success, message, factor
    return survey, problem, v, False, f"the error model at the reconciled values did not settle in {max_rounds} rounds", factor
