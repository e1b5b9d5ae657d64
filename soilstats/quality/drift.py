"""Force-zero drift: a load cell's zero that wanders over a test day (``zero-drift``).

A drifting zero adds a constant force to a whole record, and the offset grows with the order
in which tests were run. One record cannot show it: a record may start under a real
preload (Cullinan's ``method2-test4`` starts at 14 % of its peak), so the signature is across
tests. The rule reads, per sinkage test, the **start force**: the median of the samples at
or above the surface (z <= 0) among its first :data:`START_SAMPLES` good samples (spikes
removed), the load cell's reading before contact; a record with none (logged from inside
contact) is not judged (its first readings carry the soil's response: a stiffness trend over
the day, GRC-1's forces x (1 + 0.5 (repetition - 1)), was read as a drifting zero).
Replicates of one setup all start at the same zero, whatever their soil's stiffness, so their
start forces scatter around one value; a drifting zero makes them trend with test order.

*Series* are the tests of one soil and kind with the same setup (every log column but the
test's name, ``operator`` and the order columns); *test order* inside a series is the first
of :data:`ORDER_COLUMNS` that every test of the series has (a sequence number, else a
date/time column such as ``start_time``, else ``repetition``), ties and else the log's row
order. The
statistic is Kendall's S between test order and start force, summed over the series of a
soil (stratified: only tests of one series are compared), with its exact permutation
distribution (start forces shuffled within each series; ties kept). A soil is judged
drifting when the two-sided p-value, Bonferroni-adjusted over the soils tested, is below
:data:`DRIFT_ALPHA`; then each series whose own trend (Theil–Sen slope per test) has the
same sign and spans at least :data:`DRIFT_MIN_PEAK` of the series' median peak force, and
whose own Kendall S has that sign with a one-sided exact p-value at most :data:`SERIES_P`, is
drifting, and its tests whose offset since the series' first test reaches that size are
flagged. The first test sets the zero, so it is never flagged.

Shear tests are not judged (a torque zero drift would need the same study of shear
records; not done).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..campaign.times import time_columns
from .blocks import Blocks

__all__ = [
    "DRIFT_ALPHA",
    "DRIFT_MIN_PEAK",
    "MAX_EXACT",
    "ORDER_COLUMNS",
    "SERIES_P",
    "START_SAMPLES",
    "Drift",
    "find_drift",
    "kendall_p",
    "start_forces",
]

#: Samples at the start of a record whose median is its start force (one spike or one
#: sample already under load does not move it).
START_SAMPLES = 3
#: Family-wise false-alarm rate over the soils of a campaign (two-sided, Bonferroni).
DRIFT_ALPHA = 0.01
#: The smallest drift that is flagged: across a series, and per flagged test since the
#: series' first, as a fraction of the series' median peak force.
DRIFT_MIN_PEAK = 0.01
#: ... and its slope at least this many standard errors (from the start forces' robust
#: scatter around the trend): on a 25 mm plate 1 % of the peak is ~1 N, the size of a
#: load cell's per-test offset, and 8 of 200 clean noisy tests of one series were flagged.
DRIFT_SLOPE_SE = 3.0
#: A series of a drifting soil is flagged only when its own trend is clear: Kendall's S in
#: the soil's direction with a one-sided exact p-value at most this (so at least 4 tests);
#: one preloaded start does not drag a clean series in.
SERIES_P = 0.1
#: Series up to this many tests get the exact permutation distribution of Kendall's S; a
#: soil with a longer series uses the normal approximation (tie-corrected variance).
MAX_EXACT = 60
#: Log columns read as test order, first found first (a sequence over the day before the
#: repetition within a condition; discovery reads the same names as time/order).  Any
#: date/time column comes just before ``repetition`` (:func:`_order_sources`).
ORDER_COLUMNS = ("sequence", "seq", "order", "run", "test_order", "test_number", "repetition")
#: Log columns that are no part of a test's setup (besides the order columns).
NOT_SETUP = ("test_id", "operator", "n_samples")


@dataclass(frozen=True)
class Drift:
    """One flagged test: ``offset_N`` is the fitted drift since its series' first test [N],
    ``peak_N`` the series' median peak force [N], ``p_value`` its soil's Bonferroni-adjusted
    two-sided p-value, ``order`` what test order was read from."""

    test_id: str
    soil: str
    offset_N: float
    peak_N: float
    slope_N: float
    p_value: float
    order: str
    series_size: int


def start_forces(blocks: Blocks, z: np.ndarray, force: np.ndarray) -> np.ndarray:
    """The median force [N] of the samples at or above the surface (z <= 0) among the first
    :data:`START_SAMPLES` of every record; NaN where there is none (a record logged from
    inside contact: its first readings carry the soil's response, which a trend in stiffness
    over the day would move as a drifting zero would) and for an empty record. ``blocks``
    lays the records end to end (:class:`.blocks.Blocks`)."""
    head, kept = blocks.head(START_SAMPLES)
    above, where = head.keep(z[kept] <= 0)
    return above.median(force[kept[where]])


# ----------------------------------------------------------------------------- statistics
def _qbinomial(m: int, r: int) -> list[int]:
    """Coefficients of the Gaussian binomial [m choose r]_q: the number of arrangements of
    r zeros and m - r ones with k inversions, k = 0 .. r (m - r)."""
    poly = [1]
    for i in range(1, r + 1):
        # × (1 - q^(m-r+i)) / (1 - q^i): the partial product is [m-r+i choose i]_q, a
        # polynomial, so every step is exact in integers.
        j = m - r + i
        grown = poly + [0] * j
        for k in range(len(grown) - 1, j - 1, -1):
            grown[k] -= grown[k - j]
        for k in range(i, len(grown)):
            grown[k] += grown[k - i]
        while len(grown) > 1 and grown[-1] == 0:
            grown.pop()
        poly = grown
    return poly


def _inversions(ties: list[int]) -> np.ndarray:
    """The permutation distribution of the inversions of a series whose start forces fall
    in tie groups of sizes ``ties`` (the q-multinomial), as probabilities."""
    poly, total = [1], 0
    for t in ties:
        total += t
        poly = _multiply(poly, _qbinomial(total, t))
    count = sum(poly)
    return np.array([c / count for c in poly])


def _multiply(a: list[int], b: list[int]) -> list[int]:
    out = [0] * (len(a) + len(b) - 1)
    for i, x in enumerate(a):
        if x:
            for j, y in enumerate(b):
                out[i + j] += x * y
    return out


def _kendall_s(values: np.ndarray) -> tuple[int, int]:
    """(S, untied pairs) of ``values`` against their position: S = concordant - discordant."""
    d = np.sign(values[None, :] - values[:, None])
    upper = np.triu(d, 1)
    return int(upper.sum()), int(np.count_nonzero(upper))


def kendall_p(series: list[np.ndarray]) -> tuple[int, float]:
    """Stratified Kendall trend test: (S summed over ``series``, two-sided p-value).

    Each array holds one series' values in test order; values are compared only within a
    series. The p-value is exact (values permuted within each series, ties kept) when every
    series has at most :data:`MAX_EXACT` tests, else from the normal approximation with the
    tie-corrected variance.
    """
    series = [np.asarray(v, float) for v in series if np.asarray(v).size >= 2]
    if not series:
        return 0, 1.0
    s_total, shift, var, dists = 0, 0, 0.0, []
    exact = max(v.size for v in series) <= MAX_EXACT
    for v in series:
        s_total += _kendall_s(v)[0]
        _, t = np.unique(v, return_counts=True)
        n = v.size
        var += (n * (n - 1) * (2 * n + 5) - float(np.sum(t * (t - 1) * (2 * t + 5)))) / 18
        shift += n * (n - 1) // 2 - int(np.sum(t * (t - 1) // 2))  # untied pairs
        if exact:
            dists.append(_inversions(t.tolist()))
    if exact:
        dist = dists[0]
        for d in dists[1:]:
            dist = np.convolve(dist, d)
        s = shift - 2 * np.arange(dist.size)  # S = untied pairs - 2 x inversions
        return s_total, float(min(1.0, dist[np.abs(s) >= abs(s_total)].sum()))
    if var <= 0:
        return s_total, 1.0
    from scipy.stats import norm  # deferred: scipy.stats, 0.35 s (screening loads no more)

    z = (abs(s_total) - 1) / np.sqrt(var)  # continuity-corrected
    return s_total, float(min(1.0, 2 * norm.sf(max(z, 0.0))))


def _theil_sen(values: np.ndarray) -> float:
    """Median of the pairwise slopes of ``values`` against their position [unit per test]."""
    i, j = np.triu_indices(values.size, 1)
    return float(np.median((values[j] - values[i]) / (j - i)))


# ----------------------------------------------------------------------------- the rule
def _series(log: pd.DataFrame) -> pd.Series:
    """A series label for every sinkage test (same soil and setup). A column with a value of
    its own for every test (a date, a file name, a note) names tests, not setups: it is not
    a setup column (it would make every test a series of one and silence the rule)."""
    setup = [
        c
        for c in log.columns
        if c not in NOT_SETUP
        and str(c).lower() not in ORDER_COLUMNS
        and log[c].notna().any()
        and not (len(log) > 1 and log[c].nunique(dropna=False) == len(log))
    ]
    # Per column codes (a missing cell is its own level, -1), then one code per combination.
    codes = np.column_stack([pd.factorize(log[c], sort=False)[0] for c in setup])
    return pd.Series(np.unique(codes, axis=0, return_inverse=True)[1].ravel(), index=log.index)


def _order_sources(tests: pd.DataFrame) -> list[tuple[str, pd.Series]]:
    """What test order may be read from, first found first: the numeric columns of
    :data:`ORDER_COLUMNS` before ``repetition``, then every date/time column (as hours,
    :func:`~soilstats.campaign.times.time_columns`), then ``repetition`` — when a test ran
    orders a day's tests across conditions; a repetition number only within one."""
    names = {str(c).lower(): c for c in tests.columns}
    sources = []
    for name in ORDER_COLUMNS:
        if name == "repetition":
            sources += [
                (str(column), hours)
                for column, hours in time_columns(tests).items()
                if column not in NOT_SETUP
            ]
        column = names.get(name)
        if column is not None and pd.api.types.is_numeric_dtype(tests[column]):
            sources.append((str(column), tests[column]))
    return sources


