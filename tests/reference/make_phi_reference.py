"""Generate phi_reference.csv: every registry formula at (x, shape) points, from its expression text.

The values come from the formula's *expression text* in the registry (the corrected
printed form, see docs/errata.md), evaluated with mpmath at 40 significant digits, not
from the vectorised functions the package fits with.  The derived variables are solved
at the same precision from their defining equations:

* ``x_a`` of formula (11): area of the curve on 0 < x < 1 equals the measured
  efficiency, ``x_a phi5(x_a) + int_{x_a}^1 phi5 dx = eta`` (mpmath quad + findroot);
* ``b_star`` of Whiten's curve: ``(1 + beta b*) (e^a - 1)/(e^(a b*) + e^a - 2) = 1/2``.

Shapes are those giving slopes -0.3, -1 and -3 at the cut (the equal-sharpness shapes of
the package spec, section 2), found with mpmath from the slope expression text within the
fit bounds.  A formula whose curve is defined beyond its fit bounds (``monotone=False``:
the bounds keep fits to the monotone shapes, while the paper's figures, and tromplab's,
draw the curves that rise again) keeps its equal-sharpness shape there: Molerus-Hoffmann's
``km2 = -0.4`` at slope -0.3.  A slope out of the formula's reach gives the nearer bound.

``tests/test_registry.py`` regenerates the file in memory (:func:`reference_text`) and
compares it with the committed one.  Run from the repository root after adding or changing
a formula (needs mpmath, a dependency of sympy):

    python tests/reference/make_phi_reference.py
"""

from __future__ import annotations

from pathlib import Path

import mpmath as mp

from tromplab.curves.formulas import ALL_FORMULAS, evaluate_expression

#: Significant digits of the evaluation (set for the generation only: importing changes no mpmath state).
DIGITS = 40
OUT = Path(__file__).resolve().parent / "phi_reference.csv"
X_POINTS = ("0.05", "0.3", "0.7", "1", "1.3", "2", "4")
SLOPES = ("-0.3", "-1", "-3")
EXTRAS = {"bypass": "0.1", "fishhook": "0.4", "th_alpha": "2"}
MP_FUNCTIONS = {"exp": mp.exp, "ln": mp.log, "erfc": mp.erfc, "sqrt": mp.sqrt, "max": max, "pi": mp.pi, "ln2": mp.ln2}
RTOL = "1e-10"


def value(text, **values):
    return mp.mpf(evaluate_expression(text, values, MP_FUNCTIONS))


def shape_for(formula, slope, extras):
    """Shape whose slope expression (extras at zero) equals ``slope``: inside the bounds, or
    beyond them where the curve is defined there (``monotone=False``), else the nearer bound."""
    low, high = (mp.mpf(b) for b in formula.shape_bounds)
    zero = {name: 0 for name in extras}

    def gap(shape):
        return value(formula.slope_expression, **{formula.shape_name: shape}, **zero) - mp.mpf(slope)

    if gap(low) * gap(high) > 0 and not formula.monotone:
        # the equal-sharpness shape beyond the fit bounds (the registry's inverse brackets it)
        guess = mp.mpf(formula.shape_for_slope(float(slope)))
        wide = (min(low, guess - 1), max(high, guess + 1))
        if gap(wide[0]) * gap(wide[1]) <= 0:
            low, high = wide
    if gap(low) * gap(high) > 0:  # slope out of reach: the nearer bound
        return low if abs(gap(low)) < abs(gap(high)) else high
    return mp.findroot(gap, (low, high), solver="anderson")


def rosin_rammler_area(a, b, kr):
    return mp.quad(lambda x: mp.exp(-mp.log(2) * x**kr), [a, b])


def break_point(kr, efficiency):
    return mp.findroot(
        lambda xa: xa * mp.exp(-mp.log(2) * xa**kr) + rosin_rammler_area(xa, 1, kr) - efficiency,
        (mp.mpf("1e-30"), mp.mpf(1) - mp.mpf("1e-30")),
        solver="anderson",
    )


def beta_star(alpha, fishhook):
    def gap(star):
        return (1 + fishhook * star) * (mp.exp(alpha) - 1) / (mp.exp(alpha * star) + mp.exp(alpha) - 2) - mp.mpf("0.5")

    high = mp.mpf(1)
    while gap(high) > 0:
        high *= 2
    return mp.findroot(gap, (mp.mpf(0), high), solver="anderson")


def rows():
    for formula in ALL_FORMULAS:
        extras = {extra.name: mp.mpf(EXTRAS[extra.name]) for extra in formula.extras}
        for slope in SLOPES:
            shape = shape_for(formula, slope, extras)
            context, derived = {}, {}
            if "x_a" in formula.expression:
                eta_plain = rosin_rammler_area(0, 1, shape)
                efficiency = (mp.mpf("0.5") + eta_plain) / 2  # halfway: a break point exists
                context["measured_efficiency"] = efficiency
                derived["x_a"] = break_point(shape, efficiency)
            if "b_star" in formula.expression:
                derived["b_star"] = beta_star(shape, extras["fishhook"])
            for x in X_POINTS:
                phi = value(formula.expression, x=mp.mpf(x), **{formula.shape_name: shape}, **extras, **derived)
                yield {
                    "formula": formula.id,
                    "x": x,
                    "shape": mp.nstr(shape, 20),
                    "bypass": mp.nstr(extras.get("bypass", 0), 20),
                    "fishhook": mp.nstr(extras.get("fishhook", 0), 20),
                    "th_alpha": mp.nstr(extras.get("th_alpha", 0), 20),
                    "measured_efficiency": mp.nstr(context.get("measured_efficiency", mp.nan), 20),
                    "phi": mp.nstr(phi, 20),
                    "rtol": RTOL,
                }


def reference_text() -> str:
    """The text of ``phi_reference.csv``: provenance comments, header and one line per row."""
    lines = [
        "# phi(x) of every registry formula from its expression text, mpmath at 40 digits.",
        "# Generated by tests/reference/make_phi_reference.py (see its docstring); do not edit by hand.",
        "# source: tromplab.curves.formulas expression texts (corrected printed forms of Shuvalov et al. 2018, docs/errata.md)",
    ]
    with mp.workdps(DIGITS):
        table = list(rows())
    columns = list(table[0])
    lines.append(",".join(columns))
    lines += [",".join(str(row[c]) for c in columns) for row in table]
    return "\n".join(lines) + "\n"


def main():
    OUT.write_text(reference_text())
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
