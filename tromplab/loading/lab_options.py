"""How to read a lab table: the options of :func:`tromplab.loading.lab.read_lab`, checked where they are made."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError, OptionError
from ..options import DEFAULT_MIN_FEED_SHARE, DEFAULT_SUM_TOLERANCE_PCT, KINDS, PARTITION_METHODS, WEIGHTINGS
from ..validation import (
    SIZE_LIMITS,
    check_choice,
    check_optional,
    check_probability,
    check_range,
    check_share,
    check_size,
    check_water_recovery,
)


@dataclass(frozen=True)
class LabOptions:
    """How to read a lab table.

    Attributes
    ----------
    kind : str or None
        What plain stream columns hold (one of :data:`KINDS`); not needed when every
        stream column carries a kind suffix.
    fine_yield, coarse_yield : float or None
        Yield of the fine (coarse) product as a fraction of the feed; overrides a column.
    estimate_yield : bool
        Ignore a given yield and estimate it from three streams.
    reconcile : bool
        Adjust the three distributions minimally so every class balances and compute
        the partition from the adjusted values.
    min_feed_share : float
        Classes with a smaller feed share are flagged and left out of the fit.
    sum_tolerance_pct : float
        Allowed deviation of per-class percentages from 100 % (percentage points).
    top_size, pan_lower_size : float or None
        Upper bound of the open top class, lower bound of the pan (0 or None: the pan
        continues the geometric progression of its neighbour, as a blank or 0 lower
        bound in the table does; a geometric mean with 0 would put the pan at size 0).
    rename : dict
        Column renames applied before reading (``{"sieve_um": "size"}``).
    sheet : str or None
        Excel sheet.
    weight_by_feed_share : bool
        Weight each Tromp point by the feed share of its class (the same as
        ``weighting="feed-share"``).  Error model: the partition of a class is measured on
        a sample mass proportional to its feed share, so its variance is inversely
        proportional to that share.
    weighting : {"none", "feed-share", "error-model"}
        How the Tromp points are weighted in the fit (:mod:`tromplab.loading.weights`):
        every class alike (default), by its feed share, or by the inverse variance of its
        partition under the error model of the size analyses with a floor relative to the
        feed share (the weighting of ``tromplab circuit --fit``, so that one node gives the
        same fits by both paths).
    partition_from : {"products", "feed"}
        With three measured streams: ``"products"`` (default) computes the partition
        from both products, :math:`y b / (y b + (1-y) c)`, so swapping the fine and
        coarse columns gives exactly 1 - partition; ``"feed"`` divides the fine
        stream by the measured feed, :math:`y b / a` (the fine stream alone; not
        symmetric when the balance does not close).  ``reconcile`` overrides both.
    size_unit : str or None
        Unit of the sizes when the size columns carry no unit suffix (``--size-unit``);
        a contradiction with a suffix is an error.
    sep, decimal : str or None
        CSV separator and decimal mark (detected when not given).
    water_recovery : float or None
        Share of the feed water reporting to the underflow (coarse product) of a
        hydrocyclone, in [0, 1) (``--water-recovery``); the points table then also gives
        the Kelsall-corrected partition ``partition_fine_corrected`` (see
        :func:`tromplab.loading.kelsall.kelsall_corrected`).
    """

    kind: str | None = None
    fine_yield: float | None = None
    coarse_yield: float | None = None
    estimate_yield: bool = False
    reconcile: bool = False
    min_feed_share: float = DEFAULT_MIN_FEED_SHARE
    sum_tolerance_pct: float = DEFAULT_SUM_TOLERANCE_PCT
    top_size: float | None = None
    pan_lower_size: float | None = None
    rename: dict = field(default_factory=dict)
    sheet: str | None = None
    weight_by_feed_share: bool = False
    partition_from: str = "products"
    size_unit: str | None = None
    sep: str | None = None
    decimal: str | None = None
    water_recovery: float | None = None
    weighting: str = "none"

    def __post_init__(self):
        check_choice(self.weighting, "weighting", choices=WEIGHTINGS)
        if self.weight_by_feed_share and self.weighting not in ("none", "feed-share"):
            raise OptionError("weighting", f"is {self.weighting!r} and weight_by_feed_share is set too: give one weighting")
        if self.weight_by_feed_share or self.weighting == "feed-share":  # the two spellings of one weighting agree
            object.__setattr__(self, "weighting", "feed-share")
            object.__setattr__(self, "weight_by_feed_share", True)
        if self.kind is not None and self.kind not in KINDS:
            raise ValueError(f"unknown kind {self.kind!r}; choose one of {', '.join(KINDS)}")
        if self.partition_from not in PARTITION_METHODS:
            raise ValueError(f"unknown partition_from {self.partition_from!r}; choose one of {', '.join(PARTITION_METHODS)}")
        for name in ("fine_yield", "coarse_yield"):
            check_optional(check_probability, getattr(self, name), name)
        check_share(self.min_feed_share, "min_feed_share")
        check_range(self.sum_tolerance_pct, "sum_tolerance_pct", low=0.0, high=100.0)
        check_optional(check_size, self.top_size, "top_size")
        check_optional(check_range, self.pan_lower_size, "pan_lower_size", low=0.0, high=SIZE_LIMITS[1])
        check_optional(check_water_recovery, self.water_recovery, "water_recovery")
        if self.fine_yield is not None and self.coarse_yield is not None:
            if not np.isclose(self.fine_yield + self.coarse_yield, 1.0, atol=1e-6):
                raise InputError("fine_yield and coarse_yield are both given and do not add up to 1")
