"""Where the bounds' active set ends, said in words: the flows held at 0 whose multiplier has the
wrong sign (raising them would lower the sum of squares), counted on both paths
(``CircuitBalance.held_against_multipliers``) and named in the summary, with a reconciliation
that did not converge.

The dense path's rule holds such a flow for good once its release has made it negative again, so
its end need not be a minimum: on the 30-node plant with four minerals (``large_plant(10, 20)``)
it ended with 12 of them (docs/performance.md, "where the bounds' rule ends"), before large
flowsheets took bounds of their own (``sparse_solve.bounded_sparse``), which count the class
flows that emptied their class instead.  Here a flow is held on purpose where the least squares
wants it well above 0.
"""

import dataclasses
import warnings
from pathlib import Path

import numpy as np
import pytest

from tromplab.circuit import path_choice, read_flowsheet, read_survey, reconcile, sparse_solve
from tromplab.circuit.problem import build_problem, held_against_multipliers, held_multipliers, solve
from tromplab.circuit.simulation import lab_survey, large_plant

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def example():
    sheet = read_flowsheet(ROOT / "datasets" / "circuit_example_flowsheet.csv")
    survey = read_survey(ROOT / "tests" / "data" / "circuit_reference" / "inputs" / "assay_class.csv", sheet)
    return sheet, survey, reconcile(sheet, survey)


def _held_on_purpose(problem, balance):
    """The balance's held flows and its largest class flow, and the solution with all of them held."""
    v = balance._unknowns
    largest = int(np.argmax(v[: balance.class_flows.size]))
    active = np.zeros(v.size, dtype=bool)
    active[list(balance.at_bound) + [largest]] = True
    return largest, active


def test_the_rules_end_on_the_bundled_surveys_is_a_minimum(example):
    _, _, balance = example
    assert balance.at_bound and balance.held_against_multipliers == 0
    assert "would lower the sum of squares" not in balance.report() and "not converged" not in balance.report()


def test_a_flow_held_where_the_least_squares_wants_it_is_counted(example):
    sheet, survey, balance = example
    problem, _ = build_problem(sheet, balance.survey)
    largest, active = _held_on_purpose(problem, balance)
    current = problem.fixed_at_zero(active)
    z, success, _ = solve(current, balance._unknowns)
    v = current.m0 + current.N @ z
    held, multipliers, threshold = held_multipliers(current, v)
    assert success and threshold < 0
    assert multipliers[held == largest][0] < threshold  # raising it lowers the sum of squares
    assert held_against_multipliers(problem, v, current.at_bound) == int(np.sum(multipliers < threshold)) >= 1


def test_both_paths_count_the_same_flows(monkeypatch):
    """The 6-node plant with four minerals, a flow held on purpose: the sparse path's count from
    its factor equals the dense path's from its null space."""
    truth = large_plant(2, 20)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the truth's grade of an empty class is 0/0 (no assay drawn)
        survey = lab_survey(truth, np.random.default_rng(40), flows={"fresh_feed": 0.02})
    monkeypatch.setattr(path_choice, "SPARSE_FLOWSHEET_UNKNOWNS", 1)
    balance = reconcile(truth.flowsheet, survey)
    assert sparse_solve.is_sparse(balance.problem) and balance.held_against_multipliers == 0
    largest, active = _held_on_purpose(balance.problem, balance)
    current = sparse_solve._held(balance.problem, active)
    free = np.setdiff1d(np.arange(active.size), current.held)
    v, success, _, _ = sparse_solve.solve_sparse(current, balance._unknowns, free=free)
    sparse_count = sparse_solve.held_against_multipliers_sparse(balance.problem, v, current.held)
    dense_problem, _ = build_problem(truth.flowsheet, balance.survey)
    dense_count = held_against_multipliers(dense_problem, v, current.held)
    assert success and sparse_count == dense_count >= 1


def test_the_summary_says_so_in_words(example):
    _, _, balance = example
    fresh = dataclasses.replace(balance)
    fresh.__dict__["held_against_multipliers"] = 3  # as the 30-node plant with four minerals ends (12 there)
    assert ("3 of the flows held at 0 would lower the sum of squares if raised" in fresh.report()
            and "not shown to be the least-squares minimum under the bounds" in fresh.report())  # fmt: skip
    stopped = dataclasses.replace(balance, success=False, message="Gauss-Newton did not converge in 200 steps")
    assert "not converged: Gauss-Newton did not converge in 200 steps" in stopped.report()


def test_a_large_flowsheet_says_why_in_its_own_words(example):
    _, _, balance = example
    counted = dataclasses.replace(balance, raisable_held=2)  # as the bounds of a large flowsheet count them
    assert counted.held_against_multipliers == 2
    assert ("2 of the flows held at 0 would lower the sum of squares if raised (each reached 0, emptied its class and "
            "took the class's assays out of the least squares)" in counted.report())  # fmt: skip
    assert dataclasses.replace(balance, raisable_held=0).held_against_multipliers == 0
