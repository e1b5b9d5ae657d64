"""Turning the tests of a campaign into the pooled arrays of Eq. 11, with per-test weights.

Section 2.1: each test contributes points equidistant in sinkage, and each test's pressures are
normalised by its own maximum (weight w = 1/max p), so large plates or deep tests do not
dominate the fit.  Everything excluded on the way is counted per test and reported.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..errors import CampaignError

__all__ = ["PooledData", "equidistant_indices", "select_one_soil"]


@dataclass(frozen=True)
class PooledData:
    """Stacked samples of several tests, ready for :func:`soilstats.identify`."""

    x: dict[str, np.ndarray]  # input columns by name, each (N,)
    y: np.ndarray  # (N,)
    weights: np.ndarray  # (N,)
    test_index: np.ndarray  # (N,) position of each sample's test in ``groups``
    groups: pd.DataFrame  # one row per test: bookkeeping of what was used and excluded


def equidistant_indices(z: np.ndarray, count: int | None) -> np.ndarray:
    """Indices of the samples nearest to ``count`` sinkages equally spaced over [min z, max z].

    Values are never interpolated: the chosen points are measured samples (Section 2.1 takes
    "data points equidistantly spaced over the measured penetration depth").  Duplicates are
    removed, so a short record may give fewer than ``count`` points.  Returned in record order.
    """
    z = np.asarray(z, float)
    if count is None or z.size <= count:
        return np.arange(z.size)
    order = np.argsort(z, kind="stable")
    zs = z[order]
    grid = np.linspace(zs[0], zs[-1], count)
    pos = np.clip(np.searchsorted(zs, grid), 1, zs.size - 1)
    nearer_left = (grid - zs[pos - 1]) <= (zs[pos] - grid)
    chosen = order[np.where(nearer_left, pos - 1, pos)]
    return np.unique(chosen)


def select_one_soil(campaign, kind: str, selection: dict):
    """Apply ``selection`` and keep the tests of ``kind``; demand exactly one soil.

    Pooling two soils into one parameter set is never what a user means, so it is an error
    that lists the soils found and how to pick one.
    """
    chosen = campaign.select(**selection) if selection else campaign
    tests = chosen.tests[chosen.tests["kind"] == kind]
    if tests.empty:
        crit = ", ".join(f"{k}={v!r}" for k, v in selection.items()) or "no selection"
        raise CampaignError(
            f"no {kind} tests match ({crit}); the campaign has kinds "
            f"{sorted(chosen.tests['kind'].unique())}",
            file="tests.csv",
            column="kind",
        )
    soils = sorted(tests["soil"].astype(str).unique())
    if len(soils) > 1:
        raise CampaignError(
            f"the selection holds {len(soils)} soils {soils}; parameters of different soils "
            f"must not be pooled — add soil=... to the call (e.g. soil={soils[0]!r})",
            file="tests.csv",
            column="soil",
        )
    return chosen, tests
