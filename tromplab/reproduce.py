"""Published numbers recomputed, side by side with the printed ones.

Each function returns a tidy :class:`pandas.DataFrame` with the printed value, the value
tromplab computes and whether they agree at the printed precision.  The scripts in
``analysis/`` print and save these tables; the tests check them.
"""

from __future__ import annotations

from decimal import Decimal
from pathlib import Path

import numpy as np
import pandas as pd

from .classifiers import sieve
from .curves.ranking import rank_formulas, read_f_table
from .output.csv_parts import write_csv

# Example of the kinetics paper: sieve 1.6 x 1.0 m, cells 3.2 x 3.2 mm, hole 2 mm,
# bulk density 1150 kg/m3, feed gap 4 mm, printed kinetic coefficients of two fractions.
KINETICS = {
    "L": 1.6,
    "B": 1.0,
    "pitch": 0.0032,
    "hole_mm": 2.0,
    "half_cell_mm": 1.6,
    "rho": 1150.0,
    "h": 0.004,
    "lambda_1": 1.31e-3,
    "lambda_2": 0.127,
    "purity_limit": 0.08,
    "Va": 0.287,
}
# Example of the random-walk paper: 12 decks, sieve 1.6 x 1.0 m, recovery 0.9, purity 10.4 %.
RANDOM_WALK = {"m": 12, "L": 1.6, "g": 0.9, "impurity": 0.104, "rho": 1150.0, "h": 0.003, "B": 1.0, "V": 0.1185}


def printed_unit(printed: str) -> float:
    """One unit in the last digit of a printed number.

    ``"0.150"`` is printed to 0.001 and ``"2.8e-2"`` to 0.001. The trailing zeros of a
    number printed without a decimal point are read as rounding, not as digits: ``"1340"``
    is printed to 10 and ``"1500"`` to 100.
    """
    digits = Decimal(printed).normalize() if "." not in printed.lower().split("e")[0] else Decimal(printed)
    return float(Decimal(1).scaleb(digits.as_tuple().exponent))


def compare_printed(printed: str, computed: float) -> tuple[str, float]:
    """Compare a computed value with a printed one at the printed precision.

    Returns the verdict and the difference in units of the last printed digit. The verdict
    is ``"agrees"`` when the computed value rounds to the printed one (within half a unit),
    ``"last digit"`` when it is at most one and a half units away (the size of a rounding or
    truncation of the paper's own inputs) and ``"differs"`` otherwise.
    """
    units = (computed - float(printed)) / printed_unit(printed)
    # 1e-9 absorbs the binary representation of a printed decimal such as 0.00321.
    if abs(units) <= 0.5 + 1e-9:
        return "agrees", units
    if abs(units) <= 1.5 + 1e-9:
        return "last digit", units
    return "differs", units


def _row(paper, quantity, printed: str, computed, note=""):
    verdict, units = compare_printed(printed, float(computed))
    return {
        "paper": paper,
        "quantity": quantity,
        "printed": printed,
        "computed": float(computed),
        "printed_unit": printed_unit(printed),
        "difference_in_printed_units": units,
        "agreement": verdict,
        "note": note,
    }


def sieve_checks() -> pd.DataFrame:
    """The published checks of both sieve papers, recomputed (see ``docs/errata.md``).

    Each printed value is kept as printed (a string) and compared at its printed
    precision by :func:`compare_printed`.
    """
    return pd.DataFrame(_kinetics_checks() + _random_walk_checks())


