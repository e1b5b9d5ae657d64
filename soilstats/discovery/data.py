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
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, TypeVar

import numpy as np
import pandas as pd

from ..errors import ConvergenceWarning
from ..identification import fit_per_test
from ..identification.per_test import not_converged_message
from ..identification.pooling import MIN_SAMPLES, pool_shear, pool_sinkage
from .candidates import candidate_values, with_time_hours

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign
    from ..models.base import Model

__all__ = ["Group", "build_groups"]

T = TypeVar("T")


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
    time_columns : tuple of str
        Columns of ``tests`` converted from dates/times to hours since the first test.
    model : Model, optional
        The registered model to use as the base of this kind instead of the paper's
        (``discover(model=...)``; :func:`~.library.base_model`).
    """

    kind: str
    soil: str
    tests: pd.DataFrame
    x: dict[str, np.ndarray] = field(repr=False)
    y: np.ndarray = field(repr=False)
    w: np.ndarray = field(repr=False)
    owner: np.ndarray = field(repr=False)
    notes: tuple[str, ...] = ()
    time_columns: tuple[str, ...] = ()
    model: Model | None = field(default=None, repr=False)
    # What is computed once per group from its fixed tests (see :meth:`memo`); a new group
    # (``dataclasses.replace``) starts with an empty one.
    _memo: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    @property
    def label(self) -> str:
        return f"{self.kind} / {self.soil}"

    def memo(self, key: Hashable, compute: Callable[[], T]) -> T:
        """``compute()``, once per group and ``key``: cross-validation refits the same
        extensions on the same tests hundreds of times, and the per-test features (a
        column's values as :func:`~.candidates.candidate_values` reads them) never change
        within a group."""
        try:
            return self._memo[key]
        except KeyError:
            value = self._memo[key] = compute()
            return value

    def values(self, column: str) -> pd.Series:
        """:func:`~.candidates.candidate_values` of a column of ``tests`` (memoised)."""
        return self.memo(("values", column), lambda: candidate_values(self.tests, column))

    def samples_of(self, rows: np.ndarray) -> np.ndarray:
        """Boolean mask of the samples belonging to the table rows ``rows``."""
        keep = np.zeros(len(self.tests), bool)
        keep[np.asarray(rows, int)] = True
        return keep[self.owner]


def _pool(
    campaign: Campaign, kind: str, soil: str, table: pd.DataFrame, points: int
) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Section 2.1's samples of one (kind, soil), in the rows of ``table`` (the per-test fits)."""
    if kind == "sinkage":
        pooled = pool_sinkage(campaign, points_per_test=points, on_unusable="skip", soil=soil)
        x = {"z": pooled.x["z_m"], "b": pooled.x["b_m"]}
    else:
        pooled = pool_shear(
            campaign,
            steady_only=False,
            weighting="max-stress",
            points_per_test=points,
            on_unusable="skip",
            soil=soil,
        )
        x = {"j": pooled.x["j_m"], "sigma": pooled.x["sigma_Pa"]}
    order = pooled.tests["test_id"].astype(str).to_numpy()
    if not np.array_equal(order, table["test_id"].astype(str).to_numpy()):
        raise AssertionError("pooled tests and per-test table are out of step")  # a bug
    usable = pooled.tests["used"].to_numpy() > 0
    return x, pooled.y, pooled.weights, pooled.test_index, usable


def build_groups(
    campaign: Campaign,
    *,
    points_per_test: int = 60,
    progress: bool = False,
    jobs: int | None = 1,
    model: Model | None = None,
) -> tuple[list[Group], list[str]]:
    """Split a campaign into (kind, soil) groups with per-test fits and pooled samples.

    Tests whose record is unusable (fewer than :data:`MIN_SAMPLES` samples in contact, no
    positive response; the rule of :mod:`soilstats.identification.pooling`)
    are dropped from the pooled samples, and per-test fits that fail keep NaN parameters;
    both are counted in the notes — nothing is dropped silently.  ``jobs``: worker processes
    for the per-test fits (:func:`soilstats.fit_per_test`; the same rows for any number).
    ``model``: a registered model (a record) to use as the base of its kind's groups.
    """
    groups: list[Group] = []
    notes: list[str] = []
    for kind in ("sinkage", "shear"):
        of_kind = campaign.tests[campaign.tests["kind"] == kind]
        if of_kind.empty:
            continue
        # Every test of the kind in one call (each test is fitted on its own, so the rows
        # are those of one call per soil), then split by soil: one queue for the workers.
        with warnings.catch_warnings():
            # Reported per soil below, as each group's note.
            warnings.simplefilter("ignore", ConvergenceWarning)
            fitted = fit_per_test(
                campaign, kind, points_per_test=points_per_test, progress=progress, jobs=jobs
            )
        soil_of = fitted["soil"].astype(str)
        for soil in sorted(of_kind["soil"].astype(str).unique()):
            group_notes: list[str] = []
            table = fitted[soil_of == soil].reset_index(drop=True)
            failed = not_converged_message(table, kind)
            if failed:
                group_notes.append(f"{kind} / {soil}: {failed}")
            x, y, w, owner, usable = _pool(campaign, kind, soil, table, points_per_test)
            if (~usable).any():
                bad = table.loc[~usable, "test_id"].astype(str).tolist()
                group_notes.append(
                    f"{kind} / {soil}: {len(bad)} test(s) without a usable record (fewer than "
                    f"{MIN_SAMPLES} samples in contact or no positive reading), left out: "
                    f"{', '.join(bad[:6])}"
                )
            if not usable.any():
                notes.extend(group_notes)
                continue
            table, times = with_time_hours(table)
            own = model if model is not None and model.kind == kind else None
            groups.append(
                Group(
                    kind,
                    soil,
                    table,
                    x,
                    y,
                    w,
                    owner,
                    tuple(group_notes),
                    time_columns=times,
                    model=own,
                )
            )
            notes.extend(group_notes)
    return groups, notes
