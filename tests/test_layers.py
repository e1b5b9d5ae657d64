"""Every import points down: the floors of docs/conventions.md ("Layers"), checked by ``ast``.

The order is written once, in the docs; this test reads it from there and walks every import
of every module of soilstats (module level and inside functions, relative and absolute,
``if TYPE_CHECKING`` included): none may point from a floor to a higher one, and no modules
may import each other round a loop.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "soilstats"
CONVENTIONS = ROOT / "docs" / "conventions.md"


def floors() -> dict[str, int]:
    """Floor number of every name listed in the "Layers" section (1 = the ground floor)."""
    text = CONVENTIONS.read_text(encoding="utf-8")
    section = re.search(r"^## Layers\n(.*?)(?=^## )", text, re.M | re.S)
    assert section, "docs/conventions.md has no '## Layers' section"
    out: dict[str, int] = {}
    for number, head in re.findall(r"^(\d+)\. (.*?)(?: —|$)", section.group(1), re.M):
        for name in re.findall(r"`([^`]+)`", head):
            assert name not in out, f"{name} is on two floors of docs/conventions.md"
            out[name] = int(number)
    assert out, "the 'Layers' section lists no floor"
    return out


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


MODULES = {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def unit(module: str) -> str:
    """The name a module's floor is listed by: its top-level package or module under
    soilstats, ``soilstats`` for the package's ``__init__``, ``__main__`` for entry points."""
    parts = module.split(".")
    if parts[-1] == "__main__":
        return "__main__"
    return parts[1] if len(parts) > 1 else "soilstats"


def known(name: str) -> str | None:
    """The longest prefix of ``name`` that is a module of soilstats (None: not soilstats)."""
    while name and name not in MODULES:
        name = name.rpartition(".")[0]
    return name or None


def imports(module: str, source: str, *, is_package: bool = False):
    """(line, imported soilstats module) of every import statement in ``source``, the text
    of ``module`` (``is_package``: an ``__init__.py``)."""
    package = module if is_package else module.rpartition(".")[0]
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                base = ".".join([*base, node.module] if node.module else base)
            else:
                base = node.module or ""
            # ``from package import name``: the submodule when ``name`` is one.
            targets = [
                f"{base}.{a.name}" if f"{base}.{a.name}" in MODULES else base for a in node.names
            ]
        else:
            continue
        for target in targets:
            found = known(target)
            if found is not None and found != module:
                yield node.lineno, found


GRAPH = {
    module: sorted(
        set(imports(module, path.read_text(encoding="utf-8"), is_package=path.stem == "__init__"))
    )
    for module, path in MODULES.items()
}


def test_the_layers_section_places_every_package_and_names_only_real_ones():
    listed = floors()
    units = {unit(m) for m in MODULES}
    assert not units - set(listed), (
        f"not on any floor of docs/conventions.md ('Layers'): {sorted(units - set(listed))}"
    )
    assert not set(listed) - units, f"listed but not in soilstats: {set(listed) - units}"


def test_every_import_points_down():
    listed = floors()
    upward = []
    for module, edges in GRAPH.items():
        here = unit(module)
        for line, target in edges:
            there = unit(target)
            if listed[there] > listed[here]:
                upward.append(
                    f"{MODULES[module].relative_to(ROOT)}:{line} imports {target}: floor "
                    f"{listed[here]} ({here}) -> floor {listed[there]} ({there})"
                )
    assert not upward, "imports that point up (docs/conventions.md, 'Layers'):\n" + "\n".join(
        upward
    )


def test_no_modules_import_each_other_round_a_loop():
    edges = {m: {t for _, t in targets} for m, targets in GRAPH.items()}
    loops, index, low, stack, on_stack = [], {}, {}, [], set()

    def visit(v: str) -> None:  # Tarjan's strongly connected components
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in edges[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                loops.append(sorted(component))

    for module in edges:
        if module not in index:
            visit(module)
    assert not loops, f"modules that import each other round a loop: {loops}"


def test_the_checker_sees_lazy_and_type_only_imports_that_point_up():
    """The walk finds what a careless edit would add: an import inside a function or under
    ``if TYPE_CHECKING``, relative or absolute."""
    source = (
        "from typing import TYPE_CHECKING\n"
        "if TYPE_CHECKING:\n    from soilstats.cli.main import main\n"
        "def f():\n    from ..report import document\n"
    )
    found = dict(imports("soilstats.fitting.result", source))
    assert found == {3: "soilstats.cli.main", 5: "soilstats.report.document"}
    listed = floors()
    assert all(listed[unit(t)] > listed["fitting"] for t in found.values())
