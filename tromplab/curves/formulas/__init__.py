"""The registry of separation-curve formulas: the nine of Shuvalov et al. (2018) and more.

Every formula is written in the relative size ``x = size / d_cut`` and returns the
partition number *to the fine product* ``phi(x)``, so that ``phi(1) = 0.5``.  Each one
is declared once, in :data:`FORMULAS`, together with everything the rest of the
package needs to know about it: the name and bounds of its shape parameter, the slope
at the cut, the shape that gives a requested slope (the paper's "equal sharpness"
families of Fig. 1 and 2), its equation number and its citation.  Fitting, screening,
ranking, plots and tests iterate over this registry; adding a formula touches this
package only (plus its reference rows in the tests).

The package holds one module per group, and this module looks the formulas up:
``records`` (the :class:`Formula` and :class:`MovingBreak` records), ``paper`` (the nine
formulas (3)-(11), :data:`FORMULAS`), ``extended`` (bypass and fish-hook,
:data:`EXTENDED_FORMULAS`) and ``other`` (the curves of other tools,
:data:`OTHER_FORMULAS`).  Import every name from ``tromplab.curves.formulas``: the modules
inside may move.

References
----------
.. [Shuvalov2018] Shuvalov S.I., Novoseltseva S.S., Zhukov V.P. (2018). Justifying the
   choice of a dependence for the Tromp separation curve approximation. *Vestnik IGEU*
   6, 15-23. doi:10.17588/2072-2672.2018.6.015-023
"""

from __future__ import annotations

import inspect
from collections.abc import Iterable, Mapping
from functools import cache

import numpy as np
import scipy

from .extended import (
    BYPASS,
    EXTENDED_FORMULAS,
    FISHHOOK,
    KELSALL_1953,
    NAPIER_MUNN_1996,
    PLITT_1976,
    whiten,
    whiten_beta_star,
    with_bypass,
)
from .other import (
    DYSSOL_2020,
    KING_2001,
    LN3,
    OTHER_FORMULAS,
    TEIPEL_HENNIG_ALPHA,
    logistic_linear,
    normal_linear,
    teipel_hennig,
)
from .paper import (  # noqa: F401 (checked against by tests)
    FORMULAS,
    LUCKIE_AUSTIN_1972,
    LUCKIE_AUSTIN_BREAK,
    LYNCH_RAO_1975,
    MOLERUS_1967,
    MOLERUS_HOFFMANN_1969,
    OGAWA,
    PLITT_1971,
    ROSIN_RAMMLER_1933,
    SHUVALOV_1992,
    SHUVALOV_BREAK,
    NoBreakPointError,
    lognormal,
    luckie_austin,
    lynch,
    lynch_at,
    molerus,
    molerus_hoffmann,
    ogawa_allen,
    plitt,
    plitt_efficiency,
    rosin_rammler,
    rosin_rammler_area,
    rosin_rammler_plateau,
    shuvalov,
    shuvalov_break,
    shuvalov_breaks,
    shuvalov_kink,
    with_plateau,
)
from .records import FORMULAS_BY_ID, LN2, SHUVALOV_2018, Formula, MovingBreak

#: Names that mean different curves in different tools (printed by ``tromplab formulas``).
NAME_CLASHES = (
    "'Plitt' in hydrocyclone models (Plitt 1976) and in Dyssol's Screen unit is tromplab's rosin_rammler "
    "(5) (with bypass: rosin_rammler_bypass), written to the coarse product as 1 - exp(-0.693 (d/d50)^m); "
    "tromplab's plitt (7) is Plitt's 1971 log-logistic 1/(1 + x^ks).",
    "'Whiten' in JKSimMet and Napier-Munn et al. (1996) is tromplab's whiten (alpha, beta, beta*, d50c, C = 1 - bypass, "
    "to the fine product); a plain 'Whiten' curve without beta (to the coarse product, (e^(alpha x) - 1)/(e^(alpha x) + "
    "e^alpha - 2)) is tromplab's lynch (6).",
    "'Napier-Munn' partition in some geometallurgy tools is tromplab's logistic: 1/(1 + exp(1.099 (d50 - d)/Ep)) to the "
    "coarse product.",
    "'Molerus & Hoffmann' in Dyssol is tromplab's molerus_hoffmann (4) with alpha = km2; 'Probability' is normal "
    "(Mean = d_cut, Deviation = sigma_rel d_cut, summed over the class grid).",
)
ALL_FORMULAS = FORMULAS + EXTENDED_FORMULAS + OTHER_FORMULAS

FORMULAS_BY_ID.update((formula.id, formula) for formula in ALL_FORMULAS)
_BY_EQUATION = {formula.equation: formula for formula in FORMULAS}


#: Names the expression texts may use besides x, the parameters and derived variables.
EXPRESSION_FUNCTIONS = ("exp", "ln", "erfc", "sqrt", "max", "pi", "ln2")


