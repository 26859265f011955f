"""The house's counts (issue 44), measured so they stay true: private names imported across
modules inside ``tromplab``, ``locals()`` calls, references to ``_spooled`` in the batch layer,
and the sub-packages ``docs/architecture.md`` names.

Run ``python .ci/house_counts.py`` for the numbers and the private imports listed;
``tests/test_house_counts.py`` holds the limits.
"""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "tromplab"


def module_name(path: Path) -> str:
    """The dotted name of the module at ``path`` (a package's ``__init__`` is the package)."""
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def absolute_module(node: ast.ImportFrom, importer: str, is_package: bool) -> str:
    """The module an ``from X import ...`` names, with relative imports resolved."""
    if node.level == 0:
        return node.module or ""
    base = importer.split(".")
    if not is_package:
        base = base[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def private_imports() -> list[tuple[str, int, str, str]]:
    """Every ``from tromplab.X import _name`` (relative or absolute) inside ``tromplab``, as
    (importing file, line, module, name); ``from . import _submodule`` of a private module and
    dunder names are left out (a module's file name is not a private name of another module)."""
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        importer = module_name(path)
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        for node in ast.walk(tree):
            if not isinstance(node, ast.ImportFrom):
                continue
            source = absolute_module(node, importer, path.name == "__init__.py")
            if not source.startswith("tromplab"):
                continue
            for alias in node.names:
                name = alias.name
                if not name.startswith("_") or name.startswith("__"):
                    continue
                if (PACKAGE.parent / (source.replace(".", "/") + f"/{name}.py")).exists():
                    continue  # a private module imported from its package, not a private name
                found.append((str(path.relative_to(ROOT)), node.lineno, source, name))
    return found


def locals_calls() -> list[tuple[str, int]]:
    """Every call of ``locals()`` in ``tromplab``."""
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "locals":
                found.append((str(path.relative_to(ROOT)), node.lineno))
    return found


def spooled_references() -> int:
    """Occurrences of ``_spooled`` in ``tromplab/workbench/``."""
    return sum(path.read_text(encoding="utf-8").count("_spooled") for path in (PACKAGE / "workbench").rglob("*.py"))


def subpackages() -> list[str]:
    """The sub-packages of ``tromplab`` (folders with an ``__init__.py``)."""
    return sorted(
        str(p.parent.relative_to(PACKAGE)).replace("/", ".") for p in PACKAGE.rglob("__init__.py") if p.parent != PACKAGE
    )


def unnamed_subpackages() -> list[str]:
    """The sub-packages ``docs/architecture.md`` does not name as ``name/``."""
    text = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    return [name for name in subpackages() if not re.search(rf"`{re.escape(name.replace('.', '/'))}/`", text)]


def main() -> int:
    imports = private_imports()
    for path, line, source, name in imports:
        print(f"{path}:{line}: {name} from {source}")
    print(f"private names imported across modules: {len(imports)}")
    print(f"locals() calls: {len(locals_calls())}")
    print(f"_spooled in tromplab/workbench: {spooled_references()}")
    print(f"sub-packages not named in docs/architecture.md: {unnamed_subpackages() or 'none'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
