r"""Profile-likelihood limits of rho50, Ep and the imperfection of many binomial fits at once.

Each request is one fitted curve and one quantity: the curve is written in its indices
``(rho50, Ep[, l, h])`` (``(rho50, I[, l, h])`` for the imperfection, ``Ep = I (rho50 - 1)``,
through :meth:`~tromplab.density.registry.DensityCurve.from_indices`), the quantity is held at
a value and the other parameters re-optimised (:func:`~tromplab.density.batch.minimise_deviance`,
from the optimum of the previous value and, for a curve with limits, also from the
estimate).  A limit is where the excess :math:`(D(q) - \hat D)/\phi - c` crosses zero
(``phi`` the scale and ``c`` the threshold the caller gives).  Both sides of every request
go together: from the estimate a step of a quarter of Ep (of I) and then twice as far each
time until the excess is positive (a bracket) or the search range ends (no limit); within
each bracket Newton's method kept within the bracket, every side at once, converges to the
last digits (regula falsi, Illinois, where a profile of a curve with limits does not cross its
bracket smoothly).  The search is the one every curve's profile uses, size or density
(:func:`tromplab.curves.likelihood.step_out` and
:func:`~tromplab.curves.likelihood.newton_in_bracket`); this module gives it the excess of the
re-optimised deviance and its slope (:func:`profile_limits`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..curves.likelihood import Bracket, newton_in_bracket, step_out
from .batch import TracerStack, centre_and_scale, minimise_deviance
from .registry import QUARTILES

#: The excess where no curve with a finite likelihood exists at a value: beyond any limit.
BEYOND = 1e300
#: Relative and absolute (in units of the first step) tolerances of the limits.
ROOT_RELATIVE_TOLERANCE = 1e-14
ROOT_STEP_TOLERANCE = 1e-11
#: Iterations of the root search (it converges in about fifteen).
MAX_ROOT_ITERATIONS = 100
#: How far (a factor) the chord of a bracket may be from the excess's slopes at its ends for the
#: profile of a curve with limits to be closed by Newton's steps (:func:`_smooth_brackets`).
SMOOTH_CHORD_RATIO = 5.0
#: How near (in first steps) a value of a smooth bracket must be to the last one for the start
#: at the estimate to be replaced by the optimum it reached there (:meth:`_Profiles._estimate_start`).
BRANCH_DISTANCE = 1e-2


@dataclass(frozen=True)
class ProfileRequests:
    """The profiles to trace, one row per fitted curve and quantity (all of one curve).

    Attributes
    ----------
    stack : TracerStack
        The tracer counts of each row.
    imperfection : ndarray of bool
        True where the quantity is the imperfection (the second index is ``I``, not ``Ep``).
    position : ndarray of int
        The index held: 0 (rho50) or 1 (Ep or I).
    centre : ndarray
        (rows, parameters): the estimate in the indices.
    lower, upper : ndarray
        (rows, parameters): the search range of each index.
    best : ndarray
        The fit's deviance.
    scale, threshold : ndarray
        The deviance's scale (1, or the quasi-binomial scale) and the excess's threshold.
    step : ndarray
        The first step out from the estimate.
    curve : ndarray of int or None
        Which of the curves :func:`profile_limits` is given each row is (None: the one curve).
    """

    stack: TracerStack
    imperfection: np.ndarray
    position: np.ndarray
    centre: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    best: np.ndarray
    scale: np.ndarray
    threshold: np.ndarray
    step: np.ndarray
    curve: np.ndarray | None = None


def curve_of_indices(curve, q: np.ndarray, imperfection: np.ndarray) -> dict[str, np.ndarray]:
    """The curve's parameters (each (rows, 1)) from the indices ``q`` (rows, parameters), as ``from_indices`` makes them."""
    rho50, second = q[:, 0:1], q[:, 1:2]
    ep = np.where(imperfection[:, None], second * (rho50 - 1.0), second)
    if not curve.has_limits:
        return {"rho50": rho50, "ep": ep}
    light, heavy = q[:, 2:3], q[:, 3:4]
    span = heavy - light
    form = curve.form
    centre, scale_c = centre_and_scale(form)
    q25, q50, q75 = (form.quantile((p - light) / span) for p in QUARTILES)
    ep_c = ep * 2.0 * scale_c / (q75 - q25)
    rho_c = rho50 - ep_c * (q50 - centre) / scale_c
    return {"rho_c": rho_c, "ep_c": ep_c, "light_limit": light, "heavy_limit": heavy}


