"""Which path a survey's reconciliation takes: the dense null-space form of
:mod:`tromplab.circuit.problem`, or, for a large flowsheet, the sparse augmented system of
:mod:`tromplab.circuit.sparse_solve` (docs/circuit.md, "Large flowsheets").  Decided from the
flowsheet and the survey alone, so that a survey of the usual size never imports the sparse path.
"""

from __future__ import annotations

#: From this many unknowns on (class flows, water flows and component class flows) a survey is
#: reconciled on the sparse path: the 30-node plant has 820 solids class flows, the bundled example 176.
SPARSE_FLOWSHEET_UNKNOWNS = 800


def unknown_count(flowsheet, survey) -> int:
    """The number of unknowns of the survey's reconciliation (as :func:`~tromplab.circuit.problem.build_problem` lays them out)."""
    S, n = len(flowsheet.streams), max(survey.n_classes, 1)
    n_water = S + len(flowsheet.water_streams) if len(survey.pct_solids) else 0
    return S * n + n_water + len(survey.components) * S * n


def takes_sparse_path(flowsheet, survey) -> bool:
    """Whether ``survey`` is large enough for the sparse path and has no water balance (the sparse
    path needs every free direction seen by a measurement: :mod:`tromplab.circuit.sparse_solve`)."""
    return unknown_count(flowsheet, survey) >= SPARSE_FLOWSHEET_UNKNOWNS and not len(survey.pct_solids)
