r"""The weights of Tromp points: how much each size class counts in a partition-curve fit.

One function for both paths that produce weighted points: the lab table of one classifier
(:mod:`tromplab.loading.lab`, option ``weighting``) and the reconciled plant survey
(:meth:`tromplab.circuit.reconciliation.CircuitBalance.points_table`), so that one node gives
the same weights, and the same fits, whichever way it reaches the fit.

Weightings (:data:`~tromplab.options.WEIGHTINGS`)
-------------------------------------------------
``"none"``
    Every class counts the same (ordinary least squares).
``"feed-share"``
    The weight of a class is its feed share (as given: the shares of the classes fitted): the
    partition of a class is measured on a sample mass proportional to its feed share, so its
    variance is taken as inversely proportional to that share.
``"error-model"``
    The inverse of the variance of the partition that the error model of the size analyses
    gives *at the shares the partition implies*, plus a floor relative to the feed share:

    .. math::

        \sigma_i^2 = \frac{y^2 (1-\varphi_i)^2 \sigma^2(b_i) + (1-y)^2 \varphi_i^2 \sigma^2(c_i)}{a_i^2}
                     + \tau^2 \frac{\bar a}{a_i},
        \qquad b_i = \frac{a_i \varphi_i}{y},\; c_i = \frac{a_i (1-\varphi_i)}{1-y},
        \qquad \sigma^2(x) = (r x)^2 + e^2

    with :math:`a_i` the feed share of class :math:`i`, :math:`\varphi_i` its partition to
    fines, :math:`y` the fine yield, :math:`b_i, c_i` the fine and coarse shares that
    :math:`\varphi_i` implies (so a product share reported as 0 does not make its class
    exact), :math:`r, e` the relative and absolute error of a share (the survey's error model,
    Hodouin & Everell 1980) and :math:`\tau` the partition floor
    (:data:`~tromplab.options.DEFAULT_PARTITION_FLOOR`) for a class of average feed share
    :math:`\bar a` (the mean over the classes fitted).  The first term is the delta-method
    variance of :math:`\varphi = y b / (y b + (1-y) c)` from independent errors of the two
    products; the second keeps a class whose products the absolute error alone describes (a
    class all in one product) from taking most of the weight: the partition of a class is not
    known better than its sample of particles, whose size scales with the feed share.

The weights of ``"error-model"`` are scaled to a mean of 1 over the classes fitted (scaling
changes no fitted parameter).  Evaluating a variance function at values implied by a model rather than at the
measured values avoids the bias of weights computed from the data they weight (Carroll &
Ruppert 1988, ch. 2; Baker & Cousins 1984 on the Neyman and Pearson chi-square).

References
----------
Baker, S. & Cousins, R. D. (1984). Clarification of the use of chi-square and likelihood
functions in fits to histograms. *Nuclear Instruments and Methods in Physics Research* 221(2),
437-442.

Carroll, R. J. & Ruppert, D. (1988). *Transformation and Weighting in Regression*. Chapman and
Hall, New York.

Hodouin, D. & Everell, M. D. (1980). A hierarchical procedure for adjustment and material
balancing of mineral processes data. *International Journal of Mineral Processing* 7(2), 91-116.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..options import (
    DEFAULT_ABSOLUTE_ERROR,
    DEFAULT_PARTITION_FLOOR,
    DEFAULT_RELATIVE_ERROR,
    WEIGHT_CONCENTRATION_CLASSES,
    WEIGHT_CONCENTRATION_SHARE,
    WEIGHTINGS,
)
from ..validation import check_choice, check_non_negative
from .size_classes import class_label


def partition_variance(
    partition_fine,
    feed_share,
    fine_yield: float,
    *,
    fine_error: tuple[float, float] = (DEFAULT_RELATIVE_ERROR, DEFAULT_ABSOLUTE_ERROR),
    coarse_error: tuple[float, float] = (DEFAULT_RELATIVE_ERROR, DEFAULT_ABSOLUTE_ERROR),
    floor: float = DEFAULT_PARTITION_FLOOR,
    used=None,
) -> np.ndarray:
    r"""Variance of each class's partition under the error model, at the shares it implies.

    Parameters
    ----------
    partition_fine : array
        Partition to fines per class (clipped to 0..1 here).
    feed_share : array
        Share of the separator's feed in each class (0..1).
    fine_yield : float
        Fine yield of the separator, in (0, 1).
    fine_error, coarse_error : (float, float)
        Relative and absolute error of a share of the fine and the coarse product.
    floor : float
        Partition standard deviation :math:`\tau` added for a class of average feed share
        (0: none).
    used : array of bool, optional
        The classes fitted (their mean feed share is :math:`\bar a`); default all.

    Returns
    -------
    numpy.ndarray
        :math:`\sigma_i^2` of the module's formula; NaN where the partition or the feed
        share is missing, infinite where the feed share is 0.

    Examples
    --------
    A class all in the fine product is not exact (the coarse share's absolute error, even
    without the floor), and a class at the cut is known less well than one in the tail:

    >>> v = partition_variance([1.0, 0.5], [0.2, 0.2], 0.5, floor=0.0)
    >>> np.sqrt(v).round(4).tolist()
    [0.0025, 0.0178]
    """
    check_non_negative(floor, "floor")
    phi = np.clip(np.asarray(partition_fine, dtype=float), 0.0, 1.0)
    a = np.asarray(feed_share, dtype=float)
    y = float(fine_yield)
    used = np.ones(a.shape, dtype=bool) if used is None else np.asarray(used, dtype=bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        fine = a * phi / y
        coarse = a * (1.0 - phi) / (1.0 - y)
        share_variance = (y * (1.0 - phi)) ** 2 * _share_variance(fine, fine_error) + ((1.0 - y) * phi) ** 2 * _share_variance(
            coarse, coarse_error
        )
        typical = np.mean(a[used & np.isfinite(a)]) if (used & np.isfinite(a)).any() else np.nan
        return share_variance / a**2 + floor**2 * typical / a


def _share_variance(share, error: tuple[float, float]) -> np.ndarray:
    relative, absolute = error
    return (relative * share) ** 2 + absolute**2


def scaled_to_mean_one(weight, used) -> np.ndarray:
    """``weight`` over its mean on the ``used`` classes with a finite positive weight; NaN elsewhere."""
    weight = np.asarray(weight, dtype=float)
    keep = np.asarray(used, dtype=bool) & np.isfinite(weight) & (weight > 0)
    if not keep.any():
        return np.full(weight.shape, np.nan)
    return np.where(keep, weight / np.mean(weight[keep]), np.nan)


def partition_weights(
    weighting: str,
    partition_fine,
    feed_share,
    fine_yield: float,
    used=None,
    *,
    fine_error: tuple[float, float] = (DEFAULT_RELATIVE_ERROR, DEFAULT_ABSOLUTE_ERROR),
    coarse_error: tuple[float, float] = (DEFAULT_RELATIVE_ERROR, DEFAULT_ABSOLUTE_ERROR),
    floor: float = DEFAULT_PARTITION_FLOOR,
) -> np.ndarray | None:
    """The weight of each class under ``weighting`` (NaN for the classes not ``used``).

    Parameters
    ----------
    weighting : {"none", "feed-share", "error-model"}
        See the module notes.
    partition_fine, feed_share : array
        Partition to fines and feed share per class.
    fine_yield : float
        Fine yield of the separator.
    used : array of bool, optional
        The classes fitted (default all); the others get NaN.
    fine_error, coarse_error, floor
        The error model of ``"error-model"`` (:func:`partition_variance`).

    Returns
    -------
    numpy.ndarray or None
        None for ``"none"`` (the fit weights every point alike).

    Examples
    --------
    >>> partition_weights("error-model", [0.0, 0.3, 0.7, 1.0], [0.2, 0.3, 0.3, 0.2], 0.5).round(3).tolist()
    [0.924, 1.076, 1.076, 0.924]
    """
    check_choice(weighting, "weighting", choices=WEIGHTINGS)
    feed_share = np.asarray(feed_share, dtype=float)
    used = np.ones(feed_share.shape, dtype=bool) if used is None else np.asarray(used, dtype=bool)
    if weighting == "none":
        return None
    if weighting == "feed-share":
        return np.where(used, feed_share, np.nan)
    variance = partition_variance(
        partition_fine, feed_share, fine_yield, fine_error=fine_error, coarse_error=coarse_error, floor=floor, used=used
    )
    with np.errstate(divide="ignore"):
        return scaled_to_mean_one(1.0 / variance, used)


@dataclass(frozen=True)
class WeightConcentration:
    """How much of the total weight the heaviest classes carry.

    ``share`` is the fraction of the total weight on the :data:`~tromplab.options.WEIGHT_CONCENTRATION_CLASSES`
    heaviest classes, ``classes`` their indices (heaviest first), ``concentrated`` whether the
    share exceeds :data:`~tromplab.options.WEIGHT_CONCENTRATION_SHARE` while at least twice as
    many classes are weighted (with fewer, any two classes carry much of the weight).
    """

    share: float
    classes: tuple[int, ...]
    n_weighted: int

    @property
    def concentrated(self) -> bool:
        return bool(self.n_weighted >= 2 * WEIGHT_CONCENTRATION_CLASSES and self.share > WEIGHT_CONCENTRATION_SHARE)


def weight_concentration(weight) -> WeightConcentration:
    """The share of the total weight on the heaviest classes (NaN weights: classes not fitted).

    Examples
    --------
    >>> c = weight_concentration([5.0, 0.2, 0.2, 0.2, 0.2, 3.0])
    >>> round(c.share, 3), c.classes, c.concentrated
    (0.909, (0, 5), True)
    """
    weight = np.asarray(weight, dtype=float)
    weighted = np.flatnonzero(np.isfinite(weight) & (weight > 0))
    if weighted.size == 0:
        return WeightConcentration(float("nan"), (), 0)
    heaviest = weighted[np.argsort(weight[weighted], kind="stable")[::-1][:WEIGHT_CONCENTRATION_CLASSES]]
    share = float(weight[heaviest].sum() / weight[weighted].sum())
    return WeightConcentration(share, tuple(int(i) for i in heaviest), int(weighted.size))


def concentration_note(weight, labels) -> str | None:
    """A note when the heaviest classes carry most of the weight, else None.

    Parameters
    ----------
    weight : array
        Weight per class (NaN: not fitted).
    labels : sequence of str
        How each class reads in a message (``"38-53 um"``).

    Examples
    --------
    >>> concentration_note([9.0, 0.5, 0.5, 0.5, 0.5, 6.0], ["a", "b", "c", "d", "e", "f"])
    '2 of 6 classes (a, f) carry 88 % of the weight of the fit (more than 50 %): the curve fitted follows them more than the other classes'
    """
    found = weight_concentration(weight)
    if not found.concentrated:
        return None
    named = ", ".join(str(labels[i]) for i in found.classes)
    return (
        f"{len(found.classes)} of {found.n_weighted} classes ({named}) carry {100 * found.share:.0f} % of the weight of the fit "
        f"(more than {100 * WEIGHT_CONCENTRATION_SHARE:.0f} %): the curve fitted follows them more than the other classes"
    )


def stream_error(shares, stream: str) -> tuple[float, float]:
    """The relative and absolute error of the shares of ``stream`` in a table of measured shares.

    ``shares`` has the columns ``stream, relative, absolute`` (NaN where the table gave a
    standard deviation instead of the error model); the median over the stream's modelled
    shares, or the defaults when it has none (a stream not sampled).
    """
    rows = shares[(shares["stream"] == stream) & shares["relative"].notna() & shares["absolute"].notna()]
    if rows.empty:
        return DEFAULT_RELATIVE_ERROR, DEFAULT_ABSOLUTE_ERROR
    return float(rows["relative"].median()), float(rows["absolute"].median())


def weight_notes(points) -> list[str]:
    """One note per experiment of a Tromp-points table whose weights are concentrated
    (:func:`concentration_note`), naming the experiment.

    ``points`` has the columns ``experiment, weight`` and the class bounds ``size_lower`` and
    ``size_upper`` (with or without a unit suffix, as written); rows without a weight are
    classes not fitted.
    """
    return [f"note ({name}): {note}" for name, note in weight_notices(points)]


def weight_notices(points) -> list[tuple[str, str]]:
    """``(experiment, note)`` of each experiment of a Tromp-points table whose weights are
    concentrated (:func:`concentration_note`; ``points`` as for :func:`weight_notes`)."""
    if "weight" not in points.columns or points.empty:
        return []
    lower = next(c for c in points.columns if c.startswith("size_lower"))
    upper = next(c for c in points.columns if c.startswith("size_upper"))
    unit = lower.removeprefix("size_lower").removeprefix("_")
    notes = []
    for name, part in points.groupby("experiment", sort=False):
        labels = [class_label(lo, hi, unit) for lo, hi in zip(part[lower], part[upper])]
        note = concentration_note(part["weight"].to_numpy(dtype=float), labels)
        notes += [(str(name), note)] if note else []
    return notes
