"""Comparing fits: nested models and experiments.

* :func:`nested_f_test`: does a bypass or fish-hook term improve a fit beyond chance?
  The extra-sum-of-squares F test of a reduced model nested in a full one.
* :func:`shared_fit`: did the sharpness (or the cut size) change between experiments?
  One formula fitted to several experiments at once with the shape (or ``d_cut``) shared,
  against separate fits, by the same extra-sum-of-squares test.  A significant F test
  says the data tell the values apart, not that the difference matters:
  :meth:`SharedFit.conclusion` says "equal within the margin" when the experiments'
  estimates differ by less than a relative margin of practical equivalence
  (:data:`DEFAULT_MARGIN`), however small the p-value.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import stats

from ..curves.curve_fit import CurveFit, fit_formula
from ..curves.fitting import ParameterFit, least_squares
from ..curves.formulas import get_formula
from ..curves.measured import measured_efficiency, normalised_weights
from ..curves.parameters import Parameter, d_cut_parameter
from ..errors import InputError, OptionError, expect_kind
from ..loading.points import TrompPoints
from ..options import DEFAULT_MARGIN
from ..results_contract import ResultContract


@dataclass(frozen=True)
class ExtraSumOfSquares(ResultContract):
    """Extra-sum-of-squares F test of a reduced model against a fuller one.

    Attributes
    ----------
    ssr_reduced, ssr_full : float
        Sums of squares of the reduced and the fuller model.
    df_extra : int
        Parameters the fuller model adds.
    df_full : int
        Residual degrees of freedom of the fuller model.
    F : float
        ``((ssr_reduced - ssr_full) / df_extra) / (ssr_full / df_full)`` (inf when ``ssr_full`` is 0).
    p_value : float
        Upper tail of the F distribution on ``(df_extra, df_full)`` at ``F``.
    """

    ssr_reduced: float
    ssr_full: float
    df_extra: int
    df_full: int

    @property
    def F(self) -> float:
        if self.ssr_full <= 0:
            return np.inf
        return max(self.ssr_reduced - self.ssr_full, 0.0) / self.df_extra / (self.ssr_full / self.df_full)

    @property
    def p_value(self) -> float:
        return float(stats.f.sf(self.F, self.df_extra, self.df_full))

    def needed(self, alpha: float = 0.05) -> bool:
        """True when the fuller model is needed at significance ``alpha``."""
        return self.p_value < alpha

    def summary(self) -> pd.DataFrame:
        """One row: the sums of squares, the degrees of freedom, ``F``, ``p_value`` and ``needed`` (at 0.05)."""
        row = {"ssr_reduced": self.ssr_reduced, "ssr_full": self.ssr_full, "df_extra": self.df_extra,
               "df_full": self.df_full, "F": self.F, "p_value": self.p_value, "needed": self.needed()}  # fmt: skip
        return pd.DataFrame([row])

    def _result_context(self) -> str:
        return f"Extra sum of squares: F = {self.F:.4g} on ({self.df_extra}, {self.df_full}) df, p = {self.p_value:.4g}"


def nested_f_test(reduced: CurveFit, full: CurveFit) -> ExtraSumOfSquares:
    """Whether the extra terms of ``full`` are needed beyond ``reduced`` (same points).

    ``F = ((SSR_r - SSR_f) / (p_f - p_r)) / (SSR_f / (n - p_f))``.

    Parameters
    ----------
    reduced, full : CurveFit
        Fits to the same points; ``full.formula.nests`` names ``reduced``'s formula.

    Returns
    -------
    ExtraSumOfSquares
        ``F``, ``p_value`` and ``needed(alpha)``.

    Examples
    --------
    >>> points = TrompPoints("run", [10, 20, 40, 80, 160], [0.98, 0.91, 0.62, 0.21, 0.04])
    >>> test = nested_f_test(fit_formula(points, "plitt"), fit_formula(points, "plitt_bypass"))
    >>> test.df_extra, test.df_full, round(test.p_value, 3), test.needed(0.05)
    (1, 2, 0.197, False)

    Raises
    ------
    ValueError
        When the fits are to different points, failed, or not nested.
    """
    expect_kind(reduced, CurveFit, "reduced", "a CurveFit (tromplab.fit_formula)")
    expect_kind(full, CurveFit, "full", "a CurveFit (tromplab.fit_formula)")
    if reduced.points is not full.points and not (
        np.array_equal(reduced.points.size, full.points.size)
        and np.array_equal(reduced.points.partition_fine, full.points.partition_fine)
    ):
        raise ValueError("the two fits must be to the same points")
    if not (reduced.success and full.success):
        raise ValueError("both fits must have succeeded")
    if full.formula.nests != reduced.formula.id:
        raise ValueError(f"{full.formula.id} does not nest {reduced.formula.id} (it nests {full.formula.nests})")
    extra = full.formula.n_params - reduced.formula.n_params
    return ExtraSumOfSquares(reduced.fit.ssr, full.fit.ssr, extra, full.points.n - full.formula.n_params)


#: Columns of :func:`nested_tests` beside ``experiment`` and ``formula`` (in ``fits.csv``).
NESTED_COLUMNS = ("nests", "nested_F", "nested_p")


def nested_tests(fits: Sequence[CurveFit]) -> pd.DataFrame:
    """:func:`nested_f_test` of every successful fit whose formula nests another fitted to the
    same experiment (``plitt_bypass`` against ``plitt``: is the bypass needed?).

    Returns
    -------
    pandas.DataFrame
        ``experiment, formula, nests, nested_F, nested_p``, one row per such fit (no rows when
        none was fitted with the formula it nests).
    """
    by_key = {(fit.experiment, fit.formula.id): fit for fit in fits if fit.success}
    rows = []
    for (experiment, formula_id), full in by_key.items():
        reduced = by_key.get((experiment, full.formula.nests))
        if reduced is None:
            continue
        test = nested_f_test(reduced, full)
        rows.append({"experiment": experiment, "formula": formula_id, "nests": reduced.formula.id,
                     "nested_F": test.F, "nested_p": test.p_value})  # fmt: skip
    return pd.DataFrame(rows, columns=["experiment", "formula", *NESTED_COLUMNS])


@dataclass(frozen=True)
class SharedFit(ResultContract):
    """A formula fitted to several experiments with one parameter shared.

    :meth:`report` is what ``tromplab compare`` prints; :meth:`to_frame` its table.

    Attributes
    ----------
    formula_id : str
        The formula fitted.
    shared : str
        The parameter shared by the experiments (the shape, or ``d_cut``).
    fit : ParameterFit
        The joint fit: ``shared`` and one free parameter per experiment (``<name>_<i>``).
    separate : tuple of CurveFit
        The formula fitted to each experiment alone.
    test : ExtraSumOfSquares
        The F test of the joint fit against the separate ones.
    experiments : tuple of str
        The experiments, in order.
    relative_difference : float
        Spread of the separate estimates of ``shared`` over the joint estimate.
    """

    formula_id: str
    shared: str
    fit: ParameterFit
    separate: tuple[CurveFit, ...]
    test: ExtraSumOfSquares
    experiments: tuple[str, ...]

    @property
    def relative_difference(self) -> float:
        """Largest minus smallest separate estimate of the shared parameter, over the joint
        estimate (nan when the joint estimate is 0, as km2 or kp at their lower bound)."""
        values = [fit.fit.values[self.shared] for fit in self.separate]
        joint = abs(self.fit.values[self.shared])
        return float((max(values) - min(values)) / joint) if joint > 0 else float("nan")

    def verdict(self, *, margin: float = DEFAULT_MARGIN, alpha: float = 0.05) -> str:
        """``"equal within the margin"``, ``"differ"`` or ``"undecided"``.

        ``"equal within the margin"``: the estimates differ by less than ``margin``
        (relative, :attr:`relative_difference`), whatever the p-value of the F test.
        ``"differ"``: they differ by ``margin`` or more and the F test tells them apart
        (p < ``alpha``).  ``"undecided"``: they differ by ``margin`` or more but the F test
        finds no difference: the data cannot tell whether the experiments are equal.
        """
        if self.relative_difference < margin:
            return "equal within the margin"
        return "differ" if self.test.needed(alpha) else "undecided"

    def conclusion(self, *, margin: float = DEFAULT_MARGIN, alpha: float = 0.05) -> str:
        """:meth:`verdict` in a sentence, with the relative difference and the F test.

        Examples
        --------
        >>> first = TrompPoints("run1", [10, 20, 40, 80, 160], [0.98, 0.91, 0.62, 0.21, 0.04])
        >>> second = TrompPoints("run2", [10, 20, 40, 80, 160], [0.99, 0.95, 0.60, 0.10, 0.01])
        >>> joint = shared_fit([first, second], "plitt")
        >>> joint.verdict(), joint.verdict(margin=0.5)
        ('differ', 'equal within the margin')
        >>> print(joint.conclusion())
        the experiments differ in ks: their estimates differ by 35.9 % (margin 1 %) and the F test tells them apart (p = 4.67e-07, alpha 0.05)
        """
        verdict = self.verdict(margin=margin, alpha=alpha)
        test = f"p = {self.test.p_value:.3g}, alpha {alpha:g}"
        differ = f"their estimates differ by {self.relative_difference * 100:.3g} % (margin {margin * 100:g} %)"
        if verdict == "equal within the margin":
            told = "although the F test tells them apart" if self.test.needed(alpha) else "and the F test finds no difference"
            return f"the experiments are equal within the margin in {self.shared}: {differ}, {told} ({test})"
        if verdict == "differ":
            return f"the experiments differ in {self.shared}: {differ} and the F test tells them apart ({test})"
        return (
            f"the F test finds no difference in {self.shared} ({test}), but {differ}: the data cannot tell "
            "whether the experiments are equal"
        )

    def table(self) -> pd.DataFrame:
        """Per experiment: the shared-fit parameters beside the separate fits'."""
        shape = get_formula(self.formula_id).shape_name
        rows = []
        for i, (name, separate) in enumerate(zip(self.experiments, self.separate)):
            free = "d_cut" if self.shared == shape else shape
            rows.append(
                {
                    "experiment": name,
                    f"shared_{self.shared}": self.fit.values[self.shared],
                    f"{free}_joint": self.fit.values[f"{free}_{i}"],
                    f"{free}_separate": separate.fit.values[free],
                    f"{self.shared}_separate": separate.fit.values[self.shared],
                }
            )
        return pd.DataFrame(rows)

    def to_frame(self) -> pd.DataFrame:
        """:meth:`table`: per experiment, the shared-fit parameters beside the separate fits'."""
        return self.table()

    def summary(self, *, margin: float = DEFAULT_MARGIN, alpha: float = 0.05) -> pd.DataFrame:
        """One row: the formula, the shared parameter and its joint estimate, the F test, the
        relative difference and the :meth:`verdict` at ``margin`` and ``alpha``."""
        row = {"formula": self.formula_id, "shared": self.shared, "experiments": ", ".join(self.experiments),
               "estimate": self.fit.values[self.shared], "F": self.test.F, "p_value": self.test.p_value,
               "relative_difference": self.relative_difference, "verdict": self.verdict(margin=margin, alpha=alpha)}  # fmt: skip
        return pd.DataFrame([row])

    def _result_context(self) -> str:
        return f"{self.formula_id} fitted to {', '.join(self.experiments)} with {self.shared} shared"

    def report(self, *, margin: float = DEFAULT_MARGIN, alpha: float = 0.05) -> str:
        """What ``tromplab compare`` prints: the table, the F test and the :meth:`conclusion`."""
        table = self.table().to_string(index=False, float_format=lambda v: f"{v:.4g}")
        test = self.test
        f_test = f"Extra sum of squares: F = {test.F:.4g} on ({test.df_extra}, {test.df_full}) df, p = {test.p_value:.4g}"
        return f"{self._result_context()}\n{table}\n\n{f_test}\n{self.conclusion(margin=margin, alpha=alpha)}"


