r"""Survey planning: the design advice of :mod:`tromplab.circuit.design` for a survey taken or
for one still to take, simulated from the flowsheet.

With a survey, the advice is linearised at its reconciled values.  Without one, the survey
is simulated at the steady state of the flowsheet under stated assumptions
(:data:`SIMULATION_ASSUMPTIONS`): every feed a Rosin-Rammler distribution, every mill a
Rosin-Rammler discharge, every separator Plitt's (1976) curve (the registry's
``rosin_rammler_bypass`` without bypass) cutting at the geometric mean size of its own feed
(found by fixed-point iteration, recycles included), measured without noise at the expected
values, with the error model's standard deviations.  The prediction then says what the
measurements would give on a plant like that, not on the plant itself: its sds scale with
the error model, and the ranking is what carries over.

References
----------
Narasimhan, S. & Jordache, C. (2000). *Data Reconciliation and Gross Error Detection: An
Intelligent Use of Process Data*. Gulf Publishing, Houston, chapter 10 (design of sensor
networks).

Plitt, L. R. (1976). A mathematical model of the hydrocyclone classifier. *CIM Bulletin*
69(776), 114-123.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..errors import OptionError
from ..results_contract import ResultContract
from .design import design_table, observability_table, select_quantities
from .flowsheet import Flowsheet, read_flowsheet
from .measurements import SHARE_COLUMNS, STREAM_VALUE_COLUMNS, ErrorModel, Survey
from .reconciliation import CircuitBalance, reconcile
from .simulation import (
    EXAMPLE_EDGES_UM,
    classes_from_edges,
    plitt_partition_to_fines,
    rosin_rammler_shares,
    steady_state,
)

#: The simulated plant: feeds (t/h each, Rosin-Rammler d63 um and n), mill discharge
#: (Rosin-Rammler d63 um and n), separators' Plitt sharpness m, and the sieve series (um).
SIMULATED_FEED = (100.0, 2000.0, 1.0)
SIMULATED_DISCHARGE = (250.0, 1.0)
SIMULATED_SHARPNESS = 2.5
SIMULATED_EDGES_UM = EXAMPLE_EDGES_UM
#: Rounds of the fixed point that sets each separator's cut at its feed's geometric mean size.
CUT_ITERATIONS = 50

SIMULATION_ASSUMPTIONS = (
    f"each feed {SIMULATED_FEED[0]:g} t/h, Rosin-Rammler d63 {SIMULATED_FEED[1]:g} um, n {SIMULATED_FEED[2]:g}; "
    f"each mill discharge Rosin-Rammler d63 {SIMULATED_DISCHARGE[0]:g} um, n {SIMULATED_DISCHARGE[1]:g}; "
    f"each separator Plitt's curve, sharpness m {SIMULATED_SHARPNESS:g}, no bypass, cut at the geometric mean size "
    f"of its feed; sieves {', '.join(f'{e:g}' for e in SIMULATED_EDGES_UM)} um (pan and open top added); "
    "measured at the expected values (no noise) with the error model's sds"
)


@dataclass(frozen=True)
class DesignAdvice(ResultContract):
    """The design advice of a survey (taken or simulated) and what it rests on.

    Attributes
    ----------
    balance : CircuitBalance
        The reconciled survey the prediction is linearised at.
    table : pandas.DataFrame
        :func:`~tromplab.circuit.design.design_table` (``DIR/design.csv``).
    simulated : bool
        True when no survey was given and the survey was simulated from the flowsheet.
    assumptions : str
        What the simulated survey assumes (:data:`SIMULATION_ASSUMPTIONS`, the streams sampled
        and the flows measured); "" for a survey taken.
    errors : ErrorModel or None
        The error model of the survey and of the candidates (None: the default
        :class:`~tromplab.circuit.measurements.ErrorModel`).
    """

    balance: CircuitBalance
    table: pd.DataFrame
    simulated: bool
    assumptions: str
    errors: ErrorModel | None = None

    def summary(self) -> pd.DataFrame:
        """The best candidate of each measurement and stream: rows of :attr:`table`, ranked."""
        return self.table.drop_duplicates(["stream", "measurement"]).reset_index(drop=True)

    def to_frame(self) -> pd.DataFrame:
        """:attr:`table`, what ``design.csv`` holds."""
        return self.table.copy()

    def _result_context(self) -> str:
        where = "a survey simulated from the flowsheet" if self.simulated else f"the survey {self.balance.survey.source}"
        return f"Survey design advice for {self.balance.flowsheet.describe()}, predicted at the reconciled values of {where}"

    def save(self, directory) -> dict:
        """Write what ``tromplab circuit design`` writes into ``directory`` (replaced as a whole):
        ``design.csv``, ``observability.csv``, ``summary.txt`` (:meth:`report`) and, for a simulated
        survey, ``simulated_survey.csv``.  Returns ``{file name: path}``."""
        from ..output.csv_parts import file_writers
        from ..output.outputs import replace_folder
        from .simulation import survey_table

        tables = {"design": self.table, "observability": observability_table(self.balance, self.errors)}
        if self.simulated:
            tables["simulated_survey"] = survey_table(self.balance.survey)
        return replace_folder(file_writers(tables, texts={"summary.txt": self.report() + "\n"}), directory)

    def report(self, top: int = 5) -> str:
        """A few lines: what the advice rests on and the best candidates, one per measurement."""
        where = "a survey simulated from the flowsheet" if self.simulated else f"the survey {self.balance.survey.source}"
        lines = [
            f"Survey design advice for {self.balance.flowsheet.describe()}",
            f"predicted at the reconciled values of {where}",
        ]
        if self.simulated:
            lines.append(f"simulated: {self.assumptions}")
        best = self.summary().head(top)
        if best.empty:
            lines.append("no measurement to add: nothing in this survey is adjusted, so no sd to predict")
        for row in best.itertuples():
            testable = f"; makes testable: {row.makes_testable}" if row.makes_testable else ""
            lines.append(f"  {row.rank}. {row.measurement} of {row.stream}: sd of {row.quantity} {row.sd_before:.3g} -> "
                         f"{row.sd_after:.3g} (-{100 * row.reduction:.0f} %){testable}")  # fmt: skip
        return "\n".join(lines)


def design_advice(
    flowsheet,
    measurements=None,
    *,
    quantity=None,
    sampled=None,
    flows=None,
    errors: ErrorModel | None = None,
    alpha: float | None = None,
    size_unit: str | None = None,
    exclude=(),
    progress=None,
) -> DesignAdvice:
    """Rank the measurements one could add to a survey by how much they would lower the sd of
    the results named, and say which measurements they would make testable.

    Parameters
    ----------
    flowsheet : Flowsheet, path or DataFrame
        The flowsheet.
    measurements : Survey, path or DataFrame, optional
        The survey taken; without it, a survey simulated from the flowsheet
        (:func:`simulated_survey`).
    quantity : str or list of str, optional
        The results whose sd matters (:func:`~tromplab.circuit.design.select_quantities`;
        default each separator's partition at its cut and each circulating load).
    sampled, flows : str or list of str, optional
        Without a survey: the streams with a size analysis (default every stream) and those
        with a measured solids flow (default none: flows relative to a feed of 100).
    errors : ErrorModel, optional
        The error model of the survey and of the candidates.
    alpha, size_unit, exclude, progress
        As for :func:`~tromplab.circuit.reconciliation.reconcile` (``progress`` also hears
        ``"design: candidate i of n"``).

    Returns
    -------
    DesignAdvice
    """
    errors = errors or ErrorModel()
    if not isinstance(flowsheet, Flowsheet):
        flowsheet = read_flowsheet(flowsheet)
    options = {} if alpha is None else {"alpha": alpha}
    if measurements is None:
        survey, assumptions = simulated_survey(flowsheet, sampled=sampled, flows=flows, errors=errors)
    else:
        for name, value in (("sampled", sampled), ("flows", flows)):
            if value:
                raise OptionError(name, "describes a survey to simulate: it is not taken with a survey given")
        survey, assumptions = measurements, ""
    balance = reconcile(flowsheet, survey, errors=errors, size_unit=size_unit, exclude=exclude, progress=progress, **options)
    table = design_table(balance, select_quantities(balance, quantity), errors=errors, progress=progress)
    return DesignAdvice(balance=balance, table=table, simulated=measurements is None, assumptions=assumptions, errors=errors)


def _streams(value, option: str, flowsheet: Flowsheet, default) -> tuple[str, ...]:
    """Stream names given as a list or a comma-separated string, checked against the flowsheet."""
    if value is None or (isinstance(value, str) and not value.strip()):
        return tuple(default)
    names = [n.strip() for n in value.split(",")] if isinstance(value, str) else [str(n).strip() for n in value]
    unknown = [n for n in names if n not in flowsheet.stream_index]
    if unknown:
        raise OptionError(option, f"names {', '.join(repr(n) for n in unknown)}, not a stream of the flowsheet "
                          f"({', '.join(flowsheet.stream_names)})")  # fmt: skip
    return tuple(dict.fromkeys(names))


def simulated_truth(flowsheet: Flowsheet) -> tuple[pd.DataFrame, np.ndarray]:
    """``(classes, class flows)`` of the steady state of :data:`SIMULATION_ASSUMPTIONS`."""
    classes = classes_from_edges(SIMULATED_EDGES_UM)
    log_size = np.log(classes["size"].to_numpy(float))
    total, d63, n = SIMULATED_FEED
    feeds = {feed: total * rosin_rammler_shares(SIMULATED_EDGES_UM, d63, n) for feed in flowsheet.feeds}
    discharge = rosin_rammler_shares(SIMULATED_EDGES_UM, *SIMULATED_DISCHARGE)
    mills = {node.name: discharge for node in flowsheet.nodes if node.kind == "mill"}
    cuts = {node.name: float(np.exp(log_size.mean())) for node in flowsheet.separators}
    for _ in range(CUT_ITERATIONS):
        partitions = {name: plitt_partition_to_fines(classes["size"], cut, SIMULATED_SHARPNESS) for name, cut in cuts.items()}
        class_flows = steady_state(flowsheet, classes, feeds, partitions, mills)
        previous, cuts = cuts, {}
        for node in flowsheet.separators:
            feed = sum(class_flows[flowsheet.stream_index[s]] for s in node.inputs)
            cuts[node.name] = float(np.exp(feed @ log_size / feed.sum()))
        if all(abs(cuts[name] / previous[name] - 1.0) < 1e-9 for name in cuts):
            break
    return classes, class_flows


def simulated_survey(flowsheet: Flowsheet, *, sampled=None, flows=None, errors: ErrorModel | None = None) -> tuple[Survey, str]:
    """A survey of the flowsheet simulated under :data:`SIMULATION_ASSUMPTIONS` and the words
    that say so: size analyses of the ``sampled`` streams (default every stream) and solids
    flows of the ``flows`` streams (default none), at the expected values, with the sds of
    ``errors``."""
    errors = errors or ErrorModel()
    sampled = _streams(sampled, "sampled", flowsheet, flowsheet.stream_names)
    measured_flows = _streams(flows, "flows", flowsheet, ())
    classes, class_flows = simulated_truth(flowsheet)
    shares, flow_rows = [], []
    for stream in sampled:
        x = class_flows[flowsheet.stream_index[stream]] / class_flows[flowsheet.stream_index[stream]].sum()
        relative, absolute = errors.streams.get(stream, (errors.relative_error, errors.absolute_error))
        shares.append(pd.DataFrame({"stream": stream, "class_index": np.arange(x.size), "value": x,
                                    "sd": errors.share_sd(x, stream), "row": None, "relative": relative,
                                    "absolute": absolute}, columns=SHARE_COLUMNS))  # fmt: skip
    for stream in measured_flows:
        value = float(class_flows[flowsheet.stream_index[stream]].sum())
        flow_rows.append({"stream": stream, "value": value, "sd": errors.flow_relative_error * value, "row": None,
                          "relative": errors.flow_relative_error})  # fmt: skip
    survey = Survey(classes=classes, shares=pd.concat(shares, ignore_index=True) if shares else pd.DataFrame(columns=SHARE_COLUMNS),
                    flows=pd.DataFrame(flow_rows, columns=STREAM_VALUE_COLUMNS),
                    pct_solids=pd.DataFrame(columns=STREAM_VALUE_COLUMNS), size_unit="um",
                    source="simulated survey", closed_streams=sampled, evaluated_at=errors.evaluated_at)  # fmt: skip
    words = (f"{SIMULATION_ASSUMPTIONS}; size analyses of {', '.join(sampled) or 'no stream'}; "
             f"solids flows measured on {', '.join(measured_flows) or 'no stream (flows relative to a feed of 100)'}")  # fmt: skip
    return survey, words
