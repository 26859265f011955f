"""Figures of a reconciled survey: the flowsheet with its flows, the adjustments, the distributions.

Each function takes ``ax=None`` (a new figure is made) and returns the Axes; nothing is shown
and no style is set (the caller's scripts choose the backend and the theme).
"""

from __future__ import annotations

import numpy as np

from .flowsheet import Flowsheet

#: Spacing of the flowsheet's grid (data units): node columns, rows, and the reach of feeds and products.
COLUMN_STEP, ROW_STEP, FEED_REACH, PRODUCT_REACH = 3.6, 2.4, 1.6, 1.5
#: Colours of the flowsheet: forward streams, recycles (drawn back below the nodes), water.
STREAM_COLOUR, RECYCLE_COLOUR, WATER_COLOUR = "#555555", "#b35900", "#2a7fb8"
#: Label moves tried, nearest first: (across in label widths, up in label heights), before a
#: label is left where it overlaps.
LABEL_MOVES = tuple(
    sorted(
        ((dx, dy) for dx in (0.0, -0.3, 0.3, -0.6, 0.6) for dy in (0.0, 0.6, -0.6, 1.2, -1.2, 1.8, -1.8, 2.4, -2.4, 3.6, -3.6)),
        key=lambda move: (abs(move[0]) > 0, abs(move[0]) + abs(move[1]) / 4),
    )[1:]
)


def figure_size(balance, kind: str) -> tuple[float, float]:
    """Width and height (inches) of figure ``kind`` of ``balance``, for a caller that makes the axes."""
    if kind == "flowsheet":
        flowsheet = balance if isinstance(balance, Flowsheet) else balance.flowsheet
        xs, ys = zip(*_layout(flowsheet).values())
        return (max(8.0, 0.75 * (max(xs) - min(xs)) + 4.0), max(4.5, 0.75 * (max(ys) - min(ys)) + 3.0))
    if kind == "adjustments":
        return (8.0, max(3.0, 0.16 * min(len(balance.adjustments_table()), ADJUSTMENTS_SHOWN) + 1.0))
    return (8.0, 5.0)


#: The adjustments figure shows at most this many measurements: those of the largest measurement
#: tests (every bundled survey has fewer; the 30-node plant with four minerals has 2,861, a figure
#: 460 inches tall that took 18 s to draw).
ADJUSTMENTS_SHOWN = 150


def _adjustments_shown(table):
    """The rows of the adjustments ``table`` the figure shows: all of them, or the
    :data:`ADJUSTMENTS_SHOWN` of the largest measurement tests (in absolute value, a test not
    made last), in the table's order."""
    if len(table) <= ADJUSTMENTS_SHOWN:
        return table
    size = np.nan_to_num(np.abs(table["measurement_test"].to_numpy(dtype=float)), nan=-1.0)
    keep = np.sort(np.argsort(-size, kind="stable")[:ADJUSTMENTS_SHOWN])
    return table.iloc[keep]


def prepared_axes(ax, size):
    """``ax``, or the axes of a new pyplot figure (interactive use, as the library's other figures)."""
    if ax is not None:
        return ax
    import matplotlib.pyplot as plt

    _, ax = plt.subplots(figsize=size)
    return ax


def _columns(flowsheet: Flowsheet) -> dict[str, int]:
    """Column of each node: the longest path to it from the feeds once the recycles are cut.

    A recycle is an edge back to a node on the path that reached it, in a depth-first walk
    from the feeds' nodes in the order of the file (so a loop is cut where the flowsheet
    returns, not where a second feed enters it)."""
    import networkx as nx  # only when a figure is drawn

    graph = nx.DiGraph()
    graph.add_nodes_from(node.name for node in flowsheet.nodes)
    for stream in flowsheet.streams:
        if stream.source and stream.target:
            graph.add_edge(stream.source, stream.target)
    back, done, path = set(), set(), []

    def walk(node):
        path.append(node)
        for following in graph.successors(node):
            if following in path:
                back.add((node, following))
            elif following not in done:
                walk(following)
        path.pop()
        done.add(node)

    for entry in [*(flowsheet.stream(s).target for s in flowsheet.feeds), *graph.nodes]:
        if entry not in done:
            walk(entry)
    graph.remove_edges_from(back)
    depth = {}
    for node in nx.topological_sort(graph):
        depth[node] = max((depth[p] + 1 for p in graph.predecessors(node)), default=0)
    return depth


