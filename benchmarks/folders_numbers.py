"""The largest relative difference between the numbers of two trees of results folders.

For a change that moves numbers in their last digits on purpose (a different order of the
floating-point operations, a root search closed at another point within its tolerance), the
digests of ``fit_folders_digest.py`` and ``density_folders_digest.py`` differ; this script,
run on the folders those scripts keep (``--keep``), says by how much.  Every CSV file present
in both trees is read with pandas; text columns must be equal, numeric ones are compared as
``|a - b| / max(|a|, |b|)`` (NaN equal to NaN, infinities equal to themselves).

    python benchmarks/folders_numbers.py BEFORE_DIR AFTER_DIR --rtol 1e-9

Prints each file with a difference above ``--rtol`` and the largest difference overall;
exits 1 when any file differs by more than ``--rtol`` or in its text.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd


def relative_difference(a: pd.Series, b: pd.Series) -> float:
    """The largest relative difference between two numeric columns (inf where one is NaN and the other not)."""
    x, y = a.to_numpy(dtype=float), b.to_numpy(dtype=float)
    both_nan = np.isnan(x) & np.isnan(y)
    same = (x == y) | both_nan
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.maximum(np.abs(x), np.abs(y))
        difference = np.where(same, 0.0, np.abs(x - y) / scale)
    return float(np.nanmax(np.where(np.isnan(difference), np.inf, difference), initial=0.0))


def compare_file(before: Path, after: Path) -> tuple[float, str]:
    """``(largest relative difference, what differs in the text)`` of one CSV file."""
    try:
        old, new = pd.read_csv(before, comment=None), pd.read_csv(after, comment=None)
    except (pd.errors.ParserError, UnicodeDecodeError, pd.errors.EmptyDataError):
        return 0.0, "" if before.read_bytes() == after.read_bytes() else "not a table, and not equal"
    if list(old.columns) != list(new.columns) or len(old) != len(new):
        return np.inf, f"shape or columns differ ({old.shape} -> {new.shape})"
    largest, text = 0.0, []
    for column in old.columns:
        numeric = pd.api.types.is_numeric_dtype(old[column]) and pd.api.types.is_numeric_dtype(new[column])
        if numeric:
            largest = max(largest, relative_difference(old[column], new[column]))
        elif not old[column].fillna("").astype(str).equals(new[column].fillna("").astype(str)):
            text.append(str(column))
    return largest, f"text differs in {', '.join(text)}" if text else ""


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("before", type=Path)
    parser.add_argument("after", type=Path)
    parser.add_argument("--rtol", type=float, default=1e-9, help="relative difference allowed (default 1e-9)")
    args = parser.parse_args(argv)
    names = sorted(
        {p.relative_to(args.before) for p in args.before.rglob("*.csv")}
        & {p.relative_to(args.after) for p in args.after.rglob("*.csv")}
    )
    overall, failed = 0.0, 0
    for name in names:
        largest, text = compare_file(args.before / name, args.after / name)
        if largest > 0 or text:
            print(f"{name}: largest relative difference {largest:.3g}{'; ' + text if text else ''}")
        overall = max(overall, largest)
        failed += bool(text) or largest > args.rtol
    print(
        f"{len(names)} CSV files compared; largest relative difference {overall:.3g}; {failed} above {args.rtol:g} or with text differences"
    )
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
