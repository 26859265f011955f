"""A coal-washing plant from tests to tonnes: washability by size fraction, a device per size fraction.

:func:`predict` reads the washability of every size fraction of the feed
(:func:`~tromplab.plant.inputs.read_plant_washability`) and the device washing each
(:func:`~tromplab.plant.inputs.read_plant`, or the curves of a ``density fit`` folder,
:func:`~tromplab.plant.inputs.devices_from_fits`), and returns a
:class:`~tromplab.plant.prediction.PlantPrediction` whose ``save(DIR)`` writes what
``tromplab plant predict WASH PLANT -o DIR`` writes; :func:`optimize` finds the cut densities
of the most clean coal at a contract ash (:class:`~tromplab.plant.optimum.PlantOptimum`, what
``tromplab plant optimize`` writes); :func:`evaluate` gives a tested separation's performance
in the standard form (``tromplab plant evaluate``).  Definitions and sources in ``docs/plant.md``.
"""

from .evaluation import SeparationEvaluation, evaluate
from .inputs import Device, SizeFraction, devices_from_fits, read_plant, read_plant_washability
from .optimum import PlantOptimum, optimize
from .prediction import PlantPrediction, predict

__all__ = [
    "Device",
    "PlantOptimum",
    "PlantPrediction",
    "SeparationEvaluation",
    "SizeFraction",
    "devices_from_fits",
    "evaluate",
    "optimize",
    "predict",
    "read_plant",
    "read_plant_washability",
]