def evaluate_expression(text: str, values: Mapping[str, object], functions: Mapping[str, object] | None = None):
    """Evaluate a registry expression text (``expression`` or ``slope_expression``).

    The texts are written for readers - ``^`` is a power, ``ln`` the natural log - and
    are evaluated here with asteval (no Python ``eval``) so that tests can hold each text
    against its function.  ``functions`` replaces the numpy implementations of
    :data:`EXPRESSION_FUNCTIONS`, e.g. with mpmath's for high-precision references.

    Examples
    --------
    >>> round(float(evaluate_expression(get_formula("plitt").expression, {"x": 2.0, "ks": 3.0})), 12)
    0.111111111111
    """
    from asteval import Interpreter

    if functions is None:
        functions = {
            "exp": np.exp,
            "ln": np.log,
            "erfc": scipy.special.erfc,
            "sqrt": np.sqrt,
            "max": np.maximum,
            "pi": np.pi,
            "ln2": LN2,
        }
    interpreter = Interpreter(minimal=True, use_numpy=False)
    interpreter.symtable.update(functions)
    interpreter.symtable.update(values)
    return interpreter.eval(text.replace("^", "**"), show_errors=False, raise_errors=True)


def get_formula(key: str | int) -> Formula:
    """Look a formula up by id (``"plitt"``) or equation number (``7``, ``"7"``, ``"(7)"``).

    Parameters
    ----------
    key : str, int or Formula
        Id, equation number of Shuvalov et al. (2018), or a record (returned as is).

    Returns
    -------
    Formula

    Raises
    ------
    KeyError
        For an unknown key, listing the known formulas.
    TypeError
        For a key that is no name at all (None, a boolean, a collection).

    Examples
    --------
    >>> get_formula("(9)").id
    'lognormal'
    """
    if isinstance(key, Formula):
        return key
    if key is None or isinstance(key, (bool, np.bool_, bytes, list, tuple, dict, set, np.ndarray)):
        raise TypeError(f"a formula is named by its id (str) or its equation number (int), got {type(key).__name__}")
    text = str(key).strip()
    if text in FORMULAS_BY_ID:
        return FORMULAS_BY_ID[text]
    number = text.strip("()")
    if number.isdigit() and int(number) in _BY_EQUATION:
        return _BY_EQUATION[int(number)]
    raise KeyError(unknown_formula_message(key))


#: The groups a formula selection may name (``--formulas paper,other``), in the order listed.
FORMULA_GROUPS = {"paper": FORMULAS, "other": OTHER_FORMULAS, "extended": EXTENDED_FORMULAS}


def unknown_formula_message(key) -> str:
    """Why ``key`` names no formula: the closest ids and groups (:func:`difflib.get_close_matches`),
    then every id with its equation number, group by group.

    Examples
    --------
    >>> unknown_formula_message("plit").split(";")[0]
    "unknown formula 'plit' (did you mean plitt?)"
    """
    import difflib

    names = [*FORMULAS_BY_ID, *FORMULA_GROUPS]
    close = difflib.get_close_matches(str(key).strip().lower(), names, n=3, cutoff=0.6)
    hint = f" (did you mean {', '.join(close)}?)" if close else ""
    groups = "; ".join(
        f"{group}: " + ", ".join(f"{f.id} ({f.equation})" for f in formulas) for group, formulas in FORMULA_GROUPS.items()
    )
    return f"unknown formula {key!r}{hint}; give an id, an equation number or a group ({', '.join(FORMULA_GROUPS)}). {groups}"


def select_formulas(keys=None) -> tuple[Formula, ...]:
    """The formulas named by ``keys`` (ids or equation numbers), or all nine.

    Parameters
    ----------
    keys : str, int, iterable of str/int, or None
        Ids or equation numbers (a comma-separated string is split); ``"extended"``
        stands for every extended curve (bypass, fish-hook), ``"paper"`` for the nine,
        ``"other"`` for the curves of other tools (normal, logistic, Teipel/Hennig,
        Plitt 1976).

    Returns
    -------
    tuple of Formula

    Examples
    --------
    >>> [f.id for f in select_formulas("plitt,9,extended")][:3]
    ['plitt', 'lognormal', 'plitt_bypass']
    """
    if keys is None:
        return FORMULAS
    if isinstance(keys, str):
        keys = [k for k in keys.replace(" ", "").split(",") if k]
    elif isinstance(keys, (int, np.integer, Formula)):
        keys = [keys]
    elif not isinstance(keys, Iterable) or isinstance(keys, Mapping):
        raise TypeError(f"formulas are ids or equation numbers (a str, an int or an iterable of them), got {type(keys).__name__}")
    chosen = []
    for key in keys:
        group = FORMULA_GROUPS[key] if isinstance(key, str) and key in FORMULA_GROUPS else (get_formula(key),)
        chosen += [f for f in group if f not in chosen]
    return tuple(chosen)


