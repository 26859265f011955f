"""The package's import graph: no cycles, counting imports inside functions.

The layer contracts themselves are checked by ``lint-imports`` (pyproject.toml,
``[tool.importlinter]``, run by .ci/run); this test adds what a layers contract cannot say:
that no module reaches back to itself through any chain of imports.
"""

import grimp


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
