"""The density partition curves: declarations, values and indices against mpmath at 40 digits."""

import math

import mpmath as mp
import numpy as np
import pytest
from numpy.testing import assert_allclose

from tromplab.curves.formulas import evaluate_expression
from tromplab.density.registry import (
    DENSITY_CURVES,
    LIMIT_CURVES,
    PLAIN_CURVES,
    density_registry_table,
    get_density_curve,
    select_density_curves,
)

mp.mp.dps = 40
all_curves = pytest.mark.parametrize("curve", DENSITY_CURVES, ids=[c.id for c in DENSITY_CURVES])
plain_curves = pytest.mark.parametrize("curve", PLAIN_CURVES, ids=[c.id for c in PLAIN_CURVES])
limit_curves = pytest.mark.parametrize("curve", LIMIT_CURVES, ids=[c.id for c in LIMIT_CURVES])

RHO = np.linspace(1.2, 2.2, 41)
# (rho50, Ep) of the plain curves and (rho_c, ep_c, light, heavy) of the limits: a sharp DMS cyclone,
# a jig and a poor separation
PLAIN_CASES = [(1.45, 0.02), (1.62, 0.08), (1.9, 0.25)]
LIMIT_CASES = [(1.45, 0.02, 0.0, 1.0), (1.6, 0.05, 0.03, 0.96), (1.8, 0.2, 0.2, 0.8)]


def mp_standard_cdf(curve_id: str, t):
    """The standard forms written from their textbook definitions, in mpmath."""
    base = curve_id.removesuffix("_limits")
    if base == "normal":
        return mp.ncdf(t)
    if base == "logistic":
        return 1 / (1 + mp.exp(-t))
    return 1 - mp.exp(-mp.exp(t))


def mp_standard_quantile(curve_id: str, p):
    base = curve_id.removesuffix("_limits")
    if base == "normal":
        return mp.sqrt(2) * mp.erfinv(2 * p - 1)
    if base == "logistic":
        return mp.log(p / (1 - p))
    return mp.log(-mp.log(1 - p))


def mp_partition(curve_id: str, rho, cut, ep, light=0, heavy=1):
    """P = l + (h - l) F(q50 + k (rho - cut)/ep), k = (q75 - q25)/2, in mpmath."""
    q = {p: mp_standard_quantile(curve_id, mp.mpf(p)) for p in ("0.25", "0.5", "0.75")}
    k = (q["0.75"] - q["0.25"]) / 2
    t = q["0.5"] + k * (mp.mpf(rho) - mp.mpf(cut)) / mp.mpf(ep)
    return mp.mpf(light) + (mp.mpf(heavy) - mp.mpf(light)) * mp_standard_cdf(curve_id, t)


def mp_density_at(curve_id, p, cut, ep, light=0, heavy=1):
    """The root of P(rho) = p by mpmath's solver (independent of the closed-form inverse)."""
    bracket = (mp.mpf(cut) - 20 * mp.mpf(ep), mp.mpf(cut) + 20 * mp.mpf(ep))
    return mp.findroot(lambda rho: mp_partition(curve_id, rho, cut, ep, light, heavy) - p, bracket, solver="anderson")


def params_of(curve, case):
    return dict(zip(curve.parameter_names, case))


#: The standard forms' densities f = F' at 40 digits (McCullagh & Nelder 1989, sect. 4.3), by link.
MP_PDF = {
    "probit": lambda t: mp.exp(-t * t / 2) / mp.sqrt(2 * mp.pi),
    "logit": lambda t: mp.exp(-t) / (1 + mp.exp(-t)) ** 2,
    "cloglog": lambda t: mp.exp(t - mp.exp(t)),
}


@plain_curves
def test_every_standard_form_declares_its_density_and_its_log(curve):
    """``pdf`` and ``log_pdf`` of the record, which the GLM's iterations and the plant's cut search read,
    against mpmath (rtol 1e-12; the log far into the tails, where the density itself underflows)."""
    form = curve.form
    t = np.linspace(-8.0, 6.0, 57)
    expected = np.array([float(MP_PDF[form.link](mp.mpf(v))) for v in t])
    assert_allclose(form.pdf(t), expected, rtol=1e-12, atol=1e-300)
    assert_allclose(form.log_pdf(t), np.log(expected), rtol=1e-12)
    far = np.array([-30.0, -12.0, 3.0])
    assert_allclose(form.log_pdf(far), [float(mp.log(MP_PDF[form.link](mp.mpf(v)))) for v in far], rtol=1e-12)


