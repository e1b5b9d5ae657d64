"""Input checks shared by every test in :mod:`soilstats.statistics`.

Each public function takes a tidy :class:`pandas.DataFrame` (one row per observation) and the
names of its columns.  The checks here turn bad input into a :class:`StatisticsInputError`
that names the column, the value seen and the fix, before any arithmetic happens.  Rows with a
missing value are never dropped silently: they raise unless the caller passes ``dropna=True``,
and then the number dropped is recorded in the result's ``attrs["n_dropped"]``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from ..errors import ConfoundingError, StatisticsInputError

__all__ = ["ConfoundingError", "StatisticsInputError", "prepare"]


def _check_frame(data: object) -> pd.DataFrame:
    if not isinstance(data, pd.DataFrame):
        raise StatisticsInputError(
            f"data must be a pandas DataFrame with one row per observation, got "
            f"{type(data).__name__}; build one with pandas.DataFrame({{...}})"
        )
    return data


def prepare(
    data: pd.DataFrame,
    numeric: Sequence[str],
    categorical: Sequence[str],
    *,
    dropna: bool,
    min_levels: dict[str, int] | None = None,
) -> tuple[pd.DataFrame, int]:
    """Select, check and clean the columns a test needs.

    Parameters
    ----------
    data : pandas.DataFrame
        Tidy data, one row per observation.  Never modified.
    numeric : sequence of str
        Columns that must hold finite numbers (the response, a covariate).
    categorical : sequence of str
        Grouping columns (factor, blocks).  Their values are used as labels.
    dropna : bool
        If False, a missing value in any of the columns raises; if True, such rows are dropped.
    min_levels : dict, optional
        Minimum number of distinct levels per categorical column (default 2 for each).

    Returns
    -------
    frame : pandas.DataFrame
        A new frame with just these columns (numeric as float64, categorical as str-free
        ``object`` labels) and a fresh ``RangeIndex``.
    n_dropped : int
        Rows dropped because of missing values (0 unless ``dropna``).

    Raises
    ------
    StatisticsInputError
        Missing column, missing values without ``dropna``, non-finite numbers, too few levels.
    """
    data = _check_frame(data)
    columns = [*numeric, *categorical]
    if len(set(columns)) != len(columns):
        raise StatisticsInputError(
            f"the same column is used twice in {columns}; pass distinct columns"
        )
    for col in columns:
        if col not in data.columns:
            raise StatisticsInputError(
                f"not in the data; available columns are {sorted(map(str, data.columns))}",
                column=col,
            )
    frame = data.loc[:, columns].copy()
    for col in numeric:
        try:
            frame[col] = pd.to_numeric(frame[col], errors="raise").astype("float64")
        except (TypeError, ValueError) as exc:
            raise StatisticsInputError(
                f"must hold numbers, found {frame[col].dtype} values ({exc})", column=col
            ) from exc
    missing = frame.isna()
    n_missing = int(missing.any(axis=1).sum())
    if n_missing and not dropna:
        per_col = {c: int(n) for c, n in missing.sum().items() if n}
        raise StatisticsInputError(
            f"{n_missing} row(s) have missing values (per column: {per_col}); clean the data "
            "or pass dropna=True to drop them (the count is then reported in attrs['n_dropped'])"
        )
    frame = frame.loc[~missing.any(axis=1)].reset_index(drop=True)
    for col in numeric:
        values = frame[col].to_numpy()
        bad = ~np.isfinite(values)
        if bad.any():
            raise StatisticsInputError(
                f"{int(bad.sum())} non-finite value(s) (first {values[bad][0]!r} in row "
                f"{int(np.flatnonzero(bad)[0])}); responses must be finite numbers",
                column=col,
            )
    min_levels = min_levels or {}
    for col in categorical:
        if isinstance(frame[col].dtype, pd.CategoricalDtype):
            counts = frame[col].value_counts(sort=False)
            empty = [lvl for lvl, n in counts.items() if n == 0]
            if empty:
                raise StatisticsInputError(
                    f"level(s) {empty} have no observations"
                    + (" left after dropping missing values" if n_missing else "")
                    + "; every level compared needs at least one observation "
                    "(drop unused levels with .cat.remove_unused_categories())",
                    column=col,
                )
            frame[col] = frame[col].astype(object)
        need = min_levels.get(col, 2)
        levels = frame[col].unique()
        if len(levels) < need:
            raise StatisticsInputError(
                f"needs at least {need} distinct levels to compare, found {len(levels)} "
                f"({list(levels)}) in {len(frame)} usable row(s)",
                column=col,
            )
    return frame, n_missing