def registry_table():
    """The registry as a :class:`pandas.DataFrame` (one row per formula).

    Columns: ``id, equation, title, formula, shape_name, shape_bounds, slope_at_cut,
    shape_at_slope_-0.5, extras, family, shape_meaning`` (what ``tromplab formulas`` prints).

    Examples
    --------
    >>> table = registry_table().set_index("id")
    >>> row = table.loc["ogawa_allen"]
    >>> row["formula"], row["slope_at_cut"], float(row["shape_at_slope_-0.5"])
    ('1/(1 + x*exp(-kp*(1 - x)))', '-(1 + kp)/4', 1.0)
    """
    import pandas as pd

    rows = []
    for formula in ALL_FORMULAS:
        shape_at_half = formula.shape_for_slope(-0.5)
        rows.append(
            {
                "id": formula.id,
                "equation": formula.equation,
                "title": formula.title,
                "formula": formula.expression,
                "shape_name": formula.shape_name,
                "shape_bounds": f"[{formula.shape_bounds[0]:g}, {formula.shape_bounds[1]:g}]",
                "slope_at_cut": formula.slope_expression,
                "shape_at_slope_-0.5": round(shape_at_half, 4),
                "extras": ", ".join(extra.name for extra in formula.extras),
                "family": formula.family,
                "shape_meaning": formula.shape_meaning,
            }
        )
    return pd.DataFrame(rows)


def formula_table_markdown(family: str = "paper") -> str:
    """The README's formula table (Markdown), generated from the registry.

    A test keeps the README's copy equal to this text.
    """
    lines = ["| id | eq. | phi(x), x = size/d_cut | shape | bounds | slope at the cut |", "|---|---|---|---|---|---|"]
    for formula in ALL_FORMULAS:
        if formula.family != family:
            continue
        low, high = formula.shape_bounds
        lines.append(
            f"| {formula.id} | ({formula.equation}) | `{formula.expression}` | {formula.shape_name} | "
            f"[{low:g}, {high:g}] | `{formula.slope_expression}` |"
        )
    return "\n".join(lines)


# --- the curves on arrays ----------------------------------------------------------------
def is_batchable(formula) -> bool:
    """True when the engine can evaluate ``formula`` on arrays of parameters."""
    return _batchable(get_formula(formula).id)


@cache
def _batchable(formula_id: str) -> bool:
    formula = get_formula(formula_id)
    if formula.moving_break is not None:  # evaluated through its break hooks
        return True
    if len(formula.extras) >= 2:  # interacting extras (Teipel-Hennig's alpha and bypass): one start is not enough
        return False
    x = np.array([[0.5, 1.0, 2.0], [0.5, 1.0, 2.0]])
    shape = np.array([[formula.clip_shape(1.0)], [formula.clip_shape(2.0)]])
    extras = {extra.name: np.full((2, 1), extra.start) for extra in formula.extras}
    try:
        with np.errstate(all="ignore"):
            value = np.asarray(formula.phi(x, shape, **extras), dtype=float)
    except (TypeError, ValueError):  # needs a scalar parameter (a root per parameter set)
        return False
    return value.shape == x.shape


__all__ = [
    "ALL_FORMULAS",
    "BYPASS",
    "DYSSOL_2020",
    "EXPRESSION_FUNCTIONS",
    "EXTENDED_FORMULAS",
    "FISHHOOK",
    "FORMULAS",
    "FORMULA_GROUPS",
    "Formula",
    "KELSALL_1953",
    "KING_2001",
    "LN2",
    "LN3",
    "LUCKIE_AUSTIN_1972",
    "LUCKIE_AUSTIN_BREAK",
    "LYNCH_RAO_1975",
    "MOLERUS_1967",
    "MOLERUS_HOFFMANN_1969",
    "MovingBreak",
    "NAME_CLASHES",
    "NAPIER_MUNN_1996",
    "NoBreakPointError",
    "OGAWA",
    "OTHER_FORMULAS",
    "PLITT_1971",
    "PLITT_1976",
    "ROSIN_RAMMLER_1933",
    "SHUVALOV_1992",
    "SHUVALOV_2018",
    "SHUVALOV_BREAK",
    "TEIPEL_HENNIG_ALPHA",
    "evaluate_expression",
    "formula_table_markdown",
    "get_formula",
    "is_batchable",
    "logistic_linear",
    "lognormal",
    "luckie_austin",
    "lynch",
    "molerus",
    "molerus_hoffmann",
    "normal_linear",
    "ogawa_allen",
    "plitt",
    "registry_table",
    "rosin_rammler",
    "rosin_rammler_plateau",
    "select_formulas",
    "shuvalov",
    "shuvalov_break",
    "shuvalov_breaks",
    "shuvalov_kink",
    "teipel_hennig",
    "unknown_formula_message",
    "whiten",
    "whiten_beta_star",
    "with_bypass",
    "with_plateau",
]

# The records and curves keep their public path (pickles name them by it, the API reference
# lists them here) whichever module of the package declares them.
for _name in __all__:
    if isinstance(globals()[_name], type) or inspect.isfunction(globals()[_name]):
        globals()[_name].__module__ = __name__