def test_a_limit_is_on_its_bound_within_a_millionth():
    curve = get_density_curve("logistic_limits")
    assert curve.limit_on_bound("light_limit", 0.0) and curve.limit_on_bound("heavy_limit", 1.0 - 9e-7)
    assert curve.limit_on_bound("heavy_limit", 0.5 + 5e-7)  # the heavy limit's lower bound is 1/2
    assert not curve.limit_on_bound("light_limit", 2e-6) and not curve.limit_on_bound("heavy_limit", 0.99)
    assert not curve.limit_on_bound("rho_c", curve.parameters[0].lower)  # only the limits are held on a bound


@all_curves
def test_every_curve_is_fully_declared(curve):
    assert curve.title and curve.citation and curve.notes and curve.expression
    assert curve.link in ("probit", "logit", "cloglog")
    for parameter in curve.parameters:
        assert parameter.lower < parameter.upper and parameter.unit and parameter.meaning and parameter.start_rule
    assert curve.n_params == (4 if curve.has_limits else 2)
    assert get_density_curve(curve.id) is curve
    assert curve in select_density_curves("all")
    table = density_registry_table().set_index("id")
    assert table.loc[curve.id, "expression"] == curve.expression


@all_curves
def test_expression_text_evaluates_to_the_curve(curve):
    t_text = curve.expression.split("t = ")[1].split(", F(t)")[0]
    for case in PLAIN_CASES if not curve.has_limits else LIMIT_CASES:
        params = params_of(curve, case)
        t = evaluate_expression(t_text, {"rho": RHO, **params})
        inside = evaluate_expression(curve.form.text, {"t": t})
        light, heavy = params.get("light_limit", 0.0), params.get("heavy_limit", 1.0)
        assert_allclose(light + (heavy - light) * inside, curve.partition(RHO, **params), rtol=1e-13, atol=1e-15)


@all_curves
def test_partition_against_mpmath(curve):
    for case in PLAIN_CASES if not curve.has_limits else LIMIT_CASES:
        params = params_of(curve, case)
        got = curve.partition(RHO, **params)
        want = np.array([float(mp_partition(curve.id, mp.mpf(str(r)), *map(lambda v: mp.mpf(str(v)), case))) for r in RHO])
        assert_allclose(got, want, rtol=1e-13, atol=1e-15)
        assert (
            np.all(np.diff(got) >= 0) and got.min() >= params.get("light_limit", 0) and got.max() <= params.get("heavy_limit", 1)
        )


@plain_curves
def test_plain_curve_has_its_parameters_as_indices(curve):
    for rho50, ep in PLAIN_CASES:
        assert_allclose(curve.partition(rho50, rho50=rho50, ep=ep), 0.5, atol=1e-15)
        index = curve.indices(rho50=rho50, ep=ep)
        assert index.note == ""
        assert_allclose([index.rho50, (index.rho75 - index.rho25) / 2], [rho50, ep], rtol=1e-13)
        assert index.ep == ep and index.imperfection == ep / (rho50 - 1)


@all_curves
def test_quartiles_against_mpmath_root_finding(curve):
    for case in PLAIN_CASES if not curve.has_limits else LIMIT_CASES:
        params = params_of(curve, case)
        index = curve.indices(**params)
        mp_case = [mp.mpf(str(v)) for v in case]
        want = [float(mp_density_at(curve.id, mp.mpf(p), *mp_case)) for p in ("0.25", "0.5", "0.75")]
        assert_allclose([index.rho25, index.rho50, index.rho75], want, rtol=1e-13)
        assert_allclose(index.ep, (want[2] - want[0]) / 2, rtol=1e-11)
        assert_allclose(index.imperfection, index.ep / (index.rho50 - 1), rtol=1e-15)


