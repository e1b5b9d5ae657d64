"""Is the band of a new preparation calibrated on the tests it was learned from?

A population posterior (:func:`soilstats.bayes.population.sample_population`) predicts the
curve of a new preparation of the soil. This module checks that band against the tests it
was learned from, each left out in turn by Pareto-smoothed importance weights: its held-out
coverage and its width against the tests' own scatter (issue #36; docs/posterior.md,
"Population bands on real data"). The verdict is stored with the result and read back with
:func:`band_calibration`.
"""

from __future__ import annotations

import json
import warnings
from collections.abc import Iterable
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.special import stdtrit

from ._arviz import az
from .population_model import PopulationModel
from .predictive import spread_draws
from .reduction import PerTestFits
from .result import PosteriorResult

if TYPE_CHECKING:
    import xarray as xr

    from ..identification.pooling import PooledData

__all__ = ["BandCalibration", "band_calibration", "band_check"]

#: Limits of the check (issue #36; docs/posterior.md, "Population bands on real data"):
#: held-out coverage of the 90 % band within 80–97 %, its width within 3× the tests' own
#: 90 % scatter.
COVERAGE_RANGE = (0.80, 0.97)
WIDTH_MAX = 3.0
#: Where each test is looked at: these quantiles of its used sinkages (its 10th–90th percentile).
BAND_DEPTHS = (0.1, 0.3, 0.5, 0.7, 0.9)
#: Width of a normal's central 90 % interval in sds (2 × 1.645).
NORMAL_90 = 3.289707253902945
#: Pareto k above which a test's importance-weighted leave-one-out band is unreliable.
PARETO_K_MAX = 0.7
#: Up to this many tests the sd of the scatter is too uncertain to pin the band's width.
FEW_TESTS = 8
#: Posterior draws the check uses (every posterior draw would cost more and add nothing).
CHECK_DRAWS = 2000


@dataclass(frozen=True)
class BandCalibration:
    """How the 90 % band of a new preparation compares with the tests it was learned from.

    Each test is looked at at :data:`BAND_DEPTHS` of its used sinkages (``points`` in all);
    there its measured ln p (its record, interpolated) and its own Bernstein curve ln p̂_t(z)
    are set against the pointwise 90 % band of ln p over the new-preparation draws.

    * ``coverage`` — share of the measured points inside the band when the test is left out,
      approximated by importance weights 1/p(η̂_t | draw) (Pareto-smoothed) rather than by
      refitting; ``coverage_power_law`` the same for the tests' own power-law
      curves (what the model's draws can reach at all).  Criterion: within
      :data:`COVERAGE_RANGE`.
    * ``width`` — mean band width in ln p over the mean of 3.29 × the sd of the measured ln p
      over the tests of the same plate size at the same sinkages (a normal 90 % interval of
      the tests' own scatter).  Criterion: at most :data:`WIDTH_MAX`.
      ``width_floor`` is what ``tests`` tests allow at best: a new value from T normal ones
      has the 90 % interval t₀.₉₅,T−1·√(1 + 1/T)·s, i.e. that over 1.645 times the tests' own.
    * ``misfit`` — median |measured − own power law| in ln p at those sinkages;
      ``half_width`` the median half-width of the band there.
    * ``pareto_k_max`` — the largest Pareto k of the leave-one-out weights (PSIS);
      ``unreliable_tests`` how many tests have k > 0.7, where the approximation is poor
      (leaving one of few tests out moves the posterior far; the benchmark refits instead).

    ``failures`` names the criteria that fail (``"coverage"``, ``"width"``) and ``sentence``
    says which and why, with numbers (the result's last note; the report's page 1).  Stored in
    ``idata.posterior.attrs["calibration"]`` as JSON (:meth:`to_json`,
    :func:`band_calibration` reads it back).
    """

    tests: int
    points: int
    coverage: float
    coverage_power_law: float
    coverage_in_sample: float
    width: float
    width_floor: float
    misfit: float
    half_width: float
    pareto_k_max: float
    unreliable_tests: int
    failures: tuple[str, ...]
    sentence: str

    @property
    def calibrated(self) -> bool:
        return not self.failures

    def to_json(self) -> str:
        return json.dumps(
            {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(self).items()}
        )

    @classmethod
    def from_json(cls, text: str) -> BandCalibration:
        data = json.loads(text)
        data["failures"] = tuple(data["failures"])
        return cls(**data)


