r"""Three-product separations: clean coal, middlings and reject from two cuts in series.

A three-product dense-medium cyclone, or a two-stage circuit whose second vessel re-washes the
first one's sinks, makes clean coal, middlings and reject with two cuts.  The primary cut splits
the feed into clean coal and its sinks; the secondary cut splits those sinks into middlings and
reject.  Each cut has its own partition curve to sinks, relative to **its own feed** (what a
tracer test of that stage measures), so that a density fraction reports

.. math::
    \text{clean: } 1 - P_1, \qquad \text{middlings: } P_1 (1 - P_2), \qquad \text{reject: } P_1 P_2

(Wills & Finch 2016, ch. 11, partition curves of two-stage and three-product separators; ISO 923,
each separation of a multi-product test expressed as a two-product one).

The test's table (CSV, Excel or DataFrame), one row per test and density fraction:

``test``
    optional name of the test (text); several tests go in one file, one name each.
``density_lower``, ``density_upper``, ``density_mean``
    the density fraction, read by the one density-fraction reader
    (:func:`tromplab.density.fractions.density_fractions`): light to heavy, tiling, open ends
    closed as every density table's.
``feed_pct``, ``clean_pct``, ``middlings_pct``, ``reject_pct``
    mass per cent of each stream in each density fraction (``feed_pct`` optional); each stream
    adds up to 100 within ``sum_tolerance_pct`` and is normalised to 100 (a blank is no material).
``clean_yield``, ``middlings_yield``
    optional: the clean coal's and the middlings' shares of the feed (0..1, the same on each row
    of a test, both or neither); the reject has the rest.  Without them the yields are estimated
    by least squares from the four analyses (:func:`product_yields`).
``feed_ash_pct``, ``clean_ash_pct``, ``middlings_ash_pct``, ``reject_ash_pct``
    ash per cent of each stream in each fraction: each product's own where given, else the feed's.

Each cut is then a two-product float-sink test of its own feed (:func:`cut_tables`), read by
:func:`tromplab.density.read_density` with the stated yield: the primary with the clean coal as
floats and the middlings and reject recombined as sinks, the secondary with the middlings as
floats and the reject as sinks.

References
----------
ISO 923 (2000). Coal cleaning tests - Expression and presentation of results.

Wills, B. A. & Finch, J. A. (2016). *Wills' Mineral Processing Technology*, 8th ed.,
Butterworth-Heinemann, ch. 3 (mass balancing: the three-product formula) and ch. 11.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..density.fractions import density_fractions
from ..errors import InputError
from ..loading.tables import Table, read_table
from ..validation import YIELD_MARGIN

#: The products of a three-product separation, light to heavy.
PRODUCTS = ("clean", "middlings", "reject")
#: The columns of a three-product test.
THREE_PRODUCT_COLUMNS = ("test", "density_lower", "density_upper", "density_mean", "feed_pct", "clean_pct", "middlings_pct",
                         "reject_pct", "clean_yield", "middlings_yield", "feed_ash_pct", "clean_ash_pct",
                         "middlings_ash_pct", "reject_ash_pct")  # fmt: skip


@dataclass(frozen=True)
class ThreeProductTest:
    """One three-product test as read: the yields and the two cuts as two-product float-sink tables.

    Attributes
    ----------
    test : str
        Name of the test.
    yields : tuple of float
        Shares of the feed to the clean coal, the middlings and the reject (0..1, adding up to 1).
    yield_note : str
        Where the yields came from, in words.
    primary, secondary : pandas.DataFrame
        The cuts as float-sink tables (``density_lower, density_upper, [density_mean,] floats_pct,
        sinks_pct, floats_ash_pct, sinks_ash_pct``), indexed by the file's rows; the secondary's
        feed is the primary's sinks.
    source : str
        The file (or ``DataFrame``).
    """

    test: str
    yields: tuple
    yield_note: str
    primary: pd.DataFrame
    secondary: pd.DataFrame
    source: str


def is_three_product(columns) -> bool:
    """True when the columns are a three-product test's (``clean_pct``, ``middlings_pct``, ``reject_pct``)."""
    return {f"{product}_pct" for product in PRODUCTS} <= {str(column).strip() for column in columns}


