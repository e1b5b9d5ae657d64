"""Calibration of the posteriors against simulated truth (issue #5), at any size.

Used by ``tests/test_posterior_calibration.py`` (small, seeded versions that run in the suite)
and by ``benchmarks/calibrate_posterior.py`` (the full-size figures quoted in
docs/posterior.md).  Two checks:

* :func:`pooled_coverage` — equal-tailed 90 % credible intervals of the pooled posterior
  against the true parameters, on campaigns whose noise matches the likelihood
  (:mod:`posterior_sim`: per-test noise sd ∝ max p of the test);
* :func:`population_coverage` — the population model's 90 % predictive band for a new
  preparation against the *true* curves of held-out repetitions, on campaigns from
  :func:`soilstats.simulation.simulate` (preparation scatter: one log-normal stiffness factor
  on kc and kφ and a shift of n per test), and the same for the band the paper's pooled σ
  (Eq. 3–4) implies.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from posterior_sim import BEKKER_TRUTH, sinkage_campaign

from soilstats.bayes import sample_population, sample_posterior
from soilstats.errors import ConvergenceWarning
from soilstats.identification import fit_shear, fit_sinkage
from soilstats.models import BEKKER, JANOSI
from soilstats.simulation import simulate

#: Soil of the population check (Table 5, soil01, 4.8e-3 m/s).
SOIL = {"kc": -9.8e3, "kphi": 1.2e6, "n": 0.82}
PLATES = (0.025, 0.05, 0.075)


@dataclass(frozen=True)
class Coverage:
    """Hits and trials of a coverage check, and the convergence failures met on the way."""

    hits: int
    trials: int
    not_converged: int = 0

    @property
    def rate(self) -> float:
        return self.hits / self.trials


def pooled_coverage(
    n_sets: int,
    *,
    model: str = "bekker",
    seed: int = 0,
    repetitions: int = 2,
    points: int = 40,
    draws: int = 4000,
    prob: float = 0.9,
) -> Coverage:
    """Coverage of the truth by ``prob`` equal-tailed intervals over ``n_sets`` campaigns.

    Bekker campaigns have 3 plates × ``repetitions`` tests × ``points`` samples; Bernstein
    ones one plate (b = 0.05 m) × 3·``repetitions`` tests.  Noise sd 2 % of each test's max p.
    Every parameter of every campaign is one trial.
    """
    rng = np.random.default_rng(seed)
    hits = trials = failed = 0
    truth = dict(BEKKER_TRUTH)
    for i in range(n_sets):
        if model == "bekker":
            camp = sinkage_campaign(rng, repetitions=repetitions, points=points)
            true = truth
        else:
            camp = sinkage_campaign(rng, plates=(0.05,), repetitions=3 * repetitions, points=points)
            true = {"k": truth["kc"] / 0.05 + truth["kphi"], "n": truth["n"]}
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ConvergenceWarning)
            post = sample_posterior(camp, model, seed=seed * 100_000 + i, draws=draws)
        failed += any(issubclass(w.category, ConvergenceWarning) for w in caught)
        ci = post.interval(prob, kind="eti")
        for name, value in true.items():
            hits += bool(ci.loc[name, "lower"] <= value <= ci.loc[name, "upper"])
            trials += 1
    return Coverage(hits, trials, failed)


def population_spec(repetitions: int, *, stiffness_cv=0.1, n_sd=0.03, points=60) -> dict:
    """A small simulator SPEC: soil01's Bekker values, 3 plates, preparation scatter."""
    return {
        "name": "population-calibration",
        "scatter": {"stiffness_cv": stiffness_cv, "n_sd": n_sd},
        "noise": {"force_N": 0.2, "force_offset_N": 0.0},
        "soils": {"sand": dict(SOIL)},
        "series": [
            {
                "name": "plates",
                "kind": "sinkage",
                "soils": ["sand"],
                "plates": [{"shape": "circle", "radius_m": b} for b in PLATES],
                "repetitions": repetitions,
                "points": points,
                "sinkage_m": 0.03,
            }
        ],
    }


def _population_run(spec, model: str, fit_lsq, *, seed: int, i: int, train: int, draws: int):
    """One calibration campaign: the population posterior and the pooled LS fit on the first
    ``train`` repetitions, draws of each (4000), and whether the sampler warned."""
    sim = simulate(spec, seed=seed * 1000 + i)
    reps = list(range(1, train + 1))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ConvergenceWarning)
        pop = sample_population(sim.campaign, model, seed=i, draws=draws, repetition=reps)
    failed = any(issubclass(w.category, ConvergenceWarning) for w in caught)
    fit = fit_lsq(sim.campaign, model, repetition=reps)
    rng = np.random.default_rng([seed, i])
    new = pop.draws(4000, seed=i).to_numpy()
    ls = rng.multivariate_normal(fit.params.to_numpy(), fit.cov.to_numpy(), size=4000)
    return sim, pop, failed, new, ls


