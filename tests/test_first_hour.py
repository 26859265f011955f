"""The newcomer frictions of issue 41 (point 3), each fixed and kept: a full disk or a folder
that cannot be written, a broken installation, the console's words (units, what a column is,
relative paths, wrapped lines), the fit report of an lmfit object, the overview of ties."""

import errno
import os

import pandas as pd
import pytest

from tromplab.cli import main

from .conftest import TWO_EXPERIMENT_POINTS, write

FIT = ["--formulas", "plitt", "--no-figures", "--jobs", "1"]


# --- the file system, not tromplab ------------------------------------------------------------
@pytest.mark.parametrize(
    ("code", "words"),
    [(errno.ENOSPC, "No space left on device"), (errno.EACCES, "Permission denied"), (errno.EROFS, "Read-only")],
)
def test_a_full_disk_or_an_unwritable_folder_is_exit_1_naming_the_folder(tmp_path, monkeypatch, capsys, code, words):
    points = write(tmp_path, TWO_EXPERIMENT_POINTS)
    out = tmp_path / "out"
    assert main(["fit", str(points), "-o", str(out), *FIT]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir() if not p.name.startswith(".")}
    capsys.readouterr()

    def refused(self, path=None, *args, **kwargs):
        raise OSError(code, os.strerror(code), str(path))

    monkeypatch.setattr(pd.DataFrame, "to_csv", refused)
    assert main(["fit", str(points), "-o", str(out), *FIT]) == 1
    monkeypatch.undo()
    err = capsys.readouterr().err
    assert f"could not write in {out}: {words}" in err
    assert "the previous results there are intact" in err and "bug" not in err
    assert {p.name: p.read_bytes() for p in out.iterdir() if not p.name.startswith(".")} == before


def test_another_os_error_is_still_an_internal_error(tmp_path, monkeypatch, capsys):
    points = write(tmp_path, TWO_EXPERIMENT_POINTS)

    def broken(self, path=None, *args, **kwargs):
        raise OSError(errno.EBADF, os.strerror(errno.EBADF))

    monkeypatch.setattr(pd.DataFrame, "to_csv", broken)
    assert main(["fit", str(points), "-o", str(tmp_path / "out"), *FIT]) == 70
    assert "internal error" in capsys.readouterr().err


# --- a broken installation ----------------------------------------------------------------------
@pytest.mark.parametrize(
    ("missing", "words"),
    [
        ("tromplab.curves.engine", "tromplab's module tromplab.curves.engine"),
        ("lmfit", "the package lmfit, which tromplab needs,"),
    ],
)
def test_an_import_error_says_the_installation_is_broken_and_how_to_reinstall(tmp_path, monkeypatch, capsys, missing, words):
    import tromplab.cli.fit

    def run(args):
        raise ModuleNotFoundError(f"No module named '{missing}'", name=missing)

    monkeypatch.setattr(tromplab.cli.fit, "_run_fit", run)
    points = write(tmp_path, TWO_EXPERIMENT_POINTS)
    parser_run = main(["fit", str(points), "-o", str(tmp_path / "out"), *FIT])
    err = capsys.readouterr().err
    assert parser_run == 70
    assert f"the installation is broken: {words} cannot be imported" in err
    assert "python -m pip install --force-reinstall tromplab" in err and "a bug in tromplab" not in err
