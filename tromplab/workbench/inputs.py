"""The experiments a batch accepts (paths, DataFrames, lab tables, mappings, points), those
the Fisher screen cannot judge, and the notes on the measured points before any fit.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import replace
from typing import NamedTuple

import numpy as np
import pandas as pd
from scipy import stats

from ..curves.measured import AMBIGUOUS_CUT_RATIO, CUT_BAND, CUT_WARNING, measured_cut_band, measured_efficiency, unbracketed_cut
from ..errors import InputError
from ..loading.lab import Experiments, LabOptions, MassBalance, iter_experiments_in_pieces, read_experiments
from ..loading.points import TrompPoints, points_from_frame
from ..loading.tables import DEFAULT_PIECE_ROWS
from ..notices import Notice


def data_size_unit(experiments: Sequence[TrompPoints], fallback: str) -> str:
    """The unit the loader found (column suffix) when all experiments share one, else ``fallback``."""
    units = {p.size_unit for p in experiments if p.size_unit}
    return units.pop() if len(units) == 1 else fallback


def screenable(experiments: Sequence[TrompPoints]) -> tuple[dict[str, str], list[TrompPoints]]:
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


class ExperimentsInPieces:
    """The experiments of a points file or lab table (CSV) read in pieces each time they are
    iterated (:func:`~tromplab.loading.lab.iter_experiments_in_pieces`): what
    :func:`fit_to_folder` streams through in bounded memory.  The first reading (the
    :meth:`census`, which makes every check of the reader) warns of the layout detected and
    keeps the balance notes of lab input (:attr:`balances`); the later ones read silently.

    Parameters
    ----------
    path : str or path-like
        The file.
    options : LabOptions, optional
        How to read it, as for :func:`~tromplab.loading.lab.read_experiments`.
    piece_rows : int
        Records per piece.

    Attributes
    ----------
    balances : list of BalanceNotes
        After the census: the notes and classes left out of each lab experiment that has any
        (what the console and ``left_out.csv`` show), not the balances themselves.
    """

    def __init__(self, path, options: LabOptions | None = None, *, piece_rows: int = DEFAULT_PIECE_ROWS):
        self.path, self.options, self.piece_rows = path, options, piece_rows
        self.balances: list[BalanceNotes] = []
        self._census = None

    def __iter__(self):
        first = self._census is None and not self.balances
        found = iter_experiments_in_pieces(self.path, self.options, piece_rows=self.piece_rows, warn=first)
        for points, balance in found:
            if first and balance is not None and (balance.notes or not balance.left_out_table().empty):
                self.balances.append(BalanceNotes(balance.experiment, balance.notes, balance.left_out_table(),
                                                  balance.left_out_summary()))  # fmt: skip
            yield points

    def census(self) -> Census:
        """The :class:`Census` of the experiments, made by a first reading (then kept)."""
        if self._census is None:
            self.balances.clear()
            self._census = census(self)
        return self._census

    def read_whole(self) -> Experiments:
        """Every experiment and mass balance in memory, as :func:`~tromplab.loading.lab.read_experiments`
        gives them (read silently after the census, which warned)."""
        warn = self._census is None and not self.balances
        pairs = list(iter_experiments_in_pieces(self.path, self.options, piece_rows=self.piece_rows, warn=warn))
        return Experiments([points for points, _ in pairs], [balance for _, balance in pairs if balance is not None])

    def __repr__(self) -> str:
        return f"ExperimentsInPieces({str(self.path)!r})"


class BalanceNotes(NamedTuple):
    """What the console and ``left_out.csv`` show of a lab experiment's mass balance
    (:class:`~tromplab.loading.lab.MassBalance`): its notes and the classes left out."""

    experiment: str
    notes: tuple
    left_out: pd.DataFrame
    left_out_line: str

    def left_out_table(self) -> pd.DataFrame:
        """The classes left out, as :meth:`MassBalance.left_out_table` gives them."""
        return self.left_out

    def left_out_summary(self) -> str:
        """The one-line summary of the classes left out (empty when none was)."""
        return self.left_out_line


class Census(NamedTuple):
    """What a batch needs to know of its experiments before the first is fitted, from one
    reading of an :class:`ExperimentsInPieces` (:func:`census`): one name per experiment,
    not its points."""

    fitted: list  # the names of the experiments the screen can judge, in order
    failures: dict  # experiment -> why the screen cannot judge it
    failed_points: tuple  # their points
    width: int  # the most points of a fitted experiment
    units: set  # the size units the loader found
    smallest: tuple  # the points of the smallest size (for the check of delta_max)
    survey_probe: tuple  # the first experiment holding each survey column
    total: int  # experiments in all


def census(source: ExperimentsInPieces) -> Census:
    """One reading of ``source``: every check of its reader (so a bad row is refused before
    anything is fitted or written) and the :class:`Census` of its experiments."""
    from ..loading.surveys import SURVEY_COLUMNS

    fitted, failures, failed, units, probe = [], {}, [], set(), {}
    width, smallest, total = 0, None, 0
    for points in source:
        total += 1
        failure, _ = screenable([points])
        if failure:
            failures.update(failure)
            failed.append(points)
        else:
            fitted.append(points.experiment)
            width = max(width, points.n)
        if points.size_unit:
            units.add(points.size_unit)
        if smallest is None or points.size.min() < smallest.size.min():
            smallest = points
        for column in SURVEY_COLUMNS:
            if column in points.meta and column not in probe:
                probe[column] = points
    if not total:
        raise InputError("no experiment to fit: the input is empty", source="experiments")
    holders = {probe[c].experiment: probe[c] for c in SURVEY_COLUMNS if c in probe}  # as _survey_probe finds them
    return Census(fitted, failures, tuple(failed), width, units, (smallest,), tuple(holders.values()), total)


class FittableInPieces:
    """The experiments of ``source`` the screen can judge (``len`` from its :class:`Census`),
    read again in pieces each time they are iterated."""

    def __init__(self, source: ExperimentsInPieces, found: Census):
        self.source, self.census = source, found

    def __len__(self) -> int:
        return len(self.census.fitted)

    def __iter__(self):
        failures = self.census.failures
        return (points for points in self.source if points.experiment not in failures)


#: What :func:`fit_experiments` takes as its experiments, for the message refusing anything else.
ACCEPTED_EXPERIMENTS = (
    "a path to a points file or lab table, a pandas or Dask DataFrame, what read_experiments returns, "
    "a mapping of experiment name to TrompPoints (or to a DataFrame of its points, or to a (sizes, "
    "partitions) pair), or an iterable of TrompPoints"
)


def points_and_balances(experiments) -> tuple[list[TrompPoints], tuple[MassBalance, ...]]:
    """Points (and the mass balances of lab input) from any of :data:`ACCEPTED_EXPERIMENTS`;
    an empty input, or two experiments of one name, is an :class:`InputError`."""
    balances = ()
    if isinstance(experiments, ExperimentsInPieces):
        experiments = experiments.read_whole()
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


def data_notes(points: TrompPoints, *, intervals: bool = False) -> tuple[str, ...]:
    """Warnings about the measured points themselves, before any fit; the note on a cut the
    points do not bracket says that no interval is given for it only with ``intervals`` (the
    batch makes intervals: ``ci`` or ``bootstrap``)."""
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
        rest = "d_cut, d50, d50c, d25, d75 and Ep rest on the formula's shape, not on measurements"
        if intervals:
            rest = "no interval is given for d_cut, d50, d50c, d25, d75 and Ep, which rest on the formula's shape, not on measurements"
        notes.append(f"{CUT_WARNING} ({unbracketed}): {extrapolated}{rest}")
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


def batch_notices(order, balances, notes: dict) -> list[Notice]:
    """Every warning of a batch as :class:`~tromplab.notices.Notice` records, experiment by
    experiment in ``order`` (names; experiments not in it last): the notes of its mass balance
    (``balances``) and the classes it left out, then the notes on its points (``notes``)."""
    found: dict[str, list[Notice]] = {}
    for balance in balances:
        said = found.setdefault(balance.experiment, [])
        said += [Notice(balance.experiment, note) for note in balance.notes]
        if left_out := balance.left_out_summary():
            said.append(Notice(balance.experiment, f"{left_out}; the list is in left_out.csv", code="classes-left-out"))
    for experiment, experiment_notes in notes.items():
        found.setdefault(experiment, []).extend(Notice(experiment, note) for note in experiment_notes)
    place = {name: i for i, name in enumerate(order)}
    ranked = sorted(found, key=lambda name: place.get(name, len(place)))
    return [notice for name in ranked for notice in found[name]]
