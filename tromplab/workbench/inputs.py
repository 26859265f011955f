"""The experiments a batch accepts (paths, DataFrames, lab tables, mappings, points), those
the Fisher screen cannot judge, and the notes on the measured points before any fit.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import replace

import numpy as np
import pandas as pd
from scipy import stats

from ..curves.measured import AMBIGUOUS_CUT_RATIO, CUT_BAND, CUT_WARNING, measured_cut_band, measured_efficiency, unbracketed_cut
from ..errors import InputError
from ..loading.lab import Experiments, MassBalance, read_experiments
from ..loading.points import TrompPoints, points_from_frame


def _data_size_unit(experiments: Sequence[TrompPoints], fallback: str) -> str:
    """The unit the loader found (column suffix) when all experiments share one, else ``fallback``."""
    units = {p.size_unit for p in experiments if p.size_unit}
    return units.pop() if len(units) == 1 else fallback


def _screenable(experiments: Sequence[TrompPoints]) -> tuple[dict[str, str], list[TrompPoints]]:
    """The experiments the Fisher screen cannot judge (with the reason), and the others."""
    failures, fittable = {}, []
    for points in experiments:
        if points.n <= 2:
            failures[points.experiment] = (
                f"experiment '{points.experiment}' has {points.n} points; the Fisher screen needs at least 3"
            )
        elif np.ptp(points.partition_fine) == 0:  # F = 0/0: no curve can be told from another
            failures[points.experiment] = (
                f"experiment '{points.experiment}' is flat: every partition equals {points.partition_fine[0]:g}, "
                "so there is no cut to fit and the Fisher screen is undefined (0/0)"
            )
        else:
            fittable.append(points)
    return failures, fittable


#: What :func:`fit_experiments` takes as its experiments, for the message refusing anything else.
ACCEPTED_EXPERIMENTS = (
    "a path to a points file or lab table, a pandas or Dask DataFrame, what read_experiments returns, "
    "a mapping of experiment name to TrompPoints (or to a DataFrame of its points, or to a (sizes, "
    "partitions) pair), or an iterable of TrompPoints"
)


def _points_and_balances(experiments) -> tuple[list[TrompPoints], tuple[MassBalance, ...]]:
    """Points (and the mass balances of lab input) from any of :data:`ACCEPTED_EXPERIMENTS`;
    an empty input, or two experiments of one name, is an :class:`InputError`."""
    balances = ()
    if isinstance(experiments, (str, os.PathLike, pd.DataFrame)):
        experiments = read_experiments(experiments)
    if isinstance(experiments, Experiments):
        points, balances = list(experiments.points), tuple(experiments.balances)
    elif hasattr(experiments, "dask") and hasattr(experiments, "compute"):
        points = points_from_frame(experiments.compute(), source="dask dataframe")
    elif isinstance(experiments, Mapping):
        points = [_named_points(name, value) for name, value in experiments.items()]
    elif isinstance(experiments, Iterable) and not isinstance(experiments, (bytes, bytearray)):
        points = list(experiments)
        for position, item in enumerate(points):
            if not isinstance(item, TrompPoints):
                raise TypeError(
                    f"experiments[{position}] is a {type(item).__name__}, not a TrompPoints; experiments must be "
                    f"{ACCEPTED_EXPERIMENTS}"
                )
    else:
        raise TypeError(f"experiments must be {ACCEPTED_EXPERIMENTS}; got {type(experiments).__name__}")
    if not points:
        raise InputError("no experiment to fit: the input is empty", source="experiments")
    seen = set()
    for item in points:
        if item.experiment in seen:
            raise InputError(
                f"two experiments are named '{item.experiment}': give each experiment its own name", source="experiments"
            )
        seen.add(item.experiment)
    return points, balances


def _named_points(name, value) -> TrompPoints:
    """The points of experiment ``name`` of a mapping: a TrompPoints (renamed to the key), a
    DataFrame of one experiment's points (the file schema, its own experiment column ignored)
    or a ``(sizes, partitions)`` pair."""
    if not isinstance(name, str):
        raise TypeError(
            f"the names of a mapping of experiments are text (str), got {type(name).__name__} {name!r}: map each "
            "name (str) to its TrompPoints, a DataFrame of its points or a (sizes, partitions) pair"
        )
    source = f"experiments['{name}']"
    if isinstance(value, TrompPoints):
        return value if value.experiment == name else replace(value, experiment=name)
    if isinstance(value, pd.DataFrame):
        found = points_from_frame(value.drop(columns=["experiment"], errors="ignore"), source=source)
        return replace(found[0], experiment=name)
    if isinstance(value, (tuple, list)) and len(value) == 2:
        return TrompPoints(name, value[0], value[1], source=source)
    raise TypeError(
        f"{source} is a {type(value).__name__}; give a TrompPoints, a DataFrame of its points or a (sizes, partitions) pair"
    )


def data_notes(points: TrompPoints) -> tuple[str, ...]:
    """Warnings about the measured points themselves, before any fit."""
    notes = []
    if points.n >= 3 and np.ptp(points.partition_fine) > 0:
        # Spearman's rho as Pearson's r of the ranks (the sizes are distinct and increasing, so
        # their ranks are 1..n): stats.spearmanr's checks cost 0.3 ms, 3 s at 10,000 experiments
        rho = float(np.corrcoef(np.arange(points.n), stats.rankdata(points.partition_fine))[0, 1])
        if rho > 0.5:
            notes.append(
                f"the partition to fines rises with size (Spearman {rho:.2f}): is the column the partition to the "
                "coarse product? (use partition_coarse)"
            )
    one_sided = np.all(points.partition_fine > 0.5) or np.all(points.partition_fine < 0.5)
    if unbracketed := unbracketed_cut(points):
        extrapolated = "the cut size is extrapolated beyond the measured sizes, and " if one_sided else ""
        notes.append(
            f"{CUT_WARNING} ({unbracketed}): {extrapolated}no interval is given for d_cut, d50, d50c, d25, d75 and Ep, "
            "which rest on the formula's shape, not on measurements"
        )
    elif (ambiguous := _ambiguous_measured_cut(points)) is not None:
        notes.append(ambiguous)
    return tuple(notes)


def _ambiguous_measured_cut(points: TrompPoints) -> str | None:
    """A note when the measured cut, and with it formula (11)'s measured efficiency, moves
    far with partitions changed within :data:`~tromplab.curves.measured.CUT_BAND` (a plateau at 1/2, or a
    curve crossing 1/2 more than once): the fit of (11) then hangs on the data's last digits."""
    low, high = measured_cut_band(points)
    if not high > AMBIGUOUS_CUT_RATIO * low:
        return None
    efficiencies = sorted(measured_efficiency(points, cut) for cut in (low, high))
    return (
        f"the measured cut is ambiguous: partitions within 1/2 +- {CUT_BAND:g} put it anywhere from "
        f"{low:.4g} to {high:.4g}; formula (11), whose measured efficiency rests on it "
        f"({efficiencies[0]:.3f} to {efficiencies[1]:.3f} over that range), may change with the data's "
        "last digits"
    )
