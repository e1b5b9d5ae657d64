"""Thin entry points of the simulator export for a notebook: the parameter table, or the JSON
record beside it, from joint draws in one call (:func:`soilstats.bayes.export.export_simulator`
does the work and says everything; these refuse a table Chrono would silently change)."""

from __future__ import annotations

from typing import Any

import pandas as pd

from .export import SimulatorConstraintError, export_simulator
from .support import SupportCheck

__all__ = ["simulator_parameters", "simulator_record"]


def simulator_parameters(
    draws: pd.DataFrame,
    simulator: str = "chrono-scm",
    **options: Any,  # export_simulator's keywords, each of its own type
) -> pd.DataFrame:
    """Joint draws as a simulator's parameter table (:func:`export_simulator`'s ``table``;
    ``options`` are its keywords: elastic_K, damping_R, priors, seed, repair, ...).

    Raises :class:`SimulatorConstraintError` when a row breaks SCM's constraints (a table
    Chrono would silently change is never returned); ``repair`` repairs elastic_K.
    """
    export = export_simulator(draws, simulator, **{"on_failure": "return", **options})
    if not export.check.passed:
        raise SimulatorConstraintError("; ".join(export.check.failures), export.check)
    return export.table


def simulator_record(
    draws: pd.DataFrame,
    simulator: str = "chrono-scm",
    *,
    support: SupportCheck | None = None,
    context: dict | None = None,
    **options: Any,  # export_simulator's keywords, each of its own type
) -> dict:
    """The JSON record beside a simulator's CSV (:meth:`SimulatorExport.record`).

    ``support``: the :class:`~soilstats.bayes.support.SupportCheck` of the draws; ``context``:
    seed, soil, selection, version and any other facts of the run, copied in; ``options``:
    the keywords of :func:`export_simulator`.
    """
    options = {"on_failure": "return", **options}
    return export_simulator(draws, simulator, **options).record(support, context)
