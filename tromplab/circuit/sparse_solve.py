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
products (:class:`SparseLinearisation`).  The bounds at 0 use the dense path's active set
(Lawson & Hanson 1974) with the held unknowns taken out of the problem.

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
    RANK_TOL,
    TESTABLE_SHARE,
    Problem,
    closure_point,
    error_model_point,
    linear_constraints,
    measurement_arrays,
    start_components,
    starting_point,
)

#: From this many unknowns on (class flows, water flows and component class flows) a survey is
#: reconciled here: the 30-node plant has 820 solids class flows, the bundled example 176.
SPARSE_FLOWSHEET_UNKNOWNS = 800
#: A pivot of the sparse LU below this share of the largest means a singular system (a direction
#: no measurement sees, or dependent constraints): the dense path decides such surveys.
SINGULAR_PIVOT = 1e-13


class DensePathNeeded(Exception):
    """The survey needs the dense path (a direction no measurement sees, dependent constraints)."""


def unknown_count(flowsheet, survey) -> int:
    """The number of unknowns of the survey's reconciliation (as :func:`~tromplab.circuit.problem.build_problem` lays them out)."""
    S, n = len(flowsheet.streams), max(survey.n_classes, 1)
    n_water = S + len(flowsheet.water_streams) if len(survey.pct_solids) else 0
    return S * n + n_water + len(survey.components) * S * n


def takes_sparse_path(flowsheet, survey) -> bool:
    """Whether ``survey`` is large enough for this path (and has no water balance, see the module notes)."""
    return unknown_count(flowsheet, survey) >= SPARSE_FLOWSHEET_UNKNOWNS and not len(survey.pct_solids)


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


# --- the augmented system ---------------------------------------------------------------------


