"""Section 2.1's rule for the samples of a test, and the pooled arrays of Eq. 11.

The one home of the rule every analysis uses (pooled fits, per-test fits, discovery,
posteriors): of a test's record keep the samples in contact (sinkage z > 0: z^n has no real
value below; shear j >= 0), take those nearest to equally spaced sinkages (or deformations),
and weight the test by 1/max of its own response, so that large plates or deep tests do not
dominate the fit. A test with fewer than :data:`MIN_SAMPLES` such samples, or no positive
response, is unusable. Everything excluded on the way is counted per test and reported.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..errors import CampaignError
from ..quality import screened

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

#: Fewest samples in contact a test needs to enter a fit (three: a power law has two
#: parameters, and one residual degree of freedom is the least that says anything).
MIN_SAMPLES = 3

_CONTACT = {"sinkage": "z > 0", "shear": "j >= 0"}


@dataclass(frozen=True)
class PooledData:
    """Stacked samples of several tests, ready for :func:`soilstats.identify`."""

    x: dict[str, np.ndarray]  # input columns by name, each (N,)
    y: np.ndarray  # (N,)
    weights: np.ndarray  # (N,)
    test_index: np.ndarray  # (N,) position of each sample's test in ``tests``
    tests: pd.DataFrame  # one row per test: bookkeeping of what was used and excluded


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
    y = np.asarray(y, float)
    contact = axis > 0 if kind == "sinkage" else axis >= 0
    inside = np.flatnonzero(contact)
    index = inside[equidistant_indices(axis[inside], points_per_test)]
    excluded = int(axis.size - inside.size)
    if index.size < MIN_SAMPLES:
        problem = (
            f"only {index.size} samples with {_CONTACT[kind]}; a fit needs at least "
            f"{MIN_SAMPLES} per test"
        )
        return KeptSamples(index, excluded, np.nan, problem)
    y_max = float(y[index].max())
    if weighting == "max" and y_max <= 0:
        problem = (
            f"max response is {y_max:g} Pa <= 0, so the weight 1/max of Section 2.1 is "
            "undefined; check the sign of the force or torque, or exclude the test"
        )
        return KeptSamples(index, excluded, np.nan, problem)
    return KeptSamples(index, excluded, 1.0 / y_max if weighting == "max" else 1.0)


def _unusable(kind: str, tid, problem: str) -> CampaignError:
    column = ("z_m" if "samples" in problem else "force_N") if kind == "sinkage" else "torque_Nm"
    return CampaignError(problem, file=f"{kind}.csv", column=column, test_id=str(tid))


def pool_sinkage(
    campaign,
    *,
    points_per_test: int | None = 100,
    weighting: str = "max-pressure",
    on_unusable: str = "raise",
    **selection,
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
        raise ValueError(f"weighting must be 'max-pressure' or 'none', got {weighting!r}")
    chosen, tests = select_one_soil(screened(campaign), "sinkage", selection)
    samples = chosen.sinkage
    by_test = samples.groupby("test_id", sort=False).indices
    z_all = samples["z_m"].to_numpy(float)
    p_all = samples["pressure_Pa"].to_numpy(float)
    empty = np.array([], int)
    zs, ps, rows = [], [], []
    for tid, b in zip(tests["test_id"], tests["b_m"].to_numpy(float), strict=True):
        idx = by_test.get(tid, empty)
        kept = kept_samples(
            z_all[idx],
            p_all[idx],
            "sinkage",
            points_per_test=points_per_test,
            weighting="max" if weighting == "max-pressure" else "none",
        )
        if kept.problem is not None and on_unusable == "raise":
            raise _unusable("sinkage", tid, kept.problem)
        use = idx[kept.index] if kept.problem is None else empty
        z, p = z_all[use], p_all[use]
        zs.append(z)
        ps.append(p)
        rows.append(
            (
                tid,
                b,
                idx.size,
                kept.excluded,
                z.size,
                float(z.max()) if z.size else np.nan,
                float(p.max()) if p.size else np.nan,
                kept.weight,
                kept.problem,
            )
        )
    groups = pd.DataFrame(
        rows,
        columns=[
            "test_id",
            "b_m",
            "samples",
            "excluded_z_nonpositive",
            "used",
            "z_max_m",
            "p_max_Pa",
            "weight",
            "problem",
        ],
    )
    used = groups["used"].to_numpy()
    return PooledData(
        x={"b_m": np.repeat(groups["b_m"].to_numpy(), used), "z_m": np.concatenate(zs)},
        y=np.concatenate(ps),
        weights=np.repeat(groups["weight"].to_numpy(), used),
        test_index=np.repeat(np.arange(len(groups)), used),
        tests=groups,
    )


def pool_shear(
    campaign,
    *,
    steady_only: bool,
    weighting: str,
    points_per_test: int | None = None,
    on_unusable: str = "raise",
    **selection,
) -> PooledData:
    """Stack the selected shear tests into (σ [Pa], j [m]) → τ [Pa] with per-test weights.

    ``steady_only`` keeps each test's steady-state part (Mohr–Coulomb, rule in
    :mod:`.steady_state`); otherwise Section 2.1's rule (:func:`kept_samples`: j >= 0,
    ``points_per_test`` nearest to equally spaced j) for Janosi–Hanamoto. ``weighting`` is
    ``"none"`` or ``"max-stress"`` (1/max τ per test). Every test keeps a row in ``tests``;
    one that contributes no sample has ``used`` 0 and the reason.
    """
    from .steady_state import steady_state

    if weighting not in ("none", "max-stress"):
        raise ValueError(f"weighting must be 'none' or 'max-stress', got {weighting!r}")
    chosen, tests = select_one_soil(screened(campaign), "shear", selection)
    samples = chosen.shear
    by_test = samples.groupby("test_id", sort=False).indices
    sig_all = samples["sigma_Pa"].to_numpy(float)
    tau_all = samples["tau_Pa"].to_numpy(float)
    j_all = samples["j_m"].to_numpy(float)
    empty = np.array([], int)
    used_rows, rows = [], []
    for tid in tests["test_id"]:
        idx = by_test.get(tid, empty)
        j, t = j_all[idx], tau_all[idx]
        row = {
            "test_id": tid,
            "samples": int(idx.size),
            "sigma_mean_Pa": float(np.mean(sig_all[idx])) if idx.size else np.nan,
        }
        if steady_only:
            ss = steady_state(j, t)
            row.update(
                steady=ss.steady,
                steady_from_j_m=float(j[ss.indices].min()) if ss.indices.size else np.nan,
                tau_ss_Pa=ss.tau_level,
                reason=ss.reason,
            )
            keep = ss.indices if ss.steady else empty
            t_max = float(np.max(t[keep])) if keep.size else np.nan
            if weighting == "max-stress" and keep.size and t_max <= 0:
                raise _unusable("shear", tid, f"max shear stress {t_max:g} Pa <= 0")
            weight = (1.0 / t_max if weighting == "max-stress" else 1.0) if keep.size else np.nan
        else:
            kept = kept_samples(
                j,
                t,
                "shear",
                points_per_test=points_per_test,
                weighting="max" if weighting == "max-stress" else "none",
            )
            if kept.problem is not None and on_unusable == "raise":
                raise _unusable("shear", tid, kept.problem)
            keep = kept.index if kept.problem is None else empty
            weight = kept.weight
            row.update(excluded_j_negative=kept.excluded, problem=kept.problem)
        row.update(used=int(keep.size), weight=weight)
        used_rows.append(idx[keep])
        rows.append(row)
    groups = pd.DataFrame(rows)
    if not groups["used"].any():
        why = (
            "no selected shear test reaches a steady state, so Mohr–Coulomb (Eq. 15) has no "
            "data; see the steady-state rule in soilstats.identification.steady_state"
            if steady_only
            else "no selected shear test has a usable record (see the fit's tests['problem'])"
        )
        raise CampaignError(why, file="shear.csv", column="torque_Nm")
    use = np.concatenate(used_rows)
    counts = groups["used"].to_numpy(int)
    return PooledData(
        x={"sigma_Pa": sig_all[use], "j_m": j_all[use]},
        y=tau_all[use],
        weights=np.repeat(groups["weight"].to_numpy(float), counts),
        test_index=np.repeat(np.arange(len(groups)), counts),
        tests=groups,
    )


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
