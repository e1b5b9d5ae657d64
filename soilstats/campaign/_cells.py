"""Cell-level conversion shared by the validator: text and numbers from CSV or typed frames.

A CSV file arrives as text cells (``""`` where empty); a Parquet file or a user's frame
arrives typed. Both go through these helpers so that the same campaign gives the same typed
tables whichever way it was stored.
"""

from __future__ import annotations

import math
import re
from decimal import Decimal, InvalidOperation
from typing import cast

import numpy as np
import numpy.typing as npt
import pandas as pd
from pandas.api.types import infer_dtype, is_bool_dtype, is_integer, is_numeric_dtype

from .schema import MISSING_TOKENS, SPECS, canonical_order, spec

__all__ = [
    "TEXT_DTYPE",
    "Numbers",
    "as_text",
    "blank",
    "control_characters",
    "empty_samples",
    "first_control",
    "first_per_key",
    "texts",
    "typed",
    "typed_extra",
    "without_controls",
]

#: Float64 holds every whole number below this exactly, and not every one above.
EXACT_WHOLE = 2.0**53
#: A whole number written out in digits ("12345678901234567", "3.0").
_WHOLE_DIGITS = r"^\s*[+-]?[0-9]+(?:\.0*)?\s*$"
#: A number whose digits before the exponent are not all zero ("1e-400", ".5e-999").
_NONZERO_MANTISSA = r"^\s*[+-]?(?:[0-9]*\.)?[0-9]*[1-9]"

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


#: C0 controls (NUL, TAB, line breaks, ...), DEL and C1 controls: never part of a name.
_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f]")


def control_characters(cells: ObjArray) -> BoolArray:
    """Return True where a text cell holds a control character (NUL, TAB, a line break, DEL).

    An id or a name with one looks like another ("c1" and "c1\\x00" print alike) but
    matches nothing: a sample of "c1\\x00" would be no sample of test "c1".
    """
    return np.array([_CONTROL.search(c) is not None for c in cells], dtype=bool)


def first_control(text: str) -> str:
    """The first control character of ``text``, as ``U+0000`` (for a message)."""
    found = _CONTROL.search(text)
    return f"U+{ord(found.group()):04X}" if found else ""