def _layout(flowsheet: Flowsheet) -> dict:
    """Positions: nodes in columns (:func:`_columns`); each feed enters from the left of its
    node, each final product leaves to the right of its node (coarse up, fine down)."""
    depth = _columns(flowsheet)
    columns = {}
    for node in flowsheet.nodes:
        columns.setdefault(depth.get(node.name, 0), []).append(node.name)
    positions = {}
    for column, nodes in columns.items():
        for k, node in enumerate(nodes):
            positions[node] = (COLUMN_STEP * column, ROW_STEP * ((len(nodes) - 1) / 2.0 - k))
    feeds_of = {}
    for name in flowsheet.feeds:
        feeds_of.setdefault(flowsheet.stream(name).target, []).append(name)
    for node, names in feeds_of.items():  # into the first column from the left, further in from above
        x, y = positions[node]
        for k, name in enumerate(names):
            spread = 0.7 * ((len(names) - 1) / 2.0 - k)
            positions[f"in:{name}"] = (
                (x - FEED_REACH, y + spread) if depth.get(node, 0) == 0 else (x - 1.0 + spread, y + 0.5 * ROW_STEP)
            )
    for name in flowsheet.products:
        stream = flowsheet.stream(name)
        x, y = positions[stream.source]
        rise = {"coarse": 0.8, "fine": -0.8}.get(stream.product, 0.0) * ROW_STEP
        positions[f"out:{name}"] = (x + PRODUCT_REACH, y + rise)
    for stream in flowsheet.water_streams:  # water drops in from above (or leaves below) its node
        x, y = positions[stream.target or stream.source]
        positions[f"water:{stream.name}"] = (x - 0.6, y + (0.45 if stream.target else -0.45) * ROW_STEP)
    return positions


def plot_flowsheet(balance, ax=None, *, flow_unit: str = ""):
    """The flowsheet as boxes and arrows, each stream labelled with its reconciled solids flow
    +/- its standard deviation (``balance`` a CircuitBalance, or a Flowsheet for the bare graph).

    Names are shown as written (no mathtext).  Recycles (a stream back to an earlier column) are drawn back below the nodes in their own
    colour.  No label lies over a box, an arrow or another label: each label starts beside
    its arrow and, where the drawn extents still meet, moves up or down until they do not
    (:func:`flowsheet_overlaps` checks the result).  Artists carry the gid ``node``,
    ``stream`` (arrows) or ``label``.
    """
    flowsheet = balance if isinstance(balance, Flowsheet) else balance.flowsheet
    ax = prepared_axes(ax, figure_size(balance, "flowsheet"))
    positions = _layout(flowsheet)
    boxes = {}
    for node in flowsheet.nodes:
        x, y = positions[node.name]
        boxes[node.name] = ax.text(x, y, f"{node.name}\n({node.kind})", ha="center", va="center", fontsize=9, gid="node",
                                   zorder=3, parse_math=False,
                                   bbox={"boxstyle": "round,pad=0.4", "facecolor": "#dde8f3", "edgecolor": "#336699"})  # fmt: skip
    recycles = 0
    for s, stream in enumerate(flowsheet.streams):
        start = positions[stream.source or f"in:{stream.name}"]
        end = positions[stream.target or f"out:{stream.name}"]
        recycles += end[0] <= start[0]
        ends = (boxes[stream.source] if stream.source else None, boxes[stream.target] if stream.target else None)
        _draw_stream(ax, start, end, _stream_label(balance, s, stream, flow_unit), recycle=recycles if end[0] <= start[0] else 0,
                     ends=ends)  # fmt: skip
    _draw_water(ax, balance, flowsheet, positions)
    for stream in flowsheet.feeds:
        ax.plot(*positions[f"in:{stream}"], marker=">", color="#336699")
    for stream in flowsheet.products:
        ax.plot(*positions[f"out:{stream}"], marker="s", color="#336699")
    xs, ys = zip(*positions.values())
    ax.set_xlim(min(xs) - 2.6, max(xs) + 2.6)
    ax.set_ylim(min(ys) - 1.2 - 0.5 * recycles, max(ys) + 0.9)
    ax.set_axis_off()
    title = "Flowsheet"
    if not isinstance(balance, Flowsheet):
        title += " with reconciled solids flows" + (f" ({balance.basis})" if balance.basis else "")
    ax.set_title(title, fontsize=10)
    _declutter(ax)
    return ax


def _stream_label(balance, s: int, stream, flow_unit: str) -> str:
    label = stream.name + (f" ({stream.product})" if stream.product else "")
    if not isinstance(balance, Flowsheet):
        unit = f" {flow_unit}" if flow_unit else ""
        label += f"\n{balance.flows[s]:.4g} +/- {balance.flow_sd[s]:.2g}{unit}"
    return label


