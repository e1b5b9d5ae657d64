"""soilstats raises its own errors, never a bare ``ValueError`` (docs/conventions.md, "Errors
and warnings"), checked by ``ast`` over every module of the package.

Every bad-input error of soilstats is a :class:`~soilstats.errors.SoilstatsError` that also
subclasses ``ValueError``, so ``except ValueError`` callers keep working while
``except SoilstatsError`` catches everything soilstats raises on purpose.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from soilstats import errors

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "soilstats"

#: ``(path relative to the repository, enclosing function)`` of a bare ``raise ValueError``
#: that is meant, each with its reason. Keep it empty: a new entry needs a reason no package
#: error can meet.
ALLOWED: dict[tuple[str, str], str] = {}


def bare_value_errors() -> list[tuple[str, int, str]]:
    """``(file, line, function)`` of every ``raise ValueError`` / ``raise ValueError(...)``."""
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        parents: dict[ast.AST, ast.AST] = {}
        for node in ast.walk(tree):
            for child in ast.iter_child_nodes(node):
                parents[child] = node
        for node in ast.walk(tree):
            if not isinstance(node, ast.Raise) or node.exc is None:
                continue
            exc = node.exc.func if isinstance(node.exc, ast.Call) else node.exc
            if not (isinstance(exc, ast.Name) and exc.id == "ValueError"):
                continue
            scope: ast.AST | None = node
            while scope is not None and not isinstance(
                scope, ast.FunctionDef | ast.AsyncFunctionDef
            ):
                scope = parents.get(scope)
            name = scope.name if scope is not None else "<module>"
            found.append((path.relative_to(ROOT).as_posix(), node.lineno, name))
    return found


def test_no_bare_value_error():
    offenders = [
        f"{file}:{line} (in {function})"
        for file, line, function in bare_value_errors()
        if (file, function) not in ALLOWED
    ]
    assert not offenders, (
        "raise a soilstats.errors class (InputError, ModelError, SpecError, CampaignError, "
        "StatisticsInputError, IdentifiabilityError, ...), not a bare ValueError: "
        + ", ".join(offenders)
    )


def test_allow_list_is_not_stale():
    present = {(file, function) for file, _, function in bare_value_errors()}
    stale = sorted(set(ALLOWED) - present)
    assert not stale, f"allow-listed bare ValueErrors no longer raised: {stale}"


@pytest.mark.parametrize(
    "cls",
    [
        getattr(errors, name)
        for name in errors.__all__
        if isinstance(getattr(errors, name), type)
        and issubclass(getattr(errors, name), errors.SoilstatsError)
        and name != "SoilstatsError"
        and name != "ConvergenceError"
    ],
    ids=lambda cls: cls.__name__,
)
def test_bad_input_errors_are_value_errors(cls):
    """``except ValueError`` keeps catching every bad-input error soilstats raises."""
    assert issubclass(cls, ValueError)
    assert issubclass(cls, errors.SoilstatsError)


def test_input_error_keeps_the_message():
    err = errors.InputError("alpha must be in (0, 1), got 2")
    assert str(err) == "alpha must be in (0, 1), got 2"
    with pytest.raises(ValueError, match=r"alpha must be in \(0, 1\), got 2"):
        raise err
