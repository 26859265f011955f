"""Sizes of the package's code: no module of ``tromplab/`` above 700 lines of code, no function
above 60 (docs/architecture.md, "Sizes").

A line of code is a line that holds a token of Python other than a comment: blank lines,
comment lines and string statements (docstrings, the strings that document an attribute) are
not code; the lines of a multi-line string inside an expression are.  A function's lines run
from its ``def`` to its last line, nested functions included (and those are measured on their
own too).  Declarations (tables written as code, such as the formula registry) are named in
:data:`DECLARATIONS` and left out of both counts.  Code that is being shrunk is named in
:data:`MODULE_DEBT` and :data:`FUNCTION_DEBT` with its size when it was listed: it may shrink,
not grow, and leaves the list when it is within the limit.
"""

from __future__ import annotations

import ast
import functools
import io
import textwrap
import tokenize
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "tromplab"
MODULE_LIMIT = 700
FUNCTION_LIMIT = 60

#: Tables written as code, left out of the counts: ``"path:name"`` (a module-level assignment or
#: a function, path relative to ``tromplab/``) -> what it declares.
DECLARATIONS = {}

#: Modules above the limit that are being split, with their lines of code as the ceiling.
MODULE_DEBT = {}
#: Functions above the limit that are being shortened, with their lines of code as the ceiling.
FUNCTION_DEBT = {}

_NOT_CODE = {
    tokenize.COMMENT,
    tokenize.NL,
    tokenize.NEWLINE,
    tokenize.INDENT,
    tokenize.DEDENT,
    tokenize.ENCODING,
    tokenize.ENDMARKER,
}


def code_lines(source: str) -> tuple[ast.Module, set[int]]:
    """The module's syntax tree and the numbers of its lines of code."""
    tree = ast.parse(source)
    lines = set()
    for token in tokenize.generate_tokens(io.StringIO(source).readline):
        if token.type not in _NOT_CODE:
            lines.update(range(token.start[0], token.end[0] + 1))
    for node in ast.walk(tree):  # a string as a statement documents; it does nothing
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant) and isinstance(node.value.value, str):
            lines.difference_update(range(node.lineno, node.end_lineno + 1))
    return tree, lines


def _functions(node: ast.AST, prefix: str = ""):
    """Every function and method under ``node`` as (qualified name, node), nested ones too."""
    for child in ast.iter_child_nodes(node):
        if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
            yield prefix + child.name, child
            yield from _functions(child, f"{prefix}{child.name}.")
        elif isinstance(child, ast.ClassDef):
            yield from _functions(child, f"{prefix}{child.name}.")


