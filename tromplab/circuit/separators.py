r"""What a reconciled survey says about each separator: its partition curve for the whole solids
and for each assayed component, and each component's grades, yield and recovery.

The partition to the fine product of class :math:`i` is

.. math:: \varphi_i = \frac{m_{f,i}}{m_{f,i} + m_{c,i}}

with :math:`m_{f,i}`, :math:`m_{c,i}` the reconciled class flows of the fine and coarse product
(of the solids, or of one component: :math:`c_{k,f,i}`, :math:`c_{k,c,i}`); its standard
deviation is the delta method's with the covariance of the reconciliation.  A component's
quantity that the survey cannot determine (a direction of the unknowns no measurement sees
moves it: the component's flows at the separator are not assayed enough) is NaN with a flag,
never given the too-small sd of the seen directions alone.

Intervals of a recovery or yield (0..1) are made on the logit scale,
:math:`\mathrm{logit}^{-1}(\mathrm{logit}\,R \pm z\,\sigma_R / (R(1 - R)))`: the delta method
there keeps them inside 0..1 (and equals the symmetric interval to first order).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..options import DEFAULT_MIN_FEED_SHARE
from ..statistics.distributions import norm_isf
from .assays import SOLIDS

#: Separator classes whose feed share (of the separator's feed) is below this are written to
#: points.csv as not used (partition not meaningful), as lab tables flag them.
MIN_FEED_SHARE = DEFAULT_MIN_FEED_SHARE
#: Columns of :func:`partition_table` (``DIR/partition.csv``).
PARTITION_COLUMNS = ["experiment", "size_lower", "size_upper", "size", "feed_share", "partition_fine", "partition_sd",
                     "fine_yield", "fine_yield_sd", "used", "flag", "component"]  # fmt: skip
#: Columns of :func:`components_table` (``DIR/components.csv``).
COMPONENT_COLUMNS = ["separator", "component", "feed_grade", "feed_grade_sd", "fine_grade", "fine_grade_sd",
                     "coarse_grade", "coarse_grade_sd", "fine_yield", "fine_yield_sd", "recovery_fine",
                     "recovery_fine_sd", "recovery_fine_low", "recovery_fine_high", "determined", "note"]  # fmt: skip
#: A quantity moves along the directions no measurement sees by less than this share of its
#: gradient's norm: the survey determines it.
DETERMINED_TOLERANCE = 1e-6
#: Level of the intervals of :func:`components_table`.
INTERVAL_LEVEL = 0.95


def partition_flags(feed_share: np.ndarray, phi: np.ndarray, at_bound: np.ndarray) -> tuple[list, list]:
    """``used`` and ``flag`` of each class of a separator: too little feed or a partition outside
    0..1 (not used), or a product's class flow held at its bound 0 (used, said)."""
    used, flags = [], []
    for share, value, bound in zip(feed_share, phi, at_bound):
        if not np.isfinite(value) or share < MIN_FEED_SHARE:
            used.append(False)
            flags.append(f"feed share {100 * share:.3g} % below {100 * MIN_FEED_SHARE:g} %: partition not meaningful")
        elif not 0.0 <= value <= 1.0:
            used.append(False)
            flags.append(f"reconciled partition {value:.4g} outside 0..1: not a partition, left out")
        else:
            used.append(True)
            flags.append("a product's class flow held at 0 (the least squares would make it negative)" if bound else "")
    return used, flags


