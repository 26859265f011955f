"""Table views: the same numbers read as the partition to the fine or to the coarse product.

Every table of the package is computed on the partition to fines (``partition_fine``,
``phi``).  Hydrocyclone and screen users read the partition to the underflow or
oversize, ``1 - phi``; :func:`partition_view` turns a table into that reading without
touching the computation.
"""

from __future__ import annotations

import pandas as pd

from ..errors import OptionError
from ..options import PARTITION_TO


def check_partition_to(partition_to: str) -> str:
    """Return ``partition_to`` if it is ``"fine"`` or ``"coarse"``, else raise ValueError."""
    if partition_to not in PARTITION_TO:
        raise OptionError("partition_to", f"must be 'fine' or 'coarse', got {partition_to!r}")
    return partition_to


def partition_view(table: pd.DataFrame, partition_to: str = "fine") -> pd.DataFrame:
    """The table as partition to the ``partition_to`` product (a copy).

    With ``"coarse"``: a ``partition_fine`` column (and its ``_low``/``_high`` bounds)
    becomes ``partition_coarse = 1 - partition_fine``, replacing an existing
    ``partition_coarse`` column; the slope at the cut of the fitted curve, which the
    fits table gives for the partition to fines (negative), becomes ``slope_coarse =
    -slope`` (positive; interval bounds swapped and negated).  Sizes, cut sizes,
    ``d25``/``d75`` (already defined on the partition to coarse), ``Ep``, ``eta`` and
    ``eps`` do not depend on the reading and stay as they are.  With ``"fine"`` the
    table is returned unchanged.

    Examples
    --------
    >>> table = pd.DataFrame({"size": [10.0, 40.0], "partition_fine": [0.9, 0.25]})
    >>> partition_view(table, "coarse")
       size  partition_coarse
    0  10.0              0.10
    1  40.0              0.75
    """
    check_partition_to(partition_to)
    view = table.copy()
    if partition_to == "fine":
        return view
    if "partition_fine" in view.columns:
        view = view.drop(columns=[c for c in ("partition_coarse",) if c in view.columns])
        view["partition_fine"] = 1.0 - view["partition_fine"]
        if "partition_fine_corrected" in view.columns:  # Kelsall's corrected partition: Y' = 1 - phi'
            view["partition_fine_corrected"] = 1.0 - view["partition_fine_corrected"]
        if {"partition_fine_low", "partition_fine_high"} <= set(view.columns):
            low, high = 1.0 - view["partition_fine_high"], 1.0 - view["partition_fine_low"]
            view["partition_fine_low"], view["partition_fine_high"] = low, high
        view = view.rename(columns=lambda c: c.replace("partition_fine", "partition_coarse"))
    if "slope" in view.columns:
        view["slope"] = -view["slope"]
        for suffix in ("", "_boot"):
            low, high = f"slope{suffix}_low", f"slope{suffix}_high"
            if low in view.columns and high in view.columns:
                view[low], view[high] = -view[high], -view[low]
        view = view.rename(columns=lambda c: "slope_coarse" + c[len("slope") :] if c.startswith("slope") else c)
    return view


#: Columns of the mass-balance table as shown to a reader (console, report), in order.
_BALANCE_STREAMS = ("size_lower", "size_upper", "size", "feed", "fine", "coarse", "balance_residual")
_ADJUSTED_STREAMS = ("feed_adjusted", "fine_adjusted", "coarse_adjusted")


def balance_view(classes: pd.DataFrame, partition_to: str = "fine", *, adjusted: bool = False) -> pd.DataFrame:
    """The balance table of a lab experiment as shown to a reader: sizes, the three streams,
    the balance residual, (with ``adjusted``, the reconciled streams), the partition to the
    ``partition_to`` product and whether the class was used; columns the table lacks are
    left out.
    """
    view = partition_view(classes, partition_to)
    wanted = (*_BALANCE_STREAMS, *(_ADJUSTED_STREAMS if adjusted else ()), f"partition_{partition_to}", "used")
    return view[[column for column in wanted if column in view.columns]]
