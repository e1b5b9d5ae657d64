"""Copied records: a test whose samples repeat an earlier test's, value for value.

Independent tests never repeat a record to the last digit, so such a test is a copy (an
export or file-naming slip) that counts one preparation twice; screening flags it
``duplicate`` (:mod:`.screen`).  A flat, dead channel over a commanded z grid repeats by
itself and is left to the other rules: a record counts only with at least
:data:`MIN_DISTINCT` distinct values of its response.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence

import numpy as np
import pandas as pd

__all__ = ["MIN_DISTINCT", "RECORDS", "find_copies"]

#: Distinct response values a record needs to be compared at all.
MIN_DISTINCT = 5
#: The channels that make up a record, and its response, by sample table.
RECORDS = {
    "sinkage": (("z_m", "force_N"), "force_N"),
    "shear": (("angle_rad", "torque_Nm", "normal_force_N"), "torque_Nm"),
}


def find_copies(
    table: pd.DataFrame, columns: Sequence[str], response: str
) -> list[tuple[str, str, np.ndarray]]:
    """``(copy, original, positions)`` of every test of ``table`` whose record (``columns``,
    in file order) repeats an earlier test's exactly; ``positions`` are the copy's rows of
    ``table``.

    Records are compared in full only where a cheap signature (length and the sum of every
    channel) collides, so a table without copies costs a few bincounts.
    """
    codes, ids = pd.factorize(table["test_id"].astype(str), sort=False)
    values = np.ascontiguousarray(table[list(columns)].to_numpy(dtype=float))
    sums = {
        c: np.bincount(codes, weights=values[:, k], minlength=ids.size)
        for k, c in enumerate(columns)
    }
    signature = pd.DataFrame({"n": np.bincount(codes, minlength=ids.size)} | sums)
    clash = signature.duplicated(keep=False).to_numpy().copy()
    if not clash.any():
        return []
    candidate = clash[codes]
    informative = values[candidate, list(columns).index(response)]
    distinct = pd.Series(informative).groupby(codes[candidate]).nunique()
    clash[distinct.index[distinct < MIN_DISTINCT]] = False
    order = np.argsort(codes, kind="stable")
    starts = np.searchsorted(codes[order], np.arange(ids.size + 1))
    first_of: dict[bytes, str] = {}
    out = []
    for t in np.flatnonzero(clash):  # in file order
        rows = order[starts[t] : starts[t + 1]]
        key = hashlib.blake2b(values[rows].tobytes(), digest_size=16).digest()
        first = first_of.setdefault(key, ids[t])  # type: ignore[call-overload]  # pandas-stubs: Index[numpy int] is valid
        if first != ids[t]:  # type: ignore[call-overload]  # pandas-stubs: Index[numpy int] is valid
            out.append((ids[t], first, rows))  # type: ignore[call-overload]  # pandas-stubs: Index[numpy int] is valid
    return out