class _RowForms:
    """The standard forms of the rows of several curves (all with limits or all plain): each form's
    functions applied to its own rows, the constants ``centre`` (q50) and ``scale`` (k) as (rows, 1)."""

    def __init__(self, curves, curve: np.ndarray, constants: np.ndarray | None = None):
        self.curves, self.curve, self.has_limits = curves, curve, curves[0].has_limits
        if len(curves) == 1:
            self.groups = [(curves[0].form, None)]
        else:
            self.groups = [(one.form, curve == number) for number, one in enumerate(curves)]
            self.groups = [(form, rows) for form, rows in self.groups if rows.any()]
        # (q50, k) of each curve's form, made once and handed to the forms of subsets of the rows
        self.constants = np.array([centre_and_scale(one.form) for one in curves]) if constants is None else constants
        self.centre, self.scale = self.constants[curve, 0:1], self.constants[curve, 1:2]

    def take(self, rows: np.ndarray) -> _RowForms:
        """The forms of the rows ``rows``."""
        return _RowForms(self.curves, self.curve[rows], self.constants)

    def _each(self, function, first: np.ndarray, *more: np.ndarray) -> np.ndarray:
        if len(self.groups) == 1:
            return function(self.groups[0][0], first, *more)
        found = np.empty(np.broadcast_shapes(first.shape, *(part.shape for part in more)))
        for form, rows in self.groups:
            found[rows] = function(form, first[rows], *(part[rows] for part in more))
        return found

    def cdf(self, t):
        return self._each(lambda form, t: form.cdf(t), t)

    def pdf(self, t):
        return self._each(lambda form, t: form.pdf(t), t)

    def quantile(self, p):
        return self._each(lambda form, p: form.quantile(p), p)

    def pdf_slope(self, t, cdf, pdf):
        """``f'(t)`` from ``t``, ``F(t)`` and ``f(t)`` (:func:`_pdf_slope`)."""
        return self._each(lambda form, *values: _pdf_slope(form.link, *values), t, cdf, pdf)


def _partitions(forms: _RowForms, density: np.ndarray, q: np.ndarray, imperfection: np.ndarray) -> np.ndarray:
    """The partitions at ``density`` of the curves whose indices are ``q``, row by row: the
    arithmetic of :func:`curve_of_indices` and :func:`~tromplab.density.batch.partition_at`,
    element by element, with each row's form."""
    rho50, second = q[:, 0:1], q[:, 1:2]
    ep = np.where(imperfection[:, None], second * (rho50 - 1.0), second)
    if not forms.has_limits:
        return forms.cdf(forms.centre + forms.scale * (density - rho50) / ep)
    light, heavy = q[:, 2:3], q[:, 3:4]
    quartiles = forms.quantile((np.array(QUARTILES) - light) / (heavy - light))
    q25, q50, q75 = quartiles[:, 0:1], quartiles[:, 1:2], quartiles[:, 2:3]
    ep_c = ep * 2.0 * forms.scale / (q75 - q25)
    rho_c = rho50 - ep_c * (q50 - forms.centre) / forms.scale
    inside = forms.cdf(forms.centre + forms.scale * (density - rho_c) / ep_c)
    return light + (heavy - light) * inside


def _pdf_slope(link: str, t: np.ndarray, cdf: np.ndarray, pdf: np.ndarray) -> np.ndarray:
    """``f'(t)`` of a standard form from ``t``, ``F(t)`` and ``f(t)``, by the GLM link the form is the inverse of."""
    if link == "probit":
        return -t * pdf
    if link == "logit":
        return pdf * (1.0 - 2.0 * cdf)
    if link == "cloglog":
        return pdf * (1.0 - np.exp(np.minimum(t, 700.0)))
    raise ValueError(f"no derivative of the density of the {link!r} form")


