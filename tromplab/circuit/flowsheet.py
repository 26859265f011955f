"""The flowsheet of a plant survey: streams between nodes, validated as a directed graph.

File schema (CSV or Excel), one row per stream:

``stream``
    the stream's name, unique (it is the key of the measurement table).
``from``, ``to``
    node names; blank ``from`` = a feed of the circuit, blank ``to`` = a final product
    (the boundary).  Recycles are allowed.
``product``
    ``fine`` or ``coarse`` (also ``overflow`` / ``underflow``, ``undersize`` /
    ``oversize``) on the two outputs of each separator; ``ground`` on the single output
    of a mill or crusher (the sizes change there: only the total solids balance); ``water``
    on a stream of water alone, added at a node (blank ``from``: mill water, sump water,
    spray water) or removed from it (blank ``to``); blank elsewhere.  A node whose single
    solids output is not marked ``ground`` is a junction (the solids of every size class
    balance).  Water streams matter only when per cent solids are measured: water then
    balances at every node, with the declared water streams as its only additions and
    removals.
``note``, ``comment``
    free text, ignored.  Any other column is refused with its name.

Every node needs an input and an output; the graph with the boundary as one more node
must be connected, and every node must be fed from a feed and reach a final product
(otherwise material could circulate unobserved).  Splitters (outputs of the same size
distribution) are not supported: a node with several outputs is a separator with
exactly one fine and one coarse output.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ..errors import InputError
from ..loading.tables import Table, read_table

if TYPE_CHECKING:
    import networkx as nx

#: The boundary of the circuit as a node of the graph (feeds come from it, products go to it).
BOUNDARY = "(boundary)"
PRODUCT_WORDS = {
    "fine": "fine",
    "overflow": "fine",
    "undersize": "fine",
    "coarse": "coarse",
    "underflow": "coarse",
    "oversize": "coarse",
    "ground": "ground",
    "water": "water",
}
NODE_KINDS = ("separator", "junction", "mill")


@dataclass(frozen=True)
class Stream:
    """One stream of the flowsheet (``source`` / ``target`` "" at the boundary)."""

    name: str
    source: str
    target: str
    product: str
    row: int | None = None


@dataclass(frozen=True)
class Node:
    """A unit of the flowsheet.

    ``kind`` is ``separator`` (two outputs, fine and coarse; every size class balances),
    ``junction`` (one output; every size class balances) or ``mill`` (one output marked
    ``ground``; only the total solids balance).
    """

    name: str
    kind: str
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    fine: str = ""
    coarse: str = ""

    @property
    def balances_classes(self) -> bool:
        return self.kind != "mill"


@dataclass(frozen=True)
class Flowsheet:
    """A validated flowsheet: streams, nodes and the stream-node incidence.

    Build it with :func:`read_flowsheet` (file or DataFrame) or :func:`flowsheet_from_streams`.

    Attributes
    ----------
    streams : tuple of Stream
        The streams that carry solids, in the order of the file.
    nodes : tuple of Node
        In order of first appearance.
    source : str
        Where the flowsheet came from (file name), for messages.
    """

    streams: tuple[Stream, ...]
    nodes: tuple[Node, ...]
    source: str = ""
    water_streams: tuple[Stream, ...] = ()

    @cached_property
    def stream_names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.streams)

    @cached_property
    def stream_index(self) -> dict[str, int]:
        return {name: i for i, name in enumerate(self.stream_names)}

    def stream(self, name: str) -> Stream:
        return self.streams[self.stream_index[name]]

    @property
    def separators(self) -> tuple[Node, ...]:
        return tuple(n for n in self.nodes if n.kind == "separator")

    @property
    def feeds(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.streams if not s.source)

    @property
    def products(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.streams if not s.target)

    def incidence(self) -> np.ndarray:
        """Nodes x streams: +1 where the stream enters the node, -1 where it leaves.

        Each row times the vector of solids flows is the node's balance (inputs minus
        outputs), zero when it closes.
        """
        matrix = np.zeros((len(self.nodes), len(self.streams)))
        where = {node.name: k for k, node in enumerate(self.nodes)}
        for j, stream in enumerate(self.streams):
            if stream.target:
                matrix[where[stream.target], j] += 1.0
            if stream.source:
                matrix[where[stream.source], j] -= 1.0
        return matrix

    def water_incidence(self) -> np.ndarray:
        """Nodes x water streams: +1 where water is added to the node, -1 where it is removed."""
        matrix = np.zeros((len(self.nodes), len(self.water_streams)))
        where = {node.name: k for k, node in enumerate(self.nodes)}
        for j, stream in enumerate(self.water_streams):
            matrix[where[stream.target or stream.source], j] = 1.0 if stream.target else -1.0
        return matrix

    @property
    def flow_degrees_of_freedom(self) -> int:
        """Stream flows left free by the total solids balances: streams minus independent balances.

        One of them is the scale of the survey (a measured flow, or the basis of 100 on a feed);
        the others (the splits of the separators and mills' recycles) must come from the size
        analyses or from further measured flows.
        """
        return len(self.streams) - int(np.linalg.matrix_rank(self.incidence()))

    def graph(self) -> nx.MultiDiGraph:
        """The flowsheet as a networkx multigraph, the boundary as node :data:`BOUNDARY`;
        each edge carries its stream's name in ``stream``."""
        import networkx as nx  # for the caller's graph algorithms; the checks of the reader need none

        graph = nx.MultiDiGraph()
        graph.add_node(BOUNDARY)
        for node in self.nodes:
            graph.add_node(node.name, kind=node.kind)
        for stream in self.streams:
            graph.add_edge(stream.source or BOUNDARY, stream.target or BOUNDARY, key=stream.name, stream=stream.name)
        return graph

    def to_frame(self) -> pd.DataFrame:
        """The flowsheet in the file schema (``stream, from, to, product``), water streams last."""
        streams = self.streams + self.water_streams
        return pd.DataFrame(
            {
                "stream": [s.name for s in streams],
                "from": [s.source for s in streams],
                "to": [s.target for s in streams],
                "product": [s.product for s in streams],
            }
        )

    def describe(self) -> str:
        """One line: streams, nodes by kind, feeds, products and the flow degrees of freedom."""
        kinds = ", ".join(f"{sum(n.kind == k for n in self.nodes)} {k}(s)" for k in NODE_KINDS)
        water = f" (and {len(self.water_streams)} water stream(s))" if self.water_streams else ""
        return (
            f"{len(self.streams)} streams{water}, {len(self.nodes)} nodes ({kinds}); feeds {', '.join(self.feeds)}; "
            f"products {', '.join(self.products)}; {self.flow_degrees_of_freedom} flow(s) free after the solids balances"
        )


def read_flowsheet(
    path, *, sheet=None, sep: str | None = None, decimal: str | None = None, source: str | None = None
) -> Flowsheet:
    """Read and validate a flowsheet (schema in the module docstring).

    Parameters
    ----------
    path : str, path-like or pandas.DataFrame
        CSV or Excel file, or a DataFrame with the same columns.
    sheet, sep, decimal
        As for :func:`tromplab.loading.tables.read_table`.
    source : str, optional
        Name used in messages instead of the file's (for a DataFrame built in code).

    Returns
    -------
    Flowsheet

    Raises
    ------
    InputError
        Naming the file, row and column, or the node or stream at fault: missing or
        unknown columns, blank or repeated stream names, a stream that touches no node or
        loops on one, a node without input or output, separator outputs not marked one
        fine and one coarse, a graph in pieces or with material that cannot leave.

    Examples
    --------
    >>> sheet = pd.DataFrame({"stream": ["feed", "over", "under"], "from": ["", "cyclone", "cyclone"],
    ...                       "to": ["cyclone", "", ""], "product": ["", "fine", "coarse"]})
    >>> read_flowsheet(sheet).describe()
    '3 streams, 1 nodes (1 separator(s), 0 junction(s), 0 mill(s)); feeds feed; products over, under; 2 flow(s) free after the solids balances'
    """
    table = read_table(path, sheet=sheet, sep=sep, decimal=decimal)
    table.require("stream", "from", "to")
    table.refuse_unknown(["stream", "from", "to", "product"], what="flowsheet")
    streams = []
    seen = {}
    for i in range(len(table.frame)):
        name = _text(table, i, "stream")
        if not name:
            raise table.error("stream name is blank", index=i, column="stream")
        if name in seen:
            raise table.error(f"stream '{name}' is declared twice (also at row {seen[name]})", index=i, column="stream")
        seen[name] = table.rows[i]
        origin, target = _text(table, i, "from"), _text(table, i, "to")
        if not origin and not target:
            raise table.error(f"stream '{name}' has neither 'from' nor 'to': it touches no node", index=i, column="from")
        if origin and origin == target:
            raise table.error(f"stream '{name}' leaves and enters node '{origin}' (a loop on one node)", index=i, column="to")
        for node, column in ((origin, "from"), (target, "to")):
            if node == BOUNDARY:
                raise table.error(f"'{BOUNDARY}' is reserved for the boundary; leave the cell blank", index=i, column=column)
        word = _text(table, i, "product").lower() if "product" in table.frame.columns else ""
        if word and word not in PRODUCT_WORDS:
            raise table.error(
                f"product '{word}' is not one of {', '.join(PRODUCT_WORDS)} (blank for a stream that is no separator "
                "or mill output)",
                index=i,
                column="product",
            )
        if word == "water" and origin and target:
            raise table.error(
                f"water stream '{name}' runs between two nodes: a water stream is an addition (blank 'from') or a "
                "removal (blank 'to'); water carried with the solids is given by their per cent solids",
                index=i,
                column="product",
            )
        if word and word != "water" and not origin:
            raise table.error(f"stream '{name}' is a feed (no 'from') but is marked '{word}'", index=i, column="product")
        streams.append(Stream(name, origin, target, PRODUCT_WORDS.get(word, ""), int(table.rows[i])))
    return flowsheet_from_streams(streams, source=source or table.source)


def _text(table: Table, i: int, column: str) -> str:
    value = table.frame[column].iloc[i]
    return "" if pd.isna(value) else str(value).strip()


def flowsheet_from_streams(streams, *, source: str = "flowsheet") -> Flowsheet:
    """Validate streams as a flowsheet (the checks of :func:`read_flowsheet`).

    Parameters
    ----------
    streams : iterable of Stream
        The streams, in the order of the file.
    source : str
        Name of the flowsheet in messages.

    Returns
    -------
    Flowsheet
    """
    streams = tuple(streams)
    water = tuple(s for s in streams if s.product == "water")
    streams = tuple(s for s in streams if s.product != "water")
    names = list(dict.fromkeys([n for s in streams for n in (s.source, s.target) if n]))

    def error(message, stream: Stream | None = None, column: str | None = None):
        return InputError(message, source=source, row=stream.row if stream else None, column=column)

    if not streams:
        raise error("the flowsheet has no streams" + (" carrying solids" if water else ""))
    for stream in water:
        node = stream.target or stream.source
        if node not in names:
            raise error(f"water stream '{stream.name}' touches node '{node}', which no solids stream passes", stream, "to")
    nodes = []
    for name in names:
        inputs = tuple(s.name for s in streams if s.target == name)
        outputs = [s for s in streams if s.source == name]
        if not inputs:
            raise error(f"node '{name}' has no input (no stream has it in 'to')")
        if not outputs:
            raise error(f"node '{name}' has no output (no stream has it in 'from')")
        marks = {s.product for s in outputs}
        if len(outputs) == 1:
            out = outputs[0]
            if out.product in ("fine", "coarse"):
                raise error(
                    f"stream '{out.name}' is marked {out.product} but node '{name}' has one output: only the two outputs "
                    "of a separator are fine and coarse",
                    out,
                    "product",
                )
            kind = "mill" if out.product == "ground" else "junction"
            nodes.append(Node(name, kind, inputs, (out.name,)))
            continue
        listed = ", ".join(s.name for s in outputs)
        if len(outputs) > 2 or marks != {"fine", "coarse"}:
            raise error(
                f"node '{name}' has {len(outputs)} outputs ({listed}): a node with several outputs is a separator with "
                "exactly two, one marked fine and one coarse in 'product' (a multi-deck screen is one node per deck; "
                "splitters are not supported)",
                outputs[0],
                "product",
            )
        fine = next(s.name for s in outputs if s.product == "fine")
        coarse = next(s.name for s in outputs if s.product == "coarse")
        nodes.append(Node(name, "separator", inputs, tuple(s.name for s in outputs), fine, coarse))
    flowsheet = Flowsheet(streams, tuple(nodes), source, water)
    _check_graph(flowsheet, error)
    return flowsheet


def _check_graph(flowsheet: Flowsheet, error) -> None:
    """Refuse a flowsheet in pieces, a node no feed reaches, or one from which no product is reached.

    The graph searches are a few lines of breadth-first search over the streams (the boundary as
    one node, then split into the feeds' source and the products' sink): networkx, a tenth of a
    second of start-up, is imported for :meth:`Flowsheet.graph` and the figures only.
    """
    if not flowsheet.feeds:
        raise error("the flowsheet has no feed (a stream with a blank 'from')")
    if not flowsheet.products:
        raise error("the flowsheet has no final product (a stream with a blank 'to')")
    edges = [(stream.source or BOUNDARY, stream.target or BOUNDARY) for stream in flowsheet.streams]
    pieces = _pieces([BOUNDARY, *(node.name for node in flowsheet.nodes)], edges)
    if len(pieces) > 1:
        apart = sorted(min(piece) for piece in pieces if BOUNDARY not in piece)
        raise error(f"the flowsheet is in {len(pieces)} pieces: node(s) {', '.join(apart)} are connected to no feed or product")
    forward = [(stream.source or "(feeds)", stream.target or "(products)") for stream in flowsheet.streams]
    fed = _reached("(feeds)", forward)
    leaving = _reached("(products)", [(target, source) for source, target in forward])
    for node in flowsheet.nodes:
        if node.name not in fed:
            raise error(f"node '{node.name}' is fed by no feed of the circuit (only by a closed loop)")
        if node.name not in leaving:
            raise error(f"material entering node '{node.name}' can never leave the circuit: no path to a final product")


def _reached(start: str, edges) -> set[str]:
    """The nodes a directed path from ``start`` reaches along ``edges`` (``start`` included)."""
    following: dict[str, list[str]] = {}
    for source, target in edges:
        following.setdefault(source, []).append(target)
    reached, frontier = {start}, [start]
    while frontier:
        node = frontier.pop()
        for after in following.get(node, ()):
            if after not in reached:
                reached.add(after)
                frontier.append(after)
    return reached


def _pieces(nodes, edges) -> list[set[str]]:
    """The weakly connected components of the graph of ``nodes`` and ``edges``."""
    both = [*edges, *((target, source) for source, target in edges)]
    pieces, seen = [], set()
    for node in nodes:
        if node not in seen:
            piece = _reached(node, both)
            seen |= piece
            pieces.append(piece)
    return pieces
