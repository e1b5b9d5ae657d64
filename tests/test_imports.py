"""Imports at the top (issue #45), checked by ``ast`` over every module of soilstats.

* An import inside a function defers a heavy or optional library, and says which on its
  first line: ``# deferred: <library> ...`` with the library one of :data:`DEFERRABLE` (an
  import of a soilstats module names the library that module loads). Any other import sits at
  the top of its module, where a reader and the import-cost tests see it.
* No private name (``_x``) is imported from another module of soilstats: a helper two
  modules share is public there (with a docstring), or lives where it is used. Private
  *modules* (``_html``, ``_lazy``) are package-internal by design and may be imported.

:data:`PENDING` lists the modules not yet converted, with their count of each kind: it only
shrinks (an entry must match its module exactly, so converting one means deleting it here).
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "soilstats"

#: What an import inside a function may defer: libraries that cost a noticeable part of a
#: second to import (on the reference machine) or that are optional extras.
DEFERRABLE = {
    "arviz": "2 s; only the Bayesian outputs need it",
    "distributed": "optional: a Dask cluster",
    "joblib": "0.4 s; only when workers start",
    "matplotlib": "1 s; only when a figure is drawn",
    "numpy": "soilstats.outputs and report.document, which every layer writes with, load none",
    "pandas": "0.5 s; the command-line parser, soilstats.outputs and report.document load none",
    "platformdirs": "optional (ArviZ's dependency)",
    "pyarrow": "optional: the parquet extra",
    "scipy.stats": "0.35 s beyond numpy",
    "statsmodels": "1 s; the ANOVA and model APIs",
    "tqdm": "0.3 s; only with a progress bar",
    "typst": "the PDF engine; only when a report is written",
    "xarray": "0.7 s; only the netCDF outputs",
}

#: module (path under soilstats/) -> (undeclared function-level imports, private names
#: imported from other modules). Only shrinks.
PENDING: dict[str, tuple[int, int]] = {}

DEFERRED = re.compile(r"#\s*deferred:\s*([A-Za-z_][\w.]*)")


def _modules() -> list[Path]:
    return sorted(PACKAGE.rglob("*.py"))


def _function_imports(tree: ast.Module) -> list[ast.Import | ast.ImportFrom]:
    out: list[ast.Import | ast.ImportFrom] = []

    def visit(node: ast.AST, inside: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.Import | ast.ImportFrom) and inside:
                out.append(child)
            visit(child, inside or isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef))

    visit(tree, False)
    return out


def _top_level_libraries(tree: ast.Module) -> set[str]:
    """Dotted names a module imports at module level (outside functions, ``if
    TYPE_CHECKING`` left out): ``import a.b`` gives ``a.b``, ``from a import b`` gives ``a``
    and ``a.b``."""
    names: set[str] = set()

    def visit(node: ast.AST) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
                continue
            if isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                continue
            if isinstance(child, ast.Import):
                names.update(a.name for a in child.names)
            elif isinstance(child, ast.ImportFrom) and child.level == 0 and child.module:
                names.add(child.module)
                names.update(f"{child.module}.{a.name}" for a in child.names)
            visit(child)

    visit(tree)
    return names


def _loaded_at_top(library: str, top: set[str]) -> bool:
    """Whether ``library`` (or a submodule of it) is imported at the module's top anyway."""
    return any(n == library or n.startswith(library + ".") for n in top)


def undeclared_imports(path: Path) -> list[str]:
    """``line: statement`` of each import inside a function of ``path`` that does not say
    which deferrable library it defers, or defers one the module imports at its top anyway."""
    source = path.read_text(encoding="utf-8")
    lines = source.splitlines()
    tree = ast.parse(source)
    top = _top_level_libraries(tree)
    out = []
    for node in _function_imports(tree):
        text = lines[node.lineno - 1]
        said = DEFERRED.search(text)
        library = said.group(1) if said else None
        ok = library in DEFERRABLE and not _loaded_at_top(library, top)
        if not ok:
            out.append(f"{node.lineno}: {text.strip()}")
    return out


def _target(path: Path, node: ast.ImportFrom) -> Path | None:
    """The package directory or module file ``node`` imports from (None: not soilstats)."""
    if node.level == 0:
        if not (node.module or "").startswith("soilstats"):
            return None
        base = ROOT
        parts = (node.module or "").split(".")
    else:
        base = path.parent
        for _ in range(node.level - 1):
            base = base.parent
        parts = node.module.split(".") if node.module else []
    for part in parts:
        base = base / part
    return base


def private_imports(path: Path) -> list[str]:
    """``line: name from module`` of each private name ``path`` imports from another module
    of soilstats (a private submodule imported by name is a module, not a name: allowed)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.ImportFrom):
            continue
        target = _target(path, node)
        if target is None:
            continue
        for alias in node.names:
            name = alias.name
            if not name.startswith("_") or name.startswith("__"):
                continue
            if (target / f"{name}.py").is_file() or (target / name / "__init__.py").is_file():
                continue  # a submodule
            out.append(f"{node.lineno}: {name} from {'.' * node.level}{node.module or ''}")
    return out


def test_function_level_imports_say_what_they_defer():
    found = {}
    for path in _modules():
        rel = path.relative_to(PACKAGE).as_posix()
        bad = undeclared_imports(path)
        allowed = PENDING.get(rel, (0, 0))[0]
        if len(bad) != allowed:
            found[rel] = bad
    assert found == {}, (
        "imports inside functions belong at the top of the module, unless they defer a library "
        f"of DEFERRABLE and say so ('# deferred: <library>'); PENDING only shrinks: {found}"
    )


def test_no_private_name_is_imported_across_modules():
    found = {}
    for path in _modules():
        rel = path.relative_to(PACKAGE).as_posix()
        bad = private_imports(path)
        allowed = PENDING.get(rel, (0, 0))[1]
        if len(bad) != allowed:
            found[rel] = bad
    assert found == {}, (
        "a private name imported from another module: make it public there (with a "
        f"docstring) or move it to where it is used; PENDING only shrinks: {found}"
    )


def test_the_checks_catch_what_they_forbid(tmp_path):
    """The walkers themselves: a bare function import, an undeferrable reason, a deferral of
    a library already at the top, and a private name are caught; a declared one is not."""
    package = tmp_path / "soilstats"
    package.mkdir()
    (package / "_private_module.py").write_text("")
    module = package / "m.py"
    module.write_text(
        "import tqdm\n"
        "from ._private_module import x\n"
        "from . import _private_module\n"
        "from .other import _helper\n"
        "def f():\n"
        "    import csv\n"
        "    import pyarrow  # deferred: pyarrow (the parquet extra)\n"
        "    import json  # deferred: json\n"
        "    from .x import y  # deferred: scipy.stats (a module that loads it)\n"
        "    from tqdm import auto  # deferred: tqdm\n"
    )
    assert [b.split(":")[0] for b in undeclared_imports(module)] == ["6", "8", "10"]
    assert private_imports(module) == ["4: _helper from .other"]