def _quartile_terms(forms: _RowForms, light, heavy) -> tuple[dict, dict]:
    """``D = Q(a75) - Q(a25)`` and ``M = Q(a50)`` (``a_p = (p - l)/(h - l)``, ``Q`` the form's
    quantile) with their first and second derivatives in ``l`` (2) and ``h`` (3), keyed by the
    index positions: ``{(): value, (2,): d/dl, (2, 3): d2/dl dh, ...}``."""
    span = heavy - light
    p = np.array(QUARTILES)  # the three quartiles as columns, (rows, 3)
    a = (p - light) / span
    q = forms.quantile(a)
    density = forms.pdf(q)
    first, second = 1.0 / density, -forms.pdf_slope(q, a, density) / density**3
    a_l, a_h = (p - heavy) / span**2, -(p - light) / span**2
    a_ll, a_lh, a_hh = 2.0 * (p - heavy) / span**3, -1.0 / span**2 - 2.0 * (p - heavy) / span**3, 2.0 * (p - light) / span**3
    found = {(): q, (2,): first * a_l, (3,): first * a_h, (2, 2): second * a_l * a_l + first * a_ll,
             (2, 3): second * a_l * a_h + first * a_lh, (3, 3): second * a_h * a_h + first * a_hh}  # fmt: skip
    return {key: value[:, 2:3] - value[:, 0:1] for key, value in found.items()}, {
        key: value[:, 1:2] for key, value in found.items()
    }


def index_derivatives(forms: _RowForms, density: np.ndarray, q: np.ndarray, imperfection: np.ndarray, held: np.ndarray):
    r"""The first and second derivatives of the partitions at ``density`` (rows, width) in the
    parameters of a profile's minimisation, analytically: the indices ``q`` (rows, parameters) of
    :func:`curve_of_indices` with the one ``held`` (0: rho50, 1: Ep or I) put first.

    In the indices the standardised variable is :math:`t = M + (\rho - \rho_{50})\,g`,
    :math:`g = D / (2 E_p)` (``M``, ``D``: the quartile terms of :func:`_quartile_terms`;
    ``M = q50`` and ``D = 2k`` for a plain curve), and :math:`P = l + (h - l) F(t)`, so that
    :math:`\partial_i P = [i = l](1 - F) + [i = h] F + (h - l) f\, t_i` and
    :math:`\partial_{ij} P = f\,(c_i t_j + c_j t_i) + (h - l)(f' t_i t_j + f\, t_{ij})`, with
    :math:`c_l = -1`, :math:`c_h = 1` and 0 otherwise.

    Returns
    -------
    tuple
        ``{i: dP/dx_i}`` and ``{(i, j): d2P/dx_i dx_j}`` (``i <= j``), each (rows, width), ``x``
        the held index (0: its derivatives, zero, left out), the other of rho50 and Ep (or I),
        then the limits.
    """
    size = q.shape[1]
    rho50_free = (held == 1)[:, None]
    rho50, ep, e_o = _ep_and_its_derivative(q, imperfection, rho50_free)  # e_o: in the index left free
    if forms.has_limits:
        span = q[:, 3:4] - q[:, 2:3]
        width, middle = _quartile_terms(forms, q[:, 2:3], q[:, 3:4])
    else:
        span, width, middle = 1.0, {(): 2.0 * forms.scale}, {(): forms.centre}
    g = _slope_terms(width, ep, e_o)
    u = density - rho50
    shift = {key: np.where(rho50_free, g[key], 0.0) for key in ((), (1,))}  # rho50 enters through u too
    t = middle[()] + u * g[()]
    t1 = {1: u * g[(1,)] - shift[()]}
    t2 = {(1, 1): u * g[1, 1] - 2.0 * shift[(1,)]}
    for i in range(2, size):
        t1[i] = middle[(i,)] + u * g[(i,)]
        t2[1, i] = u * g[1, i] - np.where(rho50_free, g[(i,)], 0.0)
        for j in range(i, size):
            t2[i, j] = middle[i, j] + u * g[i, j]
    cdf, pdf = forms.cdf(t), forms.pdf(t)
    slope = forms.pdf_slope(t, cdf, pdf)
    edge = {2: (-1.0, 1.0 - cdf), 3: (1.0, cdf)}  # c_i and the derivative of l + (h - l) F in the limit itself
    first = {i: span * pdf * t1[i] + (edge[i][1] if i in edge else 0.0) for i in range(1, size)}
    second = {}
    for i, j in t2:
        value = span * (slope * t1[i] * t1[j] + pdf * t2[i, j])
        if i in edge or j in edge:
            value = value + pdf * ((edge[i][0] if i in edge else 0.0) * t1[j] + (edge[j][0] if j in edge else 0.0) * t1[i])
        second[i, j] = value
    return first, second


