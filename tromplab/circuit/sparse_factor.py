r"""The factor of a large flowsheet's reconciliation: the sparse LU of the augmented (KKT) system
of the whitened Jacobian under the constraints (:class:`AugmentedFactor`), reused by iterative
refinement from one Gauss-Newton step or error-model round to the next, and the directions of the
unknowns no measurement sees (:func:`unseen_directions`), which the factor keeps out by pinning.
:mod:`tromplab.circuit.sparse_solve` solves the reconciliation with it; the method is described
there and in docs/circuit.md ("Large flowsheets").
"""

from __future__ import annotations

import numpy as np

#: A pivot of the sparse LU below this share of the largest means a singular system (a direction
#: no measurement sees, or dependent constraints): the dense path decides such surveys.
SINGULAR_PIVOT = 1e-13


class DensePathNeeded(Exception):
    """The survey needs the dense path (a direction no measurement sees, dependent constraints)."""


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
        r"""The dense :math:`C` of every unknown: :math:`C_p` of the kept unknowns (the pinned
        ones' rows and columns are 0), then :math:`\Pi C_p \Pi`.

        The columns of :math:`C_p` satisfy the constraints: with the kept unknowns split into
        basic ones :math:`B` (:math:`A_B` square and regular, :func:`basic_unknowns`) and the
        others :math:`F`, :math:`A_B C_{BB} + A_F C_{FB} = 0`.  So only the unit vectors of
        :math:`F` are solved (:data:`SOLVE_BLOCK` at a time), giving :math:`C_{\cdot F}`;
        :math:`C_{FB} = C_{BF}^T` (symmetry) and :math:`C_{BB} = -A_B^{-1} A_F C_{FB}` by a
        sparse LU of :math:`A_B`, whose entries are those of the balances (1,610 solves of the
        augmented system instead of 3,660 on the 30-node plant with four minerals)."""
        kept, A = self.kept, self.A[:, self.kept].tocsr()
        basic = basic_unknowns(A)
        free = np.setdiff1d(np.arange(self.unknowns), basic)
        C = np.zeros((self.size, self.size))
        for start in range(0, free.size, SOLVE_BLOCK):
            columns = free[start : start + SOLVE_BLOCK]
            unit = np.zeros((self.unknowns, columns.size))
            unit[columns, np.arange(columns.size)] = 1.0 / self.scale[columns]
            _, x, _ = self._solve(np.zeros((self.rows, columns.size)), unit)
            C[np.ix_(kept, kept[columns])] = -x / self.scale[:, None]
        if basic.size:
            _fill_basic_block(C, A, kept, basic, free)
        blocks = _direction_blocks(self.unseen)
        for rows, basis in blocks:  # Z Z^T C: the rows of each block of directions, by dense products
            C[rows] -= basis @ (basis.T @ C[rows])
        for rows, basis in blocks:  # then C Z Z^T
            C[:, rows] -= (C[:, rows] @ basis) @ basis.T
        return C

    def covariance_times(self, G: np.ndarray) -> np.ndarray:
        r""":math:`C G` for the columns of ``G`` (unknowns not held x k), :math:`C = N (N^T J^T J N)^{-1} N^T`:
        :math:`\Pi C_p \Pi G` (solved :data:`SOLVE_BLOCK` columns at a time) with :math:`C_p` the covariance with the pinned unknowns at 0 and
        :math:`\Pi = I - Z Z^T` (see the class notes)."""
        if self.unseen.shape[1]:
            G = G - self.unseen @ (self.unseen.T @ G)
        x = np.zeros((self.unknowns, G.shape[1]))
        for start in range(0, G.shape[1], SOLVE_BLOCK):
            block = G[self.kept, start : start + SOLVE_BLOCK] / self.scale[:, None]
            x[:, start : start + block.shape[1]] = self._solve(np.zeros((self.rows, block.shape[1])), block)[1]
        return -self._unseen_removed(x / self.scale[:, None])


def dense_times_sparse(D: np.ndarray, S, rows: int = 64) -> np.ndarray:
    """``D @ S`` (``D`` dense, ``S`` sparse) as a C-ordered array, ``rows`` rows of ``D`` at a time.

    scipy computes it as ``(S.T @ D.T).T``: a copy of the whole of ``D`` transposed, and a
    result in Fortran order, which the next sparse product copies whole again (94 MB each on the
    30-node plant with four minerals, where the first touch of fresh pages costs 2 ms a MB).  By
    blocks of rows the copies stay small; every entry is the same sum in the same order."""
    out = np.empty((D.shape[0], S.shape[1]))
    ST = S.T.tocsr()
    for start in range(0, D.shape[0], rows):
        out[start : start + rows] = (ST @ np.ascontiguousarray(D[start : start + rows].T)).T
    return out


#: A connected block of more constraints than this keeps its unknowns' solves (its pivoted QR,
#: dense, would cost more than they do): the 30-node plant's blocks have 410.
BASIC_BLOCK_ROWS = 1000

#: A block whose pivoted QR ends on a pivot below this share of its first keeps its unknowns'
#: solves: an ill-conditioned :math:`A_B` would lose in :math:`C_{BB}` digits the solves keep.
#: The balances of the 30-node plant end at 0.035 (:math:`A_B` of condition number 244 to 379).
BASIC_BLOCK_PIVOTS = 1e-4


