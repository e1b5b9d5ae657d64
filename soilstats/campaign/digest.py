"""The digest of a campaign's content that every output's provenance records.

:class:`soilstats.outputs.Provenance` takes it through ``Campaign.sha256()``; it lives here,
with the campaign format whose tables it hashes.
"""

from __future__ import annotations

import hashlib

import numpy as np
import pandas as pd

from .schema import DERIVED_COLUMNS, FILES
from .tables import CampaignTables

__all__ = ["campaign_sha256"]


def campaign_sha256(campaign: CampaignTables) -> str:
    """SHA-256 of a campaign's raw content (what ``Campaign.save`` writes), as hex.

    The same tables give the same hash whether they came from CSV, Parquet or DataFrames:
    numbers are hashed as little-endian float64, text as UTF-8, missing cells as a marker,
    column names and table names included. Derived columns are left out (they follow from
    the raw ones).
    """
    digest = hashlib.sha256()
    for stem in FILES:
        table = getattr(campaign, stem)
        raw = [c for c in table.columns if c not in DERIVED_COLUMNS[stem]]
        digest.update(f"\x1e{stem}:{len(table)}".encode())
        for column in raw:
            values = table[column]
            digest.update(f"\x1d{column}".encode())
            if pd.api.types.is_numeric_dtype(values) and not pd.api.types.is_bool_dtype(values):
                digest.update(values.to_numpy(dtype="<f8", na_value=np.nan).tobytes())
            else:
                digest.update("\x1f".join(_cells(values)).encode("utf-8"))
    return digest.hexdigest()


def _cells(values: pd.Series) -> list[str]:
    """The text of every cell of a column, NUL (``"\\x00"``) where missing."""
    if isinstance(values.dtype, pd.StringDtype):
        # Every present cell is a str already: one conversion in C, not a Python loop over
        # a million sample rows (the test_id column of a large campaign).
        return values.to_numpy(dtype=object, na_value="\x00").tolist()
    return ["\x00" if pd.isna(v) else str(v) for v in values]
