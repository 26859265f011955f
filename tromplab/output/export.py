"""Fitted curves written in the parameter conventions of simulators and other tools.

``tromplab export FITS_DIR --to CONVENTION`` reads the ``fits.csv`` that ``tromplab fit``
wrote and writes, for every successful fit whose curve the target convention can express
exactly, the parameters that convention expects: its names, its units, its direction
(partition to the coarse or to the fine product), its cut (corrected or actual) and its
bypass (fraction or percent).  Fits the convention cannot express are listed, not
approximated.  The conventions, and what each parameter means, are tabulated in
``docs/export.md``:

``whiten``
    Whiten's curve as in Napier-Munn et al. (1996) and JKSimMet: recovery to the fine
    product (overflow) ``E_oa = C (1 + beta beta* x)(e^alpha - 1)/(e^(alpha beta* x) +
    e^alpha - 2)``, ``x = d/d50c``; ``C`` is the classified fraction (``1 - bypass``).
    From ``whiten`` and ``lynch`` (``beta = 0``, ``C = 1``).
``plitt``
    Plitt's (1976) hydrocyclone curve: recovery to the coarse product (underflow)
    ``Y = Rf + (1 - Rf)(1 - exp(-0.693 (d/d50c)^m))``, ``Rf`` in percent.  Plitt prints
    ln 2 rounded to 0.693; the exported ``d50c`` is adjusted so that the curve with 0.693
    is tromplab's curve (``d50c_ln2`` is the cut with the exact ln 2).  From
    ``rosin_rammler`` and ``rosin_rammler_bypass``.
``dyssol``
    The Screen unit of the open flowsheet simulator Dyssol (partition to the coarse
    product; sizes in metres): model ``Plitt`` (the Rosin-Rammler form with 0.693),
    ``Molerus & Hoffmann``, ``Teipel & Hennig`` and ``Probability``.
``csv-long``
    Every fitted parameter of every successful fit, one row each, with its unit and meaning.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import scipy

from ..curves.formulas import LN2, get_formula, whiten_beta_star
from ..errors import InputError
from ..loading.tables import read_table
from .csv_parts import write_csv

#: ln 2 as Plitt (1976) and Dyssol's Screen unit print it.
PLITT_LN2 = 0.693
SIZE_UNITS_IN_METRES = {"m": 1.0, "mm": 1e-3, "um": 1e-6, "µm": 1e-6, "micron": 1e-6, "cm": 1e-2}
FITS_COLUMNS = ("experiment", "formula", "d_cut", "shape_name", "shape", "bypass", "fishhook", "success")


@dataclass(frozen=True)
class FittedCurve:
    """One successful fit read back from ``fits.csv``: formula id, cut, shape and extras."""

    experiment: str
    formula: str
    d_cut: float
    shape: float
    extras: dict

    @property
    def bypass(self) -> float:
        return float(self.extras.get("bypass", 0.0))


@dataclass(frozen=True)
class Export:
    """Exported parameters (``table``) and the fits the convention cannot express (``skipped``)."""

    convention: str
    table: pd.DataFrame
    skipped: tuple[tuple[str, str, str], ...]  # (experiment, formula, reason)

    def write_csv(self, path) -> None:
        """Write ``table`` to ``path`` (:func:`~tromplab.output.csv_parts.write_csv`: without the
        index, text that starts as a formula marked as text)."""
        write_csv(self.table, path)


def read_fits(path) -> list[FittedCurve]:
    """The successful fits of a ``fits.csv`` (or of the ``fits.csv`` in folder ``path``).

    Raises
    ------
    InputError
        When the file is missing, lacks a column, or holds a non-numeric parameter
        (naming the file, row and column).
    """
    path = Path(path)
    if path.is_dir():
        path = path / "fits.csv"
    if not path.exists():
        raise InputError("no fits.csv here: give the output folder of 'tromplab fit' or its fits.csv", source=str(path))
    table = read_table(path, columns=(*FITS_COLUMNS, "extras"))  # 10 of the 77 columns: a tenth of the memory
    table.require(*FITS_COLUMNS)
    ok = np.flatnonzero(table.boolean("success"))
    # whole columns once, of the successful rows (a row read through the frame cost about 0.1 ms),
    # and Python floats for the records (a numpy scalar per value cost a microsecond or two)
    numbers = {name: table.numeric(name, allow_blank=True)[ok] for name in ("d_cut", "shape", "bypass", "fishhook")}
    texts = table.frame["extras"].to_numpy(dtype=object)[ok] if "extras" in table.frame.columns else np.full(ok.size, "")
    formulas = table.frame["formula"].astype(str).to_numpy(dtype=object)[ok]
    codes, formula_ids = pd.factorize(formulas, use_na_sentinel=False)  # a blank formula is refused below, as any unknown
    experiments = table.frame["experiment"].astype(str).to_numpy(dtype=object)[ok].tolist()
    fits, errors = [None] * ok.size, []  # errors: (position, error) of the first fault of each formula
    for code, formula_id in enumerate(formula_ids):  # the fits of each formula at once
        at = np.flatnonzero(codes == code)
        try:
            formula = get_formula(formula_id)
        except KeyError as error:
            errors.append((at[0], table.error(str(error.args[0]), index=int(ok[at[0]]), column="formula")))
            continue
        extras = {extra.name: _extra_values(table, ok[at], extra.name, numbers, texts[at], at) for extra in formula.extras}
        cuts, shapes = numbers["d_cut"][at], numbers["shape"][at]
        bad = ~(np.isfinite(cuts) & np.isfinite(shapes))
        for values in extras.values():
            bad |= ~np.isfinite(values)  # a value missing from the text is nan here, refused in its own words
        if bad.any():
            first = int(np.flatnonzero(bad)[0])
            errors.append((at[first], _fit_error(table, int(ok[at[first]]), formula, numbers, texts[at[first]])))
            continue
        names, columns = list(extras), [values.tolist() for values in extras.values()]
        for position, cut, shape, *values in zip(at.tolist(), cuts.tolist(), shapes.tolist(), *columns):
            fits[position] = FittedCurve(experiments[position], formula.id, cut, shape, dict(zip(names, values)))
    if errors:  # the first row at fault, with the error reading the rows in order meets first
        raise min(errors, key=lambda found: found[0])[1]
    return fits


def _extra_values(table, rows: np.ndarray, name: str, numbers: dict, texts: np.ndarray, at: np.ndarray) -> np.ndarray:
    """The fitted values of extra parameter ``name`` in table ``rows`` (positions ``at`` among the
    successful fits): its own column, else the ``extras`` text (``name=VALUE; ...``), nan where
    the text has no value."""
    if name in numbers:
        return numbers[name][at]
    values = []
    for row, text in zip(rows.tolist(), texts.tolist()):
        try:
            values.append(_extra_from_text(table, row, name, str(text)))
        except InputError:
            values.append(math.nan)
    return np.asarray(values, dtype=float)


def _fit_error(table, row: int, formula, numbers: dict, text) -> InputError:
    """Why the successful fit at table ``row`` cannot be read: its first extra without a value in
    the text, else a missing parameter value."""
    for extra in formula.extras:
        if extra.name not in numbers:
            try:
                _extra_from_text(table, row, extra.name, str(text))
            except InputError as error:
                return error
    return table.error("a successful fit with a missing parameter value", index=row, column="d_cut")


def _extra_from_text(table, index: int, name: str, text: str) -> float:
    for pair in text.split(";"):
        key, _, value = pair.partition("=")
        if key.strip() == name:
            try:
                return float(value)
            except ValueError:
                break
    raise table.error(f"the fitted value of {name} is missing (expected '{name}=VALUE')", index=index, column="extras")


def _whiten(fit: FittedCurve, scale: float) -> dict | None:
    if fit.formula == "lynch":
        alpha, beta, bypass = fit.shape, 0.0, 0.0
    elif fit.formula == "whiten":
        alpha, beta, bypass = fit.shape, fit.extras["fishhook"], fit.bypass
    else:
        return None
    curve = get_formula("whiten")
    return {
        "alpha": alpha,
        "beta": beta,
        "beta_star": whiten_beta_star(alpha, beta),
        "d50c": fit.d_cut * scale,
        "C": 1.0 - bypass,
        "Rf_pct": 100.0 * bypass,
        "d50": _actual_cut(lambda x: curve.phi(x, alpha, bypass=bypass, fishhook=beta)) * fit.d_cut * scale,
    }


def _plitt(fit: FittedCurve, scale: float) -> dict | None:
    if fit.formula not in ("rosin_rammler", "rosin_rammler_bypass"):
        return None
    m, bypass = fit.shape, fit.bypass
    d50c = fit.d_cut * (PLITT_LN2 / LN2) ** (1.0 / m)
    curve = get_formula("rosin_rammler")
    return {
        "d50c": d50c * scale,
        "m": m,
        "Rf_pct": 100.0 * bypass,
        "d50c_ln2": fit.d_cut * scale,
        "d50": _actual_cut(lambda x: (1.0 - bypass) * curve.phi(x, m)) * fit.d_cut * scale,
    }


def _dyssol(fit: FittedCurve, scale: float) -> dict | None:
    cut = fit.d_cut * scale
    if fit.formula == "rosin_rammler":
        row = {"Model": "Plitt", "Xcut": cut * (PLITT_LN2 / LN2) ** (1.0 / fit.shape), "Alpha": fit.shape}
    elif fit.formula == "molerus_hoffmann":
        row = {"Model": "Molerus & Hoffmann", "Xcut": cut, "Alpha": fit.shape}
    elif fit.formula == "teipel_hennig":
        alpha = fit.extras["th_alpha"]
        row = {"Model": "Teipel & Hennig", "Xcut": cut, "Alpha": alpha, "Beta": fit.shape / (1.0 + alpha), "Offset": fit.bypass}
    elif fit.formula == "normal":
        row = {"Model": "Probability", "Mean": cut, "Deviation": fit.shape * cut}
    else:
        return None
    notes = []
    if row.get("Alpha", 0.0) < 0.0:
        notes.append("Alpha < 0 is outside Dyssol's range [0, 100]")
    if row["Model"] == "Probability":
        notes.append("Dyssol sums the normal density over its class grid: equal to this curve on a fine grid only")
    return {**row, "note": "; ".join(notes)}


def _actual_cut(curve: Callable[[float], float]) -> float:
    """Relative size where the actual curve (with bypass) crosses 1/2; nan when it never does."""
    low, high = 1e-6, 1.0
    at_low = curve(low)
    if at_low < 0.5:
        return np.nan
    while (at_high := curve(high)) > 0.5:
        high *= 2.0
        if high > 1e6:
            return np.nan
    if at_low == 0.5 or at_high == 0.5:  # a root on the bracket's end, returned as brentq returns it
        return low if at_low == 0.5 else high  # (Lynch's curve is 1/2 at x = 1: every fit of it)
    # scipy.optimize loads here, the first time a root is needed (a fifth of a second of an export)
    return float(scipy.optimize.brentq(lambda x: curve(x) - 0.5, low, high, xtol=1e-14))


#: Convention -> (converter, its columns in order)
CONVENTIONS: dict[str, tuple[Callable[[FittedCurve, float], dict | None], tuple[str, ...]]] = {
    "whiten": (_whiten, ("alpha", "beta", "beta_star", "d50c", "C", "Rf_pct", "d50")),
    "plitt": (_plitt, ("d50c", "m", "Rf_pct", "d50c_ln2", "d50")),
    "dyssol": (_dyssol, ("Model", "Xcut", "Alpha", "Beta", "Offset", "Mean", "Deviation")),
}


def export_fits(fits, convention: str, *, size_unit: str | None = None) -> Export:
    """The fitted curves in the parameters of ``convention`` (see the module docstring).

    Parameters
    ----------
    fits : sequence of FittedCurve, or a path (folder or fits.csv)
    convention : {"whiten", "plitt", "dyssol", "csv-long"}
    size_unit : str, optional
        Unit of the fitted sizes (``um``, ``mm``, ``m``, ``cm``); required by ``dyssol``,
        which takes metres; elsewhere only written to the ``size_unit`` column.

    Returns
    -------
    Export
        ``table``: one row per exported fit (``csv-long``: per fit and parameter);
        ``skipped``: fits the convention cannot express, with the reason.
    """
    if not isinstance(fits, (list, tuple)):
        fits = read_fits(fits)
    if convention not in (*CONVENTIONS, "csv-long"):
        raise InputError(f"unknown convention {convention!r}; choose one of {', '.join((*CONVENTIONS, 'csv-long'))}")
    if size_unit is not None and size_unit not in SIZE_UNITS_IN_METRES:
        raise InputError(f"unknown size unit {size_unit!r}; choose one of {', '.join(SIZE_UNITS_IN_METRES)}")
    if convention == "csv-long":
        return Export(convention, _long_table(fits, size_unit), ())
    if convention == "dyssol" and size_unit is None:
        raise InputError("the dyssol convention takes sizes in metres: give the unit of the fitted sizes (--size-unit um|mm|m)")
    converter, columns = CONVENTIONS[convention]
    scale = SIZE_UNITS_IN_METRES[size_unit] if convention == "dyssol" else 1.0
    unit = "m" if convention == "dyssol" else (size_unit or "")
    rows, skipped = [], []
    for fit in fits:
        row = converter(fit, scale)
        if row is None:
            skipped.append((fit.experiment, fit.formula, f"no {convention} equivalent of {fit.formula}"))
            continue
        rows.append({"experiment": fit.experiment, "formula": fit.formula, **row, "size_unit": unit})
    extra = ["note"] if convention == "dyssol" else []
    table = pd.DataFrame(rows, columns=["experiment", "formula", *columns, "size_unit", *extra])
    return Export(convention, table, tuple(skipped))


PARAMETER_MEANINGS = {
    "d_cut": "cut size: partition 1/2 of the classified part (the corrected cut where the curve has a bypass)",
    "bypass": "share of every size sent to the coarse product unclassified (fraction)",
    "fishhook": "Whiten's beta (fish-hook)",
    "beta_star": "Whiten's beta*, derived: keeps the corrected curve at 1/2 at d_cut",
    "sigma": "standard deviation of the separation size (sigma_rel d_cut)",
    "ep": "Ecart probable (imperfection d_cut)",
}


def _long_table(fits, size_unit) -> pd.DataFrame:
    columns = {name: [] for name in ("experiment", "formula", "parameter", "value", "unit", "meaning")}
    add_parameter, add_value = columns["parameter"].append, columns["value"].append
    add_unit, add_meaning = columns["unit"].append, columns["meaning"].append
    sized_unit = size_unit or "size unit of the fit"
    formulas, described = {}, {}  # formula id -> its record, and -> {parameter: (unit, meaning)}: the same for every fit
    for fit in fits:
        formula = formulas.get(fit.formula) or formulas.setdefault(fit.formula, get_formula(fit.formula))
        values = {"d_cut": fit.d_cut, formula.shape_name: fit.shape, **fit.extras}
        if fit.formula == "whiten":
            values["beta_star"] = whiten_beta_star(fit.shape, fit.extras["fishhook"])
        if fit.formula == "normal":
            values["sigma"] = fit.shape * fit.d_cut
        if fit.formula == "logistic":
            values["ep"] = fit.shape * fit.d_cut
        if fit.formula not in described:
            meanings = {**{extra.name: extra.meaning for extra in formula.extras}, **PARAMETER_MEANINGS}
            meanings.setdefault(formula.shape_name, f"shape parameter of {formula.title}")
            described[fit.formula] = {
                name: (sized_unit if name in ("d_cut", "sigma", "ep") else "-", meanings.get(name, "")) for name in values
            }
        units = described[fit.formula]
        for name, value in values.items():  # bound appends: a loop over the six columns per row took half the time
            unit, meaning = units[name]
            add_parameter(name)
            add_value(value)
            add_unit(unit)
            add_meaning(meaning)
        columns["experiment"] += [fit.experiment] * len(values)
        columns["formula"] += [fit.formula] * len(values)
    return pd.DataFrame(columns)
