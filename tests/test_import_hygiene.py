"""Importing soilstats is cheap and changes no global state (a notebook user's backend)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

import soilstats

HEAVY = ("pandas", "scipy.stats", "statsmodels", "matplotlib", "seaborn", "arviz", "emcee")


def _python(code: str) -> str:
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return run.stdout


def test_import_soilstats_loads_no_heavy_library():
    loaded = json.loads(
        _python(
            "import json, sys, soilstats; "
            f"print(json.dumps([m for m in {list(HEAVY)!r} if m in sys.modules]))"
        )
    )
    assert loaded == []


def test_the_command_line_parser_loads_no_heavy_library():
    loaded = json.loads(
        _python(
            "import json, sys; from soilstats.cli.main import build_parser; build_parser(); "
            f"print(json.dumps([m for m in {list(HEAVY)!r} if m in sys.modules]))"
        )
    )
    assert loaded == []


def test_no_import_changes_the_matplotlib_backend():
    code = """
import importlib, pkgutil, matplotlib
matplotlib.use("svg")
calls = []
real_use = matplotlib.use
matplotlib.use = lambda *a, **k: calls.append(a) or real_use(*a, **k)
import soilstats
for mod in pkgutil.walk_packages(soilstats.__path__, "soilstats."):
    if mod.name.startswith("soilstats.cli") or mod.name.endswith("__main__"):
        continue
    importlib.import_module(mod.name)
print(matplotlib.get_backend(), len(calls))
"""
    backend, calls = _python(code).split()
    assert backend.lower() == "svg" and calls == "0"


def test_every_public_name_resolves_and_is_listed():
    for name in soilstats.__all__:
        assert getattr(soilstats, name) is not None, name
    assert set(soilstats.__all__) <= set(dir(soilstats))


def test_only_the_report_package_renders():
    """Figures and PDFs have one home: no analysis module imports a plotting library.

    One known departure (docs/conventions.md): a fit's ``plot_fit``/``plot_residuals``, the
    lmfit-level API of issue #47, import matplotlib inside those methods (never at import)."""
    import ast
    from pathlib import Path

    package = Path(soilstats.__file__).parent
    offenders = []
    for path in package.rglob("*.py"):
        if path.relative_to(package).parts[0] == "report":
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        allowed = set()
        if path.relative_to(package).as_posix() == "fitting/result.py":
            for fn in ast.walk(tree):
                if isinstance(fn, ast.FunctionDef) and fn.name in ("plot_fit", "plot_residuals"):
                    allowed |= {id(n) for n in ast.walk(fn)}
        for node in ast.walk(tree):
            if id(node) in allowed:
                continue
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                names = [node.module]
            offenders += [
                f"{path.name}: {n}" for n in names if n.split(".")[0] in ("matplotlib", "seaborn")
            ]
    assert offenders == []


@pytest.mark.slow  # fresh interpreters: CI runs it
def test_lazy_statistics_names_are_the_functions_whatever_was_imported_first():
    """soilstats.statistics loads its modules on first use; importing every submodule first
    (as another module may) must not shadow a function by a module of the same name."""
    code = (
        "import importlib, json, pkgutil, sys, types\n"
        "import soilstats.statistics as s\n"
        "for m in pkgutil.iter_modules(s.__path__):\n"
        "    importlib.import_module('soilstats.statistics.' + m.name)\n"
        "bad = [n for n in s.__all__ if isinstance(getattr(s, n), types.ModuleType)]\n"
        "print(json.dumps(bad))\n"
    )
    assert json.loads(_python(code)) == []


@pytest.mark.slow  # a fresh interpreter: CI runs it
def test_discovery_does_not_load_the_statsmodels_model_apis():
    loaded = json.loads(
        _python(
            "import json, sys; import soilstats.discovery.pipeline; "
            "print(json.dumps([m for m in ('statsmodels.api', 'statsmodels.formula.api') "
            "if m in sys.modules]))"
        )
    )
    assert loaded == []