def _draw_stream(ax, start, end, label: str, *, recycle: int, ends: tuple) -> None:
    """One stream's arrow, from box to box (``ends``: the node texts, None at the boundary), and
    its label beside it: above a horizontal arrow, on the outer side of a rising or falling
    one, past the end marker of a product, under a recycle's arc."""
    source, target = (end.get_bbox_patch() if end is not None else None for end in ends)
    product = target is None
    rad = -(0.35 + 0.12 * (recycle - 1)) if recycle else 0.0
    colour = RECYCLE_COLOUR if recycle else STREAM_COLOUR
    ax.annotate("", xy=end, xytext=start, gid="stream",
                arrowprops={"arrowstyle": "-|>", "color": colour, "patchA": source, "patchB": target, "shrinkA": 2,
                            "shrinkB": 2 if target is not None else 6, "connectionstyle": f"arc3,rad={rad}",
                            "linewidth": 1.4 if recycle else 1.0})  # fmt: skip
    mid_x, mid_y = (start[0] + end[0]) / 2.0, (start[1] + end[1]) / 2.0
    if recycle:  # a negative arc3 radius bends a stream going back left below the nodes
        depth = abs(rad) * np.hypot(end[0] - start[0], end[1] - start[1]) / 2.0  # the quadratic curve's middle
        where, align = (mid_x, mid_y - depth - 0.12), {"ha": "center", "va": "top"}
    elif product:
        where, align = (end[0] + 0.18, end[1]), {"ha": "left", "va": "center"}
    elif source is None:  # a feed: left of its marker, where nothing else is drawn
        where, align = (start[0] - 0.2, start[1]), {"ha": "right", "va": "center"}
    elif abs(end[1] - start[1]) < 1e-9:
        where, align = (mid_x, mid_y + 0.18), {"ha": "center", "va": "bottom"}
    else:
        rising = end[1] > start[1]
        where, align = (mid_x + 0.15, mid_y), {"ha": "left", "va": "top" if rising else "bottom"}
    ax.text(*where, label, fontsize=7.5, color=RECYCLE_COLOUR if recycle else "#222222", gid="label", parse_math=False, **align)


def _draw_water(ax, balance, flowsheet: Flowsheet, positions: dict) -> None:
    """Water streams: dashed arrows into (from above) or out of (below) their node, labelled."""
    water = balance.water_table().set_index("stream") if not isinstance(balance, Flowsheet) else None
    for stream in flowsheet.water_streams:
        node, end = positions[stream.target or stream.source], positions[f"water:{stream.name}"]
        start, finish = (end, node) if stream.target else (node, end)
        ax.annotate("", xy=finish, xytext=start, gid="stream",
                    arrowprops={"arrowstyle": "-|>", "color": WATER_COLOUR, "linestyle": "--", "shrinkA": 4, "shrinkB": 22})  # fmt: skip
        label = f"{stream.name} (water)"
        if water is not None and water.loc[stream.name, "determined"]:
            label += f"\n{water.loc[stream.name, 'water_flow']:.4g} +/- {water.loc[stream.name, 'water_flow_sd']:.2g}"
        ax.text(end[0] - 0.12, end[1], label, ha="right", va="bottom" if stream.target else "top", fontsize=7,
                color=WATER_COLOUR, gid="label", parse_math=False)  # fmt: skip


def _drawn(ax):
    """``(labels, boxes, arrows)`` of a drawn flowsheet: label texts, node boxes (display
    extents) and arrow paths (display coordinates)."""
    ax.figure.draw_without_rendering()
    labels = [t for t in ax.texts if t.get_gid() == "label"]
    boxes = [t.get_bbox_patch().get_window_extent() for t in ax.texts if t.get_gid() == "node"]
    arrows = [a.arrow_patch.get_transform().transform_path(a.arrow_patch.get_path()) for a in ax.texts if a.get_gid() == "stream"]
    return labels, boxes, arrows


def _clashes(extent, others, boxes, arrows) -> bool:
    return (any(extent.overlaps(o) for o in others) or any(extent.overlaps(b) for b in boxes)
            or any(_meets(path, extent) for path in arrows))  # fmt: skip


def _meets(path, extent) -> bool:
    """Whether the drawn line of an arrow (its polylines, curves flattened) crosses or enters
    ``extent``.  Path.intersects_bbox on the arrow's compound path (curve codes and a closed
    head) reports crossings far from the line, so each polyline is tested on its own."""
    from matplotlib.path import Path  # matplotlib only when a figure is drawn

    return any(Path(line).intersects_bbox(extent, filled=False) for line in path.to_polygons(closed_only=False))


