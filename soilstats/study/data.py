"""Which tests a study reads, and the clear error when the campaign cannot answer it."""

from __future__ import annotations

from typing import TYPE_CHECKING

import pandas as pd

from ..campaign.matching import match_values
from ..errors import StudyDataError
from ..identification.conditions import condition_label

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign
    from .spec import StudySpec

__all__ = ["StudyDataError", "select_tests"]


def select_tests(campaign: Campaign, spec: StudySpec) -> pd.DataFrame:
    """The test-log rows of ``spec``: its kind, ``tests.where`` (columns required) and
    ``tests.where_present`` (applied only when the campaign has the column).

    Raises
    ------
    StudyDataError
        A required column is missing, no test matches, or the factor is not recorded.
    """
    tests = campaign.tests
    chosen = tests[tests["kind"] == spec.kind]
    what = f"{spec.name} study"
    if chosen.empty:
        raise StudyDataError(
            f"{what} needs {spec.kind} tests; the campaign {campaign.source} has none "
            f"(kinds present: {sorted(tests['kind'].unique())})"
        )
    for column, wanted in spec.where.items():
        if column not in tests.columns:
            raise StudyDataError(
                f"{what} needs the test-log column {column!r} (tests.where); columns present: "
                f"{list(tests.columns)}"
            )
        chosen = chosen[match_values(chosen[column], wanted, column)]
    for column, wanted in spec.where_present.items():
        if column in tests.columns:
            chosen = chosen[match_values(chosen[column], wanted, column)]
    if chosen.empty:
        raise StudyDataError(
            f"{what}: no {spec.kind} test matches {spec.where | spec.where_present}"
        )
    if spec.factor not in tests.columns:
        raise StudyDataError(
            f"{what} needs {spec.kind} tests with the column {spec.factor!r} (its factor); "
            f"columns present: {list(tests.columns)}"
        )
    missing = chosen[spec.factor].isna()
    if missing.all():
        raise StudyDataError(
            f"{what} needs {spec.kind} tests with {spec.factor} recorded; it is empty for all "
            f"{len(chosen)} selected tests"
        )
    return chosen[~missing].copy()


def soils_with_levels(tests: pd.DataFrame, spec: StudySpec) -> tuple[list[str], list[str]]:
    """Soils with ≥ 2 levels of the factor, and notes on the soils left out.

    Raises
    ------
    StudyDataError
        No soil has two or more levels (e.g. "velocity study needs sinkage tests with at
        least two velocity_m_s values per soil").
    """
    levels = tests.groupby("soil")[spec.factor].nunique()
    good = sorted(levels[levels >= 2].index.astype(str))

    def values(soil: object) -> str:
        return ", ".join(
            map(condition_label, tests.loc[tests["soil"] == soil, spec.factor].unique())
        )

    notes = [
        f"soil {soil} left out: one {spec.factor} value only ({values(soil)})"
        for soil in sorted(levels[levels < 2].index.astype(str))
    ]
    if not good:
        raise StudyDataError(
            f"{spec.name} study needs {spec.kind} tests with at least two {spec.factor} values "
            f"per soil; found {', '.join(f'{s}: {n}' for s, n in levels.items())}"
        )
    return good, notes


def check_reference(tests: pd.DataFrame, spec: StudySpec) -> list[str]:
    """Notes on soils lacking the spec's ``reference`` level; an error when no soil has it.

    A reference absent from the data would leave the reference-pairs table empty without a
    word (a typo such as ``reference = 0.11`` for 0.1).

    Raises
    ------
    StudyDataError
        The reference level is not a value of the factor in any selected test.
    """
    if spec.reference is None:
        return []
    ref = condition_label(spec.reference)
    labels = tests[spec.factor].map(condition_label)
    found = sorted(labels.unique())
    if ref not in set(found):
        raise StudyDataError(
            f"{spec.name} study: reference = {spec.reference!r} is not a {spec.factor} value of "
            f"the selected tests (values: {', '.join(found)})"
        )
    has = tests.loc[labels == ref, "soil"].astype(str).unique()
    return [
        f"soil {soil}: no test at the reference {spec.factor} = {ref}; no reference pairs"
        for soil in sorted(set(tests["soil"].astype(str)) - set(has))
    ]
