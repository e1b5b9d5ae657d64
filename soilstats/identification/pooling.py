"""Section 2.1's rule for the samples of a test, and the pooled arrays of Eq. 11.

The one home of the rule every analysis uses (pooled fits, per-test fits, discovery,
posteriors): of a test's record keep the samples in contact (sinkage z > 0: z^n has no real
value below; shear j >= 0), take those nearest to equally spaced sinkages (or deformations),
and weight the test by 1/max of its own response, so that large plates or deep tests do not
dominate the fit. A test with fewer than :data:`MIN_SAMPLES` such samples, or no positive
response, is unusable. Everything excluded on the way is counted per test and reported.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from ..campaign.index import campaign_index, grouped_by_code
from ..campaign.schema import MIN_SAMPLES  # re-exported: the rule below applies it
from ..errors import CampaignError, InputError
from ..quality import screened
from .steady_state import steady_state

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign
    from ..campaign.index import CampaignIndex
    from ..campaign.tables import Criterion
    from ..quality import ScreenedCampaign

__all__ = [
    "MIN_SAMPLES",
    "KeptSamples",
    "PooledData",
    "equidistant_indices",
    "kept_samples",
    "pool_shear",
    "pool_sinkage",
    "select_one_soil",
]

_CONTACT = {"sinkage": "z > 0", "shear": "j >= 0"}


@dataclass(frozen=True)
class PooledData:
    """Stacked samples of several tests, ready for :func:`soilstats.identify`."""

    x: dict[str, np.ndarray]  # input columns by name, each (N,)
    y: np.ndarray  # (N,)
    weights: np.ndarray  # (N,)
    test_index: np.ndarray  # (N,) position of each sample's test in ``tests``
    #: One entry per test, the columns of ``tests`` as arrays: what code reads on every fit
    #: (a fresh frame's first column lookup costs more than a whole reduction).
    by_test: dict[str, np.ndarray] = field(default_factory=dict, repr=False)

    @classmethod
    def of(
        cls,
        x: dict[str, np.ndarray],
        y: np.ndarray,
        weights: np.ndarray,
        test_index: np.ndarray,
        by_test: dict,
    ) -> PooledData:
        """The pooled arrays and the per-test columns (``tests`` is built from them)."""
        return cls(x, y, weights, test_index, by_test)

    @cached_property
    def tests(self) -> pd.DataFrame:
        """One row per test: bookkeeping of what was used and excluded (``by_test`` as a
        frame, built on first use: building it costs more than the fit it describes)."""
        return pd.DataFrame(self.by_test)


def equidistant_indices(z: np.ndarray, count: int | None) -> np.ndarray:
    """Indices of the samples nearest to ``count`` sinkages equally spaced over [min z, max z].

    Values are never interpolated: the chosen points are measured samples (Section 2.1 takes
    "data points equidistantly spaced over the measured penetration depth").  Duplicates are
    removed, so a short record may give fewer than ``count`` points.  Returned in record order.
    """
    z = np.asarray(z, float)
    return np.flatnonzero(_equidistant_by_test(z, np.zeros(z.size, np.intp), 1, count))


def _equidistant_by_test(
    axis: np.ndarray, test: np.ndarray, n_tests: int, count: int | None
) -> np.ndarray:
    """Mask of the samples :func:`equidistant_indices` keeps, for every test at once.

    ``test`` (N,) holds each sample's test 0 … n_tests−1.  Per test, the grid of ``count``
    values over [min, max] of ``axis`` is ``np.linspace``'s (same arithmetic, exact end
    point), and each grid value takes the nearer of its two neighbours, the lower on a tie.
    """
    keep = np.ones(axis.size, bool)
    if count is None or axis.size == 0:
        return keep
    sizes = np.bincount(test, minlength=n_tests)
    thin = np.flatnonzero(sizes > count)
    if not thin.size:
        return keep
    order = np.lexsort((axis, test))  # by test, then value; ties keep record order
    values = axis[order]
    starts = np.cumsum(sizes) - sizes
    lo, hi = values[starts[thin]], values[starts[thin] + sizes[thin] - 1]
    k = np.arange(count, dtype=float)
    if count > 1:
        grid = lo[:, None] + k * ((hi - lo) / (count - 1))[:, None]
        grid[:, -1] = hi
    else:
        grid = lo[:, None].copy()
    # Locate each grid value among its test's sorted samples with one global search: the
    # key 2t + (v − lo_t)/(hi_t − lo_t) is non-decreasing in v within a test and keeps
    # tests apart.  Rounding can merge a sample just below a grid value with it, so the
    # position is then advanced to the first sample truly >= the value (exact comparisons).
    span = np.where(hi > lo, hi - lo, 1.0)
    sample_test = test[order]
    t_lo = np.zeros(n_tests)
    t_span = np.ones(n_tests)
    t_lo[thin], t_span[thin] = lo, span
    sample_key = 2.0 * sample_test + (values - t_lo[sample_test]) / t_span[sample_test]
    grid_key = 2.0 * thin[:, None] + (grid - lo[:, None]) / span[:, None]
    pos = np.searchsorted(sample_key, grid_key.ravel()).reshape(grid.shape)
    first = starts[thin][:, None]
    last = (starts[thin] + sizes[thin] - 1)[:, None]
    while True:
        behind = (pos <= last) & (values[np.minimum(pos, last)] < grid)
        if not behind.any():
            break
        pos += behind
    pos = np.clip(pos, first + 1, last)
    nearer_left = (grid - values[pos - 1]) <= (values[pos] - grid)
    chosen = np.where(nearer_left, pos - 1, pos)
    in_thin = np.zeros(n_tests, bool)
    in_thin[thin] = True
    keep[order[in_thin[sample_test]]] = False
    keep[order[chosen.ravel()]] = True
    return keep


@dataclass(frozen=True)
class KeptSamples:
    """What Section 2.1's rule keeps of one test's record.

    Attributes
    ----------
    index : numpy.ndarray
        Positions, in the test's own record and in record order, of the samples used.
    excluded : int
        Samples out of contact (sinkage z <= 0, shear j < 0).
    weight : float
        1/max(y) over the samples used (``weighting="max"``) or 1; NaN when unusable.
    problem : str or None
        Why the test cannot be fitted (too few samples, no positive response); None if usable.
    """

    index: np.ndarray
    excluded: int
    weight: float
    problem: str | None = None


@dataclass(frozen=True)
class KeptByTest:
    """Section 2.1's rule applied to many tests at once (arrays over tests, T)."""

    used: np.ndarray  # (N,) bool: the sample is used
    excluded: np.ndarray  # (T,) samples out of contact
    counts: np.ndarray  # (T,) samples used
    y_max: np.ndarray  # (T,) max response over the samples used (NaN: none)
    weight: np.ndarray  # (T,) 1/max(y) or 1; NaN when unusable
    problems: list  # (T,) str or None

    def fitted(self, test: np.ndarray) -> np.ndarray:
        """(N,) bool: used samples of the tests without a problem (``test`` as given to
        :func:`kept_by_test`) — what a pooled fit takes."""
        usable = np.array([problem is None for problem in self.problems], bool)
        return self.used & usable[np.maximum(test, 0)]


