"""What a plant makes of its feed: :func:`predict` and its result, :class:`PlantPrediction`.

``tromplab plant predict WASH PLANT -o DIR`` calls :func:`predict` and writes
:meth:`PlantPrediction.save`, so the command and the Python API write the same files, byte for
byte: ``products.csv`` (one row per size fraction and the plant's ``total``, columns in
``docs/plant.md``), ``devices.csv`` (the curves used), ``summary.txt`` (:meth:`PlantPrediction.report`),
``yield_ash.png`` and ``partition.png`` (:mod:`tromplab.plant.plotting`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..errors import OptionError
from ..options import DEFAULT_SUM_TOLERANCE_PCT
from ..results_contract import ResultContract
from ..validation import check_count, check_optional, check_probability, check_seed
from .draws import DEFAULT_DRAWS, MAX_DRAWS, parameter_draws, percentile_interval
from .inputs import Device, SizeFraction, devices_from_fits, read_plant, read_plant_washability
from .products import QUANTITIES, composite_washability, fraction_products, plant_products
from .sampling import MAX_PARTICLES, washability_mass_draws

#: The interval level when none is asked for.
DEFAULT_CI = 0.95
#: The name of the plant's row in ``products.csv``.
TOTAL = "total"


@dataclass(frozen=True)
class PlantPrediction(ResultContract):
    """The predicted products of a plant: each size fraction's device and the blended clean coal.

    Attributes
    ----------
    fractions : list of SizeFraction
        The size fractions of the feed with their washability.
    devices : list of Device
        The device of each size fraction, in the same order.
    products : pandas.DataFrame
        ``products.csv``: one row per size fraction and the ``total`` row (columns in ``docs/plant.md``).
    ci : float
        Level of the intervals (``_low``/``_high`` columns, present when a device's curve is uncertain).
    draws : int
        Parameter draws of the parametric bootstrap (0 when every curve is exact).
    seed : int
        Seed of the draws.
    notes : tuple of str
        What the reader must know, in words.
    qualities : tuple of str
        The further qualities blended (``"sulfur"``), from the ``<name>_pct`` columns.
    """

    fractions: list
    devices: list
    products: pd.DataFrame
    ci: float = DEFAULT_CI
    draws: int = 0
    seed: int = 0
    notes: tuple = ()
    qualities: tuple = field(default=())

    def summary(self) -> pd.DataFrame:
        """``products.csv``: one row per size fraction and the plant's ``total`` row."""
        return self.products

    def _result_context(self) -> str:
        total = self.products.iloc[-1]
        how = f", {self.ci:g} intervals from {self.draws} parameter draws" if self.draws else ", curves taken as exact"
        return (f"Plant of {len(self.fractions)} size fractions ({', '.join(f.name for f in self.fractions)}): "
                f"clean coal {total['clean_yield_pct']:.4g} % of the feed at {total['clean_ash_pct']:.4g} % ash{how}")  # fmt: skip

    def report(self) -> str:
        """The products of each size fraction and of the plant, the devices, and the notes, as text."""
        shown = ["size_fraction", "device", "feed_pct", "clean_yield_pct", "clean_ash_pct", "organic_efficiency_pct"]
        table = self.products[[c for c in self.products.columns if any(c.startswith(s) for s in shown)]]
        lines = [self._result_context(), table.to_string(index=False, float_format=lambda v: f"{v:.4g}", na_rep="-"), ""]
        lines += ["devices (partition to sinks):", self.devices_table().to_string(index=False, na_rep="-")]
        lines += [f"note: {note}" for note in self.notes]
        return "\n".join(lines)

    def devices_table(self) -> pd.DataFrame:
        """``devices.csv``: per size fraction the device, its curve, rho50, Ep (or I) with standard deviations, and where it came from."""
        rows = []
        for device in self.devices:
            sd = np.sqrt(np.diag(device.covariance))
            rows.append({"size_fraction": device.size_fraction, "device": device.device, "curve": device.curve.id,
                         "rho50": device.rho50, "rho50_sd": sd[0], "ep": device.ep_at(device.rho50).item(),
                         "imperfection": device.scale if device.scale_name == "imperfection" else np.nan,
                         f"{device.scale_name}_sd": sd[1], "rho50_scale_corr": _correlation(device.covariance),
                         "light_limit": device.light_limit, "heavy_limit": device.heavy_limit, "source": device.source})  # fmt: skip
        columns = ["size_fraction", "device", "curve", "rho50", "rho50_sd", "ep", "ep_sd", "imperfection", "imperfection_sd",
                   "rho50_scale_corr", "light_limit", "heavy_limit", "source"]  # fmt: skip
        return pd.DataFrame(rows).reindex(columns=columns)

    def plot_yield_ash(self, *, ax=None):
        """The theoretical and predicted yield-ash curves of each size fraction and of the plant (:mod:`tromplab.plant.plotting`)."""
        from .plotting import plot_yield_ash

        return plot_yield_ash(self, ax=ax)

    def plot_partition(self, *, ax=None):
        """The partition curves of the devices, with their bands when uncertain (:mod:`tromplab.plant.plotting`)."""
        from .plotting import plot_partition_curves

        return plot_partition_curves(self, ax=ax)

    def save(self, outdir) -> dict:
        """Write ``products.csv``, ``devices.csv``, ``summary.txt``, ``yield_ash.png`` and ``partition.png`` into ``outdir``.

        What ``tromplab plant predict`` writes with the same options; the folder is replaced as a
        whole when everything is written (:func:`tromplab.output.outputs.replace_folder`).

        Returns
        -------
        dict
            File name -> written path.
        """
        from ..output.outputs import replace_folder

        return replace_folder(self.writers(), outdir)

    def writers(self, *, tables: dict | None = None, summary: str | None = None) -> dict:
        """File name -> writer of the folder :meth:`save` writes; ``tables`` (stem -> DataFrame) are added
        before the others and ``summary`` replaces :meth:`report` in ``summary.txt`` (for ``plant optimize``)."""
        from ..output.csv_parts import file_writers
        from ..output.plotting import figure_png, offscreen_axes
        from .plotting import plot_partition_curves, plot_yield_ash

        yield_ash = figure_png(plot_yield_ash(self, ax=offscreen_axes(figsize=(7.5, 5.5))))
        partition = figure_png(plot_partition_curves(self, ax=offscreen_axes()))
        return file_writers({**(tables or {}), "products": self.products, "devices": self.devices_table()},
                            texts={"summary.txt": (self.report() if summary is None else summary) + "\n"},
                            pictures={"yield_ash.png": yield_ash, "partition.png": partition})  # fmt: skip


def _correlation(covariance: np.ndarray) -> float:
    sd = np.sqrt(np.diag(covariance))
    return float(covariance[0, 1] / (sd[0] * sd[1])) if sd.all() else np.nan


def predict(
    washability,
    plant=None,
    *,
    curves_from=None,
    ci: float = DEFAULT_CI,
    draws: int = DEFAULT_DRAWS,
    seed: int = 0,
    sum_tolerance_pct: float = DEFAULT_SUM_TOLERANCE_PCT,
    float_lower_density: float | None = None,
    sink_upper_density: float | None = None,
    washability_particles: int | None = None,
    progress=None,
) -> PlantPrediction:
    """Predict the clean coal and reject of every size fraction and of the plant, with intervals.

    What ``tromplab plant predict`` does, with its options as keywords of the same names.

    Parameters
    ----------
    washability : path, DataFrame or list of SizeFraction
        The washability by size fraction (:func:`tromplab.plant.inputs.read_plant_washability`).
    plant : path or DataFrame, optional
        The plant table (:func:`tromplab.plant.inputs.read_plant`); or give ``curves_from``.
    curves_from : path, DensityResult or list of Device, optional
        A ``tromplab density fit`` results folder (or its result): each size fraction's best
        curve with its covariance (:func:`tromplab.plant.inputs.devices_from_fits`); or the
        devices themselves.
    ci : float
        Level of the percentile intervals, in (0, 1).
    draws : int
        Parameter draws of the parametric bootstrap (:mod:`tromplab.plant.draws`); used when a
        device's curve carries a covariance, 0 for none.
    seed : int
        Seed of the draws (the same seed, the same intervals).
    sum_tolerance_pct, float_lower_density, sink_upper_density
        As for :func:`tromplab.plant.inputs.read_plant_washability`.
    washability_particles : int, optional
        Adds the sampling error of the washability analyses to the intervals: each size fraction's
        analysis is taken as made on a sample of this many particles, its density fractions' mass
        shares drawn from a Dirichlet distribution (:mod:`tromplab.plant.sampling`) with each draw
        of the curves.  Default None: the washability is taken as exact.
    progress : callable, optional
        ``progress(done, total, label)`` after each size fraction.

    Returns
    -------
    PlantPrediction

    Examples
    --------
    >>> wash = pd.DataFrame({"size_fraction": "all", "fraction_pct": 100, "density_lower": [1.2, 1.4, 1.6],
    ...                      "density_upper": [1.4, 1.6, 2.0], "mass_pct": [60, 20, 20], "ash_pct": [5, 20, 60]})
    >>> plant = pd.DataFrame({"size_fraction": ["all"], "device": ["bath"], "curve": ["normal"], "rho50": [1.6], "ep": [0.005]})
    >>> total = predict(wash, plant).products.set_index("size_fraction").loc["total"]
    >>> [round(float(total[name]), 3) for name in ("clean_yield_pct", "clean_ash_pct", "organic_efficiency_pct")]
    [80.0, 8.75, 100.0]
    """
    ci = check_probability(ci, "ci")
    draws = check_count(draws, "draws", minimum=0, maximum=MAX_DRAWS)
    seed = check_seed(seed, "seed")
    particles = check_optional(check_count, washability_particles, "washability_particles", maximum=MAX_PARTICLES)
    if (plant is None) == (curves_from is None):
        raise OptionError("plant", "or curves_from: give exactly one of them")
    fractions = read_fractions(washability, sum_tolerance_pct, float_lower_density, sink_upper_density)
    devices = read_plant(plant, fractions) if plant is not None else devices_from(curves_from, fractions)
    uncertain = any(device.uncertain for device in devices) or particles is not None
    used = draws if uncertain else 0
    parameters = parameter_draws(devices, used, seed)
    masses = None if particles is None else washability_mass_draws(fractions, particles, used, seed)
    per_fraction = []
    for done, (fraction, device, (rho50, scale)) in enumerate(zip(fractions, devices, parameters), start=1):
        mass = None if masses is None else masses[done - 1]
        per_fraction.append(fraction_products(fraction, device, rho50, scale, mass))
        if progress is not None:
            progress(done, len(fractions) + 1, "size fractions")
    total = plant_products(fractions, per_fraction, composite_washability(fractions), masses)
    if progress is not None:
        progress(len(fractions) + 1, len(fractions) + 1, "size fractions")
    qualities = tuple(fractions[0].qualities)
    rows = [
        _row(f.name, d.device, f.feed_pct, values, qualities, used, ci) for f, d, values in zip(fractions, devices, per_fraction)
    ]
    rows.append(_row(TOTAL, "", 100.0, total, qualities, used, ci))
    notes = _notes(devices, uncertain, draws, ci, particles)
    return PlantPrediction(fractions, devices, pd.DataFrame(rows), ci, used, seed, tuple(notes), qualities)


def read_fractions(washability, tolerance, float_lower, sink_upper) -> list[SizeFraction]:
    if isinstance(washability, list | tuple) and all(isinstance(item, SizeFraction) for item in washability):
        return list(washability)
    return read_plant_washability(washability, sum_tolerance_pct=tolerance, float_lower_density=float_lower,
                                  sink_upper_density=sink_upper)  # fmt: skip


def devices_from(curves_from, fractions: list[SizeFraction]) -> list[Device]:
    if isinstance(curves_from, list | tuple) and all(isinstance(item, Device) for item in curves_from):
        names = [device.size_fraction for device in curves_from]
        if names != [fraction.name for fraction in fractions]:
            raise OptionError("curves_from", f"gives devices for {names}, not one for each size fraction in order")
        return list(curves_from)
    return devices_from_fits(curves_from, fractions)


def product_columns(qualities, *, intervals: bool) -> list[str]:
    """The columns of ``products.csv``: the quantities, the qualities' clean and reject per cents, each
    followed by ``_low`` and ``_high`` with ``intervals``."""
    quantities = [*QUANTITIES, *(f"{side}_{name}_pct" for name in qualities for side in ("clean", "reject"))]
    columns = ["size_fraction", "device", "feed_pct"]
    for name in quantities:
        columns += [name, f"{name}_low", f"{name}_high"] if intervals else [name]
    return columns


def _row(name: str, device: str, feed_pct: float, values: dict, qualities, draws: int, ci: float) -> dict:
    row = {"size_fraction": name, "device": device, "feed_pct": feed_pct}
    for column in product_columns(qualities, intervals=False)[3:]:
        row[column] = float(values[column][0])
        if draws:
            row[f"{column}_low"], row[f"{column}_high"] = percentile_interval(values[column][1:], ci)
    return row


def _notes(devices: list[Device], uncertain: bool, draws: int, ci: float, particles: int | None) -> list[str]:
    notes = []
    washability = ("the washability is taken as exact" if particles is None else
                   f"with the sampling error of the washability analyses, each taken as made on {particles:,} particles "
                   "(Dirichlet draws of the density fractions' masses)")  # fmt: skip
    if uncertain and draws:
        notes.append(f"intervals: {ci:g} percentile intervals of {draws} parametric-bootstrap draws of the "
                     f"curves' linear-predictor coefficients, independent between devices; {washability}")  # fmt: skip
    elif uncertain:
        notes.append(f"the curves carry standard deviations{'' if particles is None else ' (or the washability a sampling error)'} "
                     "but draws = 0: no intervals")  # fmt: skip
    else:
        notes.append("no curve carries a standard deviation or covariance: the curves are taken as exact, no intervals")
    limited = [d.size_fraction for d in devices if d.light_limit > 0 or d.heavy_limit < 1]
    if limited:
        notes.append(f"the limits of the curves of {', '.join(limited)} are held at their values (no uncertainty)")
    notes.append("plant theoretical yield and organic efficiency: against the washability of the whole feed "
                 "(size fractions added at equal density); different cuts by size can exceed 100 %")  # fmt: skip
    return notes