def _declared_names(statement: ast.stmt) -> list[str]:
    if isinstance(statement, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
        return [statement.name]
    targets = statement.targets if isinstance(statement, ast.Assign) else [getattr(statement, "target", None)]
    return [target.id for target in targets if isinstance(target, ast.Name)]


def measure(root: Path, declarations=DECLARATIONS) -> tuple[dict[str, int], dict[str, int], set[str]]:
    """Lines of code of every module (``"path"``) and function (``"path:qualified.name"``) under
    ``root``, the declarations left out; and the declarations found."""
    modules, functions, found = {}, {}, set()
    for path in sorted(root.rglob("*.py")):
        module = path.relative_to(root).as_posix()
        tree, lines = code_lines(path.read_text(encoding="utf-8"))
        for statement in tree.body:
            for name in _declared_names(statement):
                if f"{module}:{name}" in declarations:
                    found.add(f"{module}:{name}")
                    lines = lines - set(range(statement.lineno, statement.end_lineno + 1))
        modules[module] = len(lines)
        for name, node in _functions(tree):
            if f"{module}:{name}" not in declarations:
                functions[f"{module}:{name}"] = sum(node.lineno <= line <= node.end_lineno for line in lines)
    return modules, functions, found


@functools.cache
def _package_sizes():
    return measure(PACKAGE)


def oversized(sizes: dict[str, int], limit: int, debt: dict[str, int]) -> list[str]:
    """The entries above the limit (or above their ceiling, for debt), largest first, with sizes."""
    over = [(size, name) for name, size in sizes.items() if size > debt.get(name, limit)]
    return [
        f"{name}: {size} lines of code (limit {debt.get(name, limit)}{', the ceiling of its debt' if name in debt else ''})"
        for size, name in sorted(over, reverse=True)
    ]


@pytest.mark.slow
def test_no_module_above_700_lines_of_code():
    modules, _, _ = _package_sizes()
    offenders = oversized(modules, MODULE_LIMIT, MODULE_DEBT)
    assert not offenders, "modules too long (split them by job):\n  " + "\n  ".join(offenders)


@pytest.mark.slow
def test_no_function_above_60_lines_of_code():
    _, functions, _ = _package_sizes()
    offenders = oversized(functions, FUNCTION_LIMIT, FUNCTION_DEBT)
    assert not offenders, "functions too long (split them into steps):\n  " + "\n  ".join(offenders)


def test_the_lists_of_exceptions_are_current():
    modules, functions, found = _package_sizes()
    assert set(DECLARATIONS) == found, f"declarations named but not found: {sorted(set(DECLARATIONS) - found)}"
    stale = [name for name in MODULE_DEBT if modules.get(name, 0) <= MODULE_LIMIT]
    stale += [name for name in FUNCTION_DEBT if functions.get(name, 0) <= FUNCTION_LIMIT]
    assert not stale, f"debt paid (or the code moved): remove these entries from tests/test_code_size.py: {stale}"


def test_lines_of_code_leave_out_blank_lines_comments_and_docstrings():
    source = textwrap.dedent(
        '''\
        """Module docstring,
        two lines."""

        # a comment
        import os  # a comment after code


        def f(x):
            """Docstring."""
            #: an attribute's comment
            y = (
                x
                + 1
            )
            text = """a string
            in an expression"""
            return y, text
        '''
    )
    tree, lines = code_lines(source)
    assert sorted(lines) == [5, 8, 11, 12, 13, 14, 15, 16, 17]
    (name, node), *_ = _functions(tree)
    assert name == "f" and sum(node.lineno <= line <= node.end_lineno for line in lines) == 8


def test_a_new_long_function_or_module_is_found_with_its_size(tmp_path):
    method = "".join(f"        x{i} = {i}\n" for i in range(60))  # the def line and 60 more: 61
    (tmp_path / "long.py").write_text(f"class C:\n    def method(self):\n{method}", encoding="utf-8")
    fine = "".join(f"    x{i} = {i}\n" for i in range(59))  # at the limit
    (tmp_path / "short.py").write_text(f"def fine():\n{fine}", encoding="utf-8")
    (tmp_path / "table.py").write_text("TABLE = [\n" + "".join(f"    {i},\n" for i in range(800)) + "]\n", encoding="utf-8")
    modules, functions, found = measure(tmp_path, declarations={})
    assert functions == {"long.py:C.method": 61, "short.py:fine": 60}
    assert oversized(functions, FUNCTION_LIMIT, {}) == ["long.py:C.method: 61 lines of code (limit 60)"]
    assert oversized(functions, FUNCTION_LIMIT, {"long.py:C.method": 61}) == []  # debt at its ceiling
    assert oversized(functions, FUNCTION_LIMIT, {"long.py:C.method": 60}) == [
        "long.py:C.method: 61 lines of code (limit 60, the ceiling of its debt)"
    ]
    assert oversized(modules, MODULE_LIMIT, {}) == ["table.py: 802 lines of code (limit 700)"]
    modules, _, found = measure(tmp_path, declarations={"table.py:TABLE": "a table"})
    assert found == {"table.py:TABLE"} and modules["table.py"] == 0
