"""The one fitting layer of tromplab: bounded least squares through lmfit.

Every fit in the package - separation curves, sieve identification, process models -
goes through :func:`least_squares`.  It runs lmfit's trust-region-reflective solver from
each of several starting points, keeps the lowest sum of squares, and always returns a
:class:`ParameterFit`, also when every start failed (``success=False`` with the reason).
This is the only module that imports lmfit.
"""

from __future__ import annotations

import ast
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import lmfit
import numpy as np

from ..errors import InputError
from .likelihood import on_bound
from .parameters import Parameter


@dataclass(frozen=True)
class ParameterFit:
    """Result of one least-squares fit.

    Attributes
    ----------
    values, stderr : dict
        Best-fit values and their standard errors (nan where lmfit could not estimate
        the covariance, for example at a bound).
    ssr : float
        Sum of squared (weighted) residuals at the optimum.
    n_points : int
        Number of residuals.
    success : bool
        False when no start converged to a finite optimum.
    message : str
        Solver message, or the reason of the failure.
    at_bound : tuple of str
        Parameters that ended on a bound (their standard errors are unreliable).
    n_starts : int
        How many starting points were tried.
    raw : lmfit.minimizer.MinimizerResult or None
        The best lmfit result, for power users (confidence intervals, reports).
    """

    names: tuple[str, ...]
    values: dict[str, float]
    stderr: dict[str, float]
    ssr: float
    n_points: int
    success: bool
    message: str
    at_bound: tuple[str, ...] = ()
    n_starts: int = 0
    nfev: int = 0
    covariance: np.ndarray | None = field(default=None, repr=False, compare=False)
    residual: np.ndarray | None = field(default=None, repr=False, compare=False)
    raw: object | None = field(default=None, repr=False, compare=False)
    minimizer: object | None = field(default=None, repr=False, compare=False)

    @property
    def n_params(self) -> int:
        return len(self.names)

    def __getstate__(self):
        # The lmfit Minimizer holds the residual closure, which cannot be pickled; a result
        # that travelled (process pool, saved batch) keeps its values, covariance and the
        # raw lmfit result, and recomputes profile intervals only where it was made.
        state = dict(self.__dict__)
        state["minimizer"] = None
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)

    def information_criteria(self) -> dict[str, float]:
        """AIC, AICc and BIC from the Gaussian likelihood with the variance profiled out.

        .. math::

            AIC = n \\ln(SSR/n) + 2k, \\quad AICc = AIC + \\frac{2k(k+1)}{n-k-1}, \\quad
            BIC = n \\ln(SSR/n) + k \\ln n

        ``k = n_params + 1`` counts the error variance as an estimated parameter, as
        Burnham & Anderson (2002, section 2.2) require for least squares
        (lmfit counts the fitted parameters only).  The extra 1 is a constant shift of AIC
        and BIC for a given ``n`` but changes the AICc correction, and so the comparison of
        curves with different numbers of parameters.  AICc is infinite when
        ``n <= k + 1``.

        References
        ----------
        Burnham, K. P. and Anderson, D. R. (2002). *Model Selection and Multimodel
        Inference*, 2nd ed. Springer, New York.
        """
        n, k = self.n_points, self.n_params + 1
        if not self.success or n <= 0 or self.ssr <= 0:
            return {"aic": np.nan, "aicc": np.nan, "bic": np.nan}
        core = n * np.log(self.ssr / n)
        aic = core + 2 * k
        aicc = aic + (2 * k * (k + 1) / (n - k - 1) if n - k - 1 > 0 else np.inf)
        return {"aic": float(aic), "aicc": float(aicc), "bic": float(core + k * np.log(n))}

    def confidence_intervals(self, level: float = 0.95) -> dict[str, tuple[float, float]]:
        """Wald intervals ``value +- t(1 - (1-level)/2; n - k) * stderr`` per parameter.

        nan where the standard error is unknown.  Profile-likelihood intervals are
        available from lmfit on :attr:`raw` for power users.
        """
        from scipy import stats

        dof = self.n_points - self.n_params
        if dof <= 0:
            return {name: (np.nan, np.nan) for name in self.names}
        half = stats.t.ppf(0.5 + level / 2.0, dof)
        return {
            name: (self.values[name] - half * self.stderr[name], self.values[name] + half * self.stderr[name])
            for name in self.names
        }

    def profile_intervals(self, level: float = 0.95, names: Sequence[str] | None = None) -> dict[str, tuple[float, float]]:
        """Profile-likelihood intervals from lmfit's ``conf_interval`` (F test on the sum of squares).

        nan for a parameter whose profile stops at a bound or does not converge (lmfit
        warns and returns a point short of the level there).
        """
        names = list(names or self.names)
        missing = {name: (np.nan, np.nan) for name in names}
        if not self.success or self.minimizer is None:
            return missing
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                table = lmfit.conf_interval(self.minimizer, self.raw, p_names=names, sigmas=[level], maxiter=400)
            except (ValueError, ArithmeticError, lmfit.minimizer.MinimizerException):  # no covariance, singular profile
                return missing
        # lmfit warns, and returns a point short of the level, when a profile stops at a bound
        unreliable = {name for name in names for w in caught if f"prob({name}=" in str(w.message)}
        out = {}
        for name in names:
            rows = table[name]
            low, high = rows[0][1], rows[-1][1]
            usable = name not in unreliable
            out[name] = (
                float(low) if usable and np.isfinite(low) else np.nan,
                float(high) if usable and np.isfinite(high) else np.nan,
            )
        return out

    @classmethod
    def failed(cls, specs: Sequence[Parameter], n_points: int, message: str, n_starts: int = 0) -> ParameterFit:
        names = tuple(s.name for s in specs)
        nan = {name: np.nan for name in names}
        return cls(names, dict(nan), dict(nan), np.nan, n_points, False, message, n_starts=n_starts)