def test_gompertz_is_asymmetric_as_stated():
    index = get_density_curve("gompertz").indices(rho50=1.5, ep=0.1)
    below = float((mp.log(mp.log(2)) - mp.log(mp.log(mp.mpf(4) / 3))) / ((mp.log(mp.log(4)) - mp.log(mp.log(mp.mpf(4) / 3))) / 2))
    assert_allclose((index.rho50 - index.rho25) / 0.1, below, rtol=1e-12)
    assert "1.118 Ep against 0.882 Ep" in get_density_curve("gompertz").notes and round(below, 3) == 1.118


@limit_curves
def test_missing_quartiles_are_said_in_words(curve):
    light = curve.indices(rho_c=1.5, ep_c=0.05, light_limit=0.3, heavy_limit=0.95)
    assert math.isnan(light.rho25) and math.isnan(light.ep) and math.isnan(light.imperfection)
    assert not math.isnan(light.rho50) and not math.isnan(light.rho75)
    assert "rho25 does not exist: the light-end limit 0.3 is at or above 1/4" in light.note
    assert "Ep and the imperfection do not exist" in light.note
    heavy = curve.indices(rho_c=1.5, ep_c=0.05, light_limit=0.0, heavy_limit=0.75)
    assert math.isnan(heavy.rho75) and "rho75 does not exist: the heavy-end limit 0.75 is at or below 3/4" in heavy.note
    at_limit = curve.indices(rho_c=1.5, ep_c=0.05, light_limit=0.25, heavy_limit=1.0)
    assert math.isnan(at_limit.rho25)  # P only tends to 1/4 at the light end: it never equals it


@limit_curves
def test_from_indices_inverts_indices(curve):
    for rho50, ep, light, heavy in [(1.45, 0.02, 0.0, 1.0), (1.6, 0.05, 0.03, 0.96), (1.8, 0.2, 0.2, 0.8)]:
        params = curve.from_indices(rho50=rho50, ep=ep, light_limit=light, heavy_limit=heavy)
        index = curve.indices(**params)
        assert_allclose([index.rho50, index.ep], [rho50, ep], rtol=1e-12)
    with pytest.raises(ValueError, match="light-end limit in"):
        curve.from_indices(rho50=1.5, ep=0.05, light_limit=0.3)


@all_curves
def test_partition_broadcasts_over_parameter_arrays(curve):
    case = np.array(PLAIN_CASES if not curve.has_limits else LIMIT_CASES)
    columns = {name: case[:, [i]] for i, name in enumerate(curve.parameter_names)}
    many = curve.partition(RHO[None, :], **columns)
    one_by_one = np.array([curve.partition(RHO, **params_of(curve, row)) for row in case])
    assert many.shape == (len(case), RHO.size)
    assert_allclose(many, one_by_one, rtol=0, atol=0)


def test_wrong_parameters_are_named():
    with pytest.raises(TypeError, match=r"missing \['ep'\]"):
        get_density_curve("normal").partition(1.5, rho50=1.5)
    with pytest.raises(KeyError, match="known curves: normal"):
        get_density_curve("weibull")


@all_curves
def test_catalogue_figure_draws_each_curve_at_its_stated_indices(curve):
    from tromplab.density.plotting import FAMILY_EPS, plot_density_curve_family
    from tromplab.output.plotting import offscreen_axes

    ax = plot_density_curve_family(curve, ax=offscreen_axes())
    lines = [line for line in ax.get_lines() if line.get_label().startswith("Ep ")]
    assert [line.get_label() for line in lines] == [f"Ep {ep:g}" for ep in FAMILY_EPS]
    for line, ep in zip(lines, FAMILY_EPS):
        x, y = line.get_data()
        rho25, rho50, rho75 = np.interp([25.0, 50.0, 75.0], y, x)  # read back from the drawn curve
        assert_allclose([rho50, (rho75 - rho25) / 2], [1.5, ep], atol=2e-3)


@all_curves
def test_curves_pickle_by_id(curve):
    import pickle

    assert pickle.loads(pickle.dumps(curve)) is curve
