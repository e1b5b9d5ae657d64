"""Integer links from a campaign's samples to its tests, found once per campaign object.

An analysis selects tests by their test-log columns and then needs each selected test's
samples. Matching the text ``test_id`` of every sample against the selection (pandas
``isin``, then a factorisation to find each sample's test) costs more than a whole
paper-size fit, and grows with the campaign, not with the selection. The links themselves
never change for a campaign: each sample's test as a row position in ``campaign.tests``,
found once, turns every later selection into an integer lookup (:meth:`CampaignIndex.rows_of`).

A :class:`~soilstats.campaign.Campaign` is never modified: its methods return new campaigns
and its tables are read-only by contract (the screening cache of
:func:`soilstats.quality.screened` rests on the same contract). So the index is kept for as
long as the campaign object lives, keyed by the object: a new campaign (``select``,
``dataclasses.replace``, screening, a fitting window) gets its own. Its arrays are read-only,
so no caller can change what the next one reads.
"""

from __future__ import annotations

import weakref
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .schema import KINDS
from .tables import CampaignTables

__all__ = ["CampaignIndex", "campaign_index", "grouped_by_code", "sample_test_positions"]


def _frozen(values: np.ndarray) -> np.ndarray:
    values.flags.writeable = False
    return values


def sample_test_positions(sample_ids: pd.Series, test_ids: Iterable[str]) -> np.ndarray:
    """Each sample's position in ``test_ids`` (−1: not among them).  Factorising the
    samples first leaves one short lookup per distinct test instead of one per sample."""
    codes, distinct = pd.factorize(sample_ids.array)
    position = pd.Index(test_ids).get_indexer(distinct)
    return np.where(codes >= 0, position[codes], -1)


def grouped_by_code(codes: np.ndarray, n_codes: int) -> list[np.ndarray]:
    """The positions of each code 0 … n_codes−1 in ``codes``, in their original order (a
    record's samples stay in file order); positions coded −1 belong to none."""
    if n_codes == 0:
        return []
    member = np.flatnonzero(codes >= 0)
    order = member[np.argsort(codes[member], kind="stable")]
    ends = np.cumsum(np.bincount(codes[member], minlength=n_codes))
    return np.split(order, ends[:-1])


@dataclass(frozen=True, eq=False)
class CampaignIndex:
    """The test log's identity columns as arrays, and each sample's test (see module doc).

    Attributes
    ----------
    test_id, soil : numpy.ndarray
        (T,) object arrays in log order: ``test_id`` as in the log, ``soil`` as text.
    b_m : numpy.ndarray
        (T,) contact width b [m] (NaN for shear tests).
    of_kind : dict
        ``"sinkage"`` / ``"shear"`` → (T,) bool, the tests of that kind.
    """

    test_id: np.ndarray
    kind: np.ndarray
    soil: np.ndarray
    b_m: np.ndarray
    of_kind: dict[str, np.ndarray]
    _samples: dict[str, pd.DataFrame] = field(repr=False)
    _test_of: dict[str, np.ndarray] = field(default_factory=dict, repr=False)
    _columns: dict[tuple[str, str], np.ndarray] = field(default_factory=dict, repr=False)

    @classmethod
    def of(cls, campaign: CampaignTables) -> CampaignIndex:
        tests = campaign.tests
        kind = _frozen(tests["kind"].to_numpy())
        return cls(
            test_id=_frozen(tests["test_id"].to_numpy()),
            kind=kind,
            soil=_frozen(tests["soil"].astype(str).to_numpy()),
            b_m=_frozen(tests["b_m"].to_numpy(float)),
            of_kind={k: _frozen(kind == k) for k in KINDS},
            _samples={"sinkage": campaign.sinkage, "shear": campaign.shear},
        )

    def test_of(self, table: str) -> np.ndarray:
        """(N,) row position in the test log of each sample of ``table`` (``"sinkage"`` or
        ``"shear"``); −1 for a sample whose test_id the log does not hold."""
        if table not in self._test_of:
            self._test_of[table] = _frozen(
                sample_test_positions(self._samples[table]["test_id"], self.test_id)
            )
        return self._test_of[table]

    def column(self, table: str, name: str) -> np.ndarray:
        """(N,) float values of the sample column ``name`` of ``table``, read-only."""
        key = (table, name)
        if key not in self._columns:
            self._columns[key] = _frozen(self._samples[table][name].to_numpy(float))
        return self._columns[key]

    def rows_of(self, table: str, tests: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The samples of the tests at log rows ``tests`` (in that order): their rows in
        ``table`` (file order) and each one's test as a position in ``tests``."""
        # One lookup entry per log row, plus a last one (−1) that a sample without a test
        # (code −1) lands on.
        where = np.full(self.test_id.size + 1, -1, np.intp)
        where[tests] = np.arange(tests.size)
        test = where[self.test_of(table)]
        rows = np.flatnonzero(test >= 0)
        return rows, test[rows]


#: Index by campaign object (the campaign holds no reference back, so it is freed with it).
_INDEX: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def campaign_index(campaign: CampaignTables) -> CampaignIndex:
    """The :class:`CampaignIndex` of ``campaign``, built on first use."""
    index = _INDEX.get(campaign)
    if index is None:
        index = _INDEX[campaign] = CampaignIndex.of(campaign)
    return index
