"""A catalogue of hostile names: text that a careless reader turns into a number, a blank, a
boolean or a spreadsheet formula.  The name tests (tests/test_names_as_text.py,
tests/test_formula_injection.py) and the hostile-input battery draw from it.

Each entry is ``(name, why)``.  A name read from a file loses its surrounding white space
(:func:`as_read`); given to the Python API as a ``TrompPoints`` name it is kept whole.
"""

from __future__ import annotations

import numpy as np

HOSTILE_NAMES: tuple[tuple[str, str], ...] = (
    ("01", "a leading zero: a number reader makes it 1"),
    ("1", "the number that 01 would collide with"),
    ("007", "leading zeros"),
    ("4E2", "scientific notation: 400.0"),
    ("1e3", "scientific notation: 1000.0"),
    ("TRUE", "a boolean word"),
    ("NA", "pandas reads it as missing"),
    ("None", "pandas reads it as missing"),
    ("null", "pandas reads it as missing"),
    ("N/A", "pandas reads it as missing"),
    ("=1+1", "a spreadsheet formula"),
    ("+1", "a formula start (and a number)"),
    ("-1", "a formula start (and a number)"),
    ("@SUM(A1)", "a formula start"),
    ("-150+75", "a size-class string, and a formula to a spreadsheet"),
    ("\tx", "a tab in front: a formula start"),
    ("\rx", "a carriage return in front: a formula start"),
    ("'quoted'", "a quote that is part of the name"),
    ("#3", "a comment mark in front"),
    ("Проба 1", "Cyrillic with a space"),
    ("試料-α", "CJK and Greek"),
    ("run  two", "two spaces inside"),
    ("<script>alert(1)</script>", "HTML"),
    ("a|b`c`", "Markdown table and code marks"),
)

NAMES = tuple(name for name, _ in HOSTILE_NAMES)

#: Names that a spreadsheet would read as a formula when a CSV cell begins so.
FORMULA_LIKE = tuple(name for name in NAMES if name.startswith(("=", "+", "-", "@", "\t", "\r")))


def as_read(name: str) -> str:
    """The name a table reader gives for a cell holding ``name`` (surrounding white space trimmed)."""
    return name.strip()


def distinct_as_read(names=NAMES) -> tuple[str, ...]:
    """``names`` without those that read as one read before them (``\\tx`` and ``\\rx`` both read ``x``)."""
    seen, kept = set(), []
    for name in names:
        if as_read(name) not in seen:
            seen.add(as_read(name))
            kept.append(name)
    return tuple(kept)


SIZES = (10.0, 20.0, 40.0, 80.0, 160.0)


def partitions(shift: int) -> list[float]:
    """A plausible Tromp curve, shifted a little per experiment so no two are equal."""
    return [round(float(p), 4) for p in np.array([0.98, 0.91, 0.62, 0.21, 0.04]) - 0.001 * shift]


def points_rows(names) -> list[dict]:
    """Rows of a Tromp-points table: five sizes for each of ``names``."""
    return [
        {"experiment": name, "size": size, "partition_fine": phi}
        for shift, name in enumerate(names)
        for size, phi in zip(SIZES, partitions(shift))
    ]
