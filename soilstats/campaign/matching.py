"""The one meaning of "column = value": the selections of ``Campaign.select``, ``--select``,
fitting-window rules and study specifications.

A module of its own so that every module of the campaign format that selects tests
(:mod:`.campaign`, :mod:`.window`) imports it, and none of them the other.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np
import pandas as pd
from pandas.api.types import is_bool_dtype, is_numeric_dtype

from ..errors import CampaignError

__all__ = ["SELECT_RTOL", "match_values", "values_present"]


def values_present(series: pd.Series, limit: int = 20) -> str:
    """The distinct values of a test-log column, as error messages list them (``select``
    and the CLI's ``--select``): sorted, at most ``limit``, and whether any are missing."""
    vals = series.dropna().unique().tolist()
    vals = sorted(vals, key=lambda v: (str(type(v)), v))
    shown = ", ".join(repr(v) for v in vals[:limit])
    more = f", … ({len(vals)} in all)" if len(vals) > limit else ""
    missing = " and missing" if series.isna().any() else ""
    return f"[{shown}{more}]{missing}"


def _is_missing(value: object) -> bool:
    return value is None or value is pd.NA or (isinstance(value, float) and np.isnan(value))


#: Relative tolerance of numeric equality in selections: a value typed in a TOML file or on
#: the command line equals the value read from a CSV, whatever the last binary digit.
SELECT_RTOL = 1e-9


def match_values(series: pd.Series, want: Any, column: str) -> np.ndarray:
    """Boolean mask of the rows of ``series`` that a selection criterion keeps.

    The one meaning of "column = value" in soilstats (``Campaign.select``, ``--select``,
    study specifications): a callable gets the column and returns one bool per row; a list,
    tuple, set or array keeps members; None/NaN keeps missing values; any other scalar keeps
    equal values. Numbers in a numeric column are equal within a relative 1e-9; text columns
    compare as text (``"5"``, not ``5``).
    """
    if callable(want):
        got = want(series)
        got = got if isinstance(got, pd.Series) else pd.Series(np.asarray(got).reshape(-1))
        if len(got) != len(series) or not is_bool_dtype(got.dtype):
            raise CampaignError(
                f"the predicate must return one bool per test ({len(series)} tests), got "
                f"{len(got)} values of dtype {got.dtype} — return e.g. `col > 0.1`",
                column=column,
            )
        return got.to_numpy(dtype=bool, na_value=False)
    wanted = (
        list(want) if isinstance(want, Iterable) and not isinstance(want, str | bytes) else [want]
    )
    mask = np.zeros(len(series), dtype=bool)
    if any(_is_missing(w) for w in wanted):
        mask |= series.isna().to_numpy()
    present = [w for w in wanted if not _is_missing(w)]
    if not present:
        return mask
    numbers = [
        w for w in present if isinstance(w, int | float | np.number) and not isinstance(w, bool)
    ]
    if is_numeric_dtype(series) and not is_bool_dtype(series):
        if numbers:
            values = series.to_numpy(dtype=float, na_value=np.nan)[:, None]
            mask |= np.isclose(values, np.asarray(numbers, float), rtol=SELECT_RTOL, atol=0.0).any(
                axis=1
            )
        return mask
    try:
        return mask | series.isin(present).to_numpy(dtype=bool, na_value=False)
    except TypeError:  # e.g. unhashable values: nothing matches
        return mask
