"""Types at the boundaries (issue #38): every public function and method is annotated.

Public: a function at the top of a module, or a method of a class, whose name does not start
with ``_`` (``__init__`` counts: its parameters, not its return), in a class whose name does
not start with ``_``. Each parameter (``self`` and ``cls`` of a method aside, ``*args`` and
``**kwargs`` included) and the return need an annotation; mypy (``[tool.mypy]`` in
pyproject.toml) then checks that they are true. Walked with ``ast``, so a regression names the
file, the line, the function and what it lacks.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "soilstats"


def _missing(node: ast.FunctionDef | ast.AsyncFunctionDef, method: bool) -> list[str]:
    """What ``node`` lacks, in the order of its signature: parameter names (``*args`` and
    ``**kwargs`` with their stars), then ``return``."""
    a = node.args
    star = [] if a.vararg is None else [("*", a.vararg)]
    stars = [] if a.kwarg is None else [("**", a.kwarg)]
    params = [("", p) for p in (*a.posonlyargs, *a.args)] + star
    params += [("", p) for p in a.kwonlyargs] + stars
    if method:
        params = [(s, p) for s, p in params if s or p.arg not in ("self", "cls")]
    out = [s + p.arg for s, p in params if p.annotation is None]
    if node.returns is None and node.name != "__init__":
        out.append("return")
    return out


def unannotated(source: str) -> Iterator[tuple[int, str, list[str]]]:
    """(line, qualified name, what it lacks) of every public function or method of
    ``source`` (a module's text) that lacks an annotation."""

    def visit(node: ast.AST, owner: str | None) -> Iterator[tuple[int, str, list[str]]]:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.ClassDef):
                if not child.name.startswith("_"):
                    yield from visit(
                        child, child.name if owner is None else f"{owner}.{child.name}"
                    )
            elif isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef):
                if child.name.startswith("_") and child.name != "__init__":
                    continue
                missing = _missing(child, method=owner is not None)
                if missing:
                    name = child.name if owner is None else f"{owner}.{child.name}"
                    yield child.lineno, name, missing

    yield from visit(ast.parse(source), None)


def test_every_public_function_and_method_is_annotated():
    found = [
        f"{path.relative_to(ROOT)}:{line}: {name} lacks {', '.join(missing)}"
        for path in sorted(PACKAGE.rglob("*.py"))
        for line, name, missing in unannotated(path.read_text(encoding="utf-8"))
    ]
    assert not found, (
        "public functions without full annotations (annotate them; mypy checks them):\n"
        + "\n".join(found)
    )


def test_the_checker_sees_what_a_careless_edit_leaves_out():
    """Parameters, stars, returns and methods of public classes; not private names, not
    ``self``, not ``__init__``'s return, not functions nested in functions."""
    source = (
        "def f(a, b: int, *args, c=1, **kw): ...\n"
        "def g(a: int) -> int:\n    def inner(x): ...\n    return a\n"
        "def _private(a): ...\n"
        "class A:\n"
        "    def __init__(self, x): ...\n"
        "    def m(self, y: int): ...\n"
        "    @classmethod\n    def k(cls) -> A: ...\n"
        "    def _hidden(self, z): ...\n"
        "    class B:\n        def n(self) -> None: ...\n        def o(self, q) -> None: ...\n"
        "class _C:\n    def p(self, r): ...\n"
    )
    assert list(unannotated(source)) == [
        (1, "f", ["a", "*args", "c", "**kw", "return"]),
        (7, "A.__init__", ["x"]),
        (8, "A.m", ["return"]),
        (14, "A.B.o", ["q"]),
    ]