def without_controls(text: str) -> str:
    """``text`` with its control characters removed (the id a corrupted cell meant)."""
    return _CONTROL.sub("", text)


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
    import pyarrow as pa  # deferred: pyarrow (the parquet extra)
    import pyarrow.compute as pc  # deferred: pyarrow (the parquet extra)

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
    lost : ndarray of bool
        A number float64 does not hold as written (see :attr:`lost`); the rules refuse it.
    """

    def __init__(self, series: pd.Series) -> None:
        n = len(series)
        self.bad = np.zeros(n, dtype=bool)
        self._series = series
        self._cells: ObjArray | None = None
        self._finite: np.ndarray | None = None
        self._lost: np.ndarray | None = None
        self._typed = is_numeric_dtype(series.dtype) and not is_bool_dtype(series.dtype)
        if self._typed:
            self.values = series.to_numpy(dtype=np.float64, na_value=np.nan)
            self.missing = np.isnan(self.values)
            return
        decimal = _parse_decimals(series)
        if decimal is not None:  # every cell a plain decimal number (the common case)
            self.values = decimal
            self.missing = np.zeros(n, dtype=bool)
            return
        cells = cast(ObjArray, self.cells)  # not typed numeric: the texts exist
        # Python's float() (and numpy's) also reads "1_000" and non-ASCII digits ("٣"): no
        # spreadsheet or logger writes numbers so, and "1_5" may mean 1.5; such cells are
        # not numbers under the format's rule ('.' the only separator).
        foreign = np.fromiter((not _plain_text(c) for c in cells), np.bool_, n)
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
        if self._cells is None and not self._typed:
            self._cells = texts(self._series)
        return self._cells

    def _text(self, i: int) -> str:
        """Text of cell ``i`` without making the texts of the whole column."""
        if self._cells is not None:
            return str(self._cells[i])
        return str(texts(self._series.iloc[i : i + 1])[0])

    def cell(self, i: int) -> str:
        """Text of cell ``i`` for a message (a stored integer as itself, not as float64
        holds it: the message may be about that difference)."""
        cells = self.cells
        if cells is not None:
            return str(cells[i])
        original = self._series.iloc[i]
        return str(int(original)) if is_integer(original) else repr(float(self.values[i]))

    @property
    def lost(self) -> BoolArray:
        """True where float64 does not hold the number written, beyond the rounding of a
        decimal's last digit: a nonzero number read as 0 (below ~1e-324), or a whole number
        beyond 2^53 (written in digits, or stored as an integer) read as a neighbour.

        Such a cell would be changed without a word (a serial number 12345678901234567
        becomes ...568; a repetition 2^53 + 1 becomes 2^53), so the rules refuse it.
        """
        if self._lost is None:
            v = self.values
            with np.errstate(invalid="ignore"):
                zero = self.finite & (v == 0)
                big = self.finite & (np.abs(v) >= EXACT_WHOLE)
            self._lost = np.zeros(len(v), dtype=bool)
            # Screen in bulk (a column of a million zeros is common), confirm one by one.
            candidates = np.flatnonzero(big)
            if not self._typed:  # text: only a cell written so can have lost its number
                candidates = np.union1d(
                    self._matching(np.flatnonzero(zero), _NONZERO_MANTISSA),
                    self._matching(candidates, _WHOLE_DIGITS),
                )
            for i in candidates:
                self._lost[i] = self.lost_reason(int(i)) != ""
        return self._lost

    def _matching(self, rows: np.ndarray, pattern: str) -> np.ndarray:
        """The ``rows`` whose text matches ``pattern``, screened in Arrow (a column of a
        million zeros is common; a Python loop over it would add a second to a load)."""
        if not rows.size:
            return rows
        sub = self._series.iloc[rows]
        try:
            import pyarrow as pa  # deferred: pyarrow (the parquet extra)
            import pyarrow.compute as pc  # deferred: pyarrow (the parquet extra)
        except ImportError:  # pyarrow is the optional `parquet` extra: Python's re then
            regex = re.compile(pattern)
            return rows[[regex.search(cell) is not None for cell in texts(sub)]]
        cells = pa.array(
            sub.array if isinstance(sub.dtype, pd.StringDtype) else list(texts(sub)),
            type=pa.large_string(),
        )
        hit = pc.match_substring_regex(cells, pattern).to_numpy(zero_copy_only=False)
        return rows[hit.astype(bool)]

    def lost_reason(self, i: int) -> str:
        """Why cell ``i`` is not held as written (``""`` when it is), for a message."""
        value = float(self.values[i])
        exact = self._exact(i)
        if exact is None or exact == Decimal(value):
            return ""
        if value == 0:
            return "is too small for float64 and would be read as 0"
        return (
            "is a whole number beyond 2^53, which float64 cannot hold exactly: it would be "
            f"read as {value:.0f}"
        )

    def _exact(self, i: int) -> Decimal | None:
        """The number cell ``i`` holds exactly, where float64 may not: a whole number
        stored as an integer, a text cell written as digits; None for other cells (a
        decimal fraction is rounded in its last digit by any binary reader)."""
        if self._typed:
            original = self._series.iloc[i]
            return Decimal(int(original)) if is_integer(original) else None
        text = self._text(i)
        if self.values[i] != 0 and not re.match(_WHOLE_DIGITS, text):
            return None
        try:
            return Decimal(text.strip())
        except InvalidOperation:
            return None

    def whole(self, i: int) -> bool:
        """Whether cell ``i`` is a whole number float64 holds exactly: written as one
        (``"1.0000000000000001"`` is not, though float64 reads it as 1.0) and below 2^53."""
        value = float(self.values[i])
        if not math.isfinite(value) or value != math.trunc(value) or abs(value) >= EXACT_WHOLE:
            return False
        if self._typed:
            return True
        try:
            return Decimal(self._text(i).strip()) == Decimal(value)
        except InvalidOperation:
            return False

    @property
    def finite(self) -> BoolArray:
        """True where the value is a finite number."""
        if self._finite is None:  # asked once per cell of the log: computed once
            self._finite = np.isfinite(self.values)
        return self._finite


def typed_extra(series: pd.Series, index: pd.Index, num: Numbers | None = None) -> pd.Series:
    """Type an extra (covariate) column: float64 if every non-empty cell parses, else text.

    Parameters
    ----------
    series : Series
        The column as read or as stored.
    index : Index
        Index of the result.
    num : Numbers, optional
        The column already parsed (the validator parses it to check it).

    Returns
    -------
    Series
        float64 (NaN where not recorded) or the text dtype (NaN where empty).
    """
    num = num or Numbers(series)
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
            cols[col] = typed_extra(raw[col], index, (parsed or {}).get(col))
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
