"""The package itself: ``import tromplab`` is quick and side-effect free,
its public names load on first use (PEP 562), and the ``tromplab`` command and ``python -m
tromplab`` install their signal handling before numpy or pandas are imported.

The import time is measured by benchmarks/import_time.py, not here; these tests check what
it rests on: which modules an import loads."""

import importlib
import json
import os
import signal
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

import tromplab

REPOSITORY = Path(__file__).resolve().parents[1]
HEAVY = ("numpy", "pandas", "scipy", "matplotlib", "statsmodels", "lmfit", "seaborn")


def _loaded_after(code: str) -> list[str]:
    """Top-level packages a fresh interpreter has imported after running ``code``."""
    script = f"{code}\nimport json, sys\nprint(json.dumps(sorted({{m.split('.')[0] for m in sys.modules}})))"
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True, cwd=REPOSITORY)
    return json.loads(done.stdout.splitlines()[-1])


@pytest.mark.parametrize(
    "code",
    [
        "import tromplab",
        "import tromplab._launch",
        "import tromplab.__main__",
        "import tromplab; dir(tromplab); tromplab.__doc__",
    ],
)
def test_importing_the_package_or_its_entry_points_loads_no_numerical_library(code):
    loaded = _loaded_after(code)
    assert "tromplab" in loaded
    assert [name for name in HEAVY if name in loaded] == []


@pytest.mark.slow
def test_the_first_use_of_a_name_imports_its_module():
    loaded = _loaded_after("import tromplab; tromplab.read_points")
    assert "numpy" in loaded and "pandas" in loaded  # the loaders' own imports, not the plots'
    assert "matplotlib" not in loaded


def _summary(obj) -> str:
    """The first paragraph of ``obj``'s docstring on one line (for a tuple of formulas: what it holds)."""
    if isinstance(obj, tuple):
        which = " (the paper's nine)" if obj is tromplab.FORMULAS else " (with extended curves)"
        return f"tuple of {len(obj)} formula records{which}"
    return " ".join((obj.__doc__ or "").strip().split("\n\n")[0].split())


@pytest.mark.parametrize("name", tromplab.__all__[1:])
def test_each_line_of_the_table_is_the_first_paragraph_of_the_objects_docstring(name):
    module, line = tromplab._PUBLIC[name]
    obj = getattr(tromplab, name)
    assert obj is getattr(importlib.import_module(module, "tromplab"), name)  # the module the table names
    assert line == _summary(obj)
    assert f"- ``{name}``: {line}\n" in tromplab.__doc__


def test_the_table_lists_the_public_names_in_the_order_of_all():
    assert list(tromplab._PUBLIC) == tromplab.__all__[1:]
    assert tromplab.__all__[0] == "__version__"
    assert f"- ``__version__``: installed version ({tromplab.__version__})\n" in tromplab.__doc__
    assert sum(line.startswith("- ``") for line in tromplab.__doc__.splitlines()) == len(tromplab.__all__)


def test_dir_lists_every_public_name_and_star_imports_them():
    assert set(tromplab.__all__) <= set(dir(tromplab))
    namespace = {}
    exec("from tromplab import *", namespace)
    assert set(tromplab.__all__) <= set(namespace)
    assert namespace["fit_experiments"] is tromplab.workbench.fit_experiments


def test_the_subpackages_imported_before_are_still_attributes():
    for name in tromplab._SUBMODULES:
        assert getattr(tromplab, name) is importlib.import_module(f"tromplab.{name}")
    assert tromplab.curves.formulas.FORMULAS is tromplab.FORMULAS


def test_an_unknown_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match="module 'tromplab' has no attribute 'no_such_name'"):
        tromplab.no_such_name  # noqa: B018
    assert not hasattr(tromplab, "tromplab_launch")


_PROBE = """
import signal, sys
handled = []

class Probe:  # records, at the first import of numpy, whether tromplab's start-up handlers are installed
    def find_spec(self, name, path=None, target=None):
        if name == "numpy" and not handled:
            from tromplab import _launch
            handled.append([signal.getsignal(s) is _launch._stop_during_start_up for s in (signal.SIGINT, signal.SIGTERM)])
        return None

sys.meta_path.insert(0, Probe())
sys.argv = ["tromplab", "formulas"]
try:
    {launch}
finally:
    print(handled, file=sys.stderr)
"""