def kept_by_test(
    axis: np.ndarray,
    y: np.ndarray,
    test: np.ndarray,
    n_tests: int,
    kind: str,
    *,
    points_per_test: int | None,
    weighting: str = "max",
) -> KeptByTest:
    """Apply Section 2.1's rule to every test of a table at once (see :func:`kept_samples`).

    ``test`` (N,) holds each sample's test 0 … T−1 (−1: not selected, never used).
    """
    axis = np.asarray(axis, float)
    y = np.asarray(y, float)
    test = np.asarray(test, np.intp)
    member = test >= 0
    contact = member & ((axis > 0) if kind == "sinkage" else (axis >= 0))
    excluded = np.bincount(test[member & ~contact], minlength=n_tests)
    candidates = np.flatnonzero(contact)
    used = np.zeros(axis.size, bool)
    used[
        candidates[
            _equidistant_by_test(axis[candidates], test[candidates], n_tests, points_per_test)
        ]
    ] = True
    used_test = test[used]
    counts = np.bincount(used_test, minlength=n_tests)
    y_max = _max_by_test(y[used], used_test, n_tests)
    problems: list = [None] * n_tests
    for t in np.flatnonzero(counts < MIN_SAMPLES):
        problems[t] = (
            f"only {counts[t]} samples with {_CONTACT[kind]}; a fit needs at least "
            f"{MIN_SAMPLES} per test"
        )
    if weighting == "max":
        for t in np.flatnonzero((counts >= MIN_SAMPLES) & ~(y_max > 0)):
            problems[t] = (
                f"max response is {y_max[t]:g} Pa <= 0, so the weight 1/max of Section 2.1 is "
                "undefined; check the sign of the force or torque, or exclude the test"
            )
        with np.errstate(divide="ignore"):
            weight = 1.0 / y_max
    else:
        weight = np.ones(n_tests)
    bad = np.array([pr is not None for pr in problems], bool)
    weight[bad] = np.nan
    return KeptByTest(used, excluded, counts, y_max, weight, problems)


