"""The repository's text says what things are: no tracker numbers in the package, docs and
tests, and each file in tests/data says truthfully how its numbers were made."""

import re
import warnings
from pathlib import Path

import numpy as np
import pytest

import tromplab
from tromplab.curves.formulas import get_formula

from .conftest import ROOT

# References to the project's tracker ("issue" and a number, "(#" and a number), which a reader
# of the package or the docs cannot follow; examples in test_the_tracker_pattern_finds_what_it_should.
TRACKER_REFERENCE = re.compile(r"\bissues?\s+#?\d+|\(#\d+\)", re.IGNORECASE)
THIS_FILE = Path(__file__).resolve()
TEXT_SUFFIXES = {".py", ".md", ".rst", ".txt", ".csv", ".toml", ".cfg", ".html", ".css", ".js"}


def _text_files(folder):
    for path in sorted((ROOT / folder).rglob("*")):
        if path.is_file() and path.suffix in TEXT_SUFFIXES and "_build" not in path.parts and path != THIS_FILE:
            yield path


@pytest.mark.parametrize("folder", ["tromplab", "docs", "tests"])
def test_no_tracker_numbers_in_the_package_docs_and_tests(folder):
    found = [
        f"{path.relative_to(ROOT)}:{number}: {line.strip()}"
        for path in _text_files(folder)
        for number, line in enumerate(path.read_text(encoding="utf-8", errors="replace").splitlines(), 1)
        if TRACKER_REFERENCE.search(line)
    ]
    assert not found, "tracker numbers in the text:\n" + "\n".join(found)


def test_the_tracker_pattern_finds_what_it_should():
    for text in ("issue 12", "(Issue 24, item 1)", "see issues 10", "fixed (#31)"):
        assert TRACKER_REFERENCE.search(text), text
    for text in ("an issue with 12 points", "formula (11)", "row #3"):
        assert not TRACKER_REFERENCE.search(text), text


def _points(name, **options):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return tromplab.read_experiments(ROOT / "tests" / "data" / name, **options).points


def test_the_gas_cyclone_above_its_cut_is_the_rosin_rammler_curve_its_header_names():
    """Header: Rosin-Rammler (5), d_cut 1.0 um, kr 0.55 at the geometric class means."""
    (points,) = _points("gas_cyclone_classes_above_cut_um.csv")
    expected = get_formula("rosin_rammler").phi(points.size / 1.0, 0.55)
    np.testing.assert_allclose(points.partition_fine, expected, rtol=1e-4)
    assert not ((points.partition_fine > 0.25) & (points.partition_fine < 0.75)).any()


SIX_CLASSES = [0.02, 0.10, 0.35, 0.70, 0.92, 0.99]  # partition to fines, coarsest class first


@pytest.mark.parametrize(
    ("name", "stated"),
    [
        ("hydrocyclone_size_class_um.csv", SIX_CLASSES),
        ("european_semicolon_decimal_comma.csv", SIX_CLASSES),
        ("pan_at_zero_masses_mm.csv", SIX_CLASSES),
        ("points_size_um.csv", SIX_CLASSES[1:5]),
        ("gas_cyclone_cut_in_low_feed_classes_um.csv", [0.005, 0.015, 0.04, 0.12, 0.38, 0.62, 0.92]),
    ],
)
def test_each_test_table_holds_the_partitions_its_header_states(name, stated):
    (points,) = _points(name, min_feed_share=0.0)
    np.testing.assert_allclose(points.partition_fine[::-1], stated, atol=1e-5)  # sizes ascend


def test_every_docs_page_is_in_the_readme_table():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    table = readme.split("## Documentation\n", 1)[1].split("\n## ", 1)[0]
    for page in sorted((ROOT / "docs").glob("*.md")):
        if page.stem != "index":
            assert f"docs/{page.name}" in table, f"docs/{page.name} is not in the README's documentation table"


def test_the_readme_stays_short_and_keeps_its_two_commands():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(readme.splitlines()) <= 150
    lines = readme.splitlines()
    main_job = (
        "python -m pip install . && tromplab fit datasets/air_classifier_lab_synthetic.csv -o results --size-unit um --ci 0.95"
    )
    assert main_job in lines
    assert 'python -m pip install -e ".[test]" && python -m pytest' in lines


def test_the_architecture_page_names_every_module():
    page = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    modules = sorted(path.stem for path in (ROOT / "tromplab").rglob("*.py") if path.stem != "__init__")
    missing = [name for name in modules if f"`{name}`" not in page]
    assert not missing, f"docs/architecture.md does not name {missing}"


def test_the_cli_docstring_names_every_command():
    import argparse

    from tromplab import cli

    parser = cli.build_parser()
    (commands,) = [action for action in parser._actions if isinstance(action, argparse._SubParsersAction)]
    for name in commands.choices:
        assert f"``{name}" in cli.__doc__, f"the docstring of tromplab/cli/__init__.py does not name {name}"