def band_calibration(result: PosteriorResult) -> BandCalibration | None:
    """The band check of a population result (None for shear or an older result)."""
    text = result.idata.posterior.attrs.get("calibration")
    return None if text is None else BandCalibration.from_json(text)


def _measured_ln_p(z_sorted, ln_p_sorted, z):
    """ln p of a record at sinkages ``z`` (linear interpolation; nan outside its range)."""
    out = np.interp(z, z_sorted, ln_p_sorted)
    return np.where((z >= z_sorted[0]) & (z <= z_sorted[-1]), out, np.nan)


def _band_quantiles(
    values: np.ndarray, weights: np.ndarray, q: Iterable[float], order: np.ndarray | None = None
) -> np.ndarray:
    """Quantiles ``q`` of each column of ``values`` (S, M) under the weights ``weights``
    (S, M) (non-negative; a non-finite value must have weight 0) → (len(q), M); ``order``:
    ``np.argsort(values, axis=0)`` if already at hand."""
    order = np.argsort(values, axis=0) if order is None else order
    cum = np.cumsum(np.take_along_axis(weights, order, axis=0), axis=0)
    cum /= cum[-1]
    idx = np.stack([np.argmax(cum >= x, axis=0) for x in q])
    return np.take_along_axis(values, np.take_along_axis(order, idx, axis=0), axis=0)


def _records(
    pooled: PooledData, fits: PerTestFits
) -> tuple[list[tuple[np.ndarray, np.ndarray]], np.ndarray]:
    """Each used test's samples as (z sorted, ln p), and its :data:`BAND_DEPTHS` (T, 5)."""
    used = np.flatnonzero(np.isin(pooled.tests["test_id"].astype(str), fits.test_ids))
    z_all, p_all, which = pooled.x["z_m"], pooled.y, pooled.test_index
    records: list[tuple[np.ndarray, np.ndarray]] = []
    depths: list[np.ndarray] = []
    for pos in used:
        m = (which == pos) & (z_all > 0) & (p_all > 0)
        order = np.argsort(z_all[m], kind="stable")
        zs, lp = z_all[m][order], np.log(p_all[m][order])
        records.append((zs, lp))
        depths.append(np.quantile(zs, BAND_DEPTHS) if zs.size >= 2 else np.full(5, np.nan))
    return records, np.array(depths).reshape(-1, len(BAND_DEPTHS))


