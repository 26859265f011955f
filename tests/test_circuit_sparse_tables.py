"""The linear algebra of the sparse path's tables (tromplab.circuit.sparse_factor's covariance,
tromplab.circuit.sparse_tables) against the arithmetic it replaced: the covariance solved in
blocks of right-hand sides for the unknowns off a regular block of the constraints (the others'
block from the constraints), the unseen directions projected out block by block, its products,
the exact symmetrisation, computed here the plain way (one solve of every unit vector, the
projections by sparse products with the whole of Z, (C + C^T) / 2).

The plant: the 6-node plant of large_plant(2, 20) with four minerals assayed on every stream
(900 unknowns, 20 directions no measurement sees), at its starting point; and (slow) the
30-node plant of large_plant(10, 20) with the four minerals.
"""

import warnings

import numpy as np
import pytest
from scipy import sparse

from tromplab.circuit import sparse_factor, sparse_solve, sparse_tables
from tromplab.circuit.simulation import lab_survey, large_plant


def _factor_at_start(blocks: int):
    truth = large_plant(blocks, 20)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the truth's grade of an empty class is 0/0 (no assay drawn)
        survey = lab_survey(truth, np.random.default_rng(40), flows={"fresh_feed": 0.02})
    problem, _ = sparse_solve.build_sparse_problem(truth.flowsheet, survey)
    start = sparse_solve.sparse_solids_first_start(truth.flowsheet, survey, problem)
    v = sparse_solve.projected_start(problem, start)
    factor = sparse_factor.AugmentedFactor(problem.W @ problem.jacobian(v), problem.A)
    return factor, problem, v


@pytest.fixture(scope="module")
def factor_and_problem():
    return _factor_at_start(2)


def _plain_covariance(factor) -> np.ndarray:
    """The covariance as it was computed before: every unit vector in one solve, then
    Z Z^T C and C Z Z^T by sparse products with the whole of Z."""
    _, x, _ = factor._solve(np.zeros((factor.rows, factor.unknowns)), np.diag(1.0 / factor.scale))
    C = np.zeros((factor.size, factor.size))
    C[np.ix_(factor.kept, factor.kept)] = -x / factor.scale[:, None]
    Z = factor.unseen
    C -= Z @ (Z.T @ C)
    C -= (Z @ (Z.T @ C.T)).T
    return C


@pytest.mark.parametrize("derived", [True, False])
def test_the_covariance_is_the_one_of_a_single_solve_of_every_unit_vector(factor_and_problem, monkeypatch, derived):
    """The basic unknowns' block from the constraints (derived) or every column solved (the
    fallback for large blocks): the plain covariance to 1e-13 of its largest entry, each variance
    to 1e-9 of itself, and nothing left in the unseen directions or off the constraints."""
    factor, problem, _ = factor_and_problem
    if not derived:
        monkeypatch.setattr(sparse_factor, "BASIC_BLOCK_ROWS", 0)
    basic = sparse_factor.basic_unknowns(factor.A[:, factor.kept].tocsr())
    assert basic.size == (factor.constraints if derived else 0)
    assert factor.unknowns > 3 * sparse_factor.SOLVE_BLOCK and factor.unseen.shape[1] > 0  # blocks and projections at work
    expected = _plain_covariance(factor)
    covariance = factor.covariance()
    largest = np.abs(expected).max()
    np.testing.assert_allclose(covariance, expected, rtol=0, atol=1e-13 * largest)
    variances = np.diag(expected)
    np.testing.assert_allclose(np.diag(covariance), variances, rtol=1e-9, atol=1e-15 * largest)
    assert np.abs(covariance @ factor.unseen.toarray()).max() <= 1e-12 * largest  # nothing left in the unseen directions
    assert np.abs(problem.A @ covariance).max() <= 1e-12 * largest  # every column a feasible direction


def test_the_basic_unknowns_make_a_square_regular_block_of_the_constraints(factor_and_problem):
    factor, problem, _ = factor_and_problem
    A = factor.A[:, factor.kept].tocsr()
    basic = sparse_factor.basic_unknowns(A)
    assert basic.size == A.shape[0] == np.unique(basic).size
    singular = np.linalg.svd(A[:, basic].toarray(), compute_uv=False)
    assert singular.min() > 1e-6 * singular.max()
    dependent = sparse.vstack([A, A[:1]]).tocsr()  # a repeated balance: no square regular block
    assert sparse_factor.basic_unknowns(dependent).size == 0
    nearly = sparse.vstack([A, A[:1] + 1e-6 * A[1:2]]).tocsr()  # regular, but A_B ill-conditioned: every unknown solved
    assert sparse_factor.basic_unknowns(nearly).size == 0


