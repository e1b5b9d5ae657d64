"""Names of a package that load their module on first use (PEP 562).

``import soilstats`` and ``soilstats --help`` must not pay for pandas, SciPy, statsmodels,
matplotlib or ArviZ, and a command must load only what it uses (discovery, for instance,
needs the Holm verdicts of :mod:`soilstats.statistics`, not statsmodels' model APIs).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable


def lazy_names(
    package: str, names: dict[str, str], namespace: dict, subpackages: tuple[str, ...] = ()
) -> tuple[Callable, Callable]:
    """``(__getattr__, __dir__)`` for ``package``, whose public ``names`` map to the module
    (absolute, or relative to the package) that defines each; a name is imported on first
    access and then kept in ``namespace`` (the package's ``globals()``), so later lookups
    skip the hook.  ``subpackages`` load the same way, as ``import package`` users expect
    (``soilstats.identification.pool_sinkage`` after ``import soilstats``)."""

    def __getattr__(name: str) -> object:
        if name in subpackages:
            value = importlib.import_module(f"{package}.{name}")
            namespace[name] = value
            return value
        module = names.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module, package), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(names) | set(subpackages))

    return __getattr__, __dir__
