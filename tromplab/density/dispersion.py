r"""The quasi-binomial scale of tracer counts and the profile threshold that goes with it.

Tracers of one density often share a fate (they travel in clusters, meet the same eddy):
their counts then vary more than binomially, and binomial intervals are too narrow.  The
rules that decide how the intervals of a binomial fit take that into account are here, so
that every fit of tracer counts (one curve at a time, or many at once) applies the same ones:

- :func:`quasi_binomial_scale`: the scale :math:`\phi` the deviance differences are divided
  by, from the Pearson dispersion :math:`X^2 / (n - p)` of the fit, and whether that scale
  was estimated from the data;
- :func:`profile_threshold`: the quantile a profile's scaled deviance difference is compared
  with: :math:`\chi^2_1` when the scale is known (binomial, :math:`\phi = 1`) and
  :math:`F_{1, n - p}` when it was estimated (quasi-likelihood: the estimate of
  :math:`\phi` on :math:`n - p` degrees of freedom widens the interval as Student's t widens
  a normal one; McCullagh & Nelder 1989, sect. 9.3 and 4.5);
- :func:`pool_dispersion` and :func:`interval_rule`: the policy, :data:`SCALE_POLICY`
  (``"file_floor"``).  The tests of one file share a device and a way of counting, so their
  dispersions estimate one :math:`\phi`: pooled, :math:`\sum X^2 / \sum (n - p)` over the
  file's fits of a curve, it is estimated on many degrees of freedom.  A test's interval is
  the wider of the test's own quasi-likelihood interval (:math:`\max(1, X^2/(n-p))` against
  :math:`F_{1, n-p}`, the ``"at_least_one"`` rule) and the interval on the file's pooled
  scale (against :math:`F_{1, \sum (n-p)}`); a file of one test gets its own.

Why a floor and not the test's own scale alone: with 7 densities a test's dispersion rests on
5 degrees of freedom, and about one overdispersed test in seven (143 of 1,000 at 7 densities,
30 tracers, beta precision 10) shows counts that look cleaner than binomial
(:math:`X^2/(n-p) \le 1`), so its interval stays binomial while the truth is 3.6 times as
variable; such tests were most of the misses of the ``"at_least_one"`` rule (91.5 % coverage of
rho50 and 90.4 % of Ep there; 96.0 % and 95.2 % with the file's floor, in files of ten
tests).  Why not the pooled scale alone: the Pearson :math:`X^2` of a curve fitted to 7 points
underestimates the beta-binomial :math:`\phi` by about 13 % (the fit absorbs part of the
variation), so in a pilot simulation the pooled scale alone covered about 92-93 %; and a file
whose tests differ would give its most dispersed tests too small a scale.  The floor never
narrows an interval of the rule before it, and where the file's tests are binomial the pooled
scale is about 1 (a small cost: median widths 2-5 % larger than the rule before).  The coverage and the cost
in width, measured through the CSV reader (``benchmarks/overdispersion_coverage.py``), are in
``docs/density_columns.md``.

The earlier rules stay available for the studies: ``"pearson_test"`` (the scale only where the
Pearson test rejects at 5 %) and ``"binomial"`` (always 1).

:func:`quasi_binomial_scale`, :func:`profile_threshold` and :func:`pearson_rejects` take
numbers or numpy arrays (one value per fit).

References
----------
.. [McCullagh1989] McCullagh P., Nelder J.A. (1989). *Generalized Linear Models*, 2nd ed.
   Chapman & Hall, London (sect. 4.5: overdispersion and the quasi-binomial scale; sect. 9.3:
   quasi-likelihood, the deviance difference over the estimated dispersion against F).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from ..statistics.distributions import chi2_ppf, f_ppf

#: Level of the Pearson test of overdispersion (the ``overdispersed`` column, the QAIC ranking).
OVERDISPERSION_LEVEL = 0.05
#: How the intervals' scale is chosen (:func:`quasi_binomial_scale`).
SCALE_POLICIES = ("at_least_one", "pearson_test", "binomial")
#: The intervals' policy (:func:`interval_rule`): the test's own rule, floored by the file's pooled scale.
SCALE_POLICY = "file_floor"


@dataclass(frozen=True)
class QuasiScale:
    """The scale of a binomial fit's intervals.

    Attributes
    ----------
    scale : float or numpy.ndarray
        :math:`\\phi`: what the deviance differences of the profiles are divided by (>= 1).
    estimated : bool or numpy.ndarray
        True where :math:`\\phi` was estimated from the data (its threshold is then
        :math:`F_{1, n-p}`), False where it is the binomial 1.
    """

    scale: float | np.ndarray
    estimated: bool | np.ndarray


def pearson_rejects(dispersion, df_resid, *, level: float = OVERDISPERSION_LEVEL):
    r"""True where the Pearson test rejects the binomial variance: :math:`X^2 > \chi^2_{n-p}(1 - \text{level})`.

    Examples
    --------
    >>> bool(pearson_rejects(2.5, 5)), bool(pearson_rejects(2.0, 5))  # chi2(5) at 0.95 is 11.07
    (True, False)
    """
    dispersion, df_resid = np.asarray(dispersion, float), np.asarray(df_resid, float)
    with np.errstate(invalid="ignore"):
        rejects = (df_resid > 0) & (dispersion * df_resid > chi2_ppf(1 - level, np.maximum(df_resid, 1)))
    return rejects if rejects.ndim else bool(rejects)


def quasi_binomial_scale(dispersion, df_resid, *, policy: str = "at_least_one") -> QuasiScale:
    r"""The scale :math:`\phi` of a binomial fit's intervals, from its Pearson dispersion :math:`X^2/(n - p)`.

    ``policy``:

    - ``"at_least_one"`` (the default, a test's own rule in :func:`interval_rule`):
      :math:`\phi = \max(1, X^2/(n-p))`, estimated wherever it exceeds 1 (the counts are never
      taken as less variable than binomial);
    - ``"pearson_test"``: the dispersion where the Pearson test rejects at 5 %, else 1;
    - ``"binomial"``: always 1.

    Without residual degrees of freedom (or with a NaN dispersion) the scale is 1.

    Examples
    --------
    >>> quasi_binomial_scale(2.0, 5)
    QuasiScale(scale=2.0, estimated=True)
    >>> quasi_binomial_scale(0.6, 5)
    QuasiScale(scale=1.0, estimated=False)
    >>> quasi_binomial_scale(2.0, 5, policy="pearson_test")  # X2 = 10 < 11.07: not rejected
    QuasiScale(scale=1.0, estimated=False)
    """
    if policy not in SCALE_POLICIES:
        raise ValueError(f"unknown scale policy {policy!r}: one of {', '.join(SCALE_POLICIES)}")
    dispersion, df_resid = np.asarray(dispersion, float), np.asarray(df_resid, float)
    usable = (df_resid > 0) & np.isfinite(dispersion)
    if policy == "at_least_one":
        estimated = usable & (np.where(usable, dispersion, 0.0) > 1.0)
    elif policy == "pearson_test":
        estimated = usable & np.asarray(pearson_rejects(np.where(usable, dispersion, 0.0), df_resid))
    else:
        estimated = np.zeros_like(usable)
    scale = np.where(estimated, dispersion, 1.0)
    if scale.ndim == 0:
        return QuasiScale(float(scale), bool(estimated))
    return QuasiScale(scale, estimated)


def profile_threshold(ci, df_resid, estimated):
    r"""The quantile a profile's deviance difference over the scale is compared with, at level ``ci``.

    :math:`\chi^2_1(\text{ci})` when the scale is known (``estimated`` False) and
    :math:`F_{1, n-p}(\text{ci})` when it was estimated on ``df_resid`` degrees of freedom (the
    quasi-likelihood profile, McCullagh & Nelder 1989, sect. 9.3).  The square root is the
    quantile of a two-sided Wald interval at ``ci``: the normal's, or Student's t on
    ``df_resid`` degrees of freedom.

    Examples
    --------
    >>> round(profile_threshold(0.95, 5, False), 3), round(profile_threshold(0.95, 5, True), 3)
    (3.841, 6.608)
    """
    df_resid, estimated = np.asarray(df_resid, float), np.asarray(estimated, bool)
    known = chi2_ppf(ci, 1)
    with np.errstate(invalid="ignore"):
        quasi = f_ppf(ci, 1, np.where(estimated & (df_resid > 0), df_resid, 1.0))
    threshold = np.where(estimated, np.where(df_resid > 0, quasi, np.nan), known)
    return float(threshold) if threshold.ndim == 0 else threshold


@dataclass(frozen=True)
class PooledDispersion:
    r"""The Pearson dispersion of several binomial fits of one curve, pooled: :math:`\sum X^2 / \sum (n - p)`.

    Attributes
    ----------
    dispersion : float
        The pooled dispersion (NaN without degrees of freedom).
    df_resid : int
        :math:`\sum (n - p)`: the degrees of freedom it rests on.
    fits : int
        How many fits were pooled (those with degrees of freedom and a finite dispersion).
    """

    dispersion: float
    df_resid: int
    fits: int


def pool_dispersion(dispersions, dfs_resid) -> PooledDispersion:
    r"""The Pearson dispersions :math:`X^2_i / (n_i - p)` of fits pooled into one: :math:`\sum X^2_i / \sum (n_i - p)`.

    Fits without degrees of freedom or with a NaN dispersion do not count.

    Examples
    --------
    >>> pool_dispersion([2.0, 0.5, float("nan")], [5, 5, 0])
    PooledDispersion(dispersion=1.25, df_resid=10, fits=2)
    """
    dispersions, dfs_resid = np.asarray(dispersions, float), np.asarray(dfs_resid, float)
    usable = (dfs_resid > 0) & np.isfinite(dispersions)
    total_df = float(dfs_resid[usable].sum())
    pooled = float((dispersions[usable] * dfs_resid[usable]).sum() / total_df) if total_df > 0 else math.nan
    return PooledDispersion(pooled, int(total_df), int(usable.sum()))


@dataclass(frozen=True)
class IntervalRule:
    """How the profile intervals of one binomial fit are made at one level.

    Attributes
    ----------
    scale : float
        :math:`\\phi` the deviance differences are divided by (>= 1).
    threshold : float
        The quantile the scaled difference is compared with (:func:`profile_threshold`).
    df_resid : float
        The degrees of freedom of the scale's estimate (those of the F threshold; 0 on the binomial scale).
    source : str
        ``"binomial"`` (:math:`\\phi = 1`), ``"test"`` (the test's own dispersion) or ``"file"``
        (the dispersion pooled over the file's fits of the curve).
    """

    scale: float
    threshold: float
    df_resid: float
    source: str


def interval_rule(dispersion: float, df_resid: int, ci: float, pooled: PooledDispersion | None = None) -> IntervalRule:
    r"""The scale and threshold of a binomial fit's profile intervals at level ``ci`` by :data:`SCALE_POLICY`.

    The wider of two quasi-likelihood intervals: the test's own (:func:`quasi_binomial_scale`,
    ``"at_least_one"``, with :func:`profile_threshold`) and the one on the scale ``pooled`` over
    the file's fits of the curve, floored at 1, against :math:`F_{1, \sum(n-p)}`.  The width of a
    profile interval grows with the product scale times threshold, so the rule with the larger
    product is taken.  Without ``pooled`` (or with a pool of one fit) the test's own rule.

    Examples
    --------
    >>> interval_rule(0.6, 5, 0.95)  # cleaner than binomial, alone: the binomial interval
    IntervalRule(scale=1.0, threshold=3.841458820694124, df_resid=0, source='binomial')
    >>> rule = interval_rule(0.6, 5, 0.95, PooledDispersion(3.0, 50, 10))  # its file is overdispersed
    >>> rule.source, rule.scale, round(rule.threshold, 3)
    ('file', 3.0, 4.034)
    >>> interval_rule(5.0, 5, 0.95, PooledDispersion(3.0, 50, 10)).source  # 5 x 6.61 > 3 x 4.03
    'test'
    """
    try:  # a file's fits ask for the rule of each fit again and again (per quantity, profile and note)
        return _remembered_rule(dispersion, df_resid, ci, pooled)
    except TypeError:  # arguments that cannot be remembered (arrays): the rule itself
        return _interval_rule(dispersion, df_resid, ci, pooled)


def _interval_rule(dispersion, df_resid, ci, pooled) -> IntervalRule:
    own = quasi_binomial_scale(dispersion, df_resid)
    rule = IntervalRule(
        own.scale,
        profile_threshold(ci, df_resid, own.estimated),
        df_resid if own.estimated else 0,
        "test" if own.estimated else "binomial",
    )
    if pooled is None or pooled.fits < 2:
        return rule
    shared = quasi_binomial_scale(pooled.dispersion, pooled.df_resid)
    if not shared.estimated:
        return rule
    on_file = IntervalRule(shared.scale, profile_threshold(ci, pooled.df_resid, True), pooled.df_resid, "file")
    return on_file if on_file.scale * on_file.threshold > rule.scale * rule.threshold else rule


_remembered_rule = functools.lru_cache(maxsize=4096, typed=True)(_interval_rule)
