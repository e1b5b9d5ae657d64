"""One (kind, soil) of a campaign, ready for discovery: per-test table and pooled samples.

The per-test table (one row per test) holds the test log, the derived columns and the
per-test fits of :func:`soilstats.fit_per_test` (Bernstein k, n per sinkage test, Eq. 8;
τ_max, K per shear test, Eq. 13 at one σ).  The pooled samples are those of Section 2.1:
sinkage samples with z > 0, shear samples with j ≥ 0, each test thinned to samples nearest to
equally spaced sinkages (or deformations) and weighted by 1/max of its own response, so that
every test counts alike.  ``owner`` maps each sample to its row of the table.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..errors import ConvergenceWarning
from ..identification import fit_per_test
from ..identification.pooling import equidistant_indices

__all__ = ["Group", "build_groups"]


@dataclass(frozen=True, eq=False)
class Group:
    """The tests of one kind and one soil.

    Attributes
    ----------
    kind : {"sinkage", "shear"}
    soil : str
    tests : pandas.DataFrame
        One row per test (log, derived columns, per-test fit; diagnosis adds responses).
    x : dict of numpy.ndarray
        Per-sample inputs: sinkage ``z`` [m] and ``b`` [m]; shear ``j`` [m] and ``sigma`` [Pa].
    y : numpy.ndarray
        Per-sample response: pressure p [Pa] (Eq. 6) or shear stress τ [Pa] (Eq. 12).
    w : numpy.ndarray
        Per-sample weight 1/max(y) of its test (Section 2.1).
    owner : numpy.ndarray
        Row position in ``tests`` of each sample.
    notes : tuple of str
        What was excluded on the way, and why.
    """

    kind: str
    soil: str
    tests: pd.DataFrame
    x: dict[str, np.ndarray] = field(repr=False)
    y: np.ndarray = field(repr=False)
    w: np.ndarray = field(repr=False)
    owner: np.ndarray = field(repr=False)
    notes: tuple[str, ...] = ()

    @property
    def label(self) -> str:
        return f"{self.kind} / {self.soil}"

    def samples_of(self, rows: np.ndarray) -> np.ndarray:
        """Boolean mask of the samples belonging to the table rows ``rows``."""
        keep = np.zeros(len(self.tests), bool)
        keep[np.asarray(rows, int)] = True
        return keep[self.owner]


def _pool(tests: pd.DataFrame, samples: pd.DataFrame, kind: str, points: int):
    by_test = samples.groupby("test_id", sort=False).indices
    if kind == "sinkage":
        a_all, y_all = samples["z_m"].to_numpy(float), samples["pressure_Pa"].to_numpy(float)
        s_all = None
    else:
        a_all, y_all = samples["j_m"].to_numpy(float), samples["tau_Pa"].to_numpy(float)
        s_all = samples["sigma_Pa"].to_numpy(float)
    parts: dict[str, list] = {"a": [], "y": [], "w": [], "o": [], "s": [], "b": []}
    usable = np.zeros(len(tests), bool)
    for pos, tid in enumerate(tests["test_id"].astype(str)):
        idx = by_test.get(tid, np.array([], int))
        a, y = a_all[idx], y_all[idx]
        keep = a > 0 if kind == "sinkage" else a >= 0
        sel = np.flatnonzero(keep)
        sel = sel[equidistant_indices(a[sel], points)]
        if sel.size < 5 or y[sel].max() <= 0:
            continue
        usable[pos] = True
        parts["a"].append(a[sel])
        parts["y"].append(y[sel])
        parts["w"].append(np.full(sel.size, 1.0 / y[sel].max()))
        parts["o"].append(np.full(sel.size, pos))
        if kind == "sinkage":
            parts["b"].append(np.full(sel.size, float(tests["b_m"].iloc[pos])))
        else:
            parts["s"].append(s_all[idx][sel])
    cat = {k: np.concatenate(v) if v else np.array([]) for k, v in parts.items()}
    x = {"z": cat["a"], "b": cat["b"]} if kind == "sinkage" else {"j": cat["a"], "sigma": cat["s"]}
    return x, cat["y"], cat["w"], cat["o"].astype(int), usable


def build_groups(
    campaign, *, points_per_test: int = 60, progress: bool = False
) -> tuple[list[Group], list[str]]:
    """Split a campaign into (kind, soil) groups with per-test fits and pooled samples.

    Tests whose record is unusable (fewer than 5 samples in contact, no positive response)
    are dropped from the pooled samples, and per-test fits that fail keep NaN parameters;
    both are counted in the notes — nothing is dropped silently.
    """
    groups: list[Group] = []
    notes: list[str] = []
    for kind in ("sinkage", "shear"):
        of_kind = campaign.tests[campaign.tests["kind"] == kind]
        if of_kind.empty:
            continue
        for soil in sorted(of_kind["soil"].astype(str).unique()):
            group_notes: list[str] = []
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", ConvergenceWarning)
                table = fit_per_test(
                    campaign, kind, soil=soil, points_per_test=points_per_test, progress=progress
                )
            for w in caught:
                if issubclass(w.category, ConvergenceWarning):
                    group_notes.append(f"{kind} / {soil}: {w.message}")
                else:  # not ours to swallow
                    warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
            samples = campaign.sinkage if kind == "sinkage" else campaign.shear
            mine = samples[samples["test_id"].isin(table["test_id"])]
            x, y, w, owner, usable = _pool(table, mine, kind, points_per_test)
            if (~usable).any():
                bad = table.loc[~usable, "test_id"].astype(str).tolist()
                group_notes.append(
                    f"{kind} / {soil}: {len(bad)} test(s) without a usable record (fewer than 5 "
                    f"samples in contact or no positive reading), left out: {', '.join(bad[:6])}"
                )
            if not usable.any():
                notes.extend(group_notes)
                continue
            groups.append(Group(kind, soil, table, x, y, w, owner, notes=tuple(group_notes)))
            notes.extend(group_notes)
    return groups, notes
