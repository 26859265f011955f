"""The columns of a lab table: which hold the streams (and what they hold), the yields, the sizes.

The stream columns are ``feed``, ``fine`` (or ``overflow``), ``coarse`` (or ``underflow``), with
an optional kind suffix (``feed_pct``, ``fine_retained_frac``); what a plain column holds is
declared by the ``kind`` option, never guessed (schema: :mod:`tromplab.loading.lab`).
"""

from __future__ import annotations

import re

from ..errors import InputError
from ..options import KINDS
from .lab_options import LabOptions
from .tables import Table

STREAMS = ("feed", "fine", "coarse")
STREAM_ALIASES = {"overflow": "fine", "underflow": "coarse"}  # hydrocyclone wording
CUMULATIVE_KINDS = {"retained_pct", "retained_frac", "passing_pct", "passing_frac"}
SIZE_STEMS = ("size", "size_lower", "size_upper", "size_class", "size_representative")
YIELD_COLUMNS = {"fine_yield": "fine", "overflow_yield": "fine", "coarse_yield": "coarse", "underflow_yield": "coarse"}


def is_lab_table(columns) -> bool:
    """True when the columns look like a lab table (stream columns, no partition column)."""
    names = [str(c) for c in columns]
    has_stream = any(_stream_of(name) for name in names)
    return has_stream and not any(name.startswith("partition_") for name in names)


def _stream_of(column: str):
    """``(stream, kind)`` of a stream column (overflow = fine, underflow = coarse), else None."""
    names = "|".join((*STREAMS, *STREAM_ALIASES))
    match = re.fullmatch(r"(" + names + r")(?:_(" + "|".join(KINDS) + r"))?", column)
    if not match:
        return None
    return STREAM_ALIASES.get(match.group(1), match.group(1)), match.group(2)


def known_lab_columns(table: Table, streams, layout) -> list[str]:
    """Every column a lab table may hold given its streams and sizes (for the unknown-column check)."""
    known = ["experiment", "size_unit", *YIELD_COLUMNS, *layout.columns, *(column for column, _ in streams.values())]
    suffix = f"_{layout.unit_suffix}" if layout.unit_suffix else ""
    known += [f"{stem}{suffix}" for stem in SIZE_STEMS]  # for suggestions: the sizes spelt as the file spells them
    known += [f"{stream}_{kind}" for stream in (*STREAMS, *STREAM_ALIASES) for kind in KINDS]
    return known


def stream_columns(table: Table, options: LabOptions) -> dict[str, tuple[str, str]]:
    """``{stream: (column, kind)}`` for the streams present."""
    found = {}
    for column in table.frame.columns:
        parsed = _stream_of(column)
        if not parsed:
            continue
        stream, kind = parsed
        if stream in found:
            raise InputError(
                f"two columns for the {stream} stream ({found[stream][0]}, {column})", source=table.source, column=column
            )
        if kind is None:
            if options.kind is None:
                raise InputError(
                    f"what column '{column}' holds is not declared: declare it with kind='pct' (or another of "
                    f"{', '.join(KINDS)}) or name the column with a suffix, e.g. '{column}_pct'",
                    source=table.source,
                    column=column,
                )
            kind = options.kind
        found[stream] = (column, kind)
    if len(found) < 2:
        raise InputError(
            f"need at least two of the streams feed, fine, coarse; found {', '.join(found) or 'none'}", source=table.source
        )
    cumulative = {kind in CUMULATIVE_KINDS for _, kind in found.values()}
    if len(cumulative) > 1:
        raise InputError("cumulative and per-class stream columns are mixed; give all streams the same way", source=table.source)
    return found
