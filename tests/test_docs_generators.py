"""The generated documentation pages follow the code (docs/_ext/tromplab_docs.py), without Sphinx:
the formula catalogue has every registry formula, the CLI reference every command and option,
the API page every public name; the release files name the package's one version."""

import argparse
import dataclasses
import importlib.util
import re
import tomllib
import types
from pathlib import Path

import pytest

import tromplab
from tromplab import cli

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def docs_ext():
    spec = importlib.util.spec_from_file_location("tromplab_docs", ROOT / "docs" / "_ext" / "tromplab_docs.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _commands(parser, prefix=("tromplab",)):
    """Every (sub)command of an argparse parser, walked independently of the generator."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield (*prefix, name), sub
                yield from _commands(sub, (*prefix, name))


def test_catalogue_has_a_section_for_every_registry_formula(docs_ext):
    page = docs_ext.formula_catalogue()
    for formula in tromplab.ALL_FORMULAS:
        assert f".. _formula-{formula.id}:" in page, formula.id
        assert f"({formula.equation}) {formula.title}" in page, formula.id
        assert f"``{formula.slope_expression}``" in page, formula.id
        assert f"[{formula.shape_bounds[0]:g}, {formula.shape_bounds[1]:g}]" in page, formula.id
    assert page.count(".. math::") == len(tromplab.ALL_FORMULAS)


def test_a_formula_added_to_the_registry_needs_no_other_edit(docs_ext):
    plitt = tromplab.get_formula("plitt")
    added = dataclasses.replace(plitt, id="plitt_tenth", equation=999, title="A tenth curve (2026)")
    page = docs_ext.formula_catalogue((*tromplab.FORMULAS, added))
    assert ".. _formula-plitt_tenth:" in page and "(999) A tenth curve (2026)" in page


def test_catalogue_names_the_export_conventions_that_express_a_formula(docs_ext):
    assert "whiten" in docs_ext.export_conventions(tromplab.get_formula("lynch"))
    assert {"plitt", "dyssol"} <= set(docs_ext.export_conventions(tromplab.get_formula("rosin_rammler")))
    assert docs_ext.export_conventions(tromplab.get_formula("plitt")) == ["csv-long"]


def test_family_figure_shapes_stay_inside_the_bounds(docs_ext):
    for formula in tromplab.ALL_FORMULAS:
        shapes = docs_ext.family_shapes(formula)
        low, high = formula.shape_bounds
        assert len(shapes) >= 3, formula.id
        assert all(low <= shape <= high for shape in shapes), formula.id


def test_cli_reference_lists_every_command_and_option(docs_ext):
    parser = docs_ext.build_cli_parser()
    page = docs_ext.cli_reference(parser)
    commands = list(_commands(parser))
    assert {path[1] for path, _ in commands} >= {"fit", "report", "export", "trend", "sieve", "rank", "layer", "pulp"}
    for path, sub in commands:
        assert f"``{' '.join(path)}``\n" in page, path
        for action in sub._actions:
            for flag in action.option_strings:
                assert flag in page, (path, flag)
            if not action.option_strings and not isinstance(action, argparse._SubParsersAction):
                assert f"``{action.metavar or action.dest}``" in page, (path, action.dest)


def test_cli_help_texts_are_expanded(docs_ext):
    page = docs_ext.cli_reference()
    assert "%(default)s" not in page
    assert "default 0.05" in page  # --alpha's help, '%(default)s' filled in


def test_cli_reference_shows_options_as_typed(docs_ext):
    """Options in running text are literals, which Sphinx's smart quotes leave alone (a bare
    ``--ci`` would be shown with a typographic dash)."""
    from docutils import nodes
    from docutils.core import publish_doctree

    tree = publish_doctree(docs_ext.cli_reference(), settings_overrides={"report_level": 5, "halt_level": 5})
    code = (nodes.literal, nodes.literal_block)
    running = [node.astext() for node in tree.findall(nodes.Text) if not any(isinstance(up, code) for up in _ancestors(node))]
    assert any("default 0.05" in text for text in running)  # help texts are there
    bare = [text for text in running if re.search(r"(?<![\w-])--?[A-Za-z]", text)]
    assert not bare, bare[:5]
    assert docs_ext._rst_text("with --size-unit mm or -o DIR; pre-processing") == (
        "with ``--size-unit`` mm or ``-o`` DIR; pre-processing"
    )


def _ancestors(node):
    while node.parent is not None:
        node = node.parent
        yield node


def test_parser_factory_is_found_under_either_name(docs_ext):
    assert docs_ext.find_parser_factory(cli)().prog == "tromplab"
    renamed = types.SimpleNamespace(__name__="renamed", build_parser=lambda: argparse.ArgumentParser(prog="renamed"))
    assert docs_ext.find_parser_factory(renamed)().prog == "renamed"
    with pytest.raises(LookupError):
        docs_ext.find_parser_factory(types.SimpleNamespace(__name__="empty"))


def test_api_page_lists_every_public_name(docs_ext):
    page = docs_ext.api_reference()
    listed = set(re.findall(r"^   (\w+)$", page.split("Modules\n=======")[0], flags=re.MULTILINE))
    assert listed == set(tromplab.__all__) - {"__version__"}
    assert ".. data:: __version__" in page


def test_every_markdown_page_is_in_the_site(docs_ext):
    index = (ROOT / "docs" / "index.md").read_text()
    for page in sorted((ROOT / "docs").glob("*.md")):
        if page.stem != "index":
            assert re.search(rf"^{page.stem}$", index, flags=re.MULTILINE), f"docs/{page.name} is not in index.md's toctree"


def test_the_version_lives_in_one_place():
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "version" not in pyproject["project"] and "version" in pyproject["project"]["dynamic"]
    assert pyproject["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "tromplab._version.__version__"}
    citation = (ROOT / "CITATION.cff").read_text()
    assert re.search(rf'^version: "{re.escape(tromplab.__version__)}"$', citation, flags=re.MULTILINE)
    changelog = (ROOT / "CHANGELOG.md").read_text()
    assert f"## [{tromplab.__version__}]" in changelog or "## [Unreleased]" in changelog
    assert (ROOT / "LICENSE").read_text().startswith("MIT License")


def test_getting_started_first_fit_runs(monkeypatch):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    page = (ROOT / "docs" / "getting_started.md").read_text()
    code = page.split("## A first fit in Python", 1)[1].split("```python\n", 1)[1].split("```", 1)[0]
    monkeypatch.chdir(ROOT)  # the page's paths are relative to the repository root
    namespace = {}
    exec(compile(code, "docs/getting_started.md", "exec"), namespace)  # noqa: S102 - the page's own example
    assert namespace["fit"].success and namespace["fit"].experiment == "deck_20mesh"
    plt.close("all")


def test_a_dash_in_a_generated_table_is_a_dash_not_a_bullet(docs_ext):
    from docutils.core import publish_parts
    from docutils.writers.html4css1 import Writer

    body = publish_parts(docs_ext._table(("parameter", "unit"), [("km1", "-")]), writer=Writer())["body"]
    assert "<td>-</td>" in body and "<li>" not in body


@pytest.mark.slow
def test_catalogue_has_a_section_for_every_density_curve(docs_ext, tmp_path):
    from tromplab.density.registry import DENSITY_CURVES

    page = docs_ext.density_catalogue(figure_dir=tmp_path)
    for curve in DENSITY_CURVES:
        assert f".. _density-{curve.id}:" in page and curve.title in page, curve.id
        assert f"``{curve.expression}``" in page, curve.id
        assert (tmp_path / f"density_{curve.id}.png").exists(), curve.id
        for parameter in curve.parameters:
            assert f"[{parameter.lower:g}, {parameter.upper:g}]" in page, (curve.id, parameter.name)
    assert page.count(".. math::") == len(DENSITY_CURVES)


def test_a_function_in_a_formula_is_not_shown_as_an_option(docs_ext):
    """``-exp(t)`` in a curve's notes is maths: a literal there broke the catalogue's reST."""
    assert "``" not in docs_ext._rst_text("P = 1 - exp(-exp(t)) rises slowly")
    assert "``--size-unit``" in docs_ext._rst_text("give --size-unit mm")
