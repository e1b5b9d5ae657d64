"""The ``--select [KIND:]COLUMN=VALUE`` grammar: parse the items and restrict a campaign to
the tests that meet all of them (every command's ``--select``; moved out of
``soilstats.cli.common``, issue #45: commands only parse, call and print).

Each value is compared as its column's type (:func:`.matching.match_values`); a criterion
with a kind (``sinkage:`` or ``shear:``) speaks about that kind's tests only. A selection
that keeps nothing says why: the criteria that match nothing, or the values each column has
among the tests meeting the others.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ..errors import CampaignError, InputError
from ..kinds import TEST_KINDS
from .matching import match_values, values_present

if TYPE_CHECKING:
    from .campaign import Campaign

__all__ = ["SelectCriterion", "apply_selection", "parse_selection"]


@dataclass(frozen=True)
class SelectCriterion:
    """One ``--select [KIND:]COLUMN=VALUE`` item."""

    column: str
    text: str
    kind: str | None = None  # None: every test; "sinkage"/"shear": tests of that kind only

    def __str__(self) -> str:
        prefix = f"{self.kind}:" if self.kind else ""
        return f"{prefix}{self.column}={self.text}"


def parse_selection(items: Sequence[str]) -> list[SelectCriterion]:
    """Parse ``--select`` items; an :class:`~soilstats.errors.InputError` names the
    malformed one."""
    out = []
    for item in items:
        kind = None
        prefix, colon, rest = item.partition(":")
        if colon and prefix in TEST_KINDS:
            kind, item = prefix, rest
        column, sep, text = item.partition("=")
        if not sep or not column:
            raise InputError(
                f"--select takes [KIND:]COLUMN=VALUE (e.g. soil=soil01 or "
                f"sinkage:velocity_m_s=0.01), got {item!r}"
            )
        out.append(SelectCriterion(column.strip(), text.strip(), kind))
    return out


def apply_selection(
    campaign: Campaign, items: Sequence[str] | Sequence[SelectCriterion]
) -> Campaign:
    """The campaign restricted to the ``--select`` criteria (all must hold).

    Each value is compared as its column's type: a numeric column takes a number (an error
    otherwise), a text column the text as given. A criterion with a kind applies only to
    that kind's tests. Unknown columns and criteria that keep nothing raise the campaign's
    own :class:`~soilstats.errors.CampaignError`.
    """
    criteria = [c if isinstance(c, SelectCriterion) else parse_selection([c])[0] for c in items]
    if not criteria:
        return campaign
    tests = campaign.tests
    masks, own, scopes = [], [], []
    for crit in criteria:
        if crit.column not in tests.columns:
            raise CampaignError(
                f"--select {crit}: no such column; the test log has {list(tests.columns)}",
                file=campaign.file_name("tests"),
                column=crit.column,
            )
        value: object = crit.text
        if pd.api.types.is_numeric_dtype(tests[crit.column]):
            try:
                value = float(crit.text)
            except ValueError:
                raise CampaignError(
                    f"--select {crit}: {crit.column!r} is a numeric column; give a number",
                    file=campaign.file_name("tests"),
                    column=crit.column,
                ) from None
        # The tests a criterion speaks about: all, or those of its kind (the others pass).
        scope = np.ones(len(tests), bool) if crit.kind is None else (tests["kind"] == crit.kind)
        scope = np.asarray(scope, dtype=bool)
        hit = match_values(tests[crit.column], value, crit.column)
        scopes.append(scope)
        own.append(hit & scope)
        masks.append(hit | ~scope)
    keep = np.logical_and.reduce(masks)
    if not keep.any():
        raise _kept_nothing(campaign, criteria, masks, own, scopes)
    return campaign.select(test_id=list(tests["test_id"][keep]))


def _kept_nothing(
    campaign: Campaign,
    criteria: list[SelectCriterion],
    masks: list[np.ndarray],
    own: list[np.ndarray],
    scopes: list[np.ndarray],
) -> CampaignError:
    """The error of a selection that keeps no test: the criteria that match nothing with the
    values present in their column (as ``Campaign.select`` says), or, when each matches some
    tests, every criterion with the values its column has among the tests meeting the others.
    """
    tests = campaign.tests

    def among(crit: SelectCriterion, rows: np.ndarray) -> str:
        where = f" of the {crit.kind} tests" if crit.kind else ""
        return f"{crit.column}{where} has {values_present(tests.loc[rows, crit.column])}"

    empty = [i for i, hit in enumerate(own) if not hit.any()]
    if empty:
        why = "; ".join(
            f"{criteria[i]} matched none (values present: "
            f"{values_present(tests.loc[scopes[i], criteria[i].column])})"
            for i in empty
        )
    else:
        others = [
            np.logical_and.reduce([m for j, m in enumerate(masks) if j != i] or [scopes[i]])
            & scopes[i]
            for i in range(len(criteria))
        ]
        why = (
            f"each of {', '.join(map(str, criteria))} matches some tests, but no test meets "
            "all; among the tests meeting the other criteria, "
            + "; ".join(among(c, rows) for c, rows in zip(criteria, others, strict=True))
        )
    return CampaignError(
        f"--select kept no test: {why} — change the criteria",
        file=campaign.file_name("tests"),
        column=criteria[empty[0] if empty else 0].column,
    )