def parameters_at_bounds(specs, values: dict) -> tuple[str, ...]:
    """Names of the parameters whose fitted values sit on a bound (:func:`on_bound`)."""
    return tuple(s.name for s in specs if on_bound(values[s.name], s.lower) or on_bound(values[s.name], s.upper))


def least_squares(
    residual: Callable[[Mapping[str, float]], np.ndarray],
    specs: Sequence[Parameter],
    starts: Sequence[Mapping[str, float]],
    *,
    max_nfev: int = 2000,
) -> ParameterFit:
    """Minimise ``sum(residual(values)**2)`` within the bounds of ``specs``.

    Parameters
    ----------
    residual : callable
        Maps a ``{name: value}`` mapping to the residual vector.
    specs : sequence of Parameter
        Names and bounds of the fitted parameters.
    starts : sequence of mapping
        Starting points; each is clipped into the bounds.  The best optimum is kept.
    max_nfev : int
        Function-evaluation budget per start.

    Returns
    -------
    ParameterFit
        Never raises for a failing fit: ``success`` is False and ``message`` says why.

    Examples
    --------
    >>> x = np.linspace(0, 1, 5)
    >>> fit = least_squares(lambda p: p["a"] * x + p["b"] - (2 * x + 1),
    ...                     [Parameter("a"), Parameter("b")], [{"a": 0.0, "b": 0.0}])
    >>> round(fit.values["a"], 6), round(fit.values["b"], 6), fit.success
    (2.0, 1.0, True)
    """
    names = [s.name for s in specs]
    best, failures = _best_of_starts(residual, specs, starts, max_nfev)
    if best is None:
        detail = "; ".join(dict.fromkeys(failures)) or "no starting point given"
        return ParameterFit.failed(specs, 0, f"fit failed from every start: {detail}", len(starts))
    ssr, result, minimizer = best
    n_points = result.residual.size
    values = {name: float(result.params[name].value) for name in names}
    stderr = {name: _stderr(result.params[name]) for name in names}
    at_bound = parameters_at_bounds(specs, values)
    return ParameterFit(
        names=tuple(names),
        values=values,
        stderr=stderr,
        ssr=ssr,
        n_points=n_points,
        success=bool(result.success),
        message=str(result.message),
        at_bound=at_bound,
        n_starts=len(starts),
        nfev=int(result.nfev),
        covariance=result.covar,
        residual=np.asarray(result.residual),
        raw=result,
        minimizer=minimizer,
    )


def _best_of_starts(residual, specs: Sequence[Parameter], starts, max_nfev: int):
    """``(ssr, lmfit result, minimizer)`` of the lowest finite optimum over ``starts`` (None when
    every start failed), and why each failing start failed."""
    names = [s.name for s in specs]

    def objective(params: lmfit.Parameters) -> np.ndarray:
        return np.asarray(residual({name: params[name].value for name in names}), dtype=float)

    best = None
    failures = []
    for start in starts:
        params = lmfit.Parameters()
        for spec in specs:
            params.add(spec.name, value=spec.clip(start[spec.name]), min=spec.lower, max=spec.upper)
        minimizer = lmfit.Minimizer(objective, params)
        try:
            # lmfit takes the sqrt of the covariance's diagonal, negative where the fit does not
            # determine a parameter: its stderr is then NaN, which the fit's notes say in words
            with np.errstate(invalid="ignore"):
                result = minimizer.minimize(method="least_squares", max_nfev=max_nfev)
        except (ValueError, FloatingPointError, ArithmeticError) as error:
            failures.append(str(error))
            continue
        ssr = float(np.sum(result.residual**2))
        if not np.isfinite(ssr):
            failures.append("non-finite sum of squares")
            continue
        if best is None or ssr < best[0]:
            best = (ssr, result, minimizer)
    return best, failures


