"""What a posterior pools: the test conditions whose different values its draws mix.

A posterior over the tests of one soil describes one population of tests; where they were
run at several velocities, shapes or (for a model without a size term) plate sizes, its
draws describe the mixture, not any one condition. :func:`pooling_warnings` says so, for the
kinds of test the sampled models pool only (a sinkage-only posterior says nothing about the
campaign's shear tests, which it does not use).
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING

from .._text import natural_key  # levels in natural order: 1, 2, 10 (not 1, 10, 2)
from ..identification.conditions import DEFAULT_CONDITION_COLUMNS
from ..models import get_model

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign

__all__ = ["pooled_columns", "pooling_warnings"]


def pooled_columns(kind: str, models: Iterable[str]) -> tuple[str, ...]:
    """Test-log columns whose different values a posterior should not silently mix: the
    identification's condition columns (one home: identification.conditions) and the setup
    columns of the paper's studies; plate size only where a sinkage model has no size term."""
    sizeless = any(
        (spec := get_model(m)).kind == "sinkage" and "b_m" not in spec.columns for m in models
    )
    setup = {
        "sinkage": ("shape", "series") + (("b_m",) if sizeless else ()),
        "shear": ("grousers", "grouser_height_m", "omega_rpm", "series"),
    }
    return DEFAULT_CONDITION_COLUMNS[kind] + setup[kind]


def pooling_warnings(campaign: Campaign, soil: str, models: Iterable[str]) -> list[str]:
    """One sentence per condition column whose values the posterior of ``models`` on
    ``soil`` pools (Bernstein's plate sizes, velocities, shapes, …), for the kinds of test
    those models use (sinkage, shear) only."""
    models = list(models)
    kinds = {get_model(m).kind for m in models}
    tests = campaign.tests[campaign.tests["soil"].astype(str) == soil]
    out = []
    for kind in ("sinkage", "shear"):
        if kind not in kinds:  # a sinkage-only posterior pools no shear test
            continue
        chosen = tests[tests["kind"] == kind]
        if chosen.empty:
            continue
        for column in pooled_columns(kind, models):
            if column not in chosen:
                continue
            values = chosen[column].dropna().unique()
            if len(values) > 1:
                shown = ", ".join(str(v) for v in sorted(values, key=natural_key)[:6])
                out.append(
                    f"the {kind} posterior pools {len(values)} values of {column} ({shown}): "
                    "its draws describe the mixture, not any one condition; select one with "
                    f"--select {kind}:{column}=VALUE if they differ"
                )
    return out
