"""Figures of a reconciled survey: the flowsheet with its flows, the adjustments, the distributions.

Each function takes ``ax=None`` (a new figure is made) and returns the Axes; nothing is shown
and no style is set (the caller's scripts choose the backend and the theme).
"""

from __future__ import annotations

import networkx as nx
import numpy as np

from .flowsheet import Flowsheet


def figure_size(balance, kind: str) -> tuple[float, float]:
    """Width and height (inches) of figure ``kind`` of ``balance``, for a caller that makes the axes."""
    if kind == "flowsheet":
        return (10.0, 5.5)
    if kind == "adjustments":
        return (8.0, max(3.0, 0.16 * len(balance.adjustments_table()) + 1.0))
    return (8.0, 5.0)


def _axes(ax, size):
    """``ax``, or the axes of a new pyplot figure (interactive use, as the library's other figures)."""
    if ax is not None:
        return ax
    import matplotlib.pyplot as plt

    _, ax = plt.subplots(figsize=size)
    return ax


def _layout(flowsheet: Flowsheet) -> dict:
    """Positions: nodes in columns by their distance from the feeds; each feed enters from the
    left of its node, each final product leaves to the right of its node (coarse up, fine down)."""
    graph = nx.DiGraph()
    graph.add_nodes_from(node.name for node in flowsheet.nodes)
    for stream in flowsheet.streams:
        if stream.source and stream.target:
            graph.add_edge(stream.source, stream.target)
    entries = [flowsheet.stream(s).target for s in flowsheet.feeds]
    depth = {}
    for entry in entries:
        for node, distance in nx.single_source_shortest_path_length(graph, entry).items():
            depth[node] = min(depth.get(node, distance), distance)
    columns = {}
    for node in flowsheet.nodes:
        columns.setdefault(depth.get(node.name, 0), []).append(node.name)
    positions = {}
    for column, nodes in columns.items():
        for k, node in enumerate(nodes):
            positions[node] = (1.6 * column, 1.4 * ((len(nodes) - 1) / 2.0 - k))
    for name in flowsheet.feeds:
        x, y = positions[flowsheet.stream(name).target]
        positions[f"in:{name}"] = (x - 1.1, y)
    for name in flowsheet.products:
        stream = flowsheet.stream(name)
        x, y = positions[stream.source]
        positions[f"out:{name}"] = (x + 0.8, y + {"coarse": 0.9, "fine": -0.9}.get(stream.product, 0.0))
    for stream in flowsheet.water_streams:  # water drops in from above (or leaves below) its node
        x, y = positions[stream.target or stream.source]
        positions[f"water:{stream.name}"] = (x - 0.35, y + (1.0 if stream.target else -1.0))
    return positions


def plot_flowsheet(balance, ax=None, *, flow_unit: str = ""):
    """The flowsheet as boxes and arrows, each stream labelled with its reconciled solids flow
    +/- its standard deviation (``balance`` a CircuitBalance, or a Flowsheet for the bare graph)."""
    flowsheet = balance if isinstance(balance, Flowsheet) else balance.flowsheet
    ax = _axes(ax, figure_size(balance, "flowsheet"))
    positions = _layout(flowsheet)
    for node in flowsheet.nodes:
        x, y = positions[node.name]
        ax.text(x, y, f"{node.name}\n({node.kind})", ha="center", va="center", fontsize=9,
                bbox={"boxstyle": "round,pad=0.4", "facecolor": "#dde8f3", "edgecolor": "#336699"})  # fmt: skip
    for s, stream in enumerate(flowsheet.streams):
        start = positions[stream.source or f"in:{stream.name}"]
        end = positions[stream.target or f"out:{stream.name}"]
        backwards = end[0] <= start[0]
        rad = -0.5 if backwards else 0.0
        ax.annotate("", xy=end, xytext=start,
                    arrowprops={"arrowstyle": "-|>", "color": "#555555", "shrinkA": 22, "shrinkB": 22,
                                "connectionstyle": f"arc3,rad={rad}"})  # fmt: skip
        label = stream.name + (f" ({stream.product})" if stream.product else "")
        if not isinstance(balance, Flowsheet):
            unit = f" {flow_unit}" if flow_unit else ""
            label += f"\n{balance.flows[s]:.4g} +/- {balance.flow_sd[s]:.2g}{unit}"
        mid_x, mid_y = (start[0] + end[0]) / 2.0, (start[1] + end[1]) / 2.0
        if backwards:
            mid_y -= abs(rad) * abs(end[0] - start[0]) / 2.0 + 0.3
        elif end[1] != start[1]:
            mid_x += 0.15
        ax.text(mid_x, mid_y + 0.12, label, ha="center", va="bottom", fontsize=7.5, color="#222222")
    water = balance.water_table().set_index("stream") if not isinstance(balance, Flowsheet) else None
    for stream in flowsheet.water_streams:
        node, end = positions[stream.target or stream.source], positions[f"water:{stream.name}"]
        start, finish = (end, node) if stream.target else (node, end)
        ax.annotate("", xy=finish, xytext=start,
                    arrowprops={"arrowstyle": "-|>", "color": "#2a7fb8", "linestyle": "--", "shrinkA": 4, "shrinkB": 22})  # fmt: skip
        label = f"{stream.name} (water)"
        if water is not None and water.loc[stream.name, "determined"]:
            label += f"\n{water.loc[stream.name, 'water_flow']:.4g} +/- {water.loc[stream.name, 'water_flow_sd']:.2g}"
        ax.text(end[0], end[1] + (0.08 if stream.target else -0.08), label, ha="center",
                va="bottom" if stream.target else "top", fontsize=7, color="#2a7fb8")  # fmt: skip
    for stream in flowsheet.feeds:
        x, y = positions[f"in:{stream}"]
        ax.plot([x], [y], marker=">", color="#336699")
    for stream in flowsheet.products:
        x, y = positions[f"out:{stream}"]
        ax.plot([x], [y], marker="s", color="#336699")
    xs = [p[0] for p in positions.values()]
    ys = [p[1] for p in positions.values()]
    ax.set_xlim(min(xs) - 0.5, max(xs) + 0.5)
    ax.set_ylim(min(ys) - 0.9, max(ys) + 0.6)
    ax.set_axis_off()
    title = "Flowsheet"
    if not isinstance(balance, Flowsheet):
        title += " with reconciled solids flows" + (f" ({balance.basis})" if balance.basis else "")
    ax.set_title(title, fontsize=10)
    return ax


def plot_adjustments(balance, ax=None):
    """The measurement test of every measurement (the gross error that best explains the
    adjustments, in its standard deviations, with the sign of reconciled - measured), with its
    critical value; suspects in red."""
    table = balance.adjustments_table()
    ax = _axes(ax, figure_size(balance, "adjustments"))
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
        f"Adjustments: chi-square {balance.chi_square:.3g} on {balance.dof} dof (p = {balance.p_value:.3g})", fontsize=10
    )
    return ax


def plot_distributions(balance, ax=None):
    """Measured (points with +/- 2 sd bars) and reconciled (lines) size distributions of every
    stream: share of the stream per class against the representative size."""
    ax = _axes(ax, figure_size(balance, "distributions"))
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
