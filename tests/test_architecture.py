"""The package's import graph: no cycles, counting imports inside functions.

The layer contracts themselves are checked by ``lint-imports`` (pyproject.toml,
``[tool.importlinter]``, run by .ci/run); this test adds what a layers contract cannot say:
that no module reaches back to itself through any chain of imports, and that every module of
`tromplab.density` and `tromplab.circuit` has its place in its package's contract.
"""

import grimp
import pytest


def _cycles(graph) -> list[list[str]]:
    """Every module that lies on an import cycle, with one cycle through it."""
    found, state = [], {}

    def visit(module, path):
        state[module] = "open"
        for imported in sorted(graph.find_modules_directly_imported_by(module)):
            if state.get(imported) == "open":
                found.append(path[path.index(imported) :] + [imported])
            elif imported not in state:
                visit(imported, [*path, imported])
        state[module] = "done"

    for module in sorted(graph.modules):
        if module not in state:
            visit(module, [module])
    return found


def test_no_import_cycles_counting_function_level_imports():
    graph = grimp.build_graph("tromplab", exclude_type_checking_imports=True)
    assert _cycles(graph) == []


def test_the_cycle_finder_sees_a_cycle_made_inside_a_function():
    graph = grimp.ImportGraph()
    for module in ("pkg", "pkg.a", "pkg.b"):
        graph.add_module(module)
    graph.add_import(importer="pkg.a", imported="pkg.b")
    graph.add_import(importer="pkg.b", imported="pkg.a")  # as `def f(): from . import a` records it
    assert _cycles(graph) == [["pkg.a", "pkg.b", "pkg.a"]]


def test_function_level_imports_are_in_the_graph():
    # the curves layer's views render a fit; an import of them inside a function still counts
    graph = grimp.build_graph("tromplab", exclude_type_checking_imports=True)
    assert graph.direct_import_exists(importer="tromplab.curves.curve_fit", imported="tromplab.curves.views")
    assert not graph.direct_import_exists(importer="tromplab.curves.curve_fit", imported="tromplab.output.results")


def _contract_layers(container: str) -> list[str]:
    """The layers of the contract of ``container`` in pyproject.toml, top first."""
    import tomllib
    from pathlib import Path

    config = tomllib.loads((Path(__file__).resolve().parents[1] / "pyproject.toml").read_text())
    contracts = [c for c in config["tool"]["importlinter"]["contracts"] if c.get("containers") == [container]]
    assert len(contracts) == 1, f"{container} has {len(contracts)} layers contracts, one expected"
    return contracts[0]["layers"]


@pytest.mark.parametrize("container", ["tromplab.density", "tromplab.circuit"])
def test_every_module_of_density_and_circuit_has_its_place_in_the_package_contract(container):
    # a module left out of a layers contract may import anything in its package: the contract would
    # hold while saying nothing about it
    import importlib
    import pkgutil

    named = {name.strip() for layer in _contract_layers(container) for name in layer.split("|")}
    modules = {info.name for info in pkgutil.iter_modules(importlib.import_module(container).__path__)}
    assert modules == named, f"not in the contract: {sorted(modules - named)}; no such module: {sorted(named - modules)}"