def _kinetics_checks() -> list[dict]:
    """The checks of the sieve-kinetics paper: P_g, P_v, E and Q, at the printed and the corrected speed."""
    k = KINETICS
    rows = [
        _row(
            "kinetics",
            "P_g (D 2, cell 3.2 x 3.2 mm, d/l 0.5, l 2.2 mm)",
            "0.150",
            sieve.geometric_probability(2.0, 2.2, 1.1, 1.6),
            "computed 0.1511",
        )
    ]
    for label, vk, sigma, printed in [("P_v fraction 1", 0.148, 0.051, "0.00321"), ("P_v fraction 2", 0.185, 0.069, "0.06967")]:
        rows.append(
            _row("kinetics", f"{label} at Va = 0.287 m/s", printed, float(sieve.velocity_probability(k["Va"], vk, sigma)))
        )
    printed_speed = 2.8e-2
    g1, g2 = (np.exp(-lam * k["L"] / printed_speed) for lam in (k["lambda_1"], k["lambda_2"]))
    rows.append(
        _row(
            "kinetics",
            "E at the printed V = 0.028 m/s, %",
            "89.64",
            float(sieve.sieve_efficiency(g1, g2)),
            "the printed mean speed is inconsistent",
        )
    )
    rows.append(
        _row("kinetics", "Q at the printed V = 0.028 m/s, kg/h", "1340", sieve.capacity(k["rho"], k["h"], k["B"], printed_speed))
    )
    speed = k["L"] * k["lambda_2"] / -np.log(k["purity_limit"])
    g1 = np.exp(-k["lambda_1"] * k["L"] / speed)
    rows.append(
        _row("kinetics", "mean speed putting gamma_1^2 at the 8 % limit, m/s", "2.8e-2", speed, "corrected reading: ~0.080")
    )
    rows.append(_row("kinetics", "gamma_1^1 at the corrected speed", "0.97", float(g1)))
    rows.append(_row("kinetics", "E at the corrected speed, %", "89.64", float(sieve.sieve_efficiency(g1, k["purity_limit"]))))
    rows.append(_row("kinetics", "Q at the corrected speed, kg/h", "1340", sieve.capacity(k["rho"], k["h"], k["B"], speed)))
    probabilities = [
        sieve.geometric_probability(2.0, l, d, 1.6) * sieve.velocity_probability(k["Va"], vk, s)
        for (l, d), (vk, s) in zip([(2.5, 1.5), (2.0, 1.5)], [(0.148, 0.051), (0.185, 0.069)])
    ]
    b1, b2 = sieve.residue_share(np.array(probabilities), k["L"], k["pitch"])
    rows.append(
        _row(
            "kinetics",
            "E built up from P_g and P_v (l x d 2.5 x 1.5, 2.0 x 1.5 mm), %",
            "89.64",
            float(sieve.sieve_efficiency(b1, b2)),
            f"gamma_1^1 = {b1:.3f}, gamma_1^2 = {b2:.3f}",
        )
    )
    return rows


def _random_walk_checks() -> list[dict]:
    """The checks of the random-walk (bin) paper: C, x1, E and Q."""
    w = RANDOM_WALK
    rows = []
    exact, normal = sieve.design_bin(w["m"], w["L"], w["g"]), sieve.design_bin(w["m"], w["L"], w["g"], method="normal")
    rows.append(_row("random walk", "C, 1/m^2", "14.22", exact.c))
    rows.append(_row("random walk", "x1, exact, m", "0.98", exact.x1, "0.9867 unrounded"))
    rows.append(_row("random walk", "x1, normal approximation, m", "0.98", normal.x1))
    rows.append(_row("random walk", "E = g (1 - S), %", "81.5", sieve.bin_efficiency(w["g"], w["impurity"])))
    rows.append(_row("random walk", "Q = rho h B V, kg/h", "1490", sieve.capacity(w["rho"], w["h"], w["B"], w["V"])))
    return rows


def shuvalov_table3(table2_path, table3_path, *, use_given_marks: bool = True) -> pd.DataFrame:
    """Table 3 recomputed from Table 2, beside the published table, differences marked.

    Returns one row per formula with ``rank_<exp>`` / ``published_<exp>`` pairs,
    ``points`` / ``published_points``, ``place`` / ``published_place`` and
    ``differences`` (the cells that differ).
    """
    ours = rank_formulas(read_f_table(table2_path, use_given_marks=use_given_marks)).set_index("equation")
    published = pd.read_csv(table3_path, comment="#")
    published["equation"] = published["equation"].astype(str)
    published = published.set_index("equation")
    experiments = [c for c in ours.columns if c not in ("points", "place")]
    side = pd.DataFrame(index=ours.index)
    differences = {eq: [] for eq in ours.index}
    for experiment in experiments:
        side[f"rank_{experiment}"] = ours[experiment]
        side[f"published_{experiment}"] = published[f"rank_{experiment}"]
        for eq in ours.index[ours[experiment] != published[f"rank_{experiment}"]]:
            differences[eq].append(f"rank in exp. {experiment}")
    for column in ("points", "place"):
        side[column] = ours[column]
        side[f"published_{column}"] = published[column]
        for eq in ours.index[ours[column] != published[column]]:
            differences[eq].append(column)
    side["differences"] = ["; ".join(d) for d in differences.values()]
    return side.reset_index()


def write_table(frame: pd.DataFrame, outdir, name: str) -> Path:
    """Save a table as CSV in ``outdir`` and return its path."""
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    path = outdir / name
    write_csv(frame, path)
    return path
