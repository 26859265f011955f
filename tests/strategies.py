"""Hypothesis strategies for input tables: valid lab tables and Tromp-point tables, and
mutations of them (swapped columns, dropped cells, extreme or non-finite values, shuffled
or duplicated rows, unicode or misspelt names).

A drawn case is a :class:`Case` (the DataFrame and the names of its size columns); write
it with :func:`write_frame` and load it with the project's readers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from hypothesis import strategies as st

NAMES = ["run 1", "Проба 1", "Образец 1", "試料-α", "a,b", 'quoted "x"', "run #2", "ü" * 40, "🧪"]
EXTREMES = [1e-300, 1e300, -1e300, 5e-324, float("inf"), float("-inf"), float("nan"), 0.0, -1.0, "abc", "1,5", " "]


@dataclass(frozen=True)
class Case:
    """A drawn input table."""

    frame: pd.DataFrame
    size_columns: tuple[str, ...]


def write_frame(frame: pd.DataFrame, path):
    """Write a drawn (or mutated) table as CSV, full float precision; returns the path."""
    frame.to_csv(path, index=False)
    return path


@st.composite
def lab_tables(draw) -> Case:
    """Per-class lab tables that balance (or nearly: optional noise) with three streams, or
    two products and a stated yield; one or two experiments, classes coarse to fine."""
    n = draw(st.integers(3, 7))
    finest = draw(st.sampled_from([1e-6, 1e-3, 1.0, 75.0, 1e4]))
    ratio = draw(st.floats(1.2, 3.0))
    unit = draw(st.sampled_from(["", "_um", "_mm"]))
    edges = finest * ratio ** np.arange(n - 1)  # sieve apertures, fine to coarse
    lower = np.concatenate(([np.nan], edges))[::-1]  # coarse to fine: open top first, pan last
    upper = np.concatenate((edges, [np.nan]))[::-1]
    experiments = draw(st.lists(st.sampled_from(NAMES), min_size=1, max_size=2, unique=True))
    two_products = draw(st.booleans())
    frames = []
    for name in experiments:
        feed = np.asarray(draw(st.lists(st.floats(0.5, 50.0), min_size=n, max_size=n)))
        phi = np.sort(np.asarray(draw(st.lists(st.floats(0.0, 1.0), min_size=n, max_size=n))))  # coarse first: rising to fines
        if np.ptp(phi) < 0.05:  # a flat curve makes the products identical: no yield to estimate
            phi = np.linspace(0.1, 0.9, n)
        y = float(np.sum(feed * phi) / feed.sum())
        if not 0.01 < y < 0.99:
            phi = np.clip(phi, 0.05, 0.95)
            y = float(np.sum(feed * phi) / feed.sum())
        fine, coarse = feed * phi / y, feed * (1 - phi) / (1 - y)
        if draw(st.booleans()):  # a balance that does not close
            noise = np.asarray(draw(st.lists(st.floats(-0.15, 0.15), min_size=2 * n, max_size=2 * n)))
            fine, coarse = fine * (1 + noise[:n]), coarse * (1 + noise[n:])
        frame = pd.DataFrame({f"size_lower{unit}": lower, f"size_upper{unit}": upper})
        if not two_products:
            frame["feed_pct"] = 100 * feed / feed.sum()
        frame["fine_pct"] = 100 * fine / fine.sum()
        frame["coarse_pct"] = 100 * coarse / coarse.sum()
        if two_products:
            frame["fine_yield"] = y
        frame.insert(0, "experiment", name)
        frames.append(frame)
    return Case(pd.concat(frames, ignore_index=True), (f"size_lower{unit}", f"size_upper{unit}"))


@st.composite
def points_tables(draw) -> Case:
    """Tromp-point tables: one or two experiments, 3-8 distinct sizes each, any partition column."""
    size_column = draw(st.sampled_from(["size", "size_um", "size_mm"]))
    partition_column = draw(st.sampled_from(["partition_fine", "partition_fine_pct", "partition_coarse", "partition_coarse_pct"]))
    scale = 100.0 if partition_column.endswith("pct") else 1.0
    with_weight = draw(st.booleans())
    frames = []
    for name in draw(st.lists(st.sampled_from(NAMES), min_size=1, max_size=2, unique=True)):
        n = draw(st.integers(3, 8))
        size = draw(st.sampled_from([1e-6, 1.0, 50.0, 1e5])) * draw(st.floats(1.1, 2.5)) ** np.arange(n)
        partition = scale * np.asarray(draw(st.lists(st.floats(0.0, 1.0), min_size=n, max_size=n)))
        frame = pd.DataFrame({"experiment": name, size_column: size, partition_column: partition})
        if with_weight:
            frame["weight"] = np.asarray(draw(st.lists(st.floats(0.1, 10.0), min_size=n, max_size=n)))
        frames.append(frame)
    return Case(pd.concat(frames, ignore_index=True), (size_column,))


@dataclass(frozen=True)
class Mutation:
    """One change to a table; called with the frame and its case, returns a new frame."""

    kind: str
    seed: int
    value: object

    def __call__(self, frame: pd.DataFrame, case: Case) -> pd.DataFrame:
        rng = np.random.default_rng(self.seed)
        frame = frame.copy().astype(object)
        row = int(rng.integers(len(frame)))
        column = frame.columns[int(rng.integers(frame.shape[1]))]
        if self.kind == "cell":
            frame.loc[row, column] = self.value
        elif self.kind == "blank":
            frame.loc[row, column] = None
        elif self.kind == "swap_columns":
            other = frame.columns[int(rng.integers(frame.shape[1]))]
            frame = frame.rename(columns={column: other, other: column})
        elif self.kind == "drop_column":
            frame = frame.drop(columns=[column])
        elif self.kind == "typo":
            frame = frame.rename(columns={column: column[:-1] + column[-1] * 2 if column else "x"})
        elif self.kind == "shuffle":
            frame = frame.iloc[rng.permutation(len(frame))]
        elif self.kind == "duplicate_row":
            frame = pd.concat([frame, frame.iloc[[row]]], ignore_index=True)
        elif self.kind == "unicode_name":
            frame["experiment"] = str(self.value) if not isinstance(self.value, float) else "∅"
        elif self.kind == "scale_sizes":
            for name in case.size_columns:
                if name in frame.columns and isinstance(self.value, float):
                    frame[name] = pd.to_numeric(frame[name], errors="coerce") * self.value
        return frame


KINDS = (
    "none",
    "cell",
    "blank",
    "swap_columns",
    "drop_column",
    "typo",
    "shuffle",
    "duplicate_row",
    "unicode_name",
    "scale_sizes",
)


def mutated():
    """Mutations of a drawn table (including "none": the table as drawn)."""
    return st.builds(Mutation, st.sampled_from(KINDS), st.integers(0, 2**32 - 1), st.sampled_from(EXTREMES + NAMES))


#: Curve shapes for generated experiments: partition to fines at relative size x = d / d_cut.
SHAPES = {
    "plitt": lambda x, k: 1 / (1 + x**k),
    "rosin_rammler": lambda x, k: np.exp(-np.log(2) * x**k),
    "logistic_in_ln": lambda x, k: 1 / (1 + np.exp(k * np.log(x))),
}


@st.composite
def tromp_experiments(draw, max_experiments: int = 2) -> pd.DataFrame:
    """Tromp-point tables fit for fitting: one or more experiments, each a smooth falling
    curve (Plitt, Rosin-Rammler or logistic shape, optional bypass) with seeded noise, 5-9
    geometric sizes around the cut, the cut anywhere from 1e-2 to 1e4 size units."""
    frames = []
    names = draw(st.lists(st.sampled_from(NAMES), min_size=1, max_size=max_experiments, unique=True))
    for name in names:
        n = draw(st.integers(5, 9))
        ratio = draw(st.floats(1.3, 2.2))
        cut = 10 ** draw(st.floats(-2.0, 4.0))
        below = draw(st.integers(2, n - 2))  # sizes below the cut: the cut lies inside the data
        size = cut * ratio ** (np.arange(n) - below + draw(st.floats(0.1, 0.9)))
        shape = draw(st.sampled_from(sorted(SHAPES)))
        sharpness = draw(st.floats(1.5, 6.0))
        bypass = draw(st.sampled_from([0.0, 0.0, 0.05, 0.15]))
        noise = draw(st.sampled_from([0.0, 0.005, 0.02]))
        rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
        partition = (1 - bypass) * SHAPES[shape](size / cut, sharpness) + bypass
        partition = np.clip(partition + rng.normal(0.0, noise, n), 0.0, 1.0)
        if np.ptp(partition) < 0.2:
            partition = np.linspace(0.95, 0.05, n)
        frames.append(pd.DataFrame({"experiment": name, "size": size, "partition_fine": partition}))
    return pd.concat(frames, ignore_index=True)