@pytest.mark.slow
def test_the_covariance_of_the_30_node_plant_with_four_minerals_is_the_one_of_every_solve():
    """The plant the method was made for (4,100 unknowns, 3,660 kept, 2,050 balances, 440 unseen
    directions), at its starting point: the covariance against the one of all 3,660 solves."""
    factor, problem, _ = _factor_at_start(10)
    assert (factor.size, factor.unknowns, factor.constraints, factor.unseen.shape[1]) == (4100, 3660, 2050, 440)
    expected = _plain_covariance(factor)
    covariance = factor.covariance()
    largest = np.abs(expected).max()
    np.testing.assert_allclose(covariance, expected, rtol=0, atol=1e-13 * largest)
    np.testing.assert_allclose(np.diag(covariance), np.diag(expected), rtol=1e-9, atol=1e-15 * largest)


def test_the_covariance_times_a_matrix_is_the_covariance_times_it(factor_and_problem):
    """covariance_times(G) in blocks of columns against the dense covariance times G, for more
    columns than a block holds (and a last block short)."""
    factor, _, _ = factor_and_problem
    G = np.random.default_rng(1).standard_normal((factor.size, 2 * sparse_factor.SOLVE_BLOCK + 5))
    expected = _plain_covariance(factor) @ G
    np.testing.assert_allclose(factor.covariance_times(G), expected, rtol=0, atol=1e-11 * np.abs(expected).max())


def test_the_unseen_directions_split_into_blocks_of_disjoint_unknowns(factor_and_problem):
    factor, _, _ = factor_and_problem
    Z = factor.unseen.toarray()
    blocks = sparse_factor._direction_blocks(factor.unseen)
    rows = np.concatenate([block_rows for block_rows, _ in blocks])
    assert rows.size == np.unique(rows).size  # disjoint
    assert sum(basis.shape[1] for _, basis in blocks) == Z.shape[1]
    projector = np.zeros_like(Z @ Z.T)
    for block_rows, basis in blocks:
        projector[np.ix_(block_rows, block_rows)] += basis @ basis.T
    np.testing.assert_allclose(projector, Z @ Z.T, rtol=0, atol=1e-15)
    assert sparse_factor._direction_blocks(factor.unseen[:, :0]) == []


@pytest.mark.parametrize("size", [1, 255, 256, 257, 700])
def test_the_symmetrised_covariance_is_the_mean_with_its_transpose_bit_for_bit(size):
    C = np.random.default_rng(size).standard_normal((size, size))
    expected = (C + C.T) / 2.0
    assert np.array_equal(sparse_tables._symmetrised(C.copy()), expected)


def test_the_linearisation_holds_the_symmetrised_covariance(factor_and_problem):
    factor, problem, v = factor_and_problem
    linearisation = sparse_tables.SparseLinearisation.at(problem, v, factor)
    C = factor.covariance()
    assert np.array_equal(linearisation.C, (C + C.T) / 2.0)


def _random_sparse(rows: int, columns: int, seed: int):
    from scipy import sparse

    return sparse.random(rows, columns, density=0.05, random_state=seed, format="csc")


@pytest.mark.parametrize("rows", [1, 63, 64, 65, 200])
def test_a_dense_matrix_times_a_sparse_one_by_blocks_of_rows_is_scipy_s_product_bit_for_bit(rows):
    D = np.random.default_rng(rows).standard_normal((rows, 90))
    S = _random_sparse(90, 70, rows)
    product = sparse_tables.dense_times_sparse(D, S)
    assert product.flags["C_CONTIGUOUS"]
    assert np.array_equal(product, np.asarray(D @ S))


def test_the_scaled_projected_products_are_the_plain_expression_bit_for_bit():
    G, X = _random_sparse(120, 80, 1), _random_sparse(150, 80, 2)
    CX = np.random.default_rng(3).standard_normal((150, 80))
    scale = np.random.default_rng(4).uniform(0.5, 2.0, 80)
    expected = ((G.T @ G).toarray() - np.asarray(X.T @ CX)) / np.outer(scale, scale)
    assert np.array_equal(sparse_tables._scaled_projected_products(G, X, CX, scale, rows=32), expected)


def test_the_worth_table_s_label_columns_are_the_columns_pandas_makes_of_the_repeated_labels():
    import pandas as pd

    from tromplab.circuit.worth import _taken

    labels = np.array(["share a 1", "flow b", "assay c 2"], dtype=object)
    positions = np.tile(np.arange(labels.size), 4)
    for column in (labels, labels.astype(str)):  # object and fixed-width strings, as the table has both
        pd.testing.assert_frame_equal(pd.DataFrame({"x": _taken(column, positions)}), pd.DataFrame({"x": column[positions]}))