def _in_order(tests: pd.DataFrame) -> tuple[pd.DataFrame, pd.Series]:
    """``tests`` sorted by soil, series and test order, and what each series' order was read
    from (by series): the first source of :func:`_order_sources` that every test of the
    series has, ties and else the log's row order. One sort for all series (10,000 tests:
    ~1,000)."""
    order = pd.Series(np.nan, index=tests.index)
    source = pd.Series("log row order", index=tests.index)
    done = pd.Series(False, index=tests.index)
    for label, values in _order_sources(tests):
        full = values.notna().groupby(tests["series"]).transform("all") & ~done
        order[full], source[full], done = values[full], label, done | full
    keys = (tests["row"].to_numpy(), order.fillna(0.0).to_numpy(float), tests["series"])
    ranked = tests.iloc[np.lexsort(keys)]
    return ranked, source.groupby(tests["series"]).first()


def _slope_se(values: np.ndarray, slope: float) -> float:
    """Standard error of a trend's slope per test, from the robust scatter (1.4826 MAD) of
    the values around the Theil-Sen line."""
    m = values.size
    k = np.arange(m, dtype=float)
    residual = values - slope * k
    residual = residual - np.median(residual)
    width = 1.4826 * float(np.median(np.abs(residual)))
    spread = float(((k - k.mean()) ** 2).sum())
    return width / np.sqrt(spread) if spread > 0 else np.inf