def basic_unknowns(A) -> np.ndarray:
    """Columns of ``A`` (constraints of full row rank) forming a square regular :math:`A_B` with
    every row of ``A``, chosen block by block (the connected parts of ``A``'s pattern: a class's or
    a mineral's balances) by a pivoted QR of the block; empty when a block is too large
    (:data:`BASIC_BLOCK_ROWS`) or its QR's pivots fall below :data:`BASIC_BLOCK_PIVOTS` of the
    first (then every unknown is solved)."""
    from scipy import linalg, sparse
    from scipy.sparse import csgraph

    if not A.shape[0]:
        return np.zeros(0, dtype=int)
    pattern = sparse.csr_matrix((np.ones(A.nnz), A.indices, A.indptr), shape=A.shape)
    _, labels = csgraph.connected_components(sparse.bmat([[None, pattern], [pattern.T, None]]), directed=False)
    row_labels, column_labels = labels[: A.shape[0]], labels[A.shape[0] :]
    basic = []
    for label in np.unique(row_labels):
        rows, columns = np.flatnonzero(row_labels == label), np.flatnonzero(column_labels == label)
        if rows.size > BASIC_BLOCK_ROWS or rows.size > columns.size:
            return np.zeros(0, dtype=int)
        R, order = linalg.qr(A[rows][:, columns].toarray(), mode="r", pivoting=True)
        diagonal = np.abs(np.diag(R))
        if diagonal.min() <= BASIC_BLOCK_PIVOTS * diagonal.max():
            return np.zeros(0, dtype=int)
        basic.append(columns[order[: rows.size]])
    return np.sort(np.concatenate(basic))


def _fill_basic_block(C: np.ndarray, A, kept: np.ndarray, basic: np.ndarray, free: np.ndarray, columns: int = 64) -> None:
    r"""Fill :math:`C_{FB} = C_{BF}^T` and :math:`C_{BB} = -A_B^{-1} A_F C_{FB}` into ``C``, whose
    columns of the free unknowns are solved (``kept``: the kept unknowns' places in ``C``;
    ``basic``, ``free``: positions among them), ``columns`` basic unknowns at a time by a sparse
    LU of :math:`A_B` (no whole :math:`C_{BF}` or right-hand side: each new array of tens of MB
    costs about 2 ms a MB of first touches of its pages)."""
    from scipy.sparse import linalg as sparse_linalg

    lu = sparse_linalg.splu(A[:, basic].tocsc())
    free_constraints = A[:, free].tocsr()
    for start in range(0, basic.size, columns):
        these = kept[basic[start : start + columns]]
        free_these = C[np.ix_(these, kept[free])].T  # C_FB's columns of these unknowns, from the solves
        C[np.ix_(kept[free], these)] = free_these
        C[np.ix_(kept[basic], these)] = -lu.solve(np.asarray(free_constraints @ np.ascontiguousarray(free_these)))


def _direction_blocks(Z) -> list[tuple[np.ndarray, np.ndarray]]:
    r"""``(rows, basis)`` of each group of the columns of ``Z`` that reach the same unknowns:
    the unknowns ``rows`` and the dense block ``Z[rows]`` of the group's columns.  The groups
    reach disjoint unknowns, so :math:`Z Z^T C` is, in the rows of each, its block times its
    block's transpose times those rows of :math:`C`: dense products of a few hundred rows, where
    the sparse products with the whole of ``Z`` (blocks of 272 unknowns x 110 directions, each
    dense, on the 30-node plant with four minerals) took a quarter of the covariance's time."""
    from scipy import sparse
    from scipy.sparse import csgraph

    if not Z.shape[1]:
        return []
    Z = sparse.csc_matrix(Z)
    pattern = sparse.csc_matrix((np.ones(Z.nnz), Z.indices, Z.indptr), shape=Z.shape)
    _, labels = csgraph.connected_components(sparse.bmat([[None, pattern], [pattern.T, None]]), directed=False)
    row_labels, column_labels = labels[: Z.shape[0]], labels[Z.shape[0] :]
    reached = np.diff(pattern.tocsr().indptr) > 0
    blocks = []
    for label in np.unique(column_labels):
        rows, columns = np.flatnonzero(reached & (row_labels == label)), np.flatnonzero(column_labels == label)
        blocks.append((rows, Z[rows][:, columns].toarray()))
    return blocks


#: Right-hand sides per call of the LU's solve in :meth:`AugmentedFactor.covariance` and
#: :meth:`~AugmentedFactor.covariance_times`: SuperLU's triangular solves take 0.3 ms a column in
#: blocks of 8 to 64 columns on the 30-node plant with four minerals, 1 ms a column for all 3,660
#: at once (the right-hand sides then outgrow the caches); the columns come out the same.
SOLVE_BLOCK = 32

#: The iterative refinement of a solve through the factor of a nearby system (the last step's or
#: round's) stops at a residual of this share of the system's size times the solution's (the
#: backward error of a direct solve, a few units of rounding), after at most this many steps
#: (each a pair of triangular solves, about 1 ms on the 30-node plant with four minerals against
#: 40 ms for an LU: 30 steps left 37 of the 50 LUs of its error model's rounds, 12 steps 50).
REFINED = 1e-14
REFINEMENT_STEPS = 30

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