def kept_samples(
    axis: np.ndarray,
    y: np.ndarray,
    kind: str,
    *,
    points_per_test: int | None,
    weighting: str = "max",
) -> KeptSamples:
    """Apply Section 2.1's rule to one test's record.

    Parameters
    ----------
    axis : numpy.ndarray
        Sinkage z [m] (``kind="sinkage"``) or shear deformation j [m] (``kind="shear"``).
    y : numpy.ndarray
        Pressure p [Pa] or shear stress τ [Pa], one per sample.
    kind : {"sinkage", "shear"}
        Which contact rule applies: z > 0 or j >= 0.
    points_per_test : int or None
        Keep the samples nearest to this many equally spaced values of ``axis`` (None: all).
    weighting : {"max", "none"}
        Weight 1/max(y) per test (Section 2.1) or 1.
    """
    axis = np.asarray(axis, float)
    rule = kept_by_test(
        axis,
        y,
        np.zeros(axis.size, np.intp),
        1,
        kind,
        points_per_test=points_per_test,
        weighting=weighting,
    )
    return KeptSamples(
        np.flatnonzero(rule.used), int(rule.excluded[0]), float(rule.weight[0]), rule.problems[0]
    )


def _unusable(kind: str, tid: object, problem: str, file: str) -> CampaignError:
    column = ("z_m" if "samples" in problem else "force_N") if kind == "sinkage" else "torque_Nm"
    return CampaignError(problem, file=file, column=column, test_id=str(tid))


def pool_sinkage(
    campaign: Campaign,
    *,
    points_per_test: int | None = 100,
    weighting: str = "max-pressure",
    on_unusable: str = "raise",
    **selection: Criterion,
) -> PooledData:
    """Stack the selected sinkage tests into (b, z) → p arrays with per-test weights.

    Samples with z <= 0 (sensor zero offsets, the plate not yet in contact) are excluded:
    z^n has no real value there. Samples with p <= 0 at z > 0 are kept: they are
    measurements, and least squares handles them. Of the rest, ``points_per_test`` samples
    nearest to equally spaced sinkages are used (Section 2.1; ``None`` keeps all). Each test is
    weighted by 1/max(p) over its used samples (Section 2.1), or 1 with ``weighting="none"``.

    ``on_unusable="raise"`` makes a test the rule cannot use a :class:`CampaignError`;
    ``"skip"`` keeps its row in ``tests`` (``used`` 0, the reason in ``problem``) with no
    samples.
    """
    if weighting not in ("max-pressure", "none"):
        raise InputError(f"weighting must be 'max-pressure' or 'none', got {weighting!r}")
    index, chosen, test, (z_all, p_all) = _selected_samples(
        campaign, "sinkage", selection, ("z_m", "pressure_Pa")
    )
    test_ids, n_tests = index.test_id[chosen], chosen.size
    rule = kept_by_test(
        z_all,
        p_all,
        test,
        n_tests,
        "sinkage",
        points_per_test=points_per_test,
        weighting="max" if weighting == "max-pressure" else "none",
    )
    if on_unusable == "raise":
        _raise_first_problem("sinkage", test_ids, rule.problems, campaign.file_name("sinkage"))
    use, test_of = _used_in_test_order(rule.fitted(test), test)
    z, p = z_all[use], p_all[use]
    used = np.bincount(test_of, minlength=n_tests)
    b = index.b_m[chosen]
    by_test = {
        "test_id": test_ids,
        "b_m": b,
        "samples": np.bincount(test, minlength=n_tests),
        "excluded_z_nonpositive": rule.excluded,
        "used": used,
        "z_max_m": _max_by_test(z, test_of, n_tests),
        "p_max_Pa": _max_by_test(p, test_of, n_tests),
        "weight": rule.weight,
        "problem": rule.problems,
    }
    return PooledData.of({"b_m": b[test_of], "z_m": z}, p, rule.weight[test_of], test_of, by_test)


