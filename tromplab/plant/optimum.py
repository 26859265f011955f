"""The cut densities of the most clean coal at a contract ash: :func:`optimize` and its result, :class:`PlantOptimum`.

``tromplab plant optimize WASH PLANT --target-ash A -o DIR`` calls :func:`optimize` and writes
:meth:`PlantOptimum.save`: ``cuts.csv`` (the cuts, one row per size fraction and the ``total``,
columns in ``docs/plant.md``) and the files of ``plant predict`` at those cuts (``products.csv``
with intervals, ``devices.csv``, ``summary.txt``, ``yield_ash.png``, ``partition.png``).  The
method is in :mod:`tromplab.plant.optimization`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..errors import OptionError
from ..options import DEFAULT_SUM_TOLERANCE_PCT
from ..results_contract import ResultContract
from ..validation import check_count, check_optional, check_percent, check_probability, check_seed
from .draws import DEFAULT_DRAWS, MAX_DRAWS, parameter_draws
from .inputs import read_plant
from .optimization import CHANCE_STEPS, Blend, CutResponse, chance_constrained_cuts, cut_bounds, optimal_cuts
from .prediction import DEFAULT_CI, TOTAL, PlantPrediction, devices_from, predict, read_fractions

#: The columns of ``cuts.csv``.
CUT_COLUMNS = ("size_fraction", "device", "feed_pct", "rho50", "ep", "bound", "clean_yield_pct", "clean_ash_pct",
               "incremental_ash_pct", "target_met_probability")  # fmt: skip


@dataclass(frozen=True)
class PlantOptimum(ResultContract):
    """The cut densities that maximise the plant's clean coal at a product ash of at most the target.

    Attributes
    ----------
    cuts : pandas.DataFrame
        ``cuts.csv``: per size fraction the cut, its clean coal, ash and incremental ash, and the ``total``.
    prediction : PlantPrediction
        The products at the optimal cuts, with intervals when the curves are uncertain (``products.csv``).
    target_ash_pct : float
        The clean-coal ash not to exceed (per cent).
    confidence : float or None
        The probability asked of the ash staying at or below the target (None: the estimated curves).
    design_ash_pct : float
        The ash the expected products were optimised for: the target, or below it to meet ``confidence``.
    notes : tuple of str
        What the reader must know, in words.
    """

    cuts: pd.DataFrame
    prediction: PlantPrediction
    target_ash_pct: float
    confidence: float | None
    design_ash_pct: float
    notes: tuple = ()

    def summary(self) -> pd.DataFrame:
        """``cuts.csv``: one row per size fraction and the plant's ``total`` row."""
        return self.cuts

    def _result_context(self) -> str:
        total = self.cuts.iloc[-1]
        chance = f" with probability {self.confidence:g}" if self.confidence is not None else ""
        return (f"Optimal cuts for clean coal of at most {self.target_ash_pct:g} % ash{chance}: "
                f"{total['clean_yield_pct']:.4g} % of the feed at {total['clean_ash_pct']:.4g} % ash")  # fmt: skip

    def report(self) -> str:
        """The cuts, the products at those cuts and the notes, as text."""
        cuts = self.cuts.to_string(index=False, float_format=lambda v: f"{v:.5g}", na_rep="-")
        lines = [self._result_context(), cuts, "", "products at these cuts:", self.prediction.report()]
        return "\n".join(lines + [f"note: {note}" for note in self.notes])

    def save(self, outdir) -> dict:
        """Write ``cuts.csv`` and the files of ``plant predict`` at the optimal cuts into ``outdir``.

        What ``tromplab plant optimize`` writes with the same options, the folder replaced as a whole.

        Returns
        -------
        dict
            File name -> written path.
        """
        from ..output.outputs import replace_folder

        return replace_folder(self.prediction.writers(tables={"cuts": self.cuts}, summary=self.report()), outdir)