def _declutter(ax) -> None:
    """Move each label that meets a box, an arrow or a label placed before it (by
    :data:`LABEL_MOVES`) to the first place where it meets none."""
    labels, boxes, arrows = _drawn(ax)
    placed = []
    to_data = ax.transData.inverted()
    for label in labels:
        extent = label.get_window_extent()
        if _clashes(extent, placed, boxes, arrows):
            x, y = ax.transData.transform(label.get_position())
            for across, up in LABEL_MOVES:
                label.set_position(to_data.transform((x + across * extent.width, y + up * extent.height)))
                if not _clashes(label.get_window_extent(), placed, boxes, arrows):
                    break
            else:
                label.set_position(to_data.transform((x, y)))
        placed.append(label.get_window_extent())


def flowsheet_overlaps(ax) -> list[str]:
    """What overlaps in a drawn flowsheet (:func:`plot_flowsheet`): each label that meets a
    box, an arrow or another label, in words; empty when the figure is clean."""
    labels, boxes, arrows = _drawn(ax)
    extents = [label.get_window_extent() for label in labels]
    found = []
    for k, (label, extent) in enumerate(zip(labels, extents)):
        name = label.get_text().split("\n")[0]
        found += [f"label {name!r} over a box" for box in boxes if extent.overlaps(box)]
        found += [f"label {name!r} over an arrow" for path in arrows if _meets(path, extent)]
        found += [f"label {name!r} over label {labels[j].get_text().split(chr(10))[0]!r}"
                  for j in range(k + 1, len(labels)) if extent.overlaps(extents[j])]  # fmt: skip
    return found


def plot_adjustments(balance, ax=None):
    """The measurement test of every measurement (the gross error that best explains the
    adjustments, in its standard deviations, with the sign of reconciled - measured), with its
    critical value; suspects in red.  Of a survey of more than :data:`ADJUSTMENTS_SHOWN`
    measurements, those of the largest tests, the title says so."""
    everything = balance.adjustments_table()
    table = _adjustments_shown(everything)
    ax = prepared_axes(ax, figure_size(balance, "adjustments"))
    position = np.arange(len(table))[::-1]
    values = table["measurement_test"].to_numpy(dtype=float)
    colours = np.where(table["suspect"].to_numpy(dtype=bool), "#c0392b", "#336699")
    ax.barh(position, np.nan_to_num(values), color=colours, height=0.7)
    critical = balance.measurement_test_critical
    if np.isfinite(critical):
        for sign in (-1, 1):
            ax.axvline(sign * critical, color="#c0392b", linestyle="--", linewidth=0.8)
    ax.axvline(0.0, color="black", linewidth=0.6)
    ax.set_yticks(position, table["measurement"], fontsize=6)
    ax.set_xlabel("measurement test: estimated gross error / its sd (sign of reconciled - measured)")
    ax.set_title(
        f"Adjustments: chi-square {balance.chi_square:.3g} on {balance.dof} dof (p = {balance.p_value:.3g})"
        + (
            ""
            if len(table) == len(everything)
            else f"\nthe {len(table)} largest measurement tests of {len(everything)} (all in adjustments.csv)"
        ),
        fontsize=10,
    )
    return ax


def plot_distributions(balance, ax=None):
    """Measured (points with +/- 2 sd bars) and reconciled (lines) size distributions of every
    stream: share of the stream per class against the representative size."""
    ax = prepared_axes(ax, figure_size(balance, "distributions"))
    table = balance.distributions_table()
    unit = balance.survey.size_unit
    for k, (stream, part) in enumerate(table.groupby("stream", sort=False)):
        colour = f"C{k % 10}"
        ax.plot(part["size"], 100 * part["reconciled"], color=colour, label=stream, linewidth=1.2)
        given = part.dropna(subset=["measured"])
        ax.errorbar(given["size"], 100 * given["measured"], yerr=200 * given["measured_sd"], fmt="o", markersize=3,
                    color=colour, elinewidth=0.7, capsize=1.5)  # fmt: skip
    ax.set_xscale("log")
    ax.set_xlabel(f"size ({unit})" if unit else "size")
    ax.set_ylabel("share of the stream in the class (%)")
    ax.set_title("Size distributions: measured (points, +/- 2 sd) and reconciled (lines)", fontsize=10)
    ax.legend(fontsize=7, ncol=2)
    return ax
