"""tromplab: separation (Tromp) curves of particle classifiers and sieve-classifier models.

Importing the package has no side effects: no plotting style, no files, no network.
The public API (``__all__``, one line each, from each object's own docstring):
"""

from ._version import __version__
from .curves.curve_fit import CurveFit, fit_formula
from .curves.formulas import ALL_FORMULAS, FORMULAS, Formula, get_formula, registry_table, select_formulas
from .curves.indices import curve_indices
from .curves.parameters import Parameter
from .curves.ranking import rank_formulas
from .errors import InputError
from .loading.lab import LabOptions, MassBalance, read_experiments, read_lab
from .loading.points import TrompPoints, read_points
from .output.report import build_report, write_report
from .statistics.compare import nested_f_test, shared_fit
from .statistics.uncertainty import akaike_weights, bootstrap, interval_table, model_average
from .workbench import Workbench, fit_experiments, load, model_averages

__all__ = [
    "__version__",
    # loading
    "read_points",
    "read_lab",
    "read_experiments",
    "LabOptions",
    "MassBalance",
    "TrompPoints",
    "InputError",
    # the formula registry
    "FORMULAS",
    "ALL_FORMULAS",
    "Formula",
    "Parameter",
    "get_formula",
    "select_formulas",
    "registry_table",
    # fitting, screening, ranking
    "fit_formula",
    "fit_experiments",
    "CurveFit",
    "Workbench",
    "curve_indices",
    "rank_formulas",
    # uncertainty and comparison
    "interval_table",
    "bootstrap",
    "akaike_weights",
    "model_average",
    "model_averages",
    "shared_fit",
    "nested_f_test",
    # output
    "build_report",
    "write_report",
    "load",
]


def _one_line(name: str) -> str:
    obj = globals()[name]
    if name == "__version__":
        return f"installed version ({__version__})"
    if isinstance(obj, tuple):
        return f"tuple of {len(obj)} formula records" + (" (the paper's nine)" if obj is FORMULAS else " (with extended curves)")
    doc = (obj.__doc__ or "").strip()
    return doc.split("\n\n")[0].replace("\n", " ").strip()


__doc__ += "\n" + "\n".join(f"- ``{name}``: {_one_line(name)}" for name in __all__) + "\n"