def shared_fit(experiments: Sequence[TrompPoints], formula, *, shared: str = "shape") -> SharedFit:
    """Fit ``formula`` to all experiments at once with the shape (or ``d_cut``) shared.

    The separate fits have ``2k`` parameters for ``k`` experiments, the joint fit
    ``k + 1``; the extra-sum-of-squares test with ``k - 1`` and ``N - 2k`` degrees of
    freedom tells whether the experiments differ in the shared parameter ("did the
    sharpness change between these runs").

    Parameters
    ----------
    experiments : sequence of TrompPoints
        Two or more experiments.
    formula : Formula or str
        One of the nine paper formulas (no extras).
    shared : {"shape", "d_cut"}
        The parameter held common to all experiments.

    Returns
    -------
    SharedFit
        The joint fit, the separate fits and their extra-sum-of-squares ``test``.

    Examples
    --------
    >>> first = TrompPoints("run1", [10, 20, 40, 80, 160], [0.98, 0.91, 0.62, 0.21, 0.04])
    >>> second = TrompPoints("run2", [10, 20, 40, 80, 160], [0.99, 0.95, 0.60, 0.10, 0.01])
    >>> joint = shared_fit([first, second], "plitt", shared="shape")
    >>> joint.test.needed(0.05), joint.table()["ks_separate"].round(2).tolist()
    (True, [2.62, 3.72])
    """
    formula = get_formula(formula)
    _check_shared_fit_inputs(experiments, formula, shared)
    shape = formula.shape_name
    shared_name = shape if shared == "shape" else "d_cut"
    free = "d_cut" if shared == "shape" else shape
    separate = tuple(fit_formula(points, formula) for points in experiments)
    failed = [fit.experiment for fit in separate if not fit.success]
    if failed:
        raise InputError(f"the separate fit failed for experiment(s) {', '.join(failed)}")
    contexts = [{"measured_efficiency": measured_efficiency(p)} if formula.context_from_efficiency else {} for p in experiments]
    root_weights = [np.sqrt(normalised_weights(p)) for p in experiments]
    sizes = np.concatenate([p.size for p in experiments])
    specs = [Parameter(shared_name, *(_bounds(formula, shared_name, sizes)))]
    specs += [Parameter(f"{free}_{i}", *_bounds(formula, free, p.size)) for i, p in enumerate(experiments)]

    def residual(values):
        parts = []
        for i, (points, context, root) in enumerate(zip(experiments, contexts, root_weights)):
            params = {shared_name: values[shared_name], free: values[f"{free}_{i}"]}
            parts.append(root * (formula(points.size, params["d_cut"], params[shape], **context) - points.partition_fine))
        return np.concatenate(parts)

    starts = []
    for pick in range(len(separate)):  # each experiment's own value of the shared parameter as a start
        start = {shared_name: separate[pick].fit.values[shared_name]}
        start.update({f"{free}_{i}": fit.fit.values[free] for i, fit in enumerate(separate)})
        starts.append(start)
    mean_start = {shared_name: float(np.mean([fit.fit.values[shared_name] for fit in separate]))}
    starts.append({**starts[0], **mean_start})
    fit = least_squares(residual, specs, starts)
    n_total = sum(p.n for p in experiments)
    k = len(experiments)
    ssr_separate = float(sum(f.fit.ssr for f in separate))
    test = ExtraSumOfSquares(fit.ssr, ssr_separate, k - 1, n_total - 2 * k)
    return SharedFit(formula.id, shared_name, fit, separate, test, tuple(p.experiment for p in experiments))


def _check_shared_fit_inputs(experiments, formula, shared) -> None:
    if isinstance(experiments, (str, bytes)) or not isinstance(experiments, Sequence):
        raise TypeError(f"experiments must be a sequence of TrompPoints, got {type(experiments).__name__}")
    for position, points in enumerate(experiments):
        expect_kind(points, TrompPoints, f"experiments[{position}]", "a TrompPoints")
    if len(experiments) < 2:
        raise InputError("a shared fit needs at least two experiments")
    names = [points.experiment for points in experiments]
    repeated = sorted({name for name in names if names.count(name) > 1})
    if repeated:  # a joint fit of an experiment with itself tests nothing (F = 0, p = 1)
        raise InputError(
            f"experiment(s) {', '.join(repr(name) for name in repeated)} given more than once; compare distinct experiments"
        )
    if formula.extras:
        raise InputError("shared fits are offered for the two-parameter formulas")
    if shared not in ("shape", "d_cut"):
        raise OptionError("shared", f"must be 'shape' or 'd_cut', got {shared!r}")


def _bounds(formula, name, sizes):
    if name == "d_cut":
        return d_cut_parameter(sizes).bounds
    return formula.shape_parameter.bounds
