"""Published numbers and conclusions of the source papers, recomputed by the library.

Each row of ``tests/reference/published_conclusions.csv`` names its source and the value the
library computes; this file computes every row from the library's public functions, so a row
without a computation here fails (see the header of the reference file for the papers).
"""

from functools import cache

import numpy as np
import pandas as pd
import pytest
from scipy import integrate, optimize

from tromplab.classifiers.layer import LayerModel
from tromplab.classifiers.pulp import PulpScreen
from tromplab.classifiers.sieve import design_bin, distance_moments, distance_pdf
from tromplab.curves.formulas import NoBreakPointError, luckie_austin, rosin_rammler, rosin_rammler_plateau, shuvalov_break
from tromplab.curves.indices import efficiency
from tromplab.curves.ranking import rank_formulas, read_f_table
from tromplab.reproduce import compare_printed

from .conftest import DATASETS, REFERENCE

ROWS = pd.read_csv(REFERENCE / "published_conclusions.csv", comment="#", dtype={"printed": str, "agreement": str})
TABLE2 = DATASETS / "shuvalov2018_table2_F.csv"
KR_AT_HALF_SLOPE = 2 * 0.5 / np.log(2)  # kr of (5) at the slope -0.5 of Fig. 1: 1.4427
DECKS = 12


@cache
def _table(use_given_marks: bool):
    table = read_f_table(TABLE2, use_given_marks=use_given_marks)
    ranks = rank_formulas(table).set_index("equation")
    return table, ranks[[c for c in ranks.columns if c not in ("points", "place")]]


def _places_of_7(place: int) -> int:
    _, ranks = _table(True)
    return int((ranks.loc["7"] == place).sum())


def _inadequate_counts(use_given_marks: bool) -> pd.Series:
    table, _ = _table(use_given_marks)
    return table.groupby("equation")["adequate"].apply(lambda adequate: int((~adequate).sum()))


def _f_ratio() -> pd.Series:
    table, _ = _table(False)
    return table["F"] / table["F_crit"]


@cache
def _refit_21() -> tuple[float, float]:
    kf = np.linspace(0.75, 2.25, 61)
    exact = np.array([efficiency("lognormal", value, 6.0)[0] for value in kf])
    (coefficient, exponent), _ = optimize.curve_fit(lambda k, a, b: a / k**b, kf, exact, p0=(0.8, 0.2))
    return float(coefficient), float(exponent)


def _c_for_sd(sd: float) -> float:
    """C of the distance law on deck 12 whose exact standard deviation is ``sd``."""
    return optimize.brentq(lambda c: np.sqrt(distance_moments(DECKS, c)[1]) - sd, 1e-2, 1e4, xtol=1e-12)


@cache
def _peak(sd: float) -> tuple[float, float]:
    """(x, f) at the maximum of f_12 for the law with standard deviation ``sd``."""
    c = _c_for_sd(sd)
    mode = np.sqrt((2 * DECKS - 1) / c)  # where d/dx of x^(2m-1) exp(-C x^2/2) vanishes
    found = optimize.minimize_scalar(lambda x: -distance_pdf(x, DECKS, c), bounds=(0.5 * mode, 2 * mode), method="bounded")
    assert found.x == pytest.approx(mode, abs=1e-4)  # the numerical maximum is the analytic mode
    return float(mode), float(distance_pdf(mode, DECKS, c))


def _lowest_efficiency_with_a_break() -> float:
    """The least efficiency formula (11) reaches: the area from 0 to 1 under its plateau form (the
    Rosin-Rammler curve above the break x_a, its value at x_a below) by quadrature, the least over
    x_a in [0, 1] and kr 0.8, 1/ln 2 and 3.  A measured efficiency has a break point only down to it;
    a wrong plateau, a cut not at phi = 1/2 or a least area away from x_a = 1 changes it."""

    def curve(x, kr, x_break):
        return float(rosin_rammler_plateau(x, kr, x_break))

    areas = [
        integrate.quad(curve, 0.0, 1.0, args=(kr, x_break), points=[x_break] if 0.0 < x_break < 1.0 else None,
                       epsabs=1e-14, epsrel=1e-13)[0]
        for kr in (0.8, KR_AT_HALF_SLOPE, 3.0) for x_break in np.linspace(0.0, 1.0, 21)
    ]  # fmt: skip
    return min(areas)