def _ep_and_its_derivative(q: np.ndarray, imperfection: np.ndarray, in_rho50: np.ndarray):
    """rho50, Ep and Ep's derivative in one index (rows, 1 each), of the indices ``q`` (rho50 then
    Ep, or the imperfection I where ``imperfection``: Ep = I (rho50 - 1)); the derivative is in
    rho50 where ``in_rho50`` (rows, 1), else in the second index."""
    rho50, second = q[:, 0:1], q[:, 1:2]
    imperfect = imperfection[:, None]
    ep = np.where(imperfect, second * (rho50 - 1.0), second)
    derivative = np.where(in_rho50, np.where(imperfect, second, 0.0), np.where(imperfect, rho50 - 1.0, 1.0))
    return rho50, ep, derivative


def held_derivative(
    forms: _RowForms, density: np.ndarray, q: np.ndarray, imperfection: np.ndarray, held: np.ndarray
) -> np.ndarray:
    """``dP/dq_held`` (rows, width): the derivative of the partitions in the index each row's
    profile holds (0: rho50, 1: Ep or I), the terms of :func:`index_derivatives` for that index."""
    rho50_held = (held == 0)[:, None]
    rho50, ep, e_held = _ep_and_its_derivative(q, imperfection, rho50_held)
    if forms.has_limits:
        span = q[:, 3:4] - q[:, 2:3]
        quartiles = forms.quantile((np.array(QUARTILES) - q[:, 2:3]) / span)
        width, middle = quartiles[:, 2:3] - quartiles[:, 0:1], quartiles[:, 1:2]
    else:
        span, width, middle = 1.0, 2.0 * forms.scale, forms.centre
    g = width * 0.5 / ep
    u = density - rho50
    t = middle + u * g
    t_held = -u * width * e_held * (0.5 / ep) / ep - np.where(rho50_held, g, 0.0)
    return span * forms.pdf(t) * t_held


def _slope_terms(width: dict, ep: np.ndarray, e_o: np.ndarray) -> dict:
    """``g = D / (2 Ep)`` and its derivatives in the free index ``o`` (1) and the limits (2, 3):
    ``D`` depends on the limits, ``Ep`` on ``o`` (``e_o``: its derivative; the second is zero,
    as ``Ep = I (rho50 - 1)`` is linear in each of rho50 and I)."""
    half = 0.5 / ep
    d = width[()]
    g = {(): d * half, (1,): -d * e_o * half / ep, (1, 1): d * e_o**2 / ep**3}
    for i in (2, 3):
        g[(i,)] = width.get((i,), 0.0) * half
        g[1, i] = -width.get((i,), 0.0) * e_o * half / ep
        for j in range(i, 4):
            g[i, j] = width.get((i, j), 0.0) * half
    return g


def _ordered(values: np.ndarray, order: np.ndarray) -> np.ndarray:
    return np.take_along_axis(values, order, axis=1)