class AugmentedFactor:
    r"""The sparse LU of the augmented system of the whitened Jacobian ``J`` (rows: pieces of
    information, columns: the unknowns not held) under the constraints ``A``, columns scaled by
    their norms in ``J``.  :meth:`step` solves the linearised least squares, :meth:`covariance_times`
    applies :math:`N (N^T J^T J N)^{-1} N^T`.

    The directions no measurement sees (:math:`Z`, orthonormal, :func:`unseen_directions`) are
    kept out by pinning as many unknowns of theirs at 0 (they leave the system, whose factor
    stays as sparse as the constraints): those directions move no prediction and no constraint,
    so every other solution differs from the pinned one by a part in them, and the one without
    it, :math:`\Pi x` with :math:`\Pi = I - Z Z^T`, is the dense path's (its null-space basis
    orthonormal); the covariance is likewise :math:`\Pi C_p \Pi`.  (Joined to the constraints as
    rows :math:`Z^T`, they made the factor three times as dense on the 30-node plant with four
    minerals: the basis of a mineral's class flows spans every stream of a block.)

    Raises :class:`DensePathNeeded` when the system is singular."""

    def __init__(self, J, A, near: AugmentedFactor | None = None):
        norms = np.sqrt(np.asarray(J.multiply(J).sum(axis=0)).ravel())
        unmeasured = np.flatnonzero(norms == 0)
        if near is not None and near.A is A and near.size == J.shape[1] and np.array_equal(near.unmeasured, unmeasured):
            # the next step or round of the same problem: the factor of ``near`` solves this
            # system by iterative refinement (:meth:`_solve`), in its scaling
            self.__dict__.update({name: getattr(near, name) for name in self._LAYOUT})
            self.lu, self.refined = near.lu, True
            self.system = self._assembled(J[:, self.kept])
            return
        self.A, self.unmeasured, self.refined = A, unmeasured, False
        self.unseen, pinned = unseen_directions(A, unmeasured)
        self.n_balances, self.size = A.shape[0], J.shape[1]
        self.kept = np.setdiff1d(np.arange(self.size), pinned)
        J, A, norms = J[:, self.kept], A[:, self.kept], norms[self.kept]
        self.rows, self.unknowns, self.constraints = J.shape[0], J.shape[1], A.shape[0]
        self.scale = np.where(norms > 0, norms, 1.0)
        scaled = A.multiply(1.0 / self.scale[None, :])
        self.row_scale = np.sqrt(np.asarray(scaled.multiply(scaled).sum(axis=1)).ravel())
        self.scaled_constraints = scaled.multiply(1.0 / np.where(self.row_scale > 0, self.row_scale, 1.0)[:, None]).tocsr()
        self.system = self._assembled(J)
        self._factor()

    #: What a refined factor takes over from the one it reuses.
    _LAYOUT = ("A", "unmeasured", "unseen", "n_balances", "size", "kept", "rows", "unknowns", "constraints", "scale",
               "row_scale", "scaled_constraints")  # fmt: skip

    def _assembled(self, J):
        """The augmented system of ``J`` (kept columns) in this factor's scaling, a CSC matrix
        (its blocks placed by their triplets: ``bmat`` took a third of a step's time)."""
        from scipy import sparse

        Js = J.multiply(1.0 / self.scale[None, :]).tocoo()
        As = self.scaled_constraints.tocoo()
        r, u = self.rows, self.unknowns
        diagonal = np.arange(r)
        rows = np.concatenate([diagonal, Js.row, Js.col + r, As.col + r, As.row + r + u])
        cols = np.concatenate([diagonal, Js.col + r, Js.row, As.row + r + u, As.col + r])
        values = np.concatenate([np.ones(r), Js.data, Js.data, As.data, As.data])
        if not np.all(np.isfinite(values)):  # SuperLU is not defended against them
            raise DensePathNeeded("the Jacobian is not finite")
        size = r + u + self.constraints
        return sparse.csc_matrix((values, (rows, cols)), shape=(size, size))

    def _factor(self) -> None:
        try:
            self.lu = _factored(self.system)
        except RuntimeError as error:  # "Factor is exactly singular"
            raise DensePathNeeded(str(error)) from None
        pivots = np.abs(self.lu.U.diagonal())
        if pivots.size and pivots.min() <= SINGULAR_PIVOT * pivots.max():
            raise DensePathNeeded("a pivot of the sparse LU at rounding: a singular system")
        self.refined = False

    def fresh(self) -> AugmentedFactor:
        """This factor with an LU of its own system (for the many solves of a covariance)."""
        if self.refined:
            self._factor()
        return self

    @property
    def rank(self) -> int:
        """The free unknowns the measurements see: unknowns - constraints - unseen directions."""
        return self.unknowns - self.constraints

    def _solve(self, top: np.ndarray, middle: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        rhs = np.concatenate([top, middle, np.zeros((self.constraints,) + top.shape[1:])])
        solution = self.lu.solve(rhs)
        if self.refined:
            solution = self._refined(rhs, solution)
        r, u = self.rows, self.unknowns
        return solution[:r], solution[r : r + u], solution[r + u :]

    def _refined(self, rhs: np.ndarray, solution: np.ndarray) -> np.ndarray:
        """``solution`` (by the LU of a nearby system) refined until its residual in this system
        is at the rounding of a direct solve, :data:`REFINEMENT_STEPS` at most, each at least
        halving it; failing that, this system is factored and solved afresh."""
        size = np.abs(self.system).max() if self.system.nnz else 1.0
        before = np.inf
        for _ in range(REFINEMENT_STEPS):
            residual = rhs - self.system @ solution
            error = float(np.abs(residual).max(initial=0.0))
            if error <= REFINED * (size * float(np.abs(solution).max(initial=0.0)) + float(np.abs(rhs).max(initial=0.0))):
                return solution
            if error > 0.5 * before:
                break
            solution, before = solution + self.lu.solve(residual), error
        self._factor()
        return self.lu.solve(rhs)

    def _unseen_removed(self, x: np.ndarray) -> np.ndarray:
        r"""``x`` (kept unknowns, scaled back) in every unknown, the pinned at 0, less its part in
        the unseen directions: :math:`(I - Z Z^T) x` (the columns of :math:`Z` orthonormal)."""
        full = np.zeros((self.size,) + x.shape[1:])
        full[self.kept] = x
        if self.unseen.shape[1]:
            full -= self.unseen @ (self.unseen.T @ full)
        return full

    def step(self, residual: np.ndarray) -> np.ndarray:
        """The Gauss-Newton step of the unknowns: the least-squares solution of ``J d = -residual``
        with ``A d = 0`` and no part in the unseen directions."""
        _, x, _ = self._solve(-residual, np.zeros(self.unknowns))
        return self._unseen_removed(x / self.scale)

    def multipliers(self, gradient: np.ndarray) -> np.ndarray:
        r"""The Lagrange multipliers :math:`\mu` of the constraints with :math:`A^T \mu` the part of
        ``gradient`` (:math:`J^T \rho`, of the unknowns not held) in their row space (the pinned
        unknowns' equations, :math:`A_p^T \mu = 0`, follow from the kept ones': see the class notes)."""
        _, _, mu = self._solve(np.zeros(self.rows), gradient[self.kept] / self.scale)
        return mu / np.where(self.row_scale > 0, self.row_scale, 1.0)

    def covariance(self) -> np.ndarray:
        r"""The dense :math:`C` of every unknown: :math:`C_p` from the solves of the kept unknowns'
        unit vectors alone (the pinned ones' rows and columns are 0), then :math:`\Pi C_p \Pi`."""
        _, x, _ = self._solve(np.zeros((self.rows, self.unknowns)), np.diag(1.0 / self.scale))
        C = np.zeros((self.size, self.size))
        C[np.ix_(self.kept, self.kept)] = -x / self.scale[:, None]
        Z = self.unseen
        if Z.shape[1]:
            C -= Z @ (Z.T @ C)
            C -= (Z @ (Z.T @ C.T)).T
        return C

    def covariance_times(self, G: np.ndarray) -> np.ndarray:
        r""":math:`C G` for the columns of ``G`` (unknowns not held x k), :math:`C = N (N^T J^T J N)^{-1} N^T`:
        :math:`\Pi C_p \Pi G` with :math:`C_p` the covariance with the pinned unknowns at 0 and
        :math:`\Pi = I - Z Z^T` (see the class notes)."""
        if self.unseen.shape[1]:
            G = G - self.unseen @ (self.unseen.T @ G)
        _, x, _ = self._solve(np.zeros((self.rows, G.shape[1])), G[self.kept] / self.scale[:, None])
        return -self._unseen_removed(x / self.scale[:, None])


#: The iterative refinement of a solve through the factor of a nearby system (the last step's or
#: round's) stops at a residual of this share of the system's size times the solution's (the
#: backward error of a direct solve, a few units of rounding), after at most this many steps.
REFINED = 1e-14
REFINEMENT_STEPS = 12

#: SuperLU's options for a system of a given size and pattern, the better of two orders
#: (:func:`_factored`): COLAMD's column order with partial pivoting, or the minimum degree of the
#: symmetric pattern with pivots on the diagonal where not too small.  On the 30-node plant the
#: first makes a factor of the solids alone four times sparser, the second one with the four
#: minerals (whose unseen directions add dense rows) half as dense.
_ORDERS = ({"permc_spec": "COLAMD"},
           {"permc_spec": "MMD_AT_PLUS_A", "diag_pivot_thresh": 0.01, "options": {"SymmetricMode": True}})  # fmt: skip
_ORDER_CHOSEN: dict[tuple, int] = {}


def _factored(system):
    """The sparse LU of ``system``; the first system of its size (within a tenth in order and in
    nonzeros: the steps, rounds and held sets of one survey) tries both of :data:`_ORDERS` and
    keeps the one with the fewer nonzeros in its factors for the next ones."""
    from scipy.sparse import linalg as sparse_linalg

    key = (system.shape[0], system.nnz)
    for (order, nonzeros), chosen in _ORDER_CHOSEN.items():
        if abs(order - key[0]) <= 0.1 * order and abs(nonzeros - key[1]) <= 0.1 * nonzeros:
            return sparse_linalg.splu(system, **_ORDERS[chosen])
    factors = [sparse_linalg.splu(system, **order) for order in _ORDERS]
    sizes = [lu.L.nnz + lu.U.nnz for lu in factors]
    _ORDER_CHOSEN[key] = int(np.argmin(sizes))
    return factors[_ORDER_CHOSEN[key]]


#: The last unseen directions, by the bytes of the constraints and the unmeasured unknowns: the
#: steps and rounds of a reconciliation see the same ones.
_UNSEEN_DIRECTIONS: dict[bytes, tuple] = {}


def unseen_directions(A, unmeasured: np.ndarray) -> tuple:
    r"""``(Z, pinned)``: sparse orthonormal columns ``Z`` spanning the directions of the unknowns
    that no measurement sees, and as many of those unknowns, ``pinned``, whose values at 0 leave
    none of those directions free.  The directions are the null space of the constraints'
    columns of the unknowns ``unmeasured`` (those with no entry in the Jacobian, e.g. a
    component's flow in a class whose assays were set aside), taken block by block (the
    connected parts of those columns and their rows), each by a dense SVD (the rank decision of
    the dense path's null space, 1e-10); the pinned unknowns of a block are the columns a pivoted
    QR puts after its rank (the others independent: at 0 the block keeps its range).  A
    direction that moves a measured unknown without moving a prediction is not found here: the
    factor is then singular and the dense path decides."""
    from scipy import sparse

    key = A.shape[1].to_bytes(8, "little") + A.indptr.tobytes() + A.indices.tobytes() + A.data.tobytes() + unmeasured.tobytes()
    if key in _UNSEEN_DIRECTIONS:
        return _UNSEEN_DIRECTIONS[key]
    pieces_rows, pieces_values, pinned = [], [], []
    for cols, block in _unmeasured_blocks(A, unmeasured):
        basis, pinned_here = _block_directions(block)
        pieces_rows.extend([unmeasured[cols]] * basis.shape[1])
        pieces_values.extend(basis.T)
        pinned.extend(unmeasured[cols[pinned_here]])
    count = len(pieces_rows)
    if count:
        columns = np.repeat(np.arange(count), [rows.size for rows in pieces_rows])
        Z = sparse.coo_matrix((np.concatenate(pieces_values), (np.concatenate(pieces_rows), columns)),
                              shape=(A.shape[1], count)).tocsc()  # fmt: skip
        Z.eliminate_zeros()
    else:
        Z = sparse.csc_matrix((A.shape[1], 0))
    if len(_UNSEEN_DIRECTIONS) >= 16:
        _UNSEEN_DIRECTIONS.pop(next(iter(_UNSEEN_DIRECTIONS)))
    _UNSEEN_DIRECTIONS[key] = Z, np.sort(np.array(pinned, dtype=int))
    return _UNSEEN_DIRECTIONS[key]


def _unmeasured_blocks(A, unmeasured: np.ndarray):
    """``(columns, block)`` of each connected part of the constraints' columns ``unmeasured``:
    positions in ``unmeasured`` and the dense block of its nonzero rows (none: no row)."""
    from scipy import sparse
    from scipy.sparse import csgraph

    columns = A[:, unmeasured].tocsc()
    rows_used = np.flatnonzero(np.diff(columns.tocsr().indptr) > 0)
    sub = columns[rows_used]
    n_rows, n_cols = sub.shape
    graph = sparse.bmat([[None, sub], [sub.T, None]]) if n_rows else sparse.csr_matrix((n_cols, n_cols))
    _, labels = csgraph.connected_components(graph, directed=False)
    labels = labels[n_rows:] if n_rows else labels
    order = np.argsort(labels, kind="stable")  # the columns of each part together, in their order
    grouped = sub[:, order].tocsc()
    bounds = np.flatnonzero(np.diff(np.concatenate(([-1], labels[order], [labels.max(initial=0) + 1]))))
    for first, last in zip(bounds[:-1], bounds[1:]):
        part = grouped[:, first:last]
        used = np.unique(part.indices)
        block = np.zeros((used.size, last - first))
        for k in range(last - first):
            span = slice(part.indptr[k], part.indptr[k + 1])
            block[np.searchsorted(used, part.indices[span]), k] = part.data[span]
        yield order[first:last], block


#: The directions of the last blocks, by their bytes: a new set of held flows changes few blocks.
_BLOCK_DIRECTIONS: dict[bytes, tuple] = {}


def _block_directions(block: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The orthonormal null space of ``block`` and the columns to pin (positions), as many."""
    from scipy import linalg

    if not block.shape[0]:
        return np.eye(block.shape[1]), np.arange(block.shape[1])
    key = np.array(block.shape).tobytes() + block.tobytes()
    if key not in _BLOCK_DIRECTIONS:
        basis = linalg.null_space(block, rcond=1e-10)
        _, order = linalg.qr(block, mode="r", pivoting=True)
        if len(_BLOCK_DIRECTIONS) >= 4096:
            _BLOCK_DIRECTIONS.pop(next(iter(_BLOCK_DIRECTIONS)))
        _BLOCK_DIRECTIONS[key] = basis, np.sort(order[block.shape[1] - basis.shape[1] :])
    return _BLOCK_DIRECTIONS[key]


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
    v0 = projected_start(problem, start, free)
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


def free_constraints(problem: SparseProblem, free: np.ndarray) -> tuple:
    """``(A, b, rows)``: the constraints on the unknowns ``free`` (the others held at 0), their
    independent rows only.  A balance whose unknowns are all held says 0 = 0 and goes; holding
    unknowns can make further rows dependent (two balances left with the same unknown), found by
    a pivoted QR of each connected block of rows that lost an unknown."""
    if free.size == problem.A.shape[1]:
        return problem.A, problem.b, np.arange(problem.A.shape[0])
    key = problem.A.indptr.tobytes() + problem.A.indices.tobytes() + problem.A.data.tobytes() + free.tobytes()
    if key not in _FREE_CONSTRAINTS:
        A = problem.A[:, free].tocsr()
        rows = np.flatnonzero(np.diff(A.indptr) > 0)
        if not _full_row_rank(A[rows]):
            touched = np.asarray(abs(problem.A).sum(axis=1)).ravel() > np.asarray(abs(A).sum(axis=1)).ravel()
            rows = _independent_rows(A, rows, touched)
        if len(_FREE_CONSTRAINTS) >= 16:
            _FREE_CONSTRAINTS.pop(next(iter(_FREE_CONSTRAINTS)))
        _FREE_CONSTRAINTS[key] = A[rows], problem.b[rows], rows
    return _FREE_CONSTRAINTS[key]


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
    from scipy import linalg, sparse
    from scipy.sparse import csgraph

    sub = A[rows]
    graph = sparse.bmat([[None, sub], [sub.T, None]])
    _, labels = csgraph.connected_components(graph, directed=False)
    labels = labels[: rows.size]
    dropped = []
    for label in np.unique(labels[touched[rows]]):
        block_rows = np.flatnonzero(labels == label)
        block = sub[block_rows]
        block = block[:, np.flatnonzero(np.diff(block.tocsc().indptr) > 0)].toarray()
        R, pivots = linalg.qr(block.T, mode="r", pivoting=True)
        diagonal = np.abs(np.diag(R))
        rank = int(np.sum(diagonal > 1e-10 * diagonal.max(initial=0.0)))
        dropped.extend(block_rows[pivots[rank:]])
    return np.delete(rows, dropped)


# --- the bounds -------------------------------------------------------------------------------


def bounded_sparse(problem: SparseProblem, fitted: np.ndarray, progress=None) -> tuple[tuple[int, ...], np.ndarray]:
    """:func:`~tromplab.circuit.problem.bounded_solution` of the sparse path: the same active set
    (a negative flow held at 0, a held flow released once when its multiplier says the sum of
    squares would fall), the held unknowns taken out of the least squares.  ``progress``: called
    with the stage at each set of held flows ("reconciliation: bounds, N flows held").

    (Releasing every flow of a wrong-sign multiplier at once took fewer solves but ended on
    another set than the dense path's on the 6-node plant with four minerals: the flows released
    once stay held.)"""
    active = fitted < -BOUND_TOL * max(np.abs(fitted).max(initial=0.0), 1e-300)
    if not active.any():
        return (), np.clip(fitted, 0.0, None)
    start = np.clip(fitted, 0.0, None)
    released_before = np.zeros(fitted.size, dtype=bool)
    for _ in range(2 * fitted.size + 1):
        if progress is not None:
            progress(0, 1, f"reconciliation: bounds, {int(active.sum())} flows held")
        current = _held(problem, active)
        free = np.setdiff1d(np.arange(fitted.size), current.held)
        v, _, _, factor = solve_sparse(current, start, free=free)
        negative = (v < -BOUND_TOL * max(np.abs(v).max(), 1e-300)) & ~active
        if negative.any():
            active |= negative
        else:
            released = _wrong_sign_multiplier(current, v, free, released_before, factor)
            if released is None:
                return current.held, np.clip(v, 0.0, None)
            active[released] = False
            released_before[released] = True
        start = np.clip(v, 0.0, None)
    return tuple(np.flatnonzero(active)), np.full(fitted.size, np.nan)


def _held(problem: SparseProblem, active: np.ndarray) -> SparseProblem:
    """The problem with the unknowns ``active`` (and the component flows of their classes) held at
    0, the assays of the emptied classes left out (as :meth:`Problem.fixed_at_zero`)."""
    active = active | problem.emptied(active)
    current = replace(problem, held=tuple(int(k) for k in np.flatnonzero(active)), at_bound=())
    if not problem.n_components:
        return current
    empty_class = active[problem.stream * problem.n_classes + np.maximum(problem.klass, 0)]
    return current._measurements(~((problem.kinds == "assay") & empty_class))


def _wrong_sign_multiplier(problem: SparseProblem, v: np.ndarray, free: np.ndarray, released_before: np.ndarray, factor):
    """The held unknown whose multiplier is most negative, or None (the rule of the dense path);
    ``factor``: the Gauss-Newton factor at ``v`` (the solution), which gives the multipliers."""
    held = np.array(problem.held, dtype=int)
    if held.size == 0 or not problem.y.size:
        return None
    gradient = (problem.W @ problem.jacobian(v)).T @ _whitened(problem, v)
    _, _, rows = free_constraints(problem, free)
    mu = factor.multipliers(gradient[free])
    multipliers = gradient[held] - problem.A[rows][:, held].T @ mu
    active = np.zeros(v.size, dtype=bool)
    active[held] = True
    multipliers = np.where(problem.emptied(active)[held], np.inf, multipliers)
    multipliers = np.where(released_before[held], np.inf, multipliers)
    worst = int(np.argmin(multipliers))
    return int(held[worst]) if multipliers[worst] < -1e-8 * max(np.abs(gradient).max(), 1e-300) else None


# --- the reconciliation -----------------------------------------------------------------------


@dataclass(frozen=True)
class SparseReconciliation:
    """What :func:`reconcile_sparse` hands to the balance: the last round's survey and problem,
    the unbounded solution ``fitted`` and its linearisation, the bounded ``v`` and ``held``."""

    survey: object
    problem: SparseProblem
    basis: str
    fitted: np.ndarray
    chi_square: float
    linearisation: SparseLinearisation
    held: tuple[int, ...]
    v: np.ndarray
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
    held, bounded = bounded_sparse(problem, v, progress)
    if held and not np.all(np.isfinite(bounded)):
        success, message = False, "the bounds on the flows did not settle (active-set iterations exhausted)"
    return SparseReconciliation(survey, problem, basis, v, float(residual @ residual), linearisation, held, bounded, success,
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


# --- the linearisation and the tables' linear algebra ---------------------------------------------


@dataclass(frozen=True)
class SparseLinearisation:
    r"""The sparse path's stand-in for :class:`~tromplab.circuit.problem.Decomposition`: the
    whitened Jacobian ``J`` at the solution (sparse, every unknown), the covariance of the
    unknowns ``C`` (dense; the balance's ``covariance``) and ``rank``, the free unknowns, every
    one seen by a measurement (else the dense path would have been taken).

    The tables read it through :func:`prediction_variances`, :func:`tests_information`,
    :func:`raw_error_sensitivities` and :class:`SparseCandidateUpdates`."""

    rank: int
    J: object = None
    C: np.ndarray = None
    unseen_unknowns: object = None  # sparse columns: the directions of the unknowns no measurement sees
    _products: dict = None  # C J^T G, computed once for the tests, the worth and the design

    @classmethod
    def at(cls, problem: SparseProblem, v: np.ndarray, factor: AugmentedFactor) -> SparseLinearisation:
        """At the solution ``v`` of the problem without held unknowns, from the factor there."""
        Z = factor.unseen
        if Z.shape[1] and abs(Z[: problem.component_offset]).max() > 0:
            # a solids or water flow no measurement determines: the dense path names the streams
            raise DensePathNeeded("a solids or water flow is not observable")
        C = factor.covariance()
        return cls(rank=factor.rank, J=problem.W @ problem.jacobian(v), C=(C + C.T) / 2.0, unseen_unknowns=Z, _products={})

    def whitened_effects(self, problem: SparseProblem):
        """``(G, X, CX)``: the whitened raw-error effects :math:`G = W P`, :math:`X = J^T G` (sparse) and :math:`C X` (dense)."""
        if "CX" not in self._products:
            G = (problem.W @ problem.effects).tocsc()
            X = (self.J.T @ G).tocsc()
            self._products.update(G=G, X=X, CX=np.asarray((X.T @ self.C).T))
        return self._products["G"], self._products["X"], self._products["CX"]


def prediction_variances(C: np.ndarray, H) -> np.ndarray:
    r""":math:`\mathrm{diag}(H C H^T)` for the rows of ``H`` (sparse or dense gradients in the
    unknowns, possibly shorter than ``C``: the leading unknowns)."""
    from scipy import sparse

    H = sparse.csr_matrix(H)
    k = H.shape[1]
    return np.asarray((H @ C[:k, :k]) * H.toarray() if H.shape[0] * k <= 4_000_000 else _rowwise(H, C[:k, :k])).sum(axis=1)


def _rowwise(H, C: np.ndarray) -> np.ndarray:
    """``(H C) * H`` row by row in blocks, without a dense copy of ``H``."""
    out = np.zeros((H.shape[0], 1))
    for start in range(0, H.shape[0], 512):
        block = H[start : start + 512]
        out[start : start + 512, 0] = np.asarray((block @ C) * block.toarray()).sum(axis=1)
    return out


def tests_information(balance) -> tuple:
    r"""``(G, own, information, residual, correlation)`` of the measurement tests: the squared
    norms of the whitened effects' columns :math:`g_j`, the information of
    each raw error off the range of the whitened Jacobian, :math:`g_j^T g_j - x_j^T C x_j`
    (:math:`x_j = J^T g_j`), and the correlation of the projected effects
    :math:`(G^T G - X^T C X)` scaled by the informations."""
    problem, linearisation = balance.problem, balance.decomposition
    G, X, CX = linearisation.whitened_effects(problem)
    own = np.asarray(G.multiply(G).sum(axis=0)).ravel()
    information = own - np.asarray(X.multiply(CX).sum(axis=0)).ravel()
    residual = problem.W @ (balance.measured_y - problem.predict(balance._test_point))
    projected_products = (G.T @ G).toarray() - np.asarray(X.T @ CX)
    scale = np.sqrt(np.clip(information, 1e-300, None))
    return G, own, information, residual, projected_products / np.outer(scale, scale)


def raw_error_sensitivities(balance, gradients) -> np.ndarray:
    r"""Rows: how far each result (rows of ``gradients`` in the unknowns) moves per standard
    deviation of each raw measurement error, :math:`q^T C J^T W P \sigma` (the worth table's shifts)."""
    from scipy import sparse

    problem = balance.problem
    _, X, _ = balance.decomposition.whitened_effects(problem)
    Q = sparse.csr_matrix(gradients)
    QC = np.asarray(Q @ balance.decomposition.C[: Q.shape[1]])
    return np.asarray((X.T @ QC.T).T) * problem.sd


#: A low-rank update that removes more than all but this share of a variance is evaluated afresh
#: (:data:`tromplab.circuit.design.UPDATE_CANCELLATION`, repeated here: the design module sits above).
UPDATE_CANCELLATION = 1e-4


class SparseCandidateUpdates:
    r""":class:`~tromplab.circuit.design.CandidateUpdates` in the unknowns themselves: the same
    Sherman-Morrison-Woodbury update :math:`C' = C - C E^T (I + E C E^T)^{-1} E C` with
    :math:`C` the covariance of the unknowns (the sparse path's), :math:`E` the candidate's
    whitened rows; a candidate that reaches a direction no measurement sees, or whose update
    cancels a variance, by a fresh factor of the stacked Jacobian (:meth:`_refactored`)."""

    def __init__(self, balance, gradients: np.ndarray, v: np.ndarray):
        from scipy import sparse
        from scipy.sparse import linalg as sparse_linalg

        problem, linearisation = balance.problem, balance.decomposition
        self.balance, self.problem, self.linearisation = balance, problem, linearisation
        G, X, CX = linearisation.whitened_effects(problem)
        self.G, self.CJG = G, CX
        self.C = balance.covariance
        self.Q = sparse.csr_matrix(gradients[:, : self.C.shape[0]]) if len(gradients) else sparse.csr_matrix((0, self.C.shape[0]))
        self.CQ = np.asarray((self.Q @ self.C).T)
        self.variance_before = np.einsum("ij,ji->i", self.Q.toarray(), self.CQ)
        self.sd_before = np.sqrt(np.clip(self.variance_before, 0.0, None))
        self.own = np.asarray(G.multiply(G).sum(axis=0)).ravel()
        self.information = self.own - np.asarray(X.multiply(CX).sum(axis=0)).ravel()
        self.testable_now = self.information > TESTABLE_SHARE * self.own
        self.largest = float(sparse_linalg.norm(linearisation.J)) if linearisation.J.nnz else 0.0

    def with_candidate(self, candidate) -> tuple[np.ndarray, np.ndarray]:
        """``(sd after of each result, testable)`` as :meth:`CandidateUpdates.with_candidate`."""
        from scipy import linalg, sparse

        E = candidate.rows
        if self.balance.basis and candidate.measurement == "solids flow":
            return self.sd_before, np.concatenate([self.testable_now, np.zeros(E.shape[0], dtype=bool)])
        Z = self.linearisation.unseen_unknowns
        if Z.shape[1] and np.linalg.norm(np.asarray(Z.T @ E.T)) > RANK_TOL * 1e-3 * max(self.largest, np.linalg.norm(E)):
            return self._refactored(E)
        rows = sparse.csr_matrix(E)  # a candidate reads one stream: a few unknowns
        EC = np.asarray(rows @ self.C)
        inner = np.eye(E.shape[0]) + EC @ E.T
        factor = linalg.cho_factor(inner)
        ECQ = np.asarray((self.Q @ EC.T).T)
        variance = self.variance_before - np.einsum("ij,ij->j", ECQ, linalg.cho_solve(factor, ECQ))
        if np.any(variance < UPDATE_CANCELLATION * self.variance_before):
            return self._refactored(E)
        ECJG = np.asarray(rows @ self.CJG)
        information = self.information + np.einsum("ij,ij->j", ECJG, linalg.cho_solve(factor, ECJG))
        survey_testable = information > TESTABLE_SHARE * self.own
        own = np.diag(linalg.cho_solve(factor, np.eye(E.shape[0])))
        return np.sqrt(np.clip(variance, 0.0, None)), np.concatenate([survey_testable, own > TESTABLE_SHARE])

    def _refactored(self, E: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The candidate by a fresh factor of the Jacobian with the candidate's rows stacked."""
        from scipy import sparse

        J = sparse.vstack([self.linearisation.J, sparse.csr_matrix(E)]).tocsr()
        factor = AugmentedFactor(J, self.problem.A)
        variance = np.einsum("ij,ji->i", self.Q.toarray(), factor.covariance_times(self.Q.T.toarray()))
        pieces = E.shape[0]
        G = sparse.block_diag([self.G, sparse.identity(pieces)]).tocsc()
        X = (J.T @ G).toarray()
        own = np.asarray(G.multiply(G).sum(axis=0)).ravel()
        information = own - np.einsum("ij,ij->j", X, factor.covariance_times(X))
        return np.sqrt(np.clip(variance, 0.0, None)), information > TESTABLE_SHARE * own
