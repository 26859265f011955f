"""Docstrings as in fluids: every public function and formula documents exactly its parameters.

A small numpydoc parser (inspect + the section layout) reads the ``Parameters`` section;
the documented names must be the signature's names, in any order, no more and no fewer.
"""

import inspect
import re

import pytest

import tromplab
from tromplab.curves.formulas import ALL_FORMULAS


def numpydoc_sections(doc: str) -> dict[str, list[str]]:
    """``{section title: its lines}`` of a numpydoc docstring (the summary is ``""``)."""
    lines = inspect.cleandoc(doc or "").splitlines()
    sections, title = {"": []}, ""
    for i, line in enumerate(lines):
        if i + 1 < len(lines) and re.fullmatch(r"-{3,}", lines[i + 1].strip()) and line.strip():
            title = line.strip()
            sections[title] = []
        elif not re.fullmatch(r"-{3,}", line.strip()):
            sections[title].append(line)
    return sections


def documented_parameters(doc: str) -> list[str]:
    names = []
    for line in numpydoc_sections(doc).get("Parameters", []):
        if line and not line.startswith(" "):  # a name line; descriptions are indented
            names += [name.strip().lstrip("*") for name in line.split(" : ")[0].split(",")]
    return names


def signature_parameters(function) -> list[str]:
    return [name for name in inspect.signature(function).parameters if name not in ("self", "cls")]


PUBLIC_FUNCTIONS = [getattr(tromplab, name) for name in tromplab.__all__ if inspect.isfunction(getattr(tromplab, name))]
FORMULA_FUNCTIONS = [formula.phi for formula in ALL_FORMULAS]


@pytest.mark.parametrize("function", PUBLIC_FUNCTIONS + FORMULA_FUNCTIONS, ids=lambda f: f.__name__)
def test_documented_parameters_are_the_signature(function):
    doc = function.__doc__
    assert numpydoc_sections(doc)[""][0].strip(), "no one-line summary"
    expected = signature_parameters(function)
    if expected:
        assert "Parameters" in numpydoc_sections(doc), "no Parameters section"
    assert sorted(documented_parameters(doc)) == sorted(expected)


@pytest.mark.parametrize("function", FORMULA_FUNCTIONS, ids=lambda f: f.__name__)
def test_formula_docstrings_have_every_fluids_section(function):
    sections = numpydoc_sections(function.__doc__)
    # the bypass curves are generated from their base (with_bypass), whose doctest covers them
    generated = function.__name__.endswith("_bypass")
    for title in ("Parameters", "Returns", "Notes", "References") + (() if generated else ("Examples",)):
        assert title in sections, f"{function.__name__} lacks {title}"
    assert any(".. math::" in line for line in sections[""]), "no math block"
    notes = " ".join(sections["Notes"])
    assert "slope at the cut" in notes.lower()
    references = " ".join(sections["References"])
    assert re.search(r"\(\d{4}\)", references) or "could not be" in references or "no single primary" in references
    assert "Shuvalov S.I., Novoseltseva S.S., Zhukov V.P. (2018)" in references
    if generated:
        return
    example = "\n".join(sections["Examples"])
    assert ">>>" in example and "(1.0," not in example  # a point away from the trivial cut phi(1) = 1/2


def test_formula_notes_mention_the_corrected_print():
    for formula in ALL_FORMULAS:
        if "printed" in formula.notes.lower() and formula.family == "paper":
            assert "print" in formula.phi.__doc__.lower(), formula.id


def test_parser_reads_a_numpydoc_section():
    doc = """Summary.

    Parameters
    ----------
    a, b : float
        Text.
    *args
        More.

    Returns
    -------
    float
    """
    assert documented_parameters(doc) == ["a", "b", "args"]
