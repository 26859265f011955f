"""Generate efficiency_reference.csv: eta and eps of the nine paper formulas and the extended curves.

The values are integrals of the formula's *expression text* in the registry (the corrected
printed form, see docs/errata.md), evaluated with mpmath at 30 significant digits, not of
the vectorised functions or the closed forms the package computes with:

* ``eta = int_0^1 phi(x) dx`` and ``eps = int_1^X phi(x) dx``, both integrated in
  ``u = ln x`` (``phi(e^u) e^u du``) by mpmath's tanh-sinh rule on pieces cut at
  ``u = +-1e-4 ... +-64`` (so the curves sharpest at the upper shape bound are resolved
  next to the cut) and at the kink of the piecewise formulas (10) and (11); a row is
  written only when mpmath's error estimate is below 1e-20 of the value;
* ``x_a`` of formula (11) solved at the same precision from its defining equation, with
  the measured efficiency halfway between 1/2 and the efficiency of (5) (a break point
  exists); ``b_star`` of Whiten's curve from ``(1 + beta b*) lynch(b*) = 1/2``.

Shapes: both bounds of each formula and the shapes giving twenty slopes at the cut from
-0.02 to -30 (clipped into the bounds, rounded to 12 significant digits); relative feed
top sizes X = 1.5, 6 and 1000.  Run from the repository root after adding or changing a
formula (needs mpmath, in the test extra); it takes about two minutes:

    python tests/reference/make_efficiency_reference.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import mpmath as mp
import numpy as np

from tromplab.curves.formulas import EXTENDED_FORMULAS, FORMULAS, evaluate_expression

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository, for a run as a script
from tests.reference.make_phi_reference import beta_star, break_point, rosin_rammler_area  # noqa: E402

mp.mp.dps = 30
OUT = Path(__file__).resolve().parent / "efficiency_reference.csv"
SLOPES = -np.geomspace(0.02, 30.0, 20)
X_MAX = ("1.5", "6", "1000")
EXTRAS = {"bypass": "0.1", "fishhook": "0.4"}
MP_FUNCTIONS = {"exp": mp.exp, "ln": mp.log, "erfc": mp.erfc, "sqrt": mp.sqrt, "max": max, "pi": mp.pi, "ln2": mp.log(2)}
RTOL = "1e-10"
#: Break points in u = ln x on both sides of the cut.
BREAKS = [
    sign * mp.mpf(u)
    for sign in (1, -1)
    for u in ("1e-4", "1e-3", "3e-3", "1e-2", "3e-2", "0.1", "0.3", "1", "2", "4", "8", "16", "32", "64")
]


def shapes_of(formula):
    """Both bounds and the shapes of :data:`SLOPES`, clipped, as 12-digit decimal texts."""
    low, high = formula.shape_bounds
    inner = [formula.clip_shape(formula.shape_for_slope(s)) for s in SLOPES]
    return sorted({float(f"{shape:.12g}") for shape in (low, high, *inner)})


def integral(curve, lower, upper, kinks):
    """``int phi(e^u) e^u du`` from ``lower`` to ``upper`` on the pieces of :data:`BREAKS`."""
    points = sorted({u for u in (*BREAKS, *kinks) if lower < u < upper})
    value, error = mp.quad(lambda u: curve(mp.exp(u)) * mp.exp(u), [lower, *points, upper], error=True)
    if not error <= mp.mpf("1e-20") * abs(value):
        raise ArithmeticError(f"mpmath error estimate {error} of {value}")
    return value


def rows():
    for formula in (*FORMULAS, *EXTENDED_FORMULAS):
        extras = {extra.name: mp.mpf(EXTRAS[extra.name]) for extra in formula.extras}
        for shape_value in shapes_of(formula):
            shape = mp.mpf(repr(shape_value))
            context, derived, kinks = {}, {}, []
            if "x_a" in formula.expression:
                efficiency = (mp.mpf("0.5") + rosin_rammler_area(0, 1, shape)) / 2
                efficiency = mp.mpf(mp.nstr(efficiency, 20))  # the value written to the table
                context["measured_efficiency"] = efficiency
                derived["x_a"] = break_point(shape, efficiency)
                kinks.append(mp.log(derived["x_a"]))
            if "max(x, 1/2)" in formula.expression:
                kinks.append(-mp.log(2))
            if "b_star" in formula.expression:
                derived["b_star"] = beta_star(shape, extras["fishhook"])

            def curve(x, formula=formula, shape=shape, extras=extras, derived=derived):
                values = {"x": x, formula.shape_name: shape, **extras, **derived}
                return mp.mpf(evaluate_expression(formula.expression, values, MP_FUNCTIONS))

            eta = integral(curve, -mp.inf, mp.mpf(0), kinks)
            for x_max in X_MAX:
                eps = integral(curve, mp.mpf(0), mp.log(mp.mpf(x_max)), kinks)
                yield {
                    "formula": formula.id,
                    "shape": repr(shape_value),
                    "x_max": x_max,
                    "bypass": mp.nstr(extras.get("bypass", 0), 20),
                    "fishhook": mp.nstr(extras.get("fishhook", 0), 20),
                    "measured_efficiency": mp.nstr(context.get("measured_efficiency", mp.nan), 20),
                    "eta": mp.nstr(eta, 20),
                    "epsilon": mp.nstr(eps, 20),
                    "rtol": RTOL,
                }


def main():
    lines = [
        "# eta = int_0^1 phi dx and eps = int_1^x_max phi dx of the nine paper formulas and the extended curves,",
        "# integrated from the registry's expression texts with mpmath at 30 digits over each formula's shape range.",
        "# Generated by tests/reference/make_efficiency_reference.py (see its docstring); do not edit by hand.",
        "# source: tromplab.curves.formulas expression texts (corrected printed forms of Shuvalov et al. 2018, docs/errata.md)",
    ]
    table = list(rows())
    columns = list(table[0])
    lines.append(",".join(columns))
    lines += [",".join(str(row[c]) for c in columns) for row in table]
    OUT.write_text("\n".join(lines) + "\n")
    print(f"wrote {len(table)} rows to {OUT}")


if __name__ == "__main__":
    main()
