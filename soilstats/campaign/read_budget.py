"""A campaign file checked against the memory budget (:mod:`soilstats._budget`) before it is
read: a 100 M-row Parquet table or a gzip bomb is refused, naming the file and the size,
instead of running Arrow or pandas out of memory (issue #44)."""

from __future__ import annotations

import os
from typing import BinaryIO

from .._budget import check_budget
from ..errors import CampaignError, InputError

__all__ = ["CSV_MEMORY_FACTOR", "PARQUET_MEMORY_FACTOR", "check_csv_size", "check_parquet_size"]

#: Memory of a CSV read as text cells, per byte of the file (pandas' objects and strings).
CSV_MEMORY_FACTOR = 12
#: Memory of a Parquet table, per byte of its uncompressed pages (Arrow, then pandas).
PARQUET_MEMORY_FACTOR = 3


def _check_size(name: str, nbytes: float, detail: str) -> None:
    """Refuse a file whose table would not fit the memory budget, before reading it."""
    try:
        check_budget(f"reading {name}{detail}", nbytes, "split the campaign into smaller ones")
    except InputError as err:
        raise CampaignError(str(err), file=name) from None


def check_parquet_size(fh: BinaryIO, name: str) -> None:
    """The rows and uncompressed size a Parquet footer declares, checked against the memory
    budget before a page is decompressed (a 100 M-row table, a compression bomb)."""
    import pyarrow.parquet as pq  # deferred: pyarrow (the parquet extra)

    meta = pq.ParquetFile(fh).metadata
    size = sum(meta.row_group(i).total_byte_size for i in range(meta.num_row_groups))
    fh.seek(0)
    # Pages are encoded too (a run of equal values is a few bytes): count the cells as well,
    # 8 bytes a number and a Python string's ~60 for text.
    schema = meta.schema
    width = sum(
        60 if schema.column(j).physical_type == "BYTE_ARRAY" else 8 for j in range(meta.num_columns)
    )
    nbytes = max(size * PARQUET_MEMORY_FACTOR, meta.num_rows * width)
    _check_size(name, nbytes, f" ({meta.num_rows} rows of {meta.num_columns} columns)")


def check_csv_size(fh: BinaryIO, name: str) -> None:
    """A CSV file's size, as text cells in memory, checked against the memory budget before
    it is read."""
    _check_size(name, os.fstat(fh.fileno()).st_size * CSV_MEMORY_FACTOR, "")
