"""docs/tutorial.md runs as written: every example and output is checked (doctest)."""

import doctest

import pytest

from .conftest import ROOT


@pytest.mark.slow
def test_tutorial_runs_as_written(monkeypatch):
    monkeypatch.chdir(ROOT)  # the tutorial reads datasets/ by relative path, as a user at the root would
    result = doctest.testfile(
        str(ROOT / "docs" / "tutorial.md"),
        module_relative=False,
        report=True,
        optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE,
    )
    assert result.attempted > 20
    assert result.failed == 0, f"{result.failed} tutorial example(s) print something else (see the output above)"
