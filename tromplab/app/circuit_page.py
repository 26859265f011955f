"""What the page shows of a ``tromplab circuit`` run, as JSON-ready data: the flowsheet with its
reconciled flows (nodes and streams placed in columns, each stream with its measured and
reconciled flow, their sds and the measurements on it suspected of a gross error), the tables
of the results folder, the summary and the warnings grouped by what they say.

The figure's numbers come from the :class:`~tromplab.circuit.CircuitBalance` the run made; the
tables are read back from the files the run wrote (the folder offered for download), so the
page shows what the download holds. Nothing is computed here but where to draw the nodes.
"""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

from .payload import number, records

#: Tables of the results folder the page shows, in its order: file -> what it holds (a file the
#: run did not write, such as ``fits.csv`` without ``--fit``, is left out).
CIRCUIT_TABLES = {
    "flows.csv": "balance: measured and reconciled solids flow of every stream",
    "chi_square.csv": "the global chi-square test of the balance",
    "gross_errors.csv": "measurements suspected of a gross error, the first candidate first",
    "adjustments.csv": "every measurement: its adjustment and its measurement test",
    "elimination.csv": "serial elimination with compensation: a proposal, nothing changed",
    "partition.csv": "partition to the fine product of every separator and class, with its sd",
    "water.csv": "the water balance (per cent solids measured)",
    "components.csv": "the balance of each assayed component",
    "design.csv": "the measurements one could add, ranked by the sd they would remove",
    "worth.csv": "what each measurement is worth: solvability, redundancy, influence",
    "fits.csv": "partition curves of the separators (--fit)",
    "ranking.csv": "ranking of the formulas across the separators (--fit)",
}
#: Tables of the folder of ``tromplab circuit design``, in the page's order.
DESIGN_TABLES = {
    "design.csv": CIRCUIT_TABLES["design.csv"],
    "observability.csv": "which results the survey determines, and which measurements determine them",
    "simulated_survey.csv": "the survey the advice is predicted at, simulated from the flowsheet (no survey given)",
}
#: Rows of a table sent to the page (the file has every row; the page says how many are left out).
TABLE_ROWS = 500
#: Spacing of the drawn flowsheet: node columns, rows, the reach of feeds and products.
COLUMN_STEP, ROW_STEP, REACH = 3.0, 2.0, 1.4


def circuit_payload(run, outdir) -> dict:
    """The page's data of a circuit run: ``run`` the :class:`~tromplab.circuit.commands.CircuitResult`
    whose folder is ``outdir``."""
    balance = run.balance
    folder = Path(outdir)
    return {
        "view": "circuit",
        "flowsheet": flowsheet_figure(balance),
        "summary": (folder / "summary.txt").read_text(encoding="utf-8").splitlines(),
        "tables": [_file_table(folder / name, what) for name, what in CIRCUIT_TABLES.items() if (folder / name).is_file()],
        "warnings": circuit_warnings(run),
    }


def design_payload(advice, outdir) -> dict:
    """The page's data of a ``circuit design`` run: ``advice`` the
    :class:`~tromplab.circuit.planning.DesignAdvice` whose folder is ``outdir``; drawn as a circuit
    run is, the flows those of the survey the advice is predicted at (simulated when none was given)."""
    folder = Path(outdir)
    where = "a survey simulated from the flowsheet (summary)" if advice.simulated else "the survey dropped"
    return {
        "view": "circuit",
        "flowsheet_title": f"The flowsheet at the flows the advice is predicted at: {where}",
        "flowsheet": flowsheet_figure(advice.balance),
        "summary": (folder / "summary.txt").read_text(encoding="utf-8").splitlines(),
        "tables": [_file_table(folder / name, what) for name, what in DESIGN_TABLES.items() if (folder / name).is_file()],
        "warnings": [],
    }


def flowsheet_figure(balance) -> dict:
    """Nodes and streams of the flowsheet, placed (:func:`node_positions`), each stream with its
    flows and the suspects among its measurements."""
    sheet = balance.flowsheet
    positions = node_positions(sheet)
    flows = balance.flows_table().set_index("stream")
    suspects = defaultdict(list)
    for row in balance.gross_errors_table().itertuples():
        suspects[row.stream].append({"measurement": row.measurement, "test": number(row.measurement_test),
                                     "gross_error": number(row.gross_error)})  # fmt: skip
    largest = _largest_tests(balance.adjustments_table())
    nodes = [
        {"name": node.name, "kind": node.kind, "x": positions[node.name][0], "y": positions[node.name][1]} for node in sheet.nodes
    ]
    streams = []
    for stream in sheet.streams:
        flow = flows.loc[stream.name]
        start, end = _ends(stream, positions)
        streams.append({
            "name": stream.name, "from": stream.source, "to": stream.target, "product": stream.product,
            "path": _path(start, end, recycle=_is_recycle(stream, positions), low=min(y for _, y in positions.values())),
            "measured": number(flow["measured"]), "measured_sd": number(flow["measured_sd"]),
            "reconciled": number(flow["reconciled"]), "reconciled_sd": number(flow["reconciled_sd"]),
            "suspects": suspects.get(stream.name, []), "largest_test": largest.get(stream.name),
        })  # fmt: skip
    return {"nodes": nodes, "streams": streams, "basis": str(balance.basis or ""), "alpha": number(balance.alpha),
            "critical": number(balance.measurement_test_critical)}  # fmt: skip