def read_three_product_tests(data, *, sum_tolerance_pct: float, sheet=None, sep=None, decimal=None) -> list[ThreeProductTest]:
    """Read every three-product test of a table (schema in the module docstring).

    Raises
    ------
    InputError
        Naming the file, row and column of the first bad value: a density fraction that breaks
        the convention, a share outside 0..100 or a stream that does not add up to 100, a yield
        outside (0, 1) or differing between the rows of a test, no ash for a fraction a product
        holds, yields that cannot be estimated.
    """
    table = read_table(data, sheet=sheet, sep=sep, decimal=decimal, text_columns=("test",))
    table.refuse_unknown(THREE_PRODUCT_COLUMNS, what="three-product table")
    table.require("density_lower", "density_upper", "clean_pct", "middlings_pct", "reject_pct")
    if "test" in table.frame.columns:
        names = table.names("test", what="test")
    else:  # one test, named after the file
        names = np.full(len(table.frame), Path(table.source).stem, dtype=object)
    tests = []
    for name in dict.fromkeys(names):
        tests.append(_one_test(table.subset(np.flatnonzero(names == name)), str(name), sum_tolerance_pct))
    return tests


def _one_test(table: Table, name: str, tolerance: float) -> ThreeProductTest:
    fractions = density_fractions(table, minimum=3)
    shares = {
        stream: _shares(table, f"{stream}_pct", tolerance) for stream in ("feed", *PRODUCTS) if f"{stream}_pct" in table.frame
    }
    yields, yield_note = _yields(table, name, shares)
    ashes = _ashes(table, name, shares)
    clean, middlings, reject = (yields[i] * shares[product] for i, product in enumerate(PRODUCTS))  # shares of the feed
    sinks = middlings + reject
    bounds = {"density_lower": fractions.lower, "density_upper": fractions.upper}
    if "density_mean" in table.frame.columns:
        bounds["density_mean"] = table.numeric("density_mean", allow_blank=True)
    primary = pd.DataFrame({"test": name, **bounds, "floats_pct": 100 * shares["clean"], "sinks_pct": 100 * sinks / sinks.sum(),
                            "floats_ash_pct": ashes["clean"],
                            "sinks_ash_pct": _mixed_ash(middlings, ashes["middlings"], reject, ashes["reject"])},
                           index=table.rows)  # fmt: skip
    secondary = pd.DataFrame({"test": name, **bounds, "floats_pct": 100 * shares["middlings"], "sinks_pct": 100 * shares["reject"],
                              "floats_ash_pct": ashes["middlings"], "sinks_ash_pct": ashes["reject"]}, index=table.rows)  # fmt: skip
    return ThreeProductTest(name, yields, yield_note, primary, secondary, table.source)


def _shares(table: Table, column: str, tolerance: float) -> np.ndarray:
    """A stream's analysis as shares adding up to 1 (a blank cell is no material)."""
    values = np.nan_to_num(table.numeric(column, allow_blank=True))
    table.refuse_outside(values, column, 0.0, 100.0 + tolerance)
    total = float(values.sum())
    if not abs(total - 100.0) <= tolerance:
        raise InputError(f"{column} adds up to {total:.6g}, not 100 (tolerance {tolerance:g} percentage points)",
                         source=table.source, column=column)  # fmt: skip
    return values / total


def _stated_yield(table: Table, column: str) -> float | None:
    if column not in table.frame.columns:
        return None
    values = table.numeric(column, allow_blank=True)
    given = np.flatnonzero(np.isfinite(values))
    if given.size == 0:
        return None
    bad = given[(values[given] <= YIELD_MARGIN) | (values[given] >= 1 - YIELD_MARGIN)]
    if bad.size:
        raise table.error(f"yield {values[bad[0]]:g} outside (0, 1) (a share of the feed, not per cent)", index=int(bad[0]),
                          column=column)  # fmt: skip
    different = given[values[given] != values[given[0]]]
    if different.size:
        raise table.error(f"{column} differs between rows of the same test", index=int(different[0]), column=column)
    return float(values[given[0]])


def _yields(table: Table, name: str, shares: dict) -> tuple[tuple, str]:
    clean, middlings = _stated_yield(table, "clean_yield"), _stated_yield(table, "middlings_yield")
    if (clean is None) != (middlings is None):
        missing = "middlings_yield" if middlings is None else "clean_yield"
        raise InputError(f"test '{name}': give both clean_yield and middlings_yield, or neither (the yields are then "
                         f"estimated from feed_pct); {missing} is missing", source=table.source, column=missing)  # fmt: skip
    if clean is not None:
        if clean + middlings >= 1 - YIELD_MARGIN:
            raise InputError(f"test '{name}': clean_yield {clean:g} and middlings_yield {middlings:g} leave no reject",
                             source=table.source, column="middlings_yield")  # fmt: skip
        return (clean, middlings, 1.0 - clean - middlings), "product yields stated (clean_yield, middlings_yield)"
    if "feed" not in shares:
        raise InputError(f"test '{name}': without a feed analysis (feed_pct) give the yields (clean_yield and middlings_yield)",
                         source=table.source)  # fmt: skip
    estimated, residual_sd = product_yields(shares["feed"], shares["clean"], shares["middlings"], shares["reject"])
    if not np.all((estimated > YIELD_MARGIN) & (estimated < 1 - YIELD_MARGIN)):
        text = ", ".join(f"{product} {value:.4f}" for product, value in zip(PRODUCTS, estimated))
        raise InputError(f"test '{name}': the four analyses imply the yields {text}, not all within (0, 1): check the streams",
                         source=table.source)  # fmt: skip
    text = ", ".join(f"{product} {value:.4f}" for product, value in zip(PRODUCTS, estimated))
    return tuple(float(v) for v in estimated), (f"product yields {text} estimated by least squares from the four analyses "
                                                f"(residual sd {100 * residual_sd:.3g} percentage points)")  # fmt: skip


