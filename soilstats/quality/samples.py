"""The samples of one table laid out for screening: records test by test, end to end
(:class:`Records`, on :mod:`.blocks`), the file rows a finding names, and the ``spike`` rule
every table runs (sinkage and shear alike)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from . import blocks as blocks_mod
from . import staging
from .blocks import Blocks
from .report import QualityFlag


def rows(labels: np.ndarray) -> tuple[int, ...]:
    """1-based data rows of the sample file from its 0-based labels."""
    return tuple(int(label) + 1 for label in labels.tolist())


@dataclass
class Records:
    """The records of one sample table, test by test, laid end to end (see :mod:`.blocks`).

    Tests are in the order of their first sample (``groupby(sort=False)``), each record in
    file order; ``labels`` are the 0-based data rows of the file.
    """

    ids: list[str]
    blocks: Blocks
    labels: np.ndarray
    columns: dict[str, np.ndarray]

    @classmethod
    def of(cls, table: pd.DataFrame, columns: tuple[str, ...]) -> Records:
        codes, uniques = pd.factorize(table["test_id"], sort=False)
        # A stable sort by test keeps every record in file order (rows need not be
        # contiguous); rows without a test_id (code -1) are left out, as groupby does.
        order = np.argsort(codes, kind="stable")
        order = order[codes[order] >= 0]
        codes = codes[codes >= 0]
        blocks = Blocks.of_sizes(np.bincount(codes, minlength=len(uniques)))
        labels = table.index.to_numpy()[order]
        values = {c: table[c].to_numpy(float)[order] for c in columns}
        return cls([str(t) for t in uniques], blocks, labels, values)


def hits_by_block(blocks: Blocks, mask: np.ndarray) -> dict[int, np.ndarray]:
    """Block number → the positions (in the blocks' arrays) where ``mask`` holds, only
    blocks with any."""
    hits = np.flatnonzero(mask)
    if not hits.size:
        return {}
    block = blocks.block_of[hits]
    cut = np.flatnonzero(np.diff(block)) + 1
    return {int(b[0]): h for b, h in zip(np.split(block, cut), np.split(hits, cut), strict=True)}


def spike_findings(
    rec: Records, kind: str, columns: tuple[str, str], clean: bool
) -> tuple[list[list[QualityFlag]], list[np.ndarray], np.ndarray]:
    """``spike`` flags of every record (a spike in either column), per test in test order,
    the labels they drop in mode ``clean``, and the mask of spiked positions."""
    spiked = blocks_mod.spikes(rec.blocks, rec.columns[columns[0]]) | blocks_mod.spikes(
        rec.blocks, rec.columns[columns[1]]
    )
    out: list[list[QualityFlag]] = [[] for _ in rec.ids]
    drop: list[np.ndarray] = []
    for k, hits in hits_by_block(rec.blocks, spiked).items():
        message = f"{hits.size} isolated spiked sample(s) in {columns[0]} or {columns[1]}"
        flag = QualityFlag(rec.ids[k], kind, "spike", rows(rec.labels[hits]), message)
        staging.leave_out(out[k], drop, flag, clean)
    return out, drop, spiked


def merge(out: list[list[QualityFlag]], found: list[list[QualityFlag]]) -> None:
    """Append each test's new flags to its list."""
    for mine, new in zip(out, found, strict=True):
        mine.extend(new)