def find_drift(log: pd.DataFrame, starts: pd.DataFrame) -> list[Drift]:
    """The tests whose force zero drifted (module docstring).

    Parameters
    ----------
    log : DataFrame
        The campaign's test log (``campaign.tests``), in file order.
    starts : DataFrame
        ``test_id``, ``force_start`` (:func:`start_forces`) and ``force_end`` (the record's
        peak force) of every sinkage test [N].
    """
    tests = log[log["kind"] == "sinkage"].copy()
    tests["series"] = _series(tests).to_numpy()
    tests["test_id"] = tests["test_id"].astype(str)
    tests["row"] = np.arange(len(tests))
    frame = tests.merge(starts, on="test_id", how="inner")
    frame = frame[np.isfinite(frame["force_start"]) & np.isfinite(frame["force_end"])]
    if frame.empty:
        return []
    frame, sources = _in_order(frame)
    judged = []
    for soil, soil_tests in frame.groupby("soil", sort=True):
        groups = [
            (g, sources[key]) for key, g in soil_tests.groupby("series", sort=True) if len(g) >= 2
        ]
        if groups:
            s, p = kendall_p([g["force_start"].to_numpy(float) for g, _ in groups])
            judged.append((str(soil), groups, s, p))
    out: list[Drift] = []
    for soil, groups, s, p in judged:
        p_adj = min(1.0, p * len(judged))
        if s == 0 or p_adj >= DRIFT_ALPHA:
            continue
        for g, order in groups:
            offsets = g["force_start"].to_numpy(float)
            slope = _theil_sen(offsets)
            peak = float(np.median(g["force_end"]))
            least = DRIFT_MIN_PEAK * peak
            if np.sign(slope) != np.sign(s) or abs(slope) * (len(g) - 1) < least:
                continue
            if abs(slope) < DRIFT_SLOPE_SE * _slope_se(offsets, slope):
                continue  # within the offsets' own scatter (1 N offsets, 1 % of 100 N)
            own, p_two = kendall_p([offsets])
            if np.sign(own) != np.sign(s) or p_two / 2 > SERIES_P:  # symmetric: one-sided
                continue
            for k, tid in enumerate(g["test_id"]):
                drift = slope * k
                if abs(drift) >= least:
                    out.append(Drift(tid, soil, drift, peak, slope, p_adj, order, len(g)))
    return out