def optimize(
    washability,
    plant=None,
    *,
    target_ash_pct: float,
    confidence: float | None = None,
    curves_from=None,
    ci: float = DEFAULT_CI,
    draws: int = DEFAULT_DRAWS,
    seed: int = 0,
    sum_tolerance_pct: float = DEFAULT_SUM_TOLERANCE_PCT,
    float_lower_density: float | None = None,
    sink_upper_density: float | None = None,
    progress=None,
) -> PlantOptimum:
    """The cut densities that give the most clean coal at a clean-coal ash of at most ``target_ash_pct``.

    What ``tromplab plant optimize`` does, with its options as keywords of the same names (the
    inputs and ``ci``, ``draws``, ``seed`` as for :func:`tromplab.plant.predict`).

    Parameters
    ----------
    target_ash_pct : float
        The contract ash (per cent, in (0, 100)); a target below the lowest ash the plant can
        reach is refused naming that ash.
    confidence : float, optional
        Maximise the expected clean coal subject to P(ash <= target) >= ``confidence`` under the
        curves' uncertainty (needs curves with standard deviations or a covariance).
    progress : callable, optional
        ``progress(done, total, label)`` after each stage (and, with ``confidence``, each design ash tried).

    Returns
    -------
    PlantOptimum

    Examples
    --------
    >>> wash = pd.DataFrame({"size_fraction": ["a"] * 3 + ["b"] * 3, "fraction_pct": 50, "density_lower": [1.2, 1.4, 1.6] * 2,
    ...                      "density_upper": [1.4, 1.6, 2.0] * 2, "mass_pct": [60, 20, 20, 40, 40, 20],
    ...                      "ash_pct": [5, 20, 60, 4, 15, 60]})
    >>> plant = pd.DataFrame({"size_fraction": ["a", "b"], "device": ["bath", "dmc"], "curve": "normal",
    ...                       "rho50": 1.5, "ep": 0.03})
    >>> cuts = optimize(wash, plant, target_ash_pct=9).cuts.set_index("size_fraction")
    >>> round(float(cuts.loc["total", "clean_ash_pct"]), 6), bool(abs(cuts.loc["a", "incremental_ash_pct"] - cuts.loc["b", "incremental_ash_pct"]) < 0.01)
    (9.0, True)
    """
    target_ash_pct = check_percent(target_ash_pct, "target_ash_pct")
    confidence = check_optional(check_probability, confidence, "confidence")
    draws = check_count(draws, "draws", minimum=0, maximum=MAX_DRAWS)
    seed = check_seed(seed, "seed")
    if (plant is None) == (curves_from is None):
        raise OptionError("plant", "or curves_from: give exactly one of them")
    fractions = read_fractions(washability, sum_tolerance_pct, float_lower_density, sink_upper_density)
    devices = read_plant(plant, fractions) if plant is not None else devices_from(curves_from, fractions)
    if confidence is not None and not (draws and any(device.uncertain for device in devices)):
        raise OptionError("confidence", "needs curves with standard deviations or a covariance, and draws > 0")
    blend = Blend(_responses(fractions, devices, draws if confidence is not None else 0, seed), _shares(fractions))
    steps = 3 + (CHANCE_STEPS if confidence is not None else 0)  # one bar: the stages and the design ashes tried
    _step(progress, 1, steps, "responses")
    lowest = blend.lowest_ash()
    if target_ash_pct < lowest - 1e-9:
        raise OptionError("target_ash_pct", f"{target_ash_pct:g} % is below the lowest clean-coal ash the plant reaches, "
                          f"{lowest:.4g} % (every cut at its lowest); raise the target or the lower bounds of the cuts")  # fmt: skip
    notes, design = [], target_ash_pct
    if confidence is None:
        solution = optimal_cuts(blend, target_ash_pct)
    else:
        searched = None if progress is None else (lambda done, total, label: progress(1 + done, total + 3, label))
        solution, design, chance = chance_constrained_cuts(blend, target_ash_pct, confidence, lowest, progress=searched)
        if solution is None:
            raise OptionError("confidence", f"no cuts keep the ash at or below {target_ash_pct:g} % with probability "
                              f"{confidence:g}: the lowest-ash cuts do with probability {chance:.3g}")  # fmt: skip
        notes.append(f"optimised for the expected products at a design ash of {design:.5g} %, which keeps the ash at or "
                     f"below {target_ash_pct:g} % in {100 * chance:.1f} % of {draws} draws of the curves")  # fmt: skip
    _step(progress, steps - 1, steps, "cuts")
    at_cuts = [dataclasses.replace(device, rho50=float(cut)) for device, cut in zip(devices, solution.cuts)]
    prediction = predict(fractions, curves_from=at_cuts, ci=ci, draws=draws, seed=seed)
    _step(progress, steps, steps, "products")
    notes += _notes(solution)
    cuts = _cut_table(blend, solution, prediction, confidence, target_ash_pct, draws)
    return PlantOptimum(cuts, prediction, target_ash_pct, confidence, design, tuple(notes))