@pytest.mark.parametrize(
    "launch",
    [
        "from tromplab._launch import main; main()",  # the console script (pyproject [project.scripts])
        "import runpy; runpy.run_module('tromplab', run_name='__main__', alter_sys=True)",  # python -m tromplab
    ],
    ids=["script", "python-m"],
)
@pytest.mark.slow
def test_both_entry_points_handle_signals_before_numpy_is_imported(launch):
    # SIGINT at its default, as in a terminal: a test run started with ``&`` passes it on ignored,
    # and tromplab keeps an ignored signal so
    done = subprocess.run(
        [sys.executable, "-c", _PROBE.format(launch=launch)],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=REPOSITORY,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    assert done.returncode == 0, done.stderr
    assert "plitt" in done.stdout  # the command ran
    assert done.stderr.strip().splitlines()[-1] == "[[True, True]]"


def test_one_top_level_package_is_installed_and_the_command_goes_through_launch():
    project = tomllib.loads((REPOSITORY / "pyproject.toml").read_text(encoding="utf-8"))
    assert project["project"]["scripts"] == {"tromplab": "tromplab._launch:main"}
    setuptools = pytest.importorskip("setuptools")
    include = project["tool"]["setuptools"]["packages"]["find"]["include"]
    packages = setuptools.find_packages(where=str(REPOSITORY), include=include)
    assert {package.split(".")[0] for package in packages} == {"tromplab"}
    assert "tromplab.curves" in packages


# What a command loads: the parser is built from light modules and each command
# imports what it needs when it runs, so these never load the fitting, plotting or statistics
# stack.  Times are in docs/performance.md; this checks what they rest on.
_COMMAND = """
import json, sys
from tromplab._launch import main
sys.argv = ["tromplab", *{argv!r}]
main()
print(json.dumps(sorted(sys.modules)))
"""
NOT_AT_START_UP = (
    "lmfit",
    "matplotlib",
    "statsmodels",
    "scipy.stats",
    "networkx",
    "tromplab.workbench",
    "tromplab.classifiers.sieve",
    "tromplab.curves.fitting",
    "tromplab.statistics",
)


def _loaded_by_command(*argv: str) -> set[str]:
    done = subprocess.run(
        [sys.executable, "-c", _COMMAND.format(argv=list(argv))], capture_output=True, text=True, timeout=120, cwd=REPOSITORY
    )
    assert done.returncode == 0, done.stderr
    return set(json.loads(done.stdout.splitlines()[-1]))


@pytest.mark.parametrize("argv", [["--version"], ["-h"], ["export", "-h"], ["fit", "-h"], ["pulp", "fit", "-h"]])
@pytest.mark.slow
def test_version_and_help_load_no_numerical_stack_beyond_numpy(argv):
    loaded = _loaded_by_command(*argv)
    assert "tromplab.cli" in loaded
    assert sorted(name for name in loaded if name.split(".")[0] in ("scipy", "pandas") or name in NOT_AT_START_UP) == []


@pytest.mark.slow
def test_an_export_loads_neither_scipys_submodules_nor_the_fitting_stack(tmp_path):
    fits = tmp_path / "fits.csv"
    fits.write_text(
        "experiment,formula,d_cut,shape_name,shape,bypass,fishhook,success,extras\n"
        "a,lynch,100.0,kl,3.0,,,True,\n"
        "a,rosin_rammler,98.0,kr,2.0,,,True,\n"
        "a,plitt,97.0,ks,2.5,,,True,\n",
        encoding="utf-8",
    )
    for convention in ("whiten", "plitt", "csv-long"):
        loaded = _loaded_by_command("export", str(tmp_path), "--to", convention, "-q", "-o", str(tmp_path / "out.csv"))
        assert "tromplab.output.export" in loaded
        # scipy's package itself is light (2 ms); its numerical submodules load when first used
        # (scipy.optimize for the root of a curve with bypass)
        numerical = {"scipy.special", "scipy.optimize", "scipy.stats", "scipy.integrate", "scipy.linalg"}
        assert sorted(name for name in loaded if name in numerical or name in NOT_AT_START_UP) == []


# A command imports its modules before it starts its work (cli.main, on_start): until then an
# interrupt ends the start-up at once (tromplab._launch), never inside a module's initialisation
# (an ImportError, or Python's own exit by SIGINT instead of 130: tests/test_signals.py).
_STARTED_LATE = """
import json, sys
from tromplab import _launch, cli
late, started = [], []

class Probe:  # the modules imported once the command has started its work
    def find_spec(self, name, path=None, target=None):
        if started:
            late.append(name)
        return None

sys.meta_path.insert(0, Probe())
main = cli.main
cli.main = lambda argv=None, *, on_start: main(argv, on_start=lambda: (started.append(True), on_start()))
sys.argv = ["tromplab", *{argv!r}]
assert _launch.main() == 0 and started
print(json.dumps(late))
"""
DATASETS = REPOSITORY / "datasets"


@pytest.mark.parametrize(
    "argv",
    [
        ["formulas"],
        ["export", "{fits}", "--to", "whiten", "-o", "{tmp}/w.csv"],
        ["fit", "{points}", "-o", "{tmp}/fit", "--no-figures", "--jobs", "1"],
        ["points", str(DATASETS / "double_deck_screen_decks_lab.csv"), "-o", "{tmp}/points.csv"],
        ["rank", str(DATASETS / "shuvalov2018_table2_F.csv"), "-o", "{tmp}/rank"],
        ["sieve", "pg", "--hole", "2", "--length", "1.5", "--width", "0.5", "--cell-width", "4"],
        ["layer", "simulate", "--steps", "20"],
        ["pulp", "optimum", "--frequency", "10"],
    ],
    ids=lambda argv: " ".join(argv[:2]),
)
@pytest.mark.slow
def test_a_command_imports_its_modules_before_it_starts(tmp_path, argv):
    (tmp_path / "fits.csv").write_text(
        "experiment,formula,d_cut,shape_name,shape,bypass,fishhook,success,extras\na,lynch,100.0,kl,3.0,,,True,\n",
        encoding="utf-8",
    )
    rows = [f"E{k},{size},{share}" for k in range(2) for size, share in ((10, 0.95), (20, 0.85), (40, 0.6), (80, 0.3), (160, 0.1), (320, 0.03))]  # fmt: skip
    (tmp_path / "points.csv").write_text("experiment,size,partition_fine\n" + "\n".join(rows) + "\n", encoding="utf-8")
    argv = [a.format(fits=tmp_path, points=tmp_path / "points.csv", tmp=tmp_path) for a in argv]
    done = subprocess.run(
        [sys.executable, "-c", _STARTED_LATE.format(argv=argv)], capture_output=True, text=True, timeout=300, cwd=tmp_path,
        env={**os.environ, "PYTHONPATH": str(REPOSITORY)},
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    late = json.loads(done.stdout.splitlines()[-1])
    heavy = {"numpy", "pandas", "scipy", "scipy.special", "scipy.optimize", "scipy.stats", "lmfit", "matplotlib", "networkx"}
    assert [name for name in late if name.startswith("tromplab") or name in heavy] == []
