r"""The tables of a large flowsheet's reconciliation from its factor: the linearisation at the
solution (:class:`SparseLinearisation`, the sparse path's stand-in for the dense
:class:`~tromplab.circuit.problem.Decomposition`), the delta-method variances of predictions, the
measurement tests' information, the worth's raw-error sensitivities and the design candidates'
low-rank updates (:class:`SparseCandidateUpdates`), by sparse products and solves of one factor.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .problem import RANK_TOL, TESTABLE_SHARE, Problem
from .sparse_factor import AugmentedFactor, DensePathNeeded, dense_times_sparse

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
    def at(cls, problem: Problem, v: np.ndarray, factor: AugmentedFactor) -> SparseLinearisation:
        """At the solution ``v`` of the problem without held unknowns, from the factor there."""
        Z = factor.unseen
        if Z.shape[1] and abs(Z[: problem.component_offset]).max() > 0:
            # a solids or water flow no measurement determines: the dense path names the streams
            raise DensePathNeeded("a solids or water flow is not observable")
        return cls(rank=factor.rank, J=problem.W @ problem.jacobian(v), C=_symmetrised(factor.covariance()), unseen_unknowns=Z,
                   _products={})  # fmt: skip

    def whitened_effects(self, problem: Problem):
        """``(G, X, CX)``: the whitened raw-error effects :math:`G = W P`, :math:`X = J^T G` (sparse) and :math:`C X` (dense)."""
        if "CX" not in self._products:
            G = (problem.W @ problem.effects).tocsc()
            X = (self.J.T @ G).tocsc()
            # C-ordered: a sparse product with a transposed array copies it whole first (a design
            # candidate's rows times CX took 17 ms of copying for 0.1 ms of products)
            self._products.update(G=G, X=X, CX=dense_times_sparse(self.C, X))
        return self._products["G"], self._products["X"], self._products["CX"]


def _symmetrised(C: np.ndarray, strip: int = 256) -> np.ndarray:
    """``C`` made exactly symmetric in place, :math:`(C + C^T) / 2` (the same numbers), a strip of
    rows and its strip of columns at a time: a whole new 134 MB array took 0.3 s on the 30-node
    plant with four minerals, most of it in the first touch of its pages."""
    for start in range(0, C.shape[0], strip):
        stop = start + strip
        mean = (C[start:stop, start:] + C[start:, start:stop].T) / 2.0
        C[start:stop, start:] = mean
        C[start:, start:stop] = mean.T
    return C


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
    scale = np.sqrt(np.clip(information, 1e-300, None))
    return G, own, information, residual, _scaled_projected_products(G, X, CX, scale)


def _scaled_projected_products(G, X, CX: np.ndarray, scale: np.ndarray, rows: int = 256) -> np.ndarray:
    r""":math:`(G^T G - X^T C X) / (s s^T)` in the one array of :math:`X^T C X` (each piece of
    the plain expression a new 66 MB array on the 30-node plant with four minerals, where the
    first touch of fresh pages costs 2 ms a MB), the same numbers: :math:`0 - b`, then
    :math:`G^T G` added where it has entries (:math:`a + (-b) = a - b` exactly), then divided by
    :math:`s_i s_j`, ``rows`` rows at a time."""
    out = np.asarray(X.T @ CX)
    np.subtract(0.0, out, out=out)
    own = (G.T @ G).tocoo()
    own.sum_duplicates()  # one entry per position (as toarray sums them), for the += below
    out[own.row, own.col] += own.data
    for start in range(0, out.shape[0], rows):
        out[start : start + rows] /= np.outer(scale[start : start + rows], scale)
    return out


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
