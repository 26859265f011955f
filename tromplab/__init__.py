"""tromplab: separation (Tromp) curves of particle classifiers and sieve-classifier models.

Importing the package has no side effects: no plotting style, no files, no network.
It is also quick: the public names load on first use (PEP 562), so ``import tromplab``
imports neither numpy nor pandas, and the ``tromplab`` command installs its signal handling
before they are.
The public API (``__all__``, one line each, from each object's own docstring):
"""

import importlib as _importlib
from typing import TYPE_CHECKING

from ._version import __version__

if TYPE_CHECKING:  # the names as static tools see them; at run time __getattr__ imports them
    from .circuit import design_circuit, reconcile_circuit
    from .curves.curve_fit import CurveFit, fit_formula
    from .curves.formulas import ALL_FORMULAS, FORMULAS, Formula, get_formula, registry_table, select_formulas
    from .curves.indices import curve_indices
    from .curves.parameters import Parameter
    from .curves.ranking import rank_formulas
    from .density import fit_density, predict_density
    from .errors import InputError
    from .loading.lab import LabOptions, MassBalance, read_experiments, read_lab
    from .loading.points import TrompPoints, read_points
    from .output.report import build_report, write_report
    from .statistics.compare import nested_f_test, shared_fit
    from .statistics.uncertainty import akaike_weights, bootstrap, interval_table, model_average
    from .trend import monitor_surveys
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
    # the commands as functions (docs/architecture.md): fit_experiments above, then
    "fit_density",
    "predict_density",
    "reconcile_circuit",
    "design_circuit",
    "monitor_surveys",
]

# Each public name: the module that defines it and the first paragraph of its docstring (for a
# tuple: what it holds).  Written out so that neither the docstring below nor ``dir()`` imports
# anything; tests/test_package.py checks every line against the object itself.
_PUBLIC: dict[str, tuple[str, str]] = {
    "read_points": (".loading.points", "Read and validate Tromp points (schema in the module docstring)."),
    "read_lab": (".loading.lab", "Read a lab table and compute the Tromp points of each experiment."),
    "read_experiments": (
        ".loading.lab",
        "Tromp points from either a points file or a lab table (told apart by their columns).",
    ),
    "LabOptions": (".loading.lab", "How to read a lab table."),
    "MassBalance": (".loading.lab", "One experiment of a lab table turned into Tromp points."),
    "TrompPoints": (".loading.points", "Measured separation curve of one experiment, validated on construction."),
    "InputError": (".errors", "Bad input data."),
    "FORMULAS": (".curves.formulas", "tuple of 9 formula records (the paper's nine)"),
    "ALL_FORMULAS": (".curves.formulas", "tuple of 16 formula records (with extended curves)"),
    "Formula": (".curves.formulas", "Declaration of one separation-curve formula."),
    "Parameter": (".curves.parameters", "A fitted parameter and everything a reader or a fit needs to know about it."),
    "get_formula": (
        ".curves.formulas",
        'Look a formula up by id (``"plitt"``) or equation number (``7``, ``"7"``, ``"(7)"``).',
    ),
    "select_formulas": (".curves.formulas", "The formulas named by ``keys`` (ids or equation numbers), or all nine."),
    "registry_table": (".curves.formulas", "The registry as a :class:`pandas.DataFrame` (one row per formula)."),
    "fit_formula": (".curves.curve_fit", "Fit ``formula`` to ``points`` and record the options with the result."),
    "fit_experiments": (
        ".workbench",
        "Fit, screen and rank ``formulas`` (default: all nine) on each experiment: what ``tromplab fit`` does, "
        "with its options as keywords of the same names.",
    ),
    "CurveFit": (".curves.curve_fit", "Result of fitting one formula to one experiment."),
    "Workbench": (".workbench", "All fits of a batch with their tables."),
    "curve_indices": (".curves.indices", "All indices of one fitted curve."),
    "rank_formulas": (".curves.ranking", "Ranking table from a tidy table of per-experiment scores."),
    "interval_table": (
        ".statistics.uncertainty",
        "Estimates, standard errors and intervals of the parameters and indices of one fit.",
    ),
    "bootstrap": (".statistics.uncertainty", "Refit ``n`` resampled data sets from the optimum of ``fit``."),
    "akaike_weights": (
        ".statistics.uncertainty",
        "Akaike weights ``exp(-Delta/2) / sum exp(-Delta/2)``; missing criteria get weight 0.",
    ),
    "model_average": (".statistics.uncertainty", "Akaike-weighted averages of ``quantities`` over the fits of one experiment."),
    "model_averages": (".workbench", "Akaike-weighted d_cut, Ep and eta per experiment (the formulas ranked by the batch)."),
    "shared_fit": (
        ".statistics.compare",
        "Fit ``formula`` to all experiments at once with the shape (or ``d_cut``) shared.",
    ),
    "nested_f_test": (
        ".statistics.compare",
        "Whether the extra terms of ``full`` are needed beyond ``reduced`` (same points).",
    ),
    "build_report": (".output.report", "Assemble the report of a fitted batch (and the balances of lab input)."),
    "write_report": (
        ".output.report",
        "Write ``REPORT.html`` and ``REPORT.md`` (figures for the Markdown in ``REPORT_figures/``).",
    ),
    "load": (".workbench", "A batch saved by :meth:`Workbench.save` (refused when saved by another major version)."),
    "fit_density": (".density", "Fit density partition curves to every test of a tracer, float-sink or partition table."),
    "predict_density": (
        ".density",
        "Predict the products of every feed in ``washability``: what ``tromplab density predict`` does, its options "
        "as keywords of the same names.",
    ),
    "reconcile_circuit": (
        ".circuit",
        "Reconcile the survey ``measurements`` over ``flowsheet`` (and fit its separators): what ``tromplab circuit "
        "FLOWSHEET MEASUREMENTS`` does, its options as keywords of the same names.",
    ),
    "design_circuit": (
        ".circuit",
        "Rank the measurements one could add to a survey: what ``tromplab circuit design FLOWSHEET [MEASUREMENTS]`` "
        "does, its options as keywords of the same names.",
    ),
    "monitor_surveys": (
        ".trend",
        "Fit each survey, chart d_cut, Ep, eta (and bypass), flag the surveys where the classifier changed.",
    ),
}

# Subpackages that ``import tromplab`` used to import along with the public names: still
# reachable as attributes (``tromplab.curves.formulas``), imported on first access.
_SUBMODULES = frozenset(
    {
        "circuit",
        "classifiers",
        "curves",
        "density",
        "errors",
        "loading",
        "output",
        "parallel",
        "plant",
        "statistics",
        "trend",
        "validation",
        "workbench",
    }
)


def __getattr__(name: str):
    """Import a public name (or a subpackage) on first access and keep it in the module (PEP 562)."""
    if name in _PUBLIC:
        value = getattr(_importlib.import_module(_PUBLIC[name][0], __name__), name)
        globals()[name] = value  # later accesses skip __getattr__
        return value
    if name in _SUBMODULES:
        return _importlib.import_module(f".{name}", __name__)  # the import binds it in the package
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    """The module's names with the public ones not yet imported and the subpackages."""
    return sorted(set(globals()) | set(__all__) | _SUBMODULES)


__doc__ += (
    "\n"
    + "\n".join(
        f"- ``{name}``: " + (f"installed version ({__version__})" if name == "__version__" else _PUBLIC[name][1])
        for name in __all__
    )
    + "\n"
)
