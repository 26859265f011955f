"""Plant surveys: reconcile a whole circuit's size analyses, then give every separator its
partition curve.

``tromplab circuit`` is :func:`reconcile_circuit` (a :class:`CircuitResult` whose ``save(DIR)``
writes the command's folder) and ``tromplab circuit design`` is :func:`design_circuit` (a
:class:`~tromplab.circuit.planning.DesignAdvice`, the same); ``reconcile(flowsheet, survey)``
returns the :class:`~tromplab.circuit.reconciliation.CircuitBalance` beneath them (balance,
tests, serial elimination, what each measurement is worth, survey design advice).  The method, the error model and the validation are in ``docs/circuit.md``.
"""

from .commands import CircuitResult, design_circuit, fit_separators, reconcile_circuit
from .flowsheet import Flowsheet, Node, Stream, flowsheet_from_streams, read_flowsheet
from .measurements import ErrorModel, Survey, read_survey
from .reconciliation import CircuitBalance, reconcile

__all__ = [
    "CircuitBalance",
    "CircuitResult",
    "ErrorModel",
    "Flowsheet",
    "Node",
    "Stream",
    "Survey",
    "design_circuit",
    "fit_separators",
    "flowsheet_from_streams",
    "read_flowsheet",
    "read_survey",
    "reconcile",
    "reconcile_circuit",
]