def _used_in_test_order(used: np.ndarray, test: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions of the used samples ordered by test, record order within a test, and
    each one's test."""
    index = np.flatnonzero(used)
    order = np.argsort(test[index], kind="stable")
    return index[order], test[index[order]]


def _max_by_test(values: np.ndarray, test: np.ndarray, n_tests: int) -> np.ndarray:
    """Max of ``values`` per test; NaN for a test without samples."""
    out = np.full(n_tests, -np.inf)
    np.maximum.at(out, test, values)
    out[np.isneginf(out)] = np.nan
    return out


def _raise_first_problem(kind: str, test_ids: np.ndarray, problems: list, file: str) -> None:
    for tid, problem in zip(test_ids, problems, strict=True):
        if problem is not None:
            raise _unusable(kind, tid, problem, file)


def pool_shear(
    campaign: Campaign,
    *,
    steady_only: bool,
    weighting: str,
    points_per_test: int | None = None,
    on_unusable: str = "raise",
    **selection: Criterion,
) -> PooledData:
    """Stack the selected shear tests into (σ [Pa], j [m]) → τ [Pa] with per-test weights.

    ``steady_only`` keeps each test's steady-state part (Mohr–Coulomb, rule in
    :mod:`.steady_state`); otherwise Section 2.1's rule (:func:`kept_samples`: j >= 0,
    ``points_per_test`` nearest to equally spaced j) for Janosi–Hanamoto. ``weighting`` is
    ``"none"`` or ``"max-stress"`` (1/max τ per test). Every test keeps a row in ``tests``;
    one that contributes no sample has ``used`` 0 and the reason.
    """

    if weighting not in ("none", "max-stress"):
        raise InputError(f"weighting must be 'none' or 'max-stress', got {weighting!r}")
    index, chosen, test, (sig_all, tau_all, j_all) = _selected_samples(
        campaign, "shear", selection, ("sigma_Pa", "tau_Pa", "j_m")
    )
    test_ids, n_tests = index.test_id[chosen], chosen.size
    present = np.bincount(test, minlength=n_tests)
    with np.errstate(invalid="ignore", divide="ignore"):
        sigma_mean = np.bincount(test, sig_all, n_tests) / present
    groups = {"test_id": test_ids, "samples": present, "sigma_mean_Pa": sigma_mean}
    if steady_only:
        used, weight, steady_columns = _steady_parts(
            test, j_all, tau_all, test_ids, weighting, campaign.file_name("shear")
        )
        groups.update(steady_columns)
    else:
        rule = kept_by_test(
            j_all,
            tau_all,
            test,
            n_tests,
            "shear",
            points_per_test=points_per_test,
            weighting="max" if weighting == "max-stress" else "none",
        )
        if on_unusable == "raise":
            _raise_first_problem("shear", test_ids, rule.problems, campaign.file_name("shear"))
        used = rule.fitted(test)
        weight = rule.weight
        groups.update(excluded_j_negative=rule.excluded, problem=rule.problems)
    use, test_of = _used_in_test_order(used, test)
    counts = np.bincount(test_of, minlength=n_tests)
    groups.update(used=counts, weight=weight)
    if not counts.any():
        why = (
            "no selected shear test reaches a steady state, so Mohr–Coulomb (Eq. 15) has no "
            "data; see the steady-state rule in soilstats.identification.steady_state"
            if steady_only
            else "no selected shear test has a usable record (see the fit's tests['problem'])"
        )
        raise CampaignError(why, file=campaign.file_name("shear"), column="torque_Nm")
    return PooledData.of(
        {"sigma_Pa": sig_all[use], "j_m": j_all[use]},
        tau_all[use],
        weight[test_of],
        test_of,
        groups,
    )


def _steady_parts(
    test: np.ndarray,
    j_all: np.ndarray,
    tau_all: np.ndarray,
    test_ids: np.ndarray,
    weighting: str,
    file: str,
) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """The steady-state samples of every shear test (rule in :mod:`.steady_state`), their
    weights and the bookkeeping columns; one test at a time, as the rule reads a record.
    ``file``: the shear file's name, for messages."""
    n_tests = len(test_ids)
    used = np.zeros(test.size, bool)
    weight = np.full(n_tests, np.nan)
    columns: dict[str, Any] = {
        "steady": np.zeros(n_tests, bool),
        "steady_from_j_m": np.full(n_tests, np.nan),
        "tau_ss_Pa": np.full(n_tests, np.nan),
        "reason": [None] * n_tests,
    }
    index_of = grouped_by_code(test, n_tests)
    for t, tid in enumerate(test_ids):
        idx = index_of[t]
        j, tau = j_all[idx], tau_all[idx]
        ss = steady_state(j, tau)
        columns["steady"][t] = ss.steady
        columns["steady_from_j_m"][t] = float(j[ss.indices].min()) if ss.indices.size else np.nan
        columns["tau_ss_Pa"][t] = ss.tau_level
        columns["reason"][t] = ss.reason
        keep = ss.indices if ss.steady else np.array([], int)
        if not keep.size:
            continue
        t_max = float(np.max(tau[keep]))
        if weighting == "max-stress" and t_max <= 0:
            raise _unusable("shear", tid, f"max shear stress {t_max:g} Pa <= 0", file)
        weight[t] = 1.0 / t_max if weighting == "max-stress" else 1.0
        used[idx[keep]] = True
    return used, weight, columns


def select_one_soil(
    campaign: Campaign, kind: str, selection: dict
) -> tuple[Campaign, pd.DataFrame]:
    """Apply ``selection`` and keep the tests of ``kind``; demand exactly one soil.

    Pooling two soils into one parameter set is never what a user means, so it is an error
    that lists the soils found and how to pick one.
    """
    chosen = campaign.select(**selection) if selection else campaign
    tests = chosen.tests[chosen.tests["kind"] == kind]
    _demand_one_soil(
        kind,
        selection,
        chosen.tests["kind"],
        tests["soil"].astype(str),
        campaign.file_name("tests"),
    )
    return chosen, tests


def _selected_samples(
    campaign: Campaign, kind: str, selection: dict, columns: tuple[str, ...]
) -> tuple[CampaignIndex, np.ndarray, np.ndarray, list[np.ndarray]]:
    """The screened ``campaign``'s index, the log rows of the selected tests of ``kind``
    (:func:`_one_soil_tests`), each of their samples' test (0 … T−1, file order) and the
    samples' ``columns`` as float arrays."""
    index, chosen = _one_soil_tests(screened(campaign), kind, selection)
    rows, test = index.rows_of(kind, chosen)
    return index, chosen, test, [index.column(kind, c)[rows] for c in columns]


def _one_soil_tests(
    campaign: ScreenedCampaign, kind: str, selection: dict
) -> tuple[CampaignIndex, np.ndarray]:
    """:func:`select_one_soil` without building the selected campaign: the campaign's
    index (:mod:`soilstats.campaign.index`) and the log rows of the chosen tests, in log
    order. Same criteria, same errors."""
    index = campaign_index(campaign)
    chosen = campaign.matches(**selection) if selection else np.ones(index.kind.size, bool)
    rows = np.flatnonzero(chosen & index.of_kind[kind])
    _demand_one_soil(
        kind, selection, index.kind[chosen], index.soil[rows], campaign.file_name("tests")
    )
    return index, rows


def _demand_one_soil(
    kind: str,
    selection: dict,
    kinds: pd.Series | np.ndarray,
    soils: pd.Series | np.ndarray,
    file: str,
) -> None:
    """Raise unless the selection (``kinds`` of all its tests) holds tests of ``kind``, all
    of one soil (``soils``: theirs, as text); ``file``: the test log's name, for messages."""
    if not len(soils):
        crit = ", ".join(f"{k}={v!r}" for k, v in selection.items()) or "no selection"
        raise CampaignError(
            f"no {kind} tests match ({crit}); the campaign has kinds {sorted(set(kinds))}",
            file=file,
            column="kind",
        )
    distinct = sorted(set(soils))
    if len(distinct) > 1:
        raise CampaignError(
            f"the selection holds {len(distinct)} soils {distinct}; parameters of different soils "
            f"must not be pooled — add soil=... to the call (e.g. soil={distinct[0]!r})",
            file=file,
            column="soil",
        )