def product_yields(feed, clean, middlings, reject) -> tuple[np.ndarray, float]:
    r"""The yields of three products from the analyses of the feed and the products, by least squares.

    The mass balance of each density fraction :math:`i`, :math:`f_i = Y_c c_i + Y_m m_i + Y_r r_i`
    with :math:`Y_r = 1 - Y_c - Y_m`, gives :math:`f_i - r_i = Y_c (c_i - r_i) + Y_m (m_i - r_i)`,
    fitted over the fractions by ordinary least squares (the three-product formula of Wills &
    Finch 2016, ch. 3, with more components than unknowns).

    Returns
    -------
    yields : ndarray
        Clean coal, middlings, reject (shares of the feed).
    residual_sd : float
        The residuals' standard deviation (shares); 0 with three fractions.

    Raises
    ------
    InputError
        When the products' analyses do not tell the yields apart (two of them alike).

    Examples
    --------
    >>> c, m, r = np.array([.7, .2, .1, 0]), np.array([.1, .5, .3, .1]), np.array([0, .1, .3, .6])
    >>> yields, _ = product_yields(.5 * c + .2 * m + .3 * r, c, m, r)
    >>> yields.round(12).tolist()
    [0.5, 0.2, 0.3]
    """
    feed, clean, middlings, reject = (np.asarray(values, dtype=float) for values in (feed, clean, middlings, reject))
    design = np.column_stack([clean - reject, middlings - reject])
    if np.linalg.matrix_rank(design, tol=1e-9) < 2:
        raise InputError("two of the products' analyses are alike (or one is a mix of the others): the three yields cannot "
                         "be estimated; give clean_yield and middlings_yield")  # fmt: skip
    solution, *_ = np.linalg.lstsq(design, feed - reject, rcond=None)
    residuals = feed - reject - design @ solution
    dof = max(feed.size - 2, 1)
    residual_sd = float(np.sqrt(residuals @ residuals / dof)) if feed.size > 2 else 0.0
    return np.array([solution[0], solution[1], 1.0 - solution.sum()]), residual_sd


def _ashes(table: Table, name: str, shares: dict) -> dict:
    """Each product's ash per fraction: its own where given, else the feed's (NaN where the product holds nothing)."""
    columns = [f"{stream}_ash_pct" for stream in ("feed", *PRODUCTS)]
    given = {column: table.numeric(column, allow_blank=True) for column in columns if column in table.frame.columns}
    if not given:
        raise InputError(f"test '{name}': no ash columns (feed_ash_pct, or clean_ash_pct, middlings_ash_pct and "
                         "reject_ash_pct)", source=table.source)  # fmt: skip
    for column, values in given.items():
        table.refuse_outside(np.nan_to_num(values), column, 0.0, 100.0)
    feed = given.get("feed_ash_pct", np.full(len(table.frame), np.nan))
    ashes = {}
    for product in PRODUCTS:
        column = f"{product}_ash_pct"
        ash = np.where(np.isnan(given[column]), feed, given[column]) if column in given else feed
        missing = np.flatnonzero(np.isnan(ash) & (shares[product] > 0))
        if missing.size:
            raise table.error(f"test '{name}': the {product} hold this fraction but no ash is given for it",
                              index=int(missing[0]), column=column if column in given else "feed_ash_pct")  # fmt: skip
        ashes[product] = np.where(shares[product] > 0, ash, np.nan)
    return ashes


def _mixed_ash(first, first_ash, second, second_ash) -> np.ndarray:
    """The ash of two products recombined, per fraction (NaN where neither holds anything)."""
    mass = first + second
    ash_mass = np.nan_to_num(first * first_ash) + np.nan_to_num(second * second_ash)
    return np.divide(ash_mass, mass, out=np.full(mass.shape, np.nan), where=mass > 0)