def node_positions(sheet) -> dict[str, tuple[float, float]]:
    """Where each node is drawn: in the column of its distance (in streams) from the nearest
    feed, the nodes of a column one above the other in the flowsheet's order. A stream to a node
    in the same or an earlier column is a recycle, drawn below the nodes."""
    following = defaultdict(list)
    for stream in sheet.streams:
        if stream.source and stream.target:
            following[stream.source].append(stream.target)
    depth = {}
    frontier = [sheet.stream(name).target for name in sheet.feeds]
    for node in [*frontier, *(node.name for node in sheet.nodes)]:  # nodes no feed reaches start columns of their own
        if node in depth:
            continue
        depth[node], queue = 0 if node in frontier else max(depth.values(), default=-1) + 1, [node]
        while queue:
            here = queue.pop(0)
            for there in following[here]:
                if there not in depth:
                    depth[there] = depth[here] + 1
                    queue.append(there)
    columns = defaultdict(list)
    for node in sheet.nodes:
        columns[depth[node.name]].append(node.name)
    return {
        name: (COLUMN_STEP * column, ROW_STEP * ((len(names) - 1) / 2.0 - k))
        for column, names in columns.items()
        for k, name in enumerate(names)
    }


def _ends(stream, positions) -> tuple[tuple[float, float], tuple[float, float]]:
    """Where a stream starts and ends: at its nodes; a feed from the left of its node, a final
    product to the right of its node (coarse up, fine down)."""
    if stream.source and stream.target:
        return positions[stream.source], positions[stream.target]
    if stream.target:  # a feed
        x, y = positions[stream.target]
        return (x - REACH, y), (x, y)
    x, y = positions[stream.source]
    rise = {"coarse": 0.45, "fine": -0.45}.get(stream.product, 0.0) * ROW_STEP
    return (x, y), (x + REACH, y + rise)


def _is_recycle(stream, positions) -> bool:
    return bool(stream.source and stream.target) and positions[stream.target][0] <= positions[stream.source][0]


def _path(start, end, *, recycle: bool, low: float) -> dict:
    """The polyline of a stream: straight, or for a recycle down, back below the nodes and up."""
    if not recycle:
        return {"x": [start[0], end[0]], "y": [start[1], end[1]]}
    bottom = low - 0.6 * ROW_STEP
    return {"x": [start[0], start[0], end[0], end[0]], "y": [start[1], bottom, bottom, end[1]]}


def _largest_tests(adjustments) -> dict:
    """Per stream, its measurement with the largest absolute measurement test (suspect or not)."""
    tested = adjustments.dropna(subset=["measurement_test"])
    largest = {}
    for row in tested.reindex(tested["measurement_test"].abs().sort_values(ascending=False).index).itertuples():
        largest.setdefault(row.stream, {"measurement": row.measurement, "test": number(row.measurement_test)})
    return largest


def _file_table(path: Path, what: str) -> dict:
    import pandas as pd

    table = pd.read_csv(path, keep_default_na=False, na_values=[""])
    return {"name": path.name, "what": what, "rows_in_file": len(table), "table": records(table.head(TABLE_ROWS))}


def circuit_warnings(run) -> list[dict]:
    """The warnings of a circuit run, each kind once with how often and where it was said: the
    gross-error suspects, the rejected global test, the notes on the points' weights and (with
    ``--fit``) the notes and warnings of the separators' fits."""
    balance = run.balance
    groups = []
    suspects = balance.gross_errors_table()
    if len(suspects):
        groups.append({"kind": "gross error", "text": f"suspected gross error (|measurement test| > "
                       f"{balance.measurement_test_critical:.2f}; gross_errors.csv)", "count": len(suspects),
                       "where": list(suspects["measurement"])})  # fmt: skip
    if balance.dof > 0 and balance.rejected:
        groups.append({"kind": "balance", "text": f"the chi-square test rejects the balance at alpha {balance.alpha:g} "
                       "(elimination.csv proposes what to leave out)", "count": 1, "where": []})  # fmt: skip
    for note in run.weight_notes:
        groups.append({"kind": "data", "text": note, "count": 1, "where": []})
    if run.bench is not None:
        from .payload import notice_groups

        groups += notice_groups(run.bench.notices())
    return groups
