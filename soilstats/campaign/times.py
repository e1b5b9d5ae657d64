"""When a test ran: date/time columns of a test log read as hours.

A test log may carry when each test ran (``start_time``, ``date``, ``2024-05-02T09:15``)
as text.  Two readers need it as a number: discovery, which tests time as a cause, and the
``zero-drift`` rule, which reads it as test order.  One reading for both, here.
"""

from __future__ import annotations

import pandas as pd

__all__ = ["time_columns", "time_hours"]

_TIME_TEXT = r"\d{4}-\d{2}-\d{2}|\d{1,2}:\d{2}"


def time_hours(col: pd.Series) -> pd.Series | None:
    """A column of dates/times as hours since its earliest value, or None if it is not one.

    Text counts as a time when at least 90 % of the recorded values look like an ISO date or
    a clock time and parse (``2024-05-02T09:15``, ``2024-05-02 09:15:00+02:00``, ``09:15``).
    """
    if pd.api.types.is_datetime64_any_dtype(col):
        stamps = pd.to_datetime(col, utc=True)
    elif pd.api.types.is_object_dtype(col) or pd.api.types.is_string_dtype(col):
        text = col.dropna().astype(str)
        if text.empty or text.str.contains(_TIME_TEXT, regex=True).mean() < 0.9:
            return None
        stamps = pd.to_datetime(col, errors="coerce", utc=True, format="mixed")
        if stamps.notna().sum() < 0.9 * col.notna().sum():
            return None
    else:
        return None
    hours = (stamps - stamps.min()).dt.total_seconds() / 3600.0
    return hours.astype(float)


def time_columns(table: pd.DataFrame) -> dict[str, pd.Series]:
    """Every date/time column of ``table`` (:func:`time_hours`), as hours, by name, in the
    table's column order; numeric and boolean columns are never times."""
    hours = {}
    for name in table.columns:
        col = table[name]
        if pd.api.types.is_numeric_dtype(col) or pd.api.types.is_bool_dtype(col):
            continue
        converted = time_hours(col)
        if converted is not None:
            hours[name] = converted
    return hours