def population_coverage(
    n_sets: int,
    *,
    train: int = 4,
    held_out: int = 10,
    seed: int = 0,
    draws: int = 6000,
    prob: float = 0.9,
    grid: int = 12,
) -> tuple[Coverage, Coverage]:
    """Coverage of held-out repetitions' true curves by two ``prob`` bands.

    Each campaign has ``train + held_out`` repetitions per plate; the population model and
    the pooled least-squares fit see the first ``train``.  For every held-out test the true
    curve p = (kc_t/b + kφ_t)·z^(n_t) (its drawn parameters, ``sim.test_truth``) is
    evaluated at ``grid`` sinkages over 10–100 % of the test's range; one trial is one
    (test, sinkage) point.  Bands are pointwise equal-tailed ``prob`` quantiles of
    p(b, z) over (a) the population predictive draws of a new preparation and (b) draws of
    N(θ̂, Cov) with the paper's pooled covariance (Eq. 4).

    Returns
    -------
    (population, pooled_sigma) : Coverage, Coverage
    """
    q = [(1 - prob) / 2, (1 + prob) / 2]
    z = np.linspace(0.003, 0.03, grid)
    pop_hits = ls_hits = trials = failed = 0
    for i in range(n_sets):
        sim, _, warned, new, ls = _population_run(
            population_spec(train + held_out),
            "bekker",
            fit_sinkage,
            seed=seed,
            i=i,
            train=train,
            draws=draws,
        )
        failed += warned
        truth = sim.test_truth
        tests = sim.campaign.tests.set_index("test_id")
        for b in PLATES:
            bz = (np.full(z.size, b), z)
            bands = [
                np.quantile(BEKKER.func(bz, d[:, :1], d[:, 1:2], d[:, 2:3]), q, axis=0)
                for d in (new, ls)
            ]
            held = tests.index[(tests["radius_m"] == b) & (tests["repetition"].astype(int) > train)]
            for tid in held:
                row = truth.loc[truth["test_id"] == tid].iloc[0]
                curve = BEKKER.func(bz, row["kc"], row["kphi"], row["n"])
                pop_hits += int(np.sum((bands[0][0] <= curve) & (curve <= bands[0][1])))
                ls_hits += int(np.sum((bands[1][0] <= curve) & (curve <= bands[1][1])))
                trials += z.size
    return Coverage(pop_hits, trials, failed), Coverage(ls_hits, trials, 0)


#: Soil and normal pressures of the shear population check (sand-like; no side walls planted).
SHEAR_SOIL = {"c": 800.0, "phi": 30.0, "K": 0.012}
NORMAL_PRESSURES = (3e3, 6e3, 10e3, 15e3, 20e3)


def shear_population_spec(repetitions: int, *, c_cv=0.1, phi_sd=1.0, K_cv=0.15, points=80):
    """A shear-ring SPEC: one ring, 5 normal pressures, preparation scatter of c, φ and K."""
    return {
        "name": "shear-population-calibration",
        "scatter": {"c_cv": c_cv, "phi_sd_deg": phi_sd, "K_cv": K_cv},
        "soils": {"sand": dict(SHEAR_SOIL)},
        "series": [
            {
                "name": "ring",
                "kind": "shear",
                "soils": ["sand"],
                "rings": [{"r_inner_m": 0.1, "r_outer_m": 0.15, "tool": "ring"}],
                "grousers": [12],
                "grouser_height_m": [0.005],
                "omega_rpm": [0.1],
                "normal_pressure_Pa": list(NORMAL_PRESSURES),
                "repetitions": repetitions,
                "points": points,
                "shear_deformation_m": 0.1,
            }
        ],
    }


def shear_population_coverage(
    n_sets: int,
    *,
    train: int = 4,
    held_out: int = 10,
    seed: int = 0,
    draws: int = 6000,
    prob: float = 0.9,
    grid: int = 10,
) -> tuple[Coverage, Coverage, list]:
    """Coverage of held-out shear tests' true curves by the population and pooled-σ bands.

    As :func:`population_coverage` for Janosi (Eq. 13): each campaign has ``train +
    held_out`` repetitions per normal pressure; for every held-out test the true curve
    τ = (c_t + σ_t tan φ_t)(1 − e^(−j/K_t)) is evaluated at ``grid`` deformations j of
    2–80 mm.  Also returns each campaign's population result (for checks of its scatter).
    """
    q = [(1 - prob) / 2, (1 + prob) / 2]
    j = np.linspace(0.002, 0.08, grid)
    pop_hits = ls_hits = trials = failed = 0
    results = []
    for i in range(n_sets):
        sim, pop, warned, new, ls = _population_run(
            shear_population_spec(train + held_out),
            "janosi",
            fit_shear,
            seed=seed,
            i=i,
            train=train,
            draws=draws,
        )
        failed += warned
        results.append(pop)
        truth = sim.test_truth.set_index("test_id")
        tests = sim.campaign.tests.set_index("test_id")
        for tid in tests.index[tests["repetition"].astype(int) > train]:
            row = truth.loc[tid]
            x = (np.full(j.size, row["normal_pressure_Pa"]), j)
            curve = JANOSI.func(x, row["c"], row["phi"], row["K"])
            for d, counter in ((new, "pop"), (ls, "ls")):
                lo, hi = np.quantile(JANOSI.func(x, d[:, :1], d[:, 1:2], d[:, 2:3]), q, axis=0)
                hits = int(np.sum((lo <= curve) & (curve <= hi)))
                if counter == "pop":
                    pop_hits += hits
                else:
                    ls_hits += hits
            trials += j.size
    return Coverage(pop_hits, trials, failed), Coverage(ls_hits, trials, 0), results
