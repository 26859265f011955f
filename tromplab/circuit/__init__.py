"""Plant surveys: reconcile a whole circuit's size analyses, then give every separator its
partition curve.

``tromplab.circuit.reconcile(flowsheet, measurements)`` returns a
:class:`~tromplab.circuit.reconciliation.CircuitBalance` (balance, tests, serial elimination,
what each measurement is worth, survey design advice); ``tromplab circuit`` is the command.  The method, the error model and the validation are in ``docs/circuit.md``.
"""

from .flowsheet import Flowsheet, Node, Stream, flowsheet_from_streams, read_flowsheet
from .measurements import ErrorModel, Survey, read_survey
from .reconciliation import CircuitBalance, reconcile

__all__ = [
    "CircuitBalance",
    "ErrorModel",
    "Flowsheet",
    "Node",
    "Stream",
    "Survey",
    "flowsheet_from_streams",
    "read_flowsheet",
    "read_survey",
    "reconcile",
]
