"""Reference values of the other tools' curves, computed with mpmath from the printed expressions.

Writes ``tests/reference/other_curves.csv``; ``tests/test_registry.py`` regenerates it in
memory (:func:`reference_text`) and compares it with the committed file.  Each value is
evaluated at 30 significant digits from the expression *as the source prints it* (the
coarse-product form where the
source writes that one, turned into the partition to fines by ``1 - value``), not from
tromplab's code, so the test compares two independent implementations:

* normal: King (2001), the normal distribution of the separation size,
  ``1 - Phi((d - d50)/sigma)`` to the fines, with ``sigma = sigma_rel d50``;
* logistic: the partition in d50 and Ep, ``1/(1 + exp(ln3 (d50 - d)/Ep))`` to the coarse
  product, with ``Ep = I d50``;
* teipel_hennig: Dyssol's Screen unit, ``(1 - (1 + 3 x^((x + Alpha) Beta))^-1/2)(1 - Offset)
  + Offset`` to the coarse product, with ``Beta = k/(1 + Alpha)``;
* rosin_rammler_bypass: Plitt (1976) with exact ln 2, ``Rf + (1 - Rf)(1 - exp(-ln2 x^m))``
  to the coarse product.

Needs mpmath (``pip install mpmath``); run from the repository root, as
``python tests/reference/make_other_curve_references.py`` (or its wrapper
``python analysis/make_other_curve_references.py``).
"""

from pathlib import Path

import mpmath as mp

#: Significant digits of the evaluation (set for the generation only: importing changes no mpmath state).
DIGITS = 30
OUT = Path(__file__).resolve().parent / "other_curves.csv"


def normal(x, sigma_rel):
    return 1 - mp.ncdf((x - 1) / sigma_rel)


def logistic(x, imperfection):
    coarse = 1 / (1 + mp.exp(mp.log(3) * (1 - x) / imperfection))
    return 1 - coarse


def teipel_hennig(x, k, th_alpha, offset):
    beta = k / (1 + th_alpha)
    coarse = (1 - (1 + 3 * x ** ((x + th_alpha) * beta)) ** mp.mpf(-0.5)) * (1 - offset) + offset
    return 1 - coarse


def plitt_1976(x, m, rf):
    coarse = rf + (1 - rf) * (1 - mp.exp(-mp.log(2) * x**m))
    return 1 - coarse


CASES = [
    ("normal", normal, {"sigma_rel": "0.25"}, "King (2001) normal separation size"),
    ("normal", normal, {"sigma_rel": "0.8"}, "King (2001) normal separation size"),
    ("logistic", logistic, {"imperfection": "0.15"}, "partition in d50 and Ep (ln 3 exact)"),
    ("logistic", logistic, {"imperfection": "0.6"}, "partition in d50 and Ep (ln 3 exact)"),
    ("teipel_hennig", teipel_hennig, {"k": "4", "th_alpha": "1", "offset": "0"}, "Dyssol Screen unit (Teipel & Hennig)"),
    (
        "teipel_hennig",
        teipel_hennig,
        {"k": "4.5", "th_alpha": "8", "offset": "0.2"},
        "Dyssol Screen unit defaults (Alpha 8; Beta 0.5; Offset 0.2)",
    ),
    ("rosin_rammler_bypass", plitt_1976, {"m": "2.5", "rf": "0.15"}, "Plitt (1976) with exact ln 2"),
]
X = ["0.1", "0.5", "0.8", "1", "1.3", "2", "3.5"]


def reference_text() -> str:
    """The text of ``other_curves.csv``: provenance comments, header and one line per row."""
    lines = [
        "# Partition to fines of the other tools' curves at x = size/d_cut.",
        "# Source: tests/reference/make_other_curve_references.py: mpmath (30 digits) from the expressions as printed by",
        "#   King (2001), the d50/Ep partition, Dyssol's Screen unit (Teipel & Hennig) and Plitt (1976); see its docstring.",
        "# parameters: tromplab's names (offset = bypass). atol: float64 evaluation.",
        "formula,x,parameters,phi,atol,source",
    ]
    names = {"offset": "bypass", "rf": "bypass", "m": "kr"}
    with mp.workdps(DIGITS):
        for formula, function, params, source in CASES:
            text = ";".join(f"{names.get(k, k)}={v}" for k, v in params.items())
            for x in X:
                value = function(mp.mpf(x), *(mp.mpf(v) for v in params.values()))
                lines.append(f"{formula},{x},{text},{mp.nstr(value, 17)},1e-12,{source}")
    return "\n".join(lines) + "\n"


def main():
    OUT.write_text(reference_text())
    print(f"Wrote {OUT}")


if __name__ == "__main__":
    main()
