"""Warnings for names that differ only in case, blanks or Unicode form.

The format keeps text exactly (``docs/campaign-format.md``, "Cells"): ``'soil01 '`` and
``'soil01'`` are two soils, ``' preparation'`` is a covariate and not the format column
``preparation``, and ``'shape-0001 '`` is a test of its own. Each is read as written — nothing
is changed — but a typing slip of this kind splits one group, hides a format column or makes
two tests a person cannot tell apart, with nothing else to show it; so the reader says so.
"""

from __future__ import annotations

import unicodedata
import warnings
from collections.abc import Mapping

import pandas as pd

from ..errors import SoilstatsWarning
from .schema import DERIVED_COLUMNS, FILES, SPECS

__all__ = ["warn_near_names"]

#: Log columns whose values name groups the analyses keep apart, then the test key.
GROUP_NAMES = ("soil", "preparation", "operator")


def _key(text: str) -> str:
    """What a reader of a table sees: no outer blanks, no case, one Unicode form (NFKC:
    ``'ｓ'`` is ``'s'``, a decomposed ``'é'`` the composed one)."""
    return unicodedata.normalize("NFKC", text).strip().casefold()


def _shown(ids: list[str]) -> str:
    return ", ".join(ids[:6]) + (", …" if len(ids) > 6 else "")


def warn_near_names(tables: Mapping[str, pd.DataFrame], files: Mapping[str, str]) -> None:
    """Warn (:class:`SoilstatsWarning`) of near-equal group names, test ids and column names."""
    tests = tables["tests"]
    file = files.get("tests", "tests.csv")
    for column in GROUP_NAMES:
        if column in tests:
            _group_names(tests, column, file)
    _test_ids(tests, file)
    for stem in FILES:
        if stem in tables:
            _columns(tables[stem], stem, files.get(stem, f"{stem}.csv"))


def _variants(names: pd.Series) -> list[list[str]]:
    """Groups of distinct values of ``names`` that share one :func:`_key`."""
    keys = names.map(_key)
    groups = names.groupby(keys.to_numpy()).unique()
    return [sorted(map(str, g)) for g in groups[groups.map(len) > 1]]


def _group_names(tests: pd.DataFrame, column: str, file: str) -> None:
    names = tests[column].dropna().astype(str)
    for group in _variants(names):
        ids = tests.loc[names.index[names.isin(group)], "test_id"].astype(str).tolist()
        warnings.warn(
            f"file {file!r}, column {column!r}: "
            + ", ".join(repr(v) for v in group)
            + f" differ only in case, blanks or Unicode form (tests {_shown(ids)}) and are "
            f"analysed apart; if they are one {column}, write one name",
            SoilstatsWarning,
            stacklevel=5,  # the caller of load_campaign or from_frames
        )


def _test_ids(tests: pd.DataFrame, file: str) -> None:
    for group in _variants(tests["test_id"].astype(str)):
        warnings.warn(
            f"file {file!r}, column 'test_id': the tests "
            + ", ".join(repr(v) for v in group)
            + " differ only in case, blanks or Unicode form; they are kept as separate tests "
            "(ids are text, matched exactly) — if one is a typing slip, write one id in the "
            "log and the sample files",
            SoilstatsWarning,
            stacklevel=5,
        )


def _columns(table: pd.DataFrame, stem: str, file: str) -> None:
    known = {c.name for c in SPECS[stem]} | set(DERIVED_COLUMNS.get(stem, ()))
    by_key = {_key(name): name for name in known}
    for column in map(str, table.columns):
        meant = by_key.get(_key(column))
        if column in known or meant is None:
            continue
        present = meant in table.columns
        warnings.warn(
            f"file {file!r}: the column {column!r} is not the format column {meant!r} (column "
            "names are matched exactly: case and blanks count); it is kept as a covariate"
            + ("" if present else f", and {meant!r} counts as not given")
            + f" — if it is meant, name the column {meant!r}",
            SoilstatsWarning,
            stacklevel=5,
        )
