"""Cell-level conversion shared by the validator: text and numbers from CSV or typed frames.

A CSV file arrives as text cells (``""`` where empty); a Parquet file or a user's frame
arrives typed. Both go through these helpers so that the same campaign gives the same typed
tables whichever way it was stored.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
import pandas as pd
from pandas.api.types import infer_dtype, is_bool_dtype, is_numeric_dtype

from .schema import MISSING_TOKENS, SPECS, canonical_order, spec

__all__ = [
    "TEXT_DTYPE",
    "Numbers",
    "as_text",
    "blank",
    "empty_samples",
    "first_per_key",
    "texts",
    "typed",
    "typed_extra",
]

#: The running pandas' default string dtype ("str" in pandas 3, object in pandas 2), so that
#: text columns look the same as those pandas itself would create.
TEXT_DTYPE = pd.Series(["a"]).dtype

ObjArray = npt.NDArray[np.object_]
BoolArray = npt.NDArray[np.bool_]


def _text_of(value: object) -> str:
    if value is None or value is pd.NA:
        return ""
    if isinstance(value, float | np.floating):
        if math.isnan(value):
            return ""
        if math.isfinite(value) and value == int(value) and not isinstance(value, bool):
            return str(int(value))  # a typed 5.0 in a text column means "5"
    return str(value)


def texts(series: pd.Series) -> ObjArray:
    """Return the cells of ``series`` as Python strings, ``""`` where missing.

    Parameters
    ----------
    series : Series
        A column as read (text) or as stored (typed).

    Returns
    -------
    ndarray of object
        One ``str`` per row.
    """
    arr = series.to_numpy(dtype=object, na_value="")
    # A CSV column is all str already; infer_dtype checks that in C, not per element here.
    if isinstance(series.dtype, pd.StringDtype) or infer_dtype(arr, skipna=False) == "string":
        return arr
    return np.array([_text_of(v) for v in arr], dtype=object)


def blank(cells: ObjArray) -> BoolArray:
    """Return True where a text cell is empty or only blanks."""
    return np.array([not c.strip() for c in cells], dtype=bool)


def as_text(cells: ObjArray, index: pd.Index) -> pd.Series:
    """Build a text column; blank cells become missing (NaN), never ``""``."""
    values = np.where(blank(cells), np.nan, cells) if len(cells) else cells
    return pd.Series(values, index=index, dtype=TEXT_DTYPE)


#: A plain decimal number: the cells Arrow's parser and Python's float() both read, and
#: read alike (both are correctly rounded). Anything else (blanks around the number,
#: underscores, "NaN", "inf", non-ASCII digits) goes through float() cell by cell.
_DECIMAL = r"^[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?$"


def _plain_text(cell: str) -> bool:
    """ASCII without underscores: the only cells :class:`Numbers` hands to float()."""
    return cell.isascii() and "_" not in cell


def _parse_decimals(series: pd.Series) -> np.ndarray | None:
    """The cells of a text column as float64 when every one is a plain decimal number and
    pandas holds them in Arrow (a CSV read as text), else None.

    Parsing a million cells in Arrow takes milliseconds; through Python objects, a second.
    The values are those of ``float(cell)`` bit for bit (both parsers round correctly;
    ``tests/test_campaign_load.py`` checks them against float() on edge cases).
    """
    dtype = series.dtype
    if not (isinstance(dtype, pd.StringDtype) and dtype.storage == "pyarrow") or not len(series):
        return None
    import pyarrow as pa
    import pyarrow.compute as pc

    cells = pa.array(series.array)  # via __arrow_array__: the cells pandas holds
    if cells.null_count or not pc.all(pc.match_substring_regex(cells, _DECIMAL)).as_py():
        return None
    return np.array(pc.cast(cells, pa.float64()).to_numpy(), dtype=np.float64)


class Numbers:
    """A column parsed as numbers.

    Attributes
    ----------
    values : ndarray of float64
        Parsed values; NaN where missing or unparsable.
    missing : ndarray of bool
        Empty cell, a missing token (``NA``, ``NaN``, ``null``, ``N/A``) or a typed NaN.
    bad : ndarray of bool
        Non-empty cell that is not a number.
    cells : ndarray of object or None
        Cell texts for messages (None when the column was typed numeric).
    """

    def __init__(self, series: pd.Series) -> None:
        n = len(series)
        self.bad = np.zeros(n, dtype=bool)
        self._series = series
        self._cells: ObjArray | None = None
        self._finite: np.ndarray | None = None
        if is_numeric_dtype(series.dtype) and not is_bool_dtype(series.dtype):
            self.values = series.to_numpy(dtype=np.float64, na_value=np.nan)
            self.missing = np.isnan(self.values)
            return
        decimal = _parse_decimals(series)
        if decimal is not None:  # every cell a plain decimal number (the common case)
            self.values = decimal
            self.missing = np.zeros(n, dtype=bool)
            return
        cells = self.cells
        # Python's float() (and numpy's) also reads "1_000" and non-ASCII digits ("٣"): no
        # spreadsheet or logger writes numbers so, and "1_5" may mean 1.5; such cells are
        # not numbers under the format's rule ('.' the only separator).
        foreign = np.fromiter((not _plain_text(c) for c in cells), bool, n)
        if not foreign.any():
            try:  # fast path: every cell parses (float() is correctly rounded: repr round-trips)
                self.values = np.asarray(cells, dtype=np.float64) if n else np.empty(0)
                self.missing = np.isnan(self.values)
                return
            except (ValueError, TypeError):
                pass
        self.missing = np.array(
            [not c.strip() or c.strip().lower() in MISSING_TOKENS for c in cells], dtype=bool
        )
        self.values = np.full(n, np.nan)
        self.bad = foreign & ~self.missing
        for i in np.flatnonzero(~self.missing & ~foreign):
            try:
                self.values[i] = float(cells[i])
            except ValueError:
                self.bad[i] = True

    @property
    def cells(self) -> ObjArray | None:
        """Cell texts (None when the column was typed numeric); made when first needed,
        since a clean column of a million samples never needs them."""
        if self._cells is None and not (
            is_numeric_dtype(self._series.dtype) and not is_bool_dtype(self._series.dtype)
        ):
            self._cells = texts(self._series)
        return self._cells

    def cell(self, i: int) -> str:
        """Text of cell ``i`` for a message."""
        cells = self.cells
        return str(cells[i]) if cells is not None else repr(float(self.values[i]))

    @property
    def finite(self) -> BoolArray:
        """True where the value is a finite number."""
        if self._finite is None:  # asked once per cell of the log: computed once
            self._finite = np.isfinite(self.values)
        return self._finite


def typed_extra(series: pd.Series, index: pd.Index) -> pd.Series:
    """Type an extra (covariate) column: float64 if every non-empty cell parses, else text.

    Parameters
    ----------
    series : Series
        The column as read or as stored.
    index : Index
        Index of the result.

    Returns
    -------
    Series
        float64 (NaN where not recorded) or the text dtype (NaN where empty).
    """
    num = Numbers(series)
    if not num.bad.any() and not is_bool_dtype(series.dtype):
        return pd.Series(num.values, index=index, dtype=np.float64)
    return as_text(texts(series), index)


def typed(raw: pd.DataFrame, stem: str, parsed: dict[str, Numbers] | None = None) -> pd.DataFrame:
    """Typed copy of a table: text columns as text, format numbers as float64, extras typed."""
    index = pd.RangeIndex(len(raw))
    cols = {}
    order = canonical_order(stem, list(raw.columns)) if stem != "tests" else list(raw.columns)
    for col in order:
        s = spec(stem, col)
        if s is None:
            cols[col] = typed_extra(raw[col], index)
        elif s.dtype == "text" and col == "test_id":
            # test_id stays as written (a blank one is reported and never kept).
            cols[col] = _as_written(raw[col], index)
        elif s.dtype == "text":
            cells = texts(raw[col])
            cols[col] = as_text(cells, index)
        else:
            num = (parsed or {}).get(col) or Numbers(raw[col])
            cols[col] = pd.Series(num.values, index=index, dtype=np.float64)
    return pd.DataFrame(cols, index=index)


def _as_written(series: pd.Series, index: pd.Index) -> pd.Series:
    """A text column exactly as written (missing → ``""``), with ``index``."""
    if series.dtype == TEXT_DTYPE and not series.hasnans:
        # Already text with nothing missing (a CSV read as text): the same cells, no copy
        # through a million Python strings.
        return pd.Series(series.array, index=index)
    return pd.Series(texts(series), index=index, dtype=TEXT_DTYPE)


def first_per_key(keys: np.ndarray, mask: np.ndarray) -> list[tuple[int, str, int]]:
    """(first row position, key, count) of each key among the rows where ``mask`` holds."""
    pos = np.flatnonzero(mask)
    if not pos.size:
        return []
    uniq, first, count = np.unique(keys[pos].astype(str), return_index=True, return_counts=True)
    return [(int(pos[f]), str(u), int(c)) for u, f, c in zip(uniq, first, count, strict=True)]


def empty_samples(stem: str) -> pd.DataFrame:
    """Typed sample table with the format's columns and no rows (for an absent file)."""
    return typed(pd.DataFrame({s.name: pd.Series([], dtype=object) for s in SPECS[stem]}), stem)
