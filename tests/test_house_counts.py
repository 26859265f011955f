"""The house's counts stay true: measured by ``.ci/house_counts.py``."""

from __future__ import annotations

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SPEC = importlib.util.spec_from_file_location("house_counts", ROOT / ".ci" / "house_counts.py")
counts = importlib.util.module_from_spec(SPEC)
SPEC.loader.exec_module(counts)


def test_at_most_five_private_names_are_imported_across_modules():
    found = counts.private_imports()
    assert len(found) <= 5, "\n".join(f"{path}:{line}: {name} from {source}" for path, line, source, name in found)


def test_the_counter_sees_a_private_import(tmp_path):
    import ast

    node = ast.parse("from .fitting import _hessian, public").body[0]
    assert counts.absolute_module(node, "tromplab.density.covariance", False) == "tromplab.density.fitting"


def test_no_locals_carry_options():
    assert counts.locals_calls() == []


def test_the_batch_layer_names_its_old_storage_flag_at_most_three_times():
    assert counts.spooled_references() <= 3


def test_every_sub_package_is_named_in_the_architecture_page():
    assert counts.unnamed_subpackages() == []