class _Profiles:
    """Both sides of every request: row ``i`` of a side is request ``i % requests``."""

    def __init__(self, curves, requests: ProfileRequests):
        self.curves, self.requests = curves, requests
        self.has_limits = curves[0].has_limits
        if any(curve.has_limits != self.has_limits for curve in curves):
            raise ValueError("the profiles searched together are all of curves with limits or all of plain curves")
        count = len(requests.best)
        self.curve = np.zeros(count, dtype=int) if requests.curve is None else np.asarray(requests.curve)
        self.request = np.tile(np.arange(count), 2)
        self.direction = np.repeat([-1.0, 1.0], count)
        self.warm = requests.centre[self.request].copy()  # the optimum at the last value of each side
        # the optimum the start at the estimate reached last on each side, and the value it was at;
        # which sides may start there instead (their brackets closed by Newton's steps)
        self.from_estimate, self.estimate_value = self.warm.copy(), np.full(len(self.request), np.nan)
        self.trackable = np.zeros(len(self.request), dtype=bool)
        # the excess's slope (in the value) at the last value below and above the threshold of each side
        self.inner_slope, self.outer_slope = np.zeros(len(self.request)), np.full(len(self.request), np.nan)

    def stepping_excess(self, sides: np.ndarray, value: np.ndarray) -> np.ndarray:
        """The excess at ``value`` on each of ``sides`` (:meth:`excess`), its slope kept as the
        slope at the bracket's inner (excess below zero) or outer end for :func:`_smooth_brackets`."""
        excess, slope = self.excess_and_slope(sides, value)
        below = excess < 0
        self.inner_slope[sides[below]], self.outer_slope[sides[~below]] = slope[below], slope[~below]
        return excess

    def _estimate_start(self, sides: np.ndarray, value: np.ndarray) -> np.ndarray:
        """The second start of a curve with limits: the estimate, or, on a side whose bracket is
        closed by Newton's steps (``trackable``) and within :data:`BRANCH_DISTANCE` first steps of
        the value it was last asked at, the optimum the estimate's start reached there (the same
        local minimum, a few steps nearer)."""
        r = self.requests
        request = self.request[sides]
        near = self.trackable[sides] & (np.abs(value - self.estimate_value[sides]) <= BRANCH_DISTANCE * r.step[request])
        return np.where(near[:, None], self.from_estimate[sides], r.centre[request])

    def excess(self, sides: np.ndarray, value: np.ndarray) -> np.ndarray:
        """The excess of the re-optimised deviance at ``value`` on each of ``sides`` (warm starts updated)."""
        return self.excess_and_slope(sides, value, slope=False)[0]

    def excess_and_slope(
        self, sides: np.ndarray, value: np.ndarray, *, slope: bool = True
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """The excess of the re-optimised deviance at ``value`` on each of ``sides`` (warm starts
        updated), and its derivative in the value: the deviance's partial derivative in the held
        index at the re-optimised point (envelope theorem; NaN where no finite deviance was found).

        A curve with limits is re-optimised from two starts, the last optimum of the side and
        the estimate (:meth:`_estimate_start`), both in one minimisation (rows stacked), the
        lower deviance kept (the last optimum among equals); where the two starts are the same
        point, bit for bit (the first value of a side, or a side whose optimum came from the
        estimate's start), it is minimised once."""
        r = self.requests
        count = len(sides)
        if self.has_limits:
            # a start from the estimate's branch that is the side's warm start itself, bit for bit,
            # would repeat its minimisation: it is made once
            second = self._estimate_start(sides, value)
            apart = np.flatnonzero((second != self.warm[sides]).any(axis=1))
            found_x, found_deviance = self._minimised(
                np.concatenate([sides, sides[apart]]), np.concatenate([value, value[apart]]),
                np.concatenate([self.warm[sides], second[apart]]),
            )  # fmt: skip
            x, deviance = np.stack([found_x[:count]] * 2), np.stack([found_deviance[:count]] * 2)
            x[1, apart], deviance[1, apart] = found_x[count:], found_deviance[count:]
        else:
            found_x, found_deviance = self._minimised(sides, value, self.warm[sides])
            x, deviance = found_x[None], found_deviance[None]
        pick = np.argmin(deviance, axis=0)  # the first start among equals
        best_x, best_value = x[pick, np.arange(count)], deviance[pick, np.arange(count)]
        finite = np.isfinite(best_value)
        self.warm[sides[finite]] = best_x[finite]
        if self.has_limits:
            reached = np.isfinite(deviance[1])
            self.from_estimate[sides[reached]], self.estimate_value[sides[reached]] = x[1][reached], value[reached]
        request = self.request[sides]
        excess = (best_value - r.best[request]) / r.scale[request] - r.threshold[request]
        excess = np.where(finite, excess, BEYOND)
        if not slope:
            return excess, None
        stack, forms = r.stack.take(request), _RowForms(self.curves, self.curve[request])
        rise = self._slope(stack, forms, best_x, r.imperfection[request], r.position[request])
        return excess, np.where(finite, rise / r.scale[request], np.nan)

    def _minimised(self, sides: np.ndarray, value: np.ndarray, start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The minimum of the deviance of each row (of ``sides``) with its held index at ``value``, from
        ``start`` (in the indices), and the deviance there (inf where none finite was found)."""
        r = self.requests
        request = self.request[sides]
        stack = r.stack.take(request)
        # the held index is put first (rho50 and Ep or I swap places), so that the minimiser
        # sees one column held in every row and takes no derivative along it
        order = np.tile(np.arange(r.centre.shape[1]), (len(request), 1))
        order[:, [0, 1]] = np.where(r.position[request][:, None] == 1, [1, 0], [0, 1])
        lower, upper, start = (_ordered(part, order) for part in (r.lower[request], r.upper[request], start))
        lower[:, 0] = upper[:, 0] = start[:, 0] = value
        imperfection, position = r.imperfection[request], r.position[request]
        forms = _RowForms(self.curves, self.curve[request])

        def partition(x, rows):
            indices = _ordered(x, order[rows])  # the swap is its own inverse
            return _partitions(forms.take(rows), stack.density[rows], indices, imperfection[rows])

        def derivatives(x, rows):
            indices = _ordered(x, order[rows])
            return index_derivatives(forms.take(rows), stack.density[rows], indices, imperfection[rows], position[rows])

        exact = None if self.has_limits else derivatives  # see profile_limits: why not with limits
        found = minimise_deviance(stack, partition, start, lower, upper, derivatives=exact)
        return _ordered(found.x, order), np.where(np.isfinite(found.deviance), found.deviance, np.inf)

    @staticmethod
    def _slope(stack: TracerStack, forms: _RowForms, q: np.ndarray, imperfection, held) -> np.ndarray:
        """The derivative of the binomial deviance in the held index at the indices ``q``, row by row."""
        p = np.clip(_partitions(forms, stack.density, q, imperfection), 1e-300, 1.0 - 1e-16)
        k, n = stack.sinks, stack.trials
        with np.errstate(all="ignore"):
            slope = np.where(n > 0, 2.0 * ((n - k) / (1.0 - p) - k / p), 0.0)
            return (slope * held_derivative(forms, stack.density, q, imperfection, held)).sum(axis=1)


def profile_limits(curves, requests: ProfileRequests) -> tuple[np.ndarray, np.ndarray, list[list[str]]]:
    """The lower and upper profile limits of every request, and the notes of each (none when both are found).

    Parameters
    ----------
    curves : DensityCurve or sequence of DensityCurve
        The curve of the requests, or the curves (all with limits or all without) that
        ``requests.curve`` indexes: the profiles of several curves searched together, each
        row's arithmetic its own.
    requests : ProfileRequests

    Returns
    -------
    tuple
        ``(low, high, notes)``; a limit the profile does not reach within the search range is
        NaN and a note of its request says so.

    Notes
    -----
    A plain curve's profile re-optimises one index, whose optimum is unique: its minimisations
    take the analytic derivatives of :func:`index_derivatives` and its limits are closed by
    Newton's method in the bracket (:func:`~tromplab.curves.likelihood.newton_in_bracket`, the
    excess's slope from :meth:`_Profiles.excess_and_slope`), the limits the same as by regula
    falsi to their tolerance (1e-12 relative).  A curve with limits re-optimises three indices,
    and far from the estimate (Ep of 1 g/cm3 and more, where the curve is nearly flat) the box
    holds several local minima in its corners: which one a minimisation reaches depends on its
    path, so those profiles keep the differences and both starts (the analytic derivatives
    moved two such limits of overdispersed tests, and so did dropping the start at the
    estimate within the bracket).  Their brackets are closed by Newton's method too where the
    profile crosses the bracket smoothly (:func:`_smooth_brackets`: rising at both ends, the
    chord close to the ends' slopes), about 5 re-optimisations where regula falsi took 13;
    elsewhere (a profile that jumps between local minima within the bracket, flat or falling at
    an end) by regula falsi, whose steps are those :func:`newton_in_bracket` takes without a
    slope: the limit of such a profile is the one it always was, to the last bit.
    """
    profiles = _Profiles(list(curves) if isinstance(curves, (list, tuple)) else [curves], requests)
    sides = np.arange(len(profiles.request))
    request = profiles.request
    centre = requests.centre[request, requests.position[request]]
    edge = np.where(
        profiles.direction > 0,
        requests.upper[request, requests.position[request]],
        requests.lower[request, requests.position[request]],
    )
    step = requests.step[request]
    stepping = profiles.stepping_excess if profiles.has_limits else profiles.excess
    bracket = step_out(stepping, centre, profiles.direction, np.abs(edge - centre), step, -requests.threshold[request])
    limits = np.full(len(sides), np.nan)
    bracketed = np.flatnonzero(bracket.closed)
    if bracketed.size:
        width = 2.0 * (ROOT_STEP_TOLERANCE * step[bracketed] + 2.0 * ROOT_RELATIVE_TOLERANCE * np.abs(centre[bracketed]))

        direction = profiles.direction[bracketed]
        # a curve with limits closes by Newton's steps only the brackets its profile crosses smoothly
        smooth = _smooth_brackets(profiles, bracket, bracketed) if profiles.has_limits else np.ones(len(bracketed), bool)
        profiles.trackable[bracketed[smooth]] = True

        def excess_and_slope(rows, values):
            excess, slope = profiles.excess_and_slope(bracketed[rows], values)
            return excess, np.where(smooth[rows], slope, np.nan)  # no slope: the Illinois step (regula falsi's)

        distance = newton_in_bracket(excess_and_slope, centre[bracketed], direction, bracket.take(bracketed), width,
                                     max_iterations=MAX_ROOT_ITERATIONS)  # fmt: skip
        limits[bracketed] = centre[bracketed] + direction * distance
        profiles.trackable[:] = False
        _recheck_edges(profiles, sides, limits, edge, step)
    count = len(requests.best)
    notes = [
        [
            f"the profile does not reach the {side} limit within {edge[j]:g}"
            for side, j in (("lower", i), ("upper", i + count))
            if not np.isfinite(limits[j])
        ]
        for i in range(count)
    ]
    return limits[:count], limits[count:], notes


def _smooth_brackets(profiles: _Profiles, bracket: Bracket, bracketed: np.ndarray) -> np.ndarray:
    """Which of the brackets ``bracketed`` (sides) a profile of a curve with limits crosses
    smoothly: its excess rising at both ends (in the distance from the estimate; the slopes kept
    by :meth:`_Profiles.stepping_excess`) and the chord between the ends within
    :data:`SMOOTH_CHORD_RATIO` of their slopes.  A profile that jumps from one local minimum to
    another within the bracket, or that is flat or falling at an end, fails the test: its
    bracket is closed by regula falsi, on the path the limit was validated on."""
    direction = profiles.direction[bracketed]
    inner, outer = direction * profiles.inner_slope[bracketed], direction * profiles.outer_slope[bracketed]
    closed = bracket.take(bracketed)
    with np.errstate(all="ignore"):
        chord = (closed.outer_excess - closed.inner_excess) / (closed.outer - closed.inner)
    return (
        np.isfinite(inner) & np.isfinite(outer) & np.isfinite(chord) & (inner >= 0) & (outer > 0)
        & (chord * SMOOTH_CHORD_RATIO >= np.minimum(inner, outer)) & (chord <= SMOOTH_CHORD_RATIO * np.maximum(inner, outer))
    )  # fmt: skip


def _recheck_edges(profiles: _Profiles, sides, limits, edge, step) -> None:
    """A limit found at the edge of the search range is checked once more, from the optimum
    next to it: the step out reaches the edge in one jump, from which the re-optimisation of a
    curve grown nearly into a step (Ep near 0 with limits that take the misplaced tracers) can
    stall above the profile's minimum.  Where the profile at the edge is below the threshold
    after all, the limit is not reached (NaN, said so)."""
    at_edge = np.flatnonzero(np.abs(limits - edge) <= 1e-6 * step)
    if at_edge.size:
        below = profiles.excess(sides[at_edge], edge[at_edge]) <= 0
        limits[at_edge[below]] = np.nan