def _curve(balance, node, fine: np.ndarray, coarse: np.ndarray, size: int, component: str) -> pd.DataFrame:
    """The partition of one separator for the unknowns at indices ``fine`` and ``coarse`` (one per
    class) of the reported unknowns; gradients of length ``size``."""
    v = balance._unknowns
    classes = balance.survey.classes
    n = fine.size
    mf, mc = v[fine], v[coarse]
    total = mf + mc
    G = np.zeros((n, size))
    with np.errstate(invalid="ignore", divide="ignore"):
        phi = mf / total
        G[np.arange(n), fine] = mc / total**2
        G[np.arange(n), coarse] = -mf / total**2
    yield_gradient = np.zeros((1, size))
    Ff, Fc = mf.sum(), mc.sum()
    yield_gradient[0, fine] = Fc / (Ff + Fc) ** 2
    yield_gradient[0, coarse] = -Ff / (Ff + Fc) ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        feed_share = total / total.sum()
    held = set(balance.at_bound)
    at_bound = np.array([fine[i] in held or coarse[i] in held for i in range(n)])
    used, flags = partition_flags(feed_share, phi, at_bound)
    phi = np.where(np.isfinite(phi) & (phi >= 0.0) & (phi <= 1.0), phi, np.nan)
    partition_sd, yield_sd = np.where(np.isfinite(phi), balance._sd(G), np.nan), float(balance._sd(yield_gradient)[0])
    if component != SOLIDS:
        seen = _determined(balance, np.vstack([G, yield_gradient]))
        used = [u and bool(d) for u, d in zip(used, seen[:n])]
        flags = [f if d else "not determined by the survey: assay more streams of this separator" for f, d in zip(flags, seen)]
        phi, partition_sd = np.where(seen[:n], phi, np.nan), np.where(seen[:n], partition_sd, np.nan)
        yield_sd = yield_sd if seen[n] else np.nan
    return pd.DataFrame(
        {"experiment": node.name, "size_lower": classes["size_lower"].to_numpy(), "size_upper": classes["size_upper"].to_numpy(),
         "size": classes["size"].to_numpy(), "feed_share": feed_share, "partition_fine": phi, "partition_sd": partition_sd,
         "fine_yield": Ff / (Ff + Fc) if np.isfinite(yield_sd) or component == SOLIDS else np.nan,
         "fine_yield_sd": yield_sd, "used": used, "flag": flags, "component": component}
    )  # fmt: skip


def _determined(balance, gradients: np.ndarray) -> np.ndarray:
    """Per row of ``gradients`` (in the unknowns): True when no direction the measurements leave
    unseen moves the quantity."""
    problem, decomposition = balance.problem, balance.decomposition
    if problem is None or decomposition is None:
        return np.ones(gradients.shape[0], dtype=bool)
    unseen = decomposition.unseen_unknowns if getattr(problem, "is_sparse", False) else problem.N @ decomposition.unseen
    full = np.zeros((gradients.shape[0], unseen.shape[0]))
    full[:, : gradients.shape[1]] = np.nan_to_num(gradients)
    moved = np.abs(full @ unseen).max(axis=1, initial=0.0)
    return moved <= DETERMINED_TOLERANCE * np.maximum(np.linalg.norm(full, axis=1), 1e-300)


def partition_table(balance) -> pd.DataFrame:
    """Partition to the fine product of every separator and class, from the reconciled data:
    the whole solids (``component`` = ``solids``), then each assayed component.

    Columns :data:`PARTITION_COLUMNS`: ``experiment`` (the separator's node), ``size_lower,
    size_upper, size, feed_share`` (share of the separator's feed, of the solids or of the
    component, in the class), ``partition_fine, partition_sd`` (delta method),
    ``fine_yield, fine_yield_sd`` (of the solids; for a component its recovery to the fine
    product), ``used, flag, component``.
    """
    index = balance.flowsheet.stream_index
    S, n = balance.class_flows.shape
    problem = balance.problem
    frames = []
    for node in balance.flowsheet.separators if balance.has_size_classes else ():
        f, c = index[node.fine], index[node.coarse]
        classes = np.arange(n)
        frames.append(_curve(balance, node, f * n + classes, c * n + classes, S * n, SOLIDS))
        for k, component in enumerate(balance.survey.components):
            fine, coarse = problem.component_index(k, f, classes), problem.component_index(k, c, classes)
            frames.append(_curve(balance, node, fine, coarse, balance._unknowns.size, component))
    if not frames:
        return pd.DataFrame(columns=PARTITION_COLUMNS)
    return pd.concat(frames, ignore_index=True)


def curve_names(table: pd.DataFrame) -> list[str]:
    """The experiment name of each row's curve: the node for the whole solids, ``NODE:COMPONENT`` for a component."""
    return [
        node if component == SOLIDS else f"{node}:{component}" for node, component in zip(table["experiment"], table["component"])
    ]


def _ratio(v: np.ndarray, numerator, denominator) -> tuple[float, np.ndarray]:
    """``sum(v[numerator]) / sum(v[denominator])`` and its gradient in ``v``."""
    top, bottom = v[numerator].sum(), v[denominator].sum()
    gradient = np.zeros(v.size)
    np.add.at(gradient, numerator, 1.0 / bottom)
    np.add.at(gradient, denominator, -top / bottom**2)
    return top / bottom, gradient