def _stderr(param: lmfit.Parameter) -> float:
    return float(param.stderr) if param.stderr is not None else float("nan")


def expression_function(expression: str, variables: Sequence[str]) -> tuple[Callable[..., np.ndarray], tuple[str, ...]]:
    """Turn a formula such as ``"c0 + c1 * l / D"`` into a function and its parameter names.

    ``variables`` are the independent variables; every other name in the expression that
    is not a numpy function becomes a fitted parameter.  Evaluated with asteval (lmfit's
    safe expression interpreter), not Python's ``eval``.

    Examples
    --------
    >>> f, names = expression_function("c0 + c1 * l / D", ["l", "D"])
    >>> names, float(f(l=2.0, D=1.0, c0=1.0, c1=0.5))
    (('c0', 'c1'), 2.0)
    """
    from asteval import Interpreter

    names = _checked_expression_names(expression, variables)
    interpreter = Interpreter(minimal=True, use_numpy=True)
    interpreter.symtable.update({name: getattr(np, name) for name in EXPRESSION_FUNCTIONS})
    if not names:
        raise InputError(f"the expression {expression!r} has no parameter to fit")

    def evaluate(**values):
        interpreter.symtable.update({k: np.asarray(v, dtype=float) for k, v in values.items()})
        result = interpreter.eval(expression, show_errors=False, raise_errors=True)
        return np.asarray(result, dtype=float)

    return evaluate, tuple(names)


#: numpy functions and constants an expression may use (:func:`expression_function`).
EXPRESSION_FUNCTIONS = (
    "exp",
    "expm1",
    "log",
    "log10",
    "log1p",
    "sqrt",
    "abs",
    "sin",
    "cos",
    "tan",
    "arctan",
    "sinh",
    "cosh",
    "tanh",
    "power",
    "minimum",
    "maximum",
    "pi",
)
_EXPRESSION_NODES = (
    ast.Expression,
    ast.BinOp,
    ast.UnaryOp,
    ast.Add,
    ast.Sub,
    ast.Mult,
    ast.Div,
    ast.Pow,
    ast.USub,
    ast.UAdd,
    ast.Constant,
    ast.Name,
    ast.Load,
    ast.Call,
)


def _checked_expression_names(expression: str, variables: Sequence[str]) -> tuple[str, ...]:
    """The parameter names of a safe arithmetic expression; :class:`InputError` otherwise."""
    if not isinstance(expression, str) or len(expression) > 1000:
        raise InputError("the expression must be text of at most 1000 characters")
    try:
        tree = ast.parse(expression.strip(), mode="eval")
    except SyntaxError as error:
        raise InputError(f"cannot parse the expression {expression!r}: {error.msg}") from None
    names = []
    for node in ast.walk(tree):
        if not isinstance(node, _EXPRESSION_NODES):
            raise InputError(
                f"the expression {expression!r} may use only arithmetic, numbers, the variables "
                f"{', '.join(variables)} and the functions {', '.join(EXPRESSION_FUNCTIONS)}; "
                f"'{ast.unparse(node) if isinstance(node, ast.expr) else type(node).__name__}' is not allowed"
            )
        if isinstance(node, ast.Constant) and (isinstance(node.value, bool) or not isinstance(node.value, (int, float))):
            raise InputError(f"the expression {expression!r} may hold only numbers as constants, not {node.value!r}")
        if isinstance(node, ast.Call):
            if not (isinstance(node.func, ast.Name) and node.func.id in EXPRESSION_FUNCTIONS) or node.keywords:
                raise InputError(
                    f"the expression {expression!r} calls '{ast.unparse(node.func)}'; allowed functions: "
                    f"{', '.join(EXPRESSION_FUNCTIONS)} (positional arguments only)"
                )
        if isinstance(node, ast.Name):
            if node.id.startswith("_"):
                raise InputError(f"the expression {expression!r} uses the name '{node.id}'; names may not start with '_'")
            if node.id not in variables and node.id not in EXPRESSION_FUNCTIONS:
                names.append(node.id)
    return tuple(dict.fromkeys(names))