def _layer_linear(step: int) -> float:
    model = LayerModel(diffusion=0.005, segregation=0.026, passage=0.21, nonlinear=False)
    return float(model.simulate([0.5] * 4, 300).extraction[step - 1])


COMPUTED = {
    "table3_7_first": lambda: _places_of_7(1),
    "table3_7_last": lambda: _places_of_7(9),
    "table3_fewest_inadequate": lambda: _inadequate_counts(True).min(),
    "table3_7_inadequate_given": lambda: _inadequate_counts(True)["7"],
    "table3_7_inadequate_computed": lambda: _inadequate_counts(False)["7"],
    "table2_median_f_ratio": lambda: _f_ratio().median(),
    "table2_share_twice_critical": lambda: (_f_ratio() >= 2).mean(),
    "refit_21_coefficient": lambda: _refit_21()[0],
    "refit_21_exponent": lambda: _refit_21()[1],
    "break_11_lower": _lowest_efficiency_with_a_break,
    "break_11_upper": lambda: efficiency("rosin_rammler", KR_AT_HALF_SLOPE, 6.0)[0],
    "plateau_10": lambda: float(np.unique(luckie_austin(np.array([0.01, 0.2, 0.5]), KR_AT_HALF_SLOPE)).item()),
    "bin_fraction_sd": lambda: np.sqrt(distance_moments(DECKS, design_bin(DECKS, 1.6, 0.9).c)[1]),
    "fig3_peak_f_0117": lambda: _peak(0.117)[1],
    "fig3_peak_x_0117": lambda: _peak(0.117)[0],
    "fig3_peak_f_0185": lambda: _peak(0.185)[1],
    "fig3_peak_x_0185": lambda: _peak(0.185)[0],
    "fig3_peak_f_0269": lambda: _peak(0.269)[1],
    "fig3_peak_x_0269": lambda: _peak(0.269)[0],
    "layer_linear_100": lambda: _layer_linear(100),
    "layer_linear_200": lambda: _layer_linear(200),
    "layer_linear_300": lambda: _layer_linear(300),
    "pulp_best_head_n10": lambda: PulpScreen().best_pressure_drop(10.0)[0],
    "pulp_best_q_n10": lambda: PulpScreen().best_pressure_drop(10.0)[1],
}


def test_every_row_has_a_computation_and_every_computation_a_row():
    assert sorted(ROWS["key"]) == sorted(COMPUTED)


@pytest.mark.parametrize("row", list(ROWS.itertuples(index=False)), ids=list(ROWS["key"]))
def test_the_library_computes_the_pinned_value(row):
    assert float(COMPUTED[row.key]()) == pytest.approx(row.computed, abs=row.atol)


@pytest.mark.parametrize("row", [r for r in ROWS.itertuples(index=False) if isinstance(r.printed, str)], ids=lambda r: r.key)
def test_the_pinned_value_against_the_printed_one(row):
    if row.atol == 0:  # a count: equal or not
        verdict = "agrees" if int(row.printed) == int(row.computed) else "differs"
    else:
        verdict, _ = compare_printed(row.printed, row.computed)
    assert verdict == row.agreement


def test_the_break_of_11_exists_only_between_one_half_and_the_efficiency_of_5():
    for kr in (0.8, KR_AT_HALF_SLOPE, 3.0):
        eta_5 = efficiency("rosin_rammler", kr, 6.0)[0]
        assert shuvalov_break(kr, 0.5) == pytest.approx(1.0) and shuvalov_break(kr, eta_5) == pytest.approx(0.0, abs=1e-9)
        assert 0 < shuvalov_break(kr, (0.5 + eta_5) / 2) < 1
        for outside in (0.5 - 1e-6, eta_5 + 1e-6):
            with pytest.raises(NoBreakPointError):
                shuvalov_break(kr, outside)


def test_the_plateau_of_10_is_the_value_of_5_at_one_half():
    for kr in (0.5, KR_AT_HALF_SLOPE, 3.0):
        below = luckie_austin(np.array([1e-3, 0.1, 0.5]), kr)
        np.testing.assert_allclose(below, rosin_rammler(0.5, kr), rtol=1e-15)
        np.testing.assert_allclose(luckie_austin(np.array([0.7, 2.0]), kr), rosin_rammler(np.array([0.7, 2.0]), kr), rtol=1e-15)
