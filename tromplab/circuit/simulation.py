r"""Simulated circuit surveys with a known truth, for the validation of the reconciliation.

A truth is the steady state of a flowsheet: the feeds' flows and distributions, the
partition curve of every separator and the discharge distribution of every mill fix every
class flow through one linear system (recycles included).  A survey draws the class masses of
each analysed stream from the error model of :class:`~tromplab.circuit.measurements.ErrorModel`,
:math:`x + \sigma(x)\,\varepsilon` with :math:`\varepsilon \sim N(0, 1)` independent, not
clipped (an unbiased draw: small classes may come out slightly negative), and normalises
them to 100 % as a lab does; measured flows get :math:`F (1 + r \varepsilon)`.

The separators' true curves are Plitt's (1976) partition to the coarse product with a bypass
to it (Kelsall 1953),

.. math:: c(d) = R_f + (1 - R_f)\left(1 - \exp\left[-0.693\,(d/d_{50})^m\right]\right),

(:math:`R_f = 0` for screens); the feeds and mill discharges are Rosin-Rammler
distributions, :math:`P(d) = 1 - \exp[-(d/d_{63})^n]` passing (Rosin & Rammler 1933).

References
----------
Kelsall, D. F. (1953). A further study of the hydraulic cyclone. *Chemical Engineering
Science* 2(6), 254-272.

Plitt, L. R. (1976). A mathematical model of the hydrocyclone classifier. *CIM Bulletin*
69(776), 114-123.

Rosin, P. & Rammler, E. (1933). The laws governing the fineness of powdered coal.
*Journal of the Institute of Fuel* 7, 29-36.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..curves.formulas import get_formula
from .assays import ASSAY_COLUMNS
from .flowsheet import Flowsheet, read_flowsheet
from .measurements import SHARE_COLUMNS, STREAM_VALUE_COLUMNS, ErrorModel, Survey, read_survey
from .reconciliation import reconcile


@dataclass(frozen=True)
class CircuitTruth:
    """The true steady state of a circuit: class flows of every stream (streams x classes)."""

    flowsheet: Flowsheet
    classes: pd.DataFrame
    class_flows: np.ndarray
    size_unit: str = "um"
    partitions: dict = field(default_factory=dict)  # separator -> true partition to fines per class
    #: Assayed components: their names and class flows (components x streams x classes); the
    #: solids may hold more (an unassayed gangue).
    components: tuple[str, ...] = ()
    component_flows: np.ndarray | None = None
    component_partitions: dict = field(default_factory=dict)  # (separator, component) -> partition to fines

    @property
    def grades(self) -> np.ndarray:
        """True assays, components x streams x classes (fractions of the class's solids)."""
        return self.component_flows / self.class_flows[None, :, :]

    @property
    def flows(self) -> np.ndarray:
        return self.class_flows.sum(axis=1)

    @property
    def shares(self) -> np.ndarray:
        return self.class_flows / self.flows[:, None]


def rosin_rammler_shares(edges, d63: float, n: float) -> np.ndarray:
    """Shares of the classes between ``edges`` (increasing, the pan below the first, the open
    top above the last), coarse to fine, of a Rosin-Rammler distribution."""
    passing = 1.0 - np.exp(-((np.asarray(edges, dtype=float) / d63) ** n))
    cumulative = np.concatenate(([0.0], passing, [1.0]))
    return np.diff(cumulative)[::-1]


def plitt_partition_to_fines(size, d50: float, m: float, bypass: float = 0.0) -> np.ndarray:
    r"""Partition to the fine product of Plitt's (1976) corrected curve with a bypass to the
    coarse product: the registry's ``rosin_rammler_bypass``, :math:`(1 - R_f)\exp(-\ln 2\,(d/d_{50})^m)`."""
    formula = get_formula("rosin_rammler_bypass")
    return formula.phi(np.asarray(size, dtype=float) / d50, m, bypass=bypass)


def classes_from_edges(edges) -> pd.DataFrame:
    """Class table, coarse to fine, from increasing sieve sizes (pan and open top added)."""
    edges = np.asarray(edges, dtype=float)
    lower = np.concatenate(([np.nan], edges))[::-1]
    upper = np.concatenate((edges, [np.nan]))[::-1]
    ratio = edges[1] / edges[0]
    low = np.where(np.isfinite(lower), lower, upper / ratio)
    high = np.where(np.isfinite(upper), upper, lower * ratio)
    return pd.DataFrame({"size_lower": lower, "size_upper": upper, "size": np.sqrt(low * high)})


def steady_state(flowsheet: Flowsheet, classes: pd.DataFrame, feeds: dict, partitions: dict, discharges: dict) -> np.ndarray:
    """Class flows (streams x classes) of the steady state.

    ``feeds``: ``{stream: class flows}``; ``partitions``: ``{separator: partition to fines per
    class}``; ``discharges``: ``{mill: discharge shares per class}``.
    """
    S, n = len(flowsheet.streams), len(classes)
    index = flowsheet.stream_index
    rows, rhs = [], []

    def unit(stream, i):
        row = np.zeros(S * n)
        row[index[stream] * n + i] = 1.0
        return row

    for stream, flows in feeds.items():
        for i in range(n):
            rows.append(unit(stream, i))
            rhs.append(flows[i])
    for node in flowsheet.nodes:
        feed_rows = [sum(unit(s, i) for s in node.inputs) for i in range(n)]
        if node.kind == "separator":
            phi = partitions[node.name]
            for i in range(n):
                rows.append(unit(node.fine, i) - phi[i] * feed_rows[i])
                rows.append(unit(node.coarse, i) - (1.0 - phi[i]) * feed_rows[i])
                rhs += [0.0, 0.0]
        elif node.kind == "junction":
            for i in range(n):
                rows.append(unit(node.outputs[0], i) - feed_rows[i])
                rhs.append(0.0)
        else:
            total = sum(feed_rows)
            for i in range(n):
                rows.append(unit(node.outputs[0], i) - discharges[node.name][i] * total)
                rhs.append(0.0)
    return np.linalg.solve(np.array(rows), np.array(rhs)).reshape(S, n)


def grinding_circuit() -> CircuitTruth:
    """A closed ball-mill circuit with a hydrocyclone: fresh feed and cyclone underflow to the
    mill, mill discharge to the cyclone, overflow the product (ten classes, pan to +600 um)."""
    sheet = pd.DataFrame(
        {
            "stream": ["fresh_feed", "cyclone_feed", "cyclone_overflow", "cyclone_underflow"],
            "from": ["", "mill", "cyclone", "cyclone"],
            "to": ["mill", "cyclone", "", "mill"],
            "product": ["", "ground", "fine", "coarse"],
        }
    )
    flowsheet = read_flowsheet(sheet)
    classes = classes_from_edges([20, 38, 53, 75, 106, 150, 212, 300, 425, 600])
    phi = plitt_partition_to_fines(classes["size"], 90.0, 2.5, bypass=0.25)
    feed = 250.0 * rosin_rammler_shares([20, 38, 53, 75, 106, 150, 212, 300, 425, 600], 800.0, 1.0)
    discharge = rosin_rammler_shares([20, 38, 53, 75, 106, 150, 212, 300, 425, 600], 180.0, 1.0)
    flows = steady_state(flowsheet, classes, {"fresh_feed": feed}, {"cyclone": phi}, {"mill": discharge})
    return CircuitTruth(flowsheet=flowsheet, classes=classes, class_flows=flows, size_unit="um", partitions={"cyclone": phi})


def two_deck_screen() -> CircuitTruth:
    """A two-deck screen: the top deck's undersize feeds the bottom deck (an internal stream
    no one samples); oversize, middlings and undersize leave (eight classes, mm)."""
    sheet = pd.DataFrame(
        {
            "stream": ["screen_feed", "oversize", "top_deck_undersize", "middlings", "undersize"],
            "from": ["", "top_deck", "top_deck", "bottom_deck", "bottom_deck"],
            "to": ["top_deck", "", "bottom_deck", "", ""],
            "product": ["", "coarse", "fine", "coarse", "fine"],
        }
    )
    flowsheet = read_flowsheet(sheet)
    edges = [0.5, 1, 2, 4, 8, 16, 31.5]
    classes = classes_from_edges(edges)
    partitions = {
        "top_deck": plitt_partition_to_fines(classes["size"], 10.0, 4.0),
        "bottom_deck": plitt_partition_to_fines(classes["size"], 3.0, 3.5),
    }
    feed = 100.0 * rosin_rammler_shares(edges, 6.0, 1.0)
    flows = steady_state(flowsheet, classes, {"screen_feed": feed}, partitions, {})
    return CircuitTruth(flowsheet=flowsheet, classes=classes, class_flows=flows, size_unit="mm", partitions=partitions)


#: Sieve series of the bundled example plant (um): the pan below 38, the open top above 19000.
EXAMPLE_EDGES_UM = (38, 75, 150, 300, 600, 1180, 2360, 4750, 9500, 19000)


def example_plant() -> CircuitTruth:
    """The bundled example (``datasets/circuit_example_*.csv``): a two-deck screen whose undersize
    feeds a closed ball-mill and hydrocyclone circuit.

    Screen feed 400 t/h, Rosin-Rammler d63 5 mm, n 0.9; top deck d50 8 mm (m 4), bottom deck
    d50 2 mm (m 3.5), both without bypass; mill discharge Rosin-Rammler d63 250 um, n 1.0;
    cyclone d50c 110 um (m 2.5) with a bypass of 0.20 to the underflow.  Synthetic: chosen to
    look like a plant, not measured anywhere.
    """
    sheet = pd.DataFrame(
        {
            "stream": [
                "screen_feed",
                "oversize",
                "top_deck_undersize",
                "middlings",
                "undersize",
                "cyclone_feed",
                "cyclone_overflow",
                "cyclone_underflow",
            ],
            "from": ["", "top_deck", "top_deck", "bottom_deck", "bottom_deck", "mill", "cyclone", "cyclone"],
            "to": ["top_deck", "", "bottom_deck", "", "mill", "cyclone", "", "mill"],
            "product": ["", "coarse", "fine", "coarse", "fine", "ground", "fine", "coarse"],
        }
    )
    flowsheet = read_flowsheet(sheet, source="example plant")
    classes = classes_from_edges(EXAMPLE_EDGES_UM)
    size = classes["size"]
    partitions = {
        "top_deck": plitt_partition_to_fines(size, 8000.0, 4.0),
        "bottom_deck": plitt_partition_to_fines(size, 2000.0, 3.5),
        "cyclone": plitt_partition_to_fines(size, 110.0, 2.5, bypass=0.2),
    }
    feed = 400.0 * rosin_rammler_shares(EXAMPLE_EDGES_UM, 5000.0, 0.9)
    discharge = rosin_rammler_shares(EXAMPLE_EDGES_UM, 250.0, 1.0)
    flows = steady_state(flowsheet, classes, {"screen_feed": feed}, partitions, {"mill": discharge})
    return CircuitTruth(flowsheet=flowsheet, classes=classes, class_flows=flows, size_unit="um", partitions=partitions)


def mineral_circuit(bypass: float = 0.25) -> CircuitTruth:
    """The closed grinding circuit of :func:`grinding_circuit` treating an ore of three minerals:
    a heavy mineral (``magnetite``, 5 % of the fresh feed) classified at a finer cut than the
    gangue (the cyclone's d50c 50 um against 95 um: a denser particle settles as a larger light
    one), a sulphide of intermediate density (``pyrite``, 3 %, 65 um), and the gangue (92 %,
    not assayed).  Every mineral follows the registry's ``rosin_rammler_bypass`` curve with the
    same bypass to the underflow (the water split); the mill grinds each to its own Rosin-Rammler
    discharge (d63 150, 170 and 185 um) and conserves each.  The solids are their sum, so the
    solids' partition is the mass-weighted mixture of the minerals' (synthetic, chosen to look
    like a magnetite circuit).
    """
    base = grinding_circuit()
    edges = [20, 38, 53, 75, 106, 150, 212, 300, 425, 600]
    size = base.classes["size"]
    minerals = {"magnetite": (0.05, 50.0, 150.0), "pyrite": (0.03, 65.0, 170.0), "gangue": (0.92, 95.0, 185.0)}
    feed = 250.0 * rosin_rammler_shares(edges, 800.0, 1.0)
    flows, partitions = {}, {}
    for name, (grade, d50, d63) in minerals.items():
        partitions[("cyclone", name)] = plitt_partition_to_fines(size, d50, 2.5, bypass=bypass)
        discharge = rosin_rammler_shares(edges, d63, 1.0)
        flows[name] = steady_state(base.flowsheet, base.classes, {"fresh_feed": grade * feed},
                                   {"cyclone": partitions[("cyclone", name)]}, {"mill": discharge})  # fmt: skip
    class_flows = sum(flows.values())
    f, c = base.flowsheet.stream_index["cyclone_overflow"], base.flowsheet.stream_index["cyclone_underflow"]
    solids_partition = class_flows[f] / (class_flows[f] + class_flows[c])
    assayed = ("magnetite", "pyrite")
    return CircuitTruth(flowsheet=base.flowsheet, classes=base.classes, class_flows=class_flows, size_unit="um",
                        partitions={"cyclone": solids_partition}, components=assayed,
                        component_flows=np.array([flows[name] for name in assayed]),
                        component_partitions={key: phi for key, phi in partitions.items() if key[1] in assayed})  # fmt: skip


#: The minerals of :func:`large_plant`: name, share of the fresh feed, cut of the first cyclone
#: (um) and d63 of the first mill's discharge (um); the gangue (last) is not assayed.
LARGE_PLANT_MINERALS = (("magnetite", 0.05, 60.0, 150.0), ("pyrite", 0.03, 75.0, 170.0),
                        ("chalcopyrite", 0.02, 85.0, 180.0), ("sphalerite", 0.02, 90.0, 185.0),
                        ("gangue", 0.88, 120.0, 200.0))  # fmt: skip


def large_plant(blocks: int = 10, n_classes: int = 20) -> CircuitTruth:
    """A synthetic plant of ``3 blocks`` nodes: ``blocks`` closed grinding stages in series, each a
    sump (junction), a hydrocyclone and a ball mill whose discharge returns to the sump, the
    overflow feeding the next stage's sump (the last the product); ``n_classes`` sieve classes
    (a root-2 series from 10 um) and four assayed minerals and a gangue
    (:data:`LARGE_PLANT_MINERALS`), each classified on Plitt's curve (bypass 0.2) at a cut that
    falls by a factor 1.25 per stage and ground to its own Rosin-Rammler discharge.  The size of
    survey that stays interactive (benchmarks/circuit_speed.py); synthetic, not a plant measured.
    """
    names = {"stream": [], "from": [], "to": [], "product": []}

    def stream(name, source, target, product=""):
        for key, value in zip(names, (name, source, target, product)):
            names[key].append(value)

    stream("fresh_feed", "", "sump_1")
    for b in range(1, blocks + 1):
        stream(f"cyclone_feed_{b}", f"sump_{b}", f"cyclone_{b}")
        stream(f"overflow_{b}", f"cyclone_{b}", f"sump_{b + 1}" if b < blocks else "", "fine")
        stream(f"underflow_{b}", f"cyclone_{b}", f"mill_{b}", "coarse")
        stream(f"discharge_{b}", f"mill_{b}", f"sump_{b}", "ground")
    flowsheet = read_flowsheet(pd.DataFrame(names), source="large plant")
    edges = 10.0 * np.sqrt(2.0) ** np.arange(n_classes - 1)
    classes = classes_from_edges(edges)
    size = classes["size"]
    feed = 500.0 * rosin_rammler_shares(edges, 2000.0, 0.9)
    flows = {}
    for name, grade, d50, d63 in LARGE_PLANT_MINERALS:
        partitions = {f"cyclone_{b}": plitt_partition_to_fines(size, d50 / 1.25 ** (b - 1), 2.5, bypass=0.2)
                      for b in range(1, blocks + 1)}  # fmt: skip
        discharges = {f"mill_{b}": rosin_rammler_shares(edges, d63 / 1.25 ** (b - 1), 1.0) for b in range(1, blocks + 1)}
        flows[name] = steady_state(flowsheet, classes, {"fresh_feed": grade * feed}, partitions, discharges)
    assayed = tuple(name for name, *_ in LARGE_PLANT_MINERALS[:-1])
    return CircuitTruth(flowsheet=flowsheet, classes=classes, class_flows=sum(flows.values()), size_unit="um",
                        components=assayed, component_flows=np.array([flows[name] for name in assayed]))  # fmt: skip


def simulate_survey(
    truth: CircuitTruth,
    rng: np.random.Generator,
    *,
    errors: ErrorModel | None = None,
    measured: tuple[str, ...] | None = None,
    flows: dict | None = None,
    gross: tuple | None = None,
    assayed: tuple[str, ...] | None = None,
) -> Survey:
    """One simulated survey of ``truth``.

    Parameters
    ----------
    measured : tuple of str, optional
        Streams with a size analysis (default: every stream except those no one can sample,
        i.e. all but internal streams named ``*_deck_undersize``).
    flows : dict, optional
        ``{stream: relative sd}`` of measured solids flows (none by default: flows relative to
        the basis of 100 on the first feed).
    gross : (stream, class index, size in sd), optional
        Add a gross error of that many standard deviations to one measured share (of the
        class mass, before the normalisation); a class index of -1 puts it on the stream's
        measured flow, shifted by that many of its stated standard deviations (relative sd
        times the value written).
    assayed : tuple of str, optional
        Streams with per-class assays of every component of ``truth`` (default: the streams
        with a size analysis), each drawn as :math:`a + \\sigma(a)\\,\\varepsilon` from the assay
        error model.

    Returns
    -------
    Survey
        With the standard deviations the error model gives at the measured values (as
        :func:`~tromplab.circuit.measurements.read_survey` would).
    """
    errors = errors or ErrorModel()
    if measured is None:
        measured = tuple(s for s in truth.flowsheet.stream_names if not s.endswith("_deck_undersize"))
    records = []
    for stream in measured:
        s = truth.flowsheet.stream_index[stream]
        x = truth.shares[s]
        value = x + errors.share_sd(x, stream) * rng.standard_normal(x.size)
        if gross is not None and gross[0] == stream and gross[1] >= 0:
            value[gross[1]] += gross[2] * errors.share_sd(x[gross[1]], stream)
        value = value / value.sum()  # a closed analysis, normalised as the lab reports it
        relative, absolute = errors.streams.get(stream, (errors.relative_error, errors.absolute_error))
        for i in range(x.size):
            records.append({"stream": stream, "class_index": i, "value": value[i], "sd": float(errors.share_sd(value[i], stream)),
                            "row": None, "relative": relative, "absolute": absolute})  # fmt: skip
    shares = pd.DataFrame(records, columns=SHARE_COLUMNS)
    flow_table = _drawn_flows(truth, rng, flows or {}, gross)
    empty = pd.DataFrame(columns=STREAM_VALUE_COLUMNS)
    assays = _drawn_assays(truth, rng, errors, measured if assayed is None else assayed)
    return Survey(classes=truth.classes, shares=shares, flows=flow_table, pct_solids=empty, size_unit=truth.size_unit,
                  source="simulated survey", closed_streams=tuple(measured), evaluated_at=errors.evaluated_at,
                  assays=assays, components=truth.components)  # fmt: skip


def _drawn_flows(truth: CircuitTruth, rng: np.random.Generator, flows: dict, gross) -> pd.DataFrame:
    """Measured solids flows ``{stream: relative sd}``, the gross error on a flow when ``gross`` names one."""
    records = []
    for stream, relative in flows.items():
        true = truth.flows[truth.flowsheet.stream_index[stream]]
        value = true * (1.0 + relative * rng.standard_normal())
        if gross is not None and gross[0] == stream and gross[1] < 0:
            value = value / (1.0 - gross[2] * relative)  # shifted by gross[2] times its stated sd, relative * value
        records.append({"stream": stream, "value": value, "sd": relative * value, "row": None, "relative": relative})
    return pd.DataFrame(records, columns=STREAM_VALUE_COLUMNS)


def _drawn_assays(truth: CircuitTruth, rng: np.random.Generator, errors: ErrorModel, streams) -> pd.DataFrame:
    """Per-class assays of ``streams`` drawn from the assay error model (not clipped: unbiased)."""
    records = []
    for k, component in enumerate(truth.components):
        relative, absolute = errors.assay_errors(component)
        for stream in streams:
            s = truth.flowsheet.stream_index[stream]
            true = truth.grades[k, s]
            value = true + np.sqrt((relative * true) ** 2 + absolute**2) * rng.standard_normal(true.size)
            records += [{"stream": stream, "class_index": i, "component": component, "value": value[i],
                         "sd": float(np.hypot(relative * value[i], absolute)), "row": None, "relative": relative,
                         "absolute": absolute} for i in range(true.size)]  # fmt: skip
    return pd.DataFrame(records, columns=ASSAY_COLUMNS)


def survey_table(survey: Survey, *, decimals: int | None = 2) -> pd.DataFrame:
    """A simulated survey as a measurement table (``retained_pct``, ``assay_<name>_pct``, the
    flows on the first row of each stream), negative shares and assays clipped to 0 and rounded
    as a lab report prints them."""
    classes = survey.classes
    unit = survey.size_unit
    rows = []
    flows = survey.flows.set_index("stream")
    assays = {(r.stream, r.class_index, r.component): r.value for r in survey.assays.itertuples()}
    for stream, part in survey.shares.groupby("stream", sort=False):
        for k, record in enumerate(part.itertuples()):
            value = 100.0 * max(record.value, 0.0)
            row = {
                "stream": stream,
                f"size_lower_{unit}": classes["size_lower"].iloc[record.class_index],
                f"size_upper_{unit}": classes["size_upper"].iloc[record.class_index],
                "retained_pct": round(value, decimals) if decimals is not None else value,
            }
            for component in survey.components:
                grade = 100.0 * max(assays.get((stream, record.class_index, component), np.nan), 0.0)
                row[f"assay_{component}_pct"] = round(grade, decimals) if decimals is not None else grade
            if stream in flows.index and k == 0:
                row["solids_flow"] = round(float(flows.loc[stream, "value"]), 1)
                row["solids_flow_sd"] = round(float(flows.loc[stream, "sd"]), 1)
            rows.append(row)
    return pd.DataFrame(rows)


@dataclass(frozen=True)
class StudyResult:
    """Counts of a reconciliation study on simulated surveys without gross errors."""

    surveys: int
    rejected: int
    covered: int
    checked: int
    measured_error: float
    reconciled_error: float
    dof: int

    @property
    def coverage(self) -> float:
        """Share of reconciled values whose 95 % interval covers the truth."""
        return self.covered / self.checked

    @property
    def rejection_rate(self) -> float:
        """Share of surveys the global chi-square test rejects at 5 %."""
        return self.rejected / self.surveys


def lab_survey(
    truth: CircuitTruth,
    rng: np.random.Generator,
    *,
    errors: ErrorModel | None = None,
    flows: dict | None = None,
    gross: tuple | None = None,
    measured: tuple[str, ...] | None = None,
    assayed: tuple[str, ...] | None = None,
) -> Survey:
    """A simulated survey as a lab reports it: drawn by :func:`simulate_survey`, written as a
    measurement table with the shares and assays clipped at 0 and rounded to 0.01 %
    (:func:`survey_table`) and read back through
    :func:`~tromplab.circuit.measurements.read_survey` with ``errors``."""
    drawn = simulate_survey(truth, rng, errors=errors, flows=flows, gross=gross, measured=measured, assayed=assayed)
    return read_survey(survey_table(drawn), truth.flowsheet, errors=errors, size_unit=truth.size_unit)


def reconciliation_study(
    truth: CircuitTruth, n_surveys: int, rng, *, flows: dict | None = None, errors: ErrorModel | None = None
) -> StudyResult:
    """Reconcile ``n_surveys`` surveys of ``truth`` as a lab reports them (:func:`lab_survey`)
    and count what the validation of ``docs/circuit.md`` reports: chi-square rejections, 95 %
    interval coverage of the reconciled shares and flows, and the squared errors of the measured
    and the reconciled shares against the truth."""
    rejected = covered = checked = 0
    measured_error = reconciled_error = 0.0
    dof = 0
    for _ in range(n_surveys):
        survey = lab_survey(truth, rng, errors=errors, flows=flows or {})
        balance = reconcile(truth.flowsheet, survey)
        rejected += int(balance.rejected)
        dof = balance.dof
        streams = survey.shares["stream"].map(truth.flowsheet.stream_index).to_numpy()
        classes = survey.shares["class_index"].to_numpy(int)
        true = truth.shares[streams, classes]
        measured_error += float(np.sum((survey.shares["value"].to_numpy(float) - true) ** 2))
        reconciled_error += float(np.sum((balance.shares[streams, classes] - true) ** 2))
        scale = balance.flows[0] / truth.flows[0] if not flows else 1.0  # without a flowmeter, flows are relative
        values = np.concatenate([balance.shares.ravel(), balance.flows])
        sds = np.concatenate([balance.share_sd.ravel(), balance.flow_sd])
        target = np.concatenate([truth.shares.ravel(), truth.flows * scale])
        keep = sds > 0
        covered += int(np.sum(np.abs(values - target)[keep] <= 1.959964 * sds[keep]))
        checked += int(keep.sum())
    return StudyResult(n_surveys, rejected, covered, checked, measured_error, reconciled_error, dof)


@dataclass(frozen=True)
class ComponentStudyResult:
    """Counts of a study of the per-component partitions on simulated surveys with assays."""

    surveys: int
    rejected: int
    covered: int  # reconciled partitions of a component whose 95 % interval covers the truth
    checked: int
    recovery_covered: int  # recoveries to the fine product whose 95 % (logit) interval covers the truth
    recovery_checked: int
    dof: int

    @property
    def coverage(self) -> float:
        return self.covered / self.checked

    @property
    def recovery_coverage(self) -> float:
        return self.recovery_covered / self.recovery_checked

    @property
    def rejection_rate(self) -> float:
        return self.rejected / self.surveys


def component_study(
    truth: CircuitTruth,
    n_surveys: int,
    rng,
    *,
    flows: dict | None = None,
    errors: ErrorModel | None = None,
    assayed: tuple[str, ...] | None = None,
) -> ComponentStudyResult:
    """Reconcile ``n_surveys`` surveys of ``truth`` with per-class assays, as a lab reports them
    (:func:`lab_survey`; ``assayed``: the streams with assays, default every analysed one), and
    count the chi-square rejections and the 95 % intervals of each component's partition (used
    classes) and recovery to the fine product covering the truth."""
    rejected = covered = checked = recovered = recovery_checked = dof = 0
    for _ in range(n_surveys):
        balance = reconcile(truth.flowsheet, lab_survey(truth, rng, errors=errors, flows=flows or {}, assayed=assayed))
        rejected += int(balance.rejected)
        dof = balance.dof
        partition = balance.partition_table()
        recoveries = balance.components_table().set_index(["separator", "component"])
        for (node, component), phi in truth.component_partitions.items():
            rows = partition[(partition["experiment"] == node) & (partition["component"] == component)]
            keep = rows["used"].astype(bool).to_numpy() & np.isfinite(rows["partition_sd"].to_numpy(float))
            error = np.abs(rows["partition_fine"].to_numpy(float) - phi)[keep]
            covered += int(np.sum(error <= 1.959964 * rows["partition_sd"].to_numpy(float)[keep]))
            checked += int(keep.sum())
            fine, coarse = _products(truth, node)
            component_flows = truth.component_flows[truth.components.index(component)]
            true = component_flows[fine].sum() / (component_flows[fine].sum() + component_flows[coarse].sum())
            row = recoveries.loc[(node, component)]
            if np.isfinite(row["recovery_fine_low"]):
                recovered += int(row["recovery_fine_low"] <= true <= row["recovery_fine_high"])
                recovery_checked += 1
    return ComponentStudyResult(n_surveys, rejected, covered, checked, recovered, recovery_checked, dof)


def _products(truth: CircuitTruth, node: str) -> tuple[int, int]:
    separator = next(s for s in truth.flowsheet.separators if s.name == node)
    return truth.flowsheet.stream_index[separator.fine], truth.flowsheet.stream_index[separator.coarse]