def _step(progress, done: int, total: int, label: str) -> None:
    if progress is not None:
        progress(done, total, label)


def _shares(fractions) -> np.ndarray:
    return np.array([fraction.feed_pct / 100.0 for fraction in fractions])


def _responses(fractions, devices, draws: int, seed: int) -> list[CutResponse]:
    responses = []
    for fraction, device, (rho50, scale) in zip(fractions, devices, parameter_draws(devices, draws, seed)):
        offsets, scales = (rho50[1:] - device.rho50, scale[1:]) if draws else (np.zeros(1), scale[:1])
        responses.append(CutResponse(fraction, device, offsets, scales, *cut_bounds(fraction, device)))
    return responses


def _cut_table(blend: Blend, solution, prediction: PlantPrediction, confidence, target: float, draws: int) -> pd.DataFrame:
    rows = []
    for share, response, cut in zip(blend.shares, blend.responses, solution.cuts):
        clean, ash = response.expected(np.array([cut]))
        bound = "min" if cut <= response.low + 1e-9 else "max" if cut >= response.high - 1e-9 else ""
        rows.append({"size_fraction": response.fraction.name, "device": response.device.device, "feed_pct": 100 * share,
                     "rho50": cut, "ep": response.device.ep_at(cut).item(), "bound": bound, "clean_yield_pct": clean[0],
                     "clean_ash_pct": ash[0] / clean[0] if clean[0] > 0 else np.nan,
                     "incremental_ash_pct": response.incremental_ash(cut)})  # fmt: skip
    total_clean, total_ash = blend.totals(solution.cuts)
    uncertain = any(device.uncertain for device in prediction.devices) and draws
    chance = np.nan
    if uncertain:
        responses = _responses(prediction.fractions, prediction.devices, draws, prediction.seed)
        chance = float(np.mean(Blend(responses, blend.shares).ash_per_draw(solution.cuts) <= target))
    rows.append({"size_fraction": TOTAL, "device": "", "feed_pct": 100.0, "rho50": np.nan, "ep": np.nan, "bound": "",
                 "clean_yield_pct": total_clean, "clean_ash_pct": total_ash,
                 "incremental_ash_pct": solution.multiplier if solution.binding else np.nan,
                 "target_met_probability": chance})  # fmt: skip
    return pd.DataFrame(rows).reindex(columns=list(CUT_COLUMNS))


def _notes(solution) -> list[str]:
    if not solution.binding:
        return ["the target does not bind: every cut at its upper bound already gives clean coal below the target ash"]
    return [f"the incremental ash (the ash of the marginal clean coal) is {solution.multiplier:.4g} % in every size fraction "
            "whose cut is not on a bound (equal incremental ash, Mayer's M-curve)"]  # fmt: skip