def _loo_weights(log_lik: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Leave-one-test-out importance weights (S, T) of the draws, 1/p(η̂_t | draw), Pareto
    smoothed (PSIS, Vehtari, Gelman & Gabry 2017, through ArviZ's ``psislw``), and each
    test's Pareto k: above 0.7 the approximation is unreliable for that test."""
    log_w = np.where(np.isfinite(log_lik), -log_lik, -np.inf)
    log_w = log_w - np.max(log_w, axis=0)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        smoothed, k = az.psislw(log_w.T.copy(), reff=1.0)
    return np.exp(smoothed.T - np.max(smoothed.T, axis=0)), np.atleast_1d(np.asarray(k))


def _measured_and_scatter(
    records: list[tuple[np.ndarray, np.ndarray]], depths: np.ndarray, fits: PerTestFits
) -> tuple[np.ndarray, np.ndarray]:
    """Measured ln p of every test at the depths of every test of its plate size: its own
    (the diagonal blocks) and the tests' own scatter there (sd over ≥ 3 tests); (T, K) each."""
    k_depths = depths.shape[1]
    measured = np.full(depths.shape, np.nan)
    own_sd = np.full(depths.shape, np.nan)
    for size in np.unique(fits.covariate):
        group = np.flatnonzero(fits.covariate == size)
        at = depths[group].ravel()
        values = np.array([_measured_ln_p(*records[j], at) for j in group])  # (G, G·5)
        blocks = values.reshape(group.size, group.size, k_depths)
        measured[group] = blocks[np.arange(group.size), np.arange(group.size)]
        ok = np.isfinite(values)
        counts = ok.sum(axis=0)
        mean = np.where(ok, values, 0).sum(axis=0) / np.maximum(counts, 1)
        var = np.where(ok, (values - mean) ** 2, 0).sum(axis=0) / np.maximum(counts - 1, 1)
        own_sd[group] = np.where(counts >= 3, np.sqrt(var), np.nan).reshape(-1, k_depths)
    return measured, own_sd


def band_check(
    pops: PopulationModel,
    fits: PerTestFits,
    pooled: PooledData,
    posterior: xr.Dataset,
    chain: np.ndarray,
) -> BandCalibration:
    """:class:`BandCalibration` of a sinkage population (see there)."""
    records, depths = _records(pooled, fits)
    t_count, k_depths = depths.shape
    measured, own_sd = _measured_and_scatter(records, depths, fits)
    with np.errstate(divide="ignore", invalid="ignore"):
        own = np.log(fits.params[:, :1]) + fits.params[:, 1:] * np.log(depths)
    # The band at every test's plate and depths, from a subsample of the posterior draws
    # (at most ~2e6 values); each draw's per-test log-likelihood gives the leave-one-out
    # weights 1/p(η̂_t | draw), Pareto-smoothed (:func:`_loo_weights`).
    names = pops.model.param_names
    chains, draws = posterior.sizes["chain"], posterior.sizes["draw"]
    total = int(np.clip(2e6 / depths.size, 400, CHECK_DRAWS))
    pick = spread_draws(draws, chains, total)
    new = np.column_stack([posterior[n].to_numpy()[:, pick].reshape(-1) for n in names])
    u = chain[:, pick].reshape(-1, chain.shape[-1])
    with np.errstate(all="ignore"):
        log_lik = pops.log_likelihood(u, fits.params)  # (S, T)
        k_new = pops.layout.linear(new) @ fits.design.T  # (S, T): each test's plate
        ln_p = (
            np.log(np.where(k_new > 0, k_new, np.nan))[:, :, None]
            + pops.layout.second(new)[:, None, None] * np.log(depths)[None]
        )
    ln_p = ln_p.reshape(ln_p.shape[0], -1)  # (S, T·5)
    finite = np.isfinite(ln_p)
    ln_p = np.where(finite, ln_p, np.inf)
    w, pareto_k = _loo_weights(log_lik)
    w = np.repeat(w, k_depths, axis=1) * finite
    enough = finite.sum(axis=0).reshape(depths.shape) >= 10
    order = np.argsort(ln_p, axis=0)
    lo, hi = _band_quantiles(ln_p, finite.astype(float), (0.05, 0.95), order)
    lo_loo, hi_loo = _band_quantiles(ln_p, w, (0.05, 0.95), order)
    lo, hi, lo_loo, hi_loo = (x.reshape(depths.shape) for x in (lo, hi, lo_loo, hi_loo))
    inside = np.isfinite(measured) & enough & np.isfinite(lo_loo) & np.isfinite(hi_loo)
    points = int(inside.sum())

    def mean_of(x: np.ndarray) -> float:
        return float(np.mean(x)) if np.size(x) else float("nan")

    scale = inside & np.isfinite(own_sd) & (own_sd > 0)
    check = dict(
        tests=t_count,
        points=points,
        coverage=mean_of(((lo_loo <= measured) & (measured <= hi_loo))[inside]),
        coverage_power_law=mean_of(((lo_loo <= own) & (own <= hi_loo))[inside]),
        coverage_in_sample=mean_of(((lo <= measured) & (measured <= hi))[inside]),
        width=(
            mean_of((hi - lo)[scale]) / mean_of(NORMAL_90 * own_sd[scale])
            if scale.any()
            else float("nan")
        ),
        width_floor=float(
            stdtrit(t_count - 1, 0.95) * np.sqrt(1 + 1 / t_count) / 1.6448536269514722
        ),
        misfit=float(np.median(np.abs(measured - own)[inside])) if points else float("nan"),
        half_width=float(np.median(((hi_loo - lo_loo) / 2)[inside])) if points else float("nan"),
        pareto_k_max=float(np.max(pareto_k)) if pareto_k.size else float("nan"),
        unreliable_tests=int(np.sum(pareto_k > PARETO_K_MAX)),
    )
    missed = inside & ~((lo_loo <= measured) & (measured <= hi_loo))
    failures, sentence = _band_verdict(check, measured, own, missed)
    return BandCalibration(**check, failures=failures, sentence=sentence)


def _band_verdict(
    c: dict, measured: np.ndarray, own: np.ndarray, missed: np.ndarray
) -> tuple[tuple[str, ...], str]:
    """Which of the two criteria fail, and why, in one sentence with numbers."""
    lo_cov, hi_cov = COVERAGE_RANGE
    t = c["tests"]
    head = (
        f"Band check ({t} tests, 5 sinkages each between the 10th and 90th percentile of its "
        f"record): the 90 % band of a new preparation holds {c['coverage']:.0%} of the "
        f"measured pressures with each test left out (importance-weighted; target "
        f"{lo_cov:.0%}-{hi_cov:.0%}) and is {c['width']:.1f}x as wide as the tests' own "
        f"scatter (3.29 sd of ln p at the same sinkages; target at most {WIDTH_MAX:.0f}x)"
    )
    failures, why = [], []
    if not np.isfinite(c["width"]):
        why.append(
            "the width is not assessed (fewer than 3 tests of one plate size reach "
            "the same sinkages)"
        )
    elif c["width"] > WIDTH_MAX:
        failures.append("width")
        if t <= FEW_TESTS:
            why.append(
                f"WIDTH FAILS: {t} tests cannot pin the sd of the scatter (even {t} values of "
                f"a normal give a new value's 90 % interval {c['width_floor']:.1f}x their own "
                "scatter; the scatter here has two components and a weak prior), and the band "
                "carries that uncertainty; more tests narrow it"
            )
        else:
            why.append(
                f"WIDTH FAILS: where {t} tests would allow about {c['width_floor']:.1f}x, the "
                "tests differ by more than the model's preparation scatter (mixed conditions "
                "or plate sizes, or curves the power law does not follow)"
            )
    if not np.isfinite(c["coverage"]):
        why.append("coverage is not assessed")
    elif c["coverage"] < lo_cov:
        failures.append("coverage")
        if c["coverage_power_law"] >= lo_cov and c["coverage_power_law"] - c["coverage"] >= 0.05:
            # The tests' own power laws lie inside the band where their measured curves do
            # not: the model's misfit within a test, not its scatter between tests.
            gap = np.abs(measured - own)[missed]
            shallow, total = int(missed[:, 0].sum()), int(missed.sum())
            why.append(
                f"COVERAGE FAILS: the band holds {c['coverage_power_law']:.0%} of the tests' "
                f"own power-law curves, but where it misses a measured curve the curve is off "
                f"its own power law by a median {np.median(gap):.2f} in ln p ({shallow} of the "
                f"{total} misses at each test's shallowest sinkage; band half-width "
                f"{c['half_width']:.2f}): within-test misfit of the model, which no scatter of "
                "its parameters represents"
            )
        else:
            why.append(
                f"COVERAGE FAILS: the tests scatter more than the fitted population ({t} "
                "tests; an outlying test or heavier tails than a normal scatter)"
            )
    elif c["coverage"] > hi_cov:
        failures.append("coverage")
        why.append(
            f"COVERAGE ABOVE {hi_cov:.0%}: the band is wider than these tests need ({t} tests "
            "leave the scatter's sd uncertain and the band carries that uncertainty; with "
            f"{t} tests one test in or out moves the coverage by {1 / t:.0%})"
        )
    tail = ""
    if c["unreliable_tests"]:
        tail = (
            f" (Pareto k > {PARETO_K_MAX} for {c['unreliable_tests']} of {t} tests: leaving "
            "them out moves the posterior too far for the importance-weighted coverage to be "
            "more than approximate)"
        )
    if not failures:
        return (), head + ": both criteria met" + tail + "."
    return tuple(failures), head + ". " + "; ".join(why) + tail + "."