def _logit_interval(value: float, sd: float, level: float = INTERVAL_LEVEL) -> tuple[float, float]:
    if not (np.isfinite(value) and np.isfinite(sd)) or not 0.0 < value < 1.0:
        return (value, value) if np.isfinite(value) and sd == 0 else (np.nan, np.nan)
    from scipy import special  # imported when an interval is computed, not at start-up

    half = norm_isf((1.0 - level) / 2.0) * sd / (value * (1.0 - value))
    return float(special.expit(special.logit(value) - half)), float(special.expit(special.logit(value) + half))


def components_table(balance) -> pd.DataFrame:
    """One row per separator and assayed component (:data:`COMPONENT_COLUMNS`, empty without assays).

    ``feed_grade``, ``fine_grade``, ``coarse_grade``: the component's mass share of the solids
    of the separator's feed and products (fractions, 0..1); ``fine_yield``: the solids' split
    to the fine product; ``recovery_fine``: the component's (its fine product's mass of the
    component over its feed's), each with its delta-method sd; ``recovery_fine_low/high``: the
    95 % interval of the recovery on the logit scale (inside 0..1); ``determined``: False when
    the survey cannot determine the component's flows at this separator (then NaN, ``note``
    says so).
    """
    problem, v = balance.problem, balance._unknowns
    index = balance.flowsheet.stream_index
    n = balance.class_flows.shape[1]
    rows = []
    for node in balance.flowsheet.separators if balance.has_size_classes else ():
        f, c = index[node.fine], index[node.coarse]
        classes = np.arange(n)
        solids_fine, solids_coarse = f * n + classes, c * n + classes
        for k, component in enumerate(balance.survey.components):
            fine, coarse = problem.component_index(k, f, classes), problem.component_index(k, c, classes)
            quantities = {
                "feed_grade": _ratio(v, np.r_[fine, coarse], np.r_[solids_fine, solids_coarse]),
                "fine_grade": _ratio(v, fine, solids_fine),
                "coarse_grade": _ratio(v, coarse, solids_coarse),
                "fine_yield": _ratio(v, solids_fine, np.r_[solids_fine, solids_coarse]),
                "recovery_fine": _ratio(v, fine, np.r_[fine, coarse]),
            }
            gradients = np.array([gradient for _, gradient in quantities.values()])
            determined = bool(_determined(balance, gradients).all())
            sds = balance._sd(gradients)
            row = {"separator": node.name, "component": component, "determined": determined,
                   "note": "" if determined else "not determined by the survey: assay more streams of this separator"}  # fmt: skip
            for (name, (value, _)), sd in zip(quantities.items(), sds):
                row[name], row[f"{name}_sd"] = (value, sd) if determined else (np.nan, np.nan)
            row["recovery_fine_low"], row["recovery_fine_high"] = _logit_interval(row["recovery_fine"], row["recovery_fine_sd"])
            rows.append(row)
    return pd.DataFrame(rows, columns=COMPONENT_COLUMNS)


def plot_partitions(balance, ax=None):
    """The reconciled partition curves (to the fine product, +/- 2 sd) of every separator: one
    curve for the whole solids and one per assayed component, the used classes only."""
    from .plotting import figure_size, prepared_axes

    ax = prepared_axes(ax, figure_size(balance, "partition"))
    table = balance.partition_table()
    table["curve"] = curve_names(table)
    table = table[table["used"].astype(bool)]
    markers = {SOLIDS: "o", **{name: "sDv^<>"[k % 6] for k, name in enumerate(balance.survey.components)}}
    for k, (curve, part) in enumerate(table.groupby("curve", sort=False)):
        component = part["component"].iloc[0]
        ax.errorbar(part["size"], part["partition_fine"], yerr=2 * part["partition_sd"], color=f"C{k % 10}",
                    marker=markers[component], markersize=4, linewidth=1.6 if component == SOLIDS else 1.0,
                    linestyle="-" if component == SOLIDS else "--", elinewidth=0.7, capsize=1.5,
                    label=f"{curve}:{SOLIDS}" if component == SOLIDS else curve)  # fmt: skip
    unit = balance.survey.size_unit
    ax.set_xscale("log")
    ax.set_ylim(-0.05, 1.05)
    ax.set_xlabel(f"size ({unit})" if unit else "size")
    ax.set_ylabel("partition to the fine product")
    ax.set_title("Partition per separator and component: reconciled (+/- 2 sd)", fontsize=10)
    ax.legend(fontsize=7)
    return ax
