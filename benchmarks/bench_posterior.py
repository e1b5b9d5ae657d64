"""Benchmark: effective samples per second of the posterior sampler against plain emcee (and PyMC).

Problem: the paper-size Bekker posterior of ``bench_identify.py`` — plates b = 0.025/0.05/
0.075 m, 10 tests per plate, 100 points per test (3 000 samples), per-test weights 1/max(p),
σ_w marginalised (soilstats.bayes.likelihood).  Every contender samples the *same*
log-density (``PooledProblem.log_prob``) and starts from the same least-squares fit.

Contenders:

* ``soilstats.sample_posterior`` at its defaults (log-modulus coordinates, Student-t
  independence move + differential evolution, burn-in/thinning from τ, 16 walkers);
* plain emcee, default stretch move, 32 walkers, one Python call per walker
  (``vectorize=False``) — what a user writes first;
* plain emcee, default stretch move, 32 walkers, ``vectorize=True``;
* PyMC NUTS (4 chains) on the same model, if PyMC is installed; compile time reported apart.

Figure of merit: ESS/s = min over parameters of the bulk ESS (ArviZ, rank-normalised) of the
kept draws divided by the wall time of the whole run (for sample_posterior: LS fit, sampling
and the InferenceData).  Also: how the cost of sample_posterior grows from 3 000 to 90 000
kept draws.

    python benchmarks/bench_posterior.py            # one run, prints ratios (~1–2 min)

Ratios from one run on this machine; not a unit test.
"""

from __future__ import annotations

import time
import warnings

import emcee
import numpy as np
import pandas as pd
from bench_identify import paper_size_campaign

from soilstats.bayes import sample_posterior
from soilstats.bayes._arviz import az
from soilstats.bayes.data import pooled_problem

WALKERS = 32
STEPS = 3000  # per walker for the plain emcee runs
BURN = 500


def min_ess(chain: np.ndarray, names) -> tuple[float, float]:
    """(min bulk ESS, max R-hat) over parameters of a (chains, draws, p) array."""
    ds = {n: chain[:, :, i] for i, n in enumerate(names)}
    ess = az.ess(ds, method="bulk")
    rhat = az.rhat(ds)
    return min(float(ess[n]) for n in names), max(float(rhat[n]) for n in names)


def plain_emcee(problem, fit, vectorize: bool, seed: int = 0) -> dict:
    rng = np.random.default_rng(seed)
    theta0 = fit.params.to_numpy()
    start = rng.multivariate_normal(theta0, fit.cov.to_numpy() * 1e-2, size=WALKERS)
    if vectorize:
        fn = problem.log_prob
    else:

        def fn(theta):
            return float(problem.log_prob(theta[None])[0])

    sampler = emcee.EnsembleSampler(WALKERS, theta0.size, fn, vectorize=vectorize)
    state = emcee.State(start, random_state=np.random.RandomState(seed).get_state())
    t0 = time.perf_counter()
    sampler.run_mcmc(state, STEPS)
    seconds = time.perf_counter() - t0
    chain = np.swapaxes(sampler.get_chain(discard=BURN), 0, 1)
    ess, rhat = min_ess(chain, problem.model.param_names)
    return {"seconds": seconds, "kept": chain.shape[0] * chain.shape[1], "ess": ess, "rhat": rhat}


def ours(campaign, draws: int, seed: int = 0) -> dict:
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        post = sample_posterior(campaign, "bekker", draws=draws, seed=seed)
    seconds = time.perf_counter() - t0
    d = post.diagnostics.loc[list(post.param_names)]
    return {
        "seconds": seconds,
        "sampler_seconds": post.sampler["seconds"],
        "kept": post.sampler["kept"],
        "ess": float(d["ess_bulk"].min()),
        "rhat": float(d["r_hat"].max()),
        "converged": post.converged,
    }


def pymc_nuts(problem, fit) -> dict | None:
    try:
        import pymc as pm
        import pytensor.tensor as pt
    except ImportError:
        return None
    b, z = problem.x
    wy, w, n_obs = problem.w * problem.y, problem.w, problem.n_obs
    theta0 = fit.params.to_numpy()
    t0 = time.perf_counter()
    with pm.Model():
        kc = pm.Flat("kc", initval=theta0[0])
        kphi = pm.HalfFlat("kphi", initval=theta0[1])
        n = pm.HalfFlat("n", initval=theta0[2])
        f = (kc / b + kphi) * pt.exp(n * np.log(z))
        s = pt.sum((wy - w * f) ** 2)
        pm.Potential("lik", -0.5 * n_obs * pt.log(s))
        compiled = time.perf_counter()
        idata = pm.sample(1000, tune=1000, chains=4, cores=1, progressbar=False, random_seed=0)
    total = time.perf_counter() - t0
    chain = np.stack([idata.posterior[k].to_numpy() for k in ("kc", "kphi", "n")], axis=-1)
    ess, rhat = min_ess(chain, ("kc", "kphi", "n"))
    return {
        "seconds": total,
        "compile_seconds": compiled - t0,
        "kept": chain.shape[0] * chain.shape[1],
        "ess": ess,
        "rhat": rhat,
    }


def main() -> pd.DataFrame:
    campaign = paper_size_campaign()
    problem, fit = pooled_problem(campaign, "bekker")
    ours(campaign, 3000)  # warm imports (arviz, xarray) — not the problem
    rows = {"soilstats.sample_posterior (defaults)": ours(campaign, 6000)}
    rows["emcee stretch, vectorize=False"] = plain_emcee(problem, fit, vectorize=False)
    rows["emcee stretch, vectorize=True"] = plain_emcee(problem, fit, vectorize=True)
    nuts = pymc_nuts(problem, fit)
    if nuts is None:
        print("PyMC not installed: NUTS skipped (pip install pymc)")
    else:
        rows["PyMC NUTS (4 chains, incl. compile)"] = nuts
    table = pd.DataFrame(rows).T
    table["ESS/s"] = table["ess"] / table["seconds"]
    base = table["ESS/s"].iloc[0]
    table["ours / this"] = base / table["ESS/s"]
    print(
        f"Paper-size Bekker posterior: {problem.n_obs} samples, {len(problem.tests)} tests; "
        f"ESS = min over (kc, kphi, n) of ArviZ bulk ESS; plain emcee: {WALKERS} walkers x "
        f"{STEPS} steps, {BURN} burn-in"
    )
    cols = ["seconds", "kept", "ess", "rhat", "ESS/s", "ours / this"]
    print(table[cols].to_string(float_format=lambda v: f"{v:.4g}"))
    if nuts is not None:
        print(f"PyMC compile time: {nuts['compile_seconds']:.1f} s (included above)")
    print(f"\nsample_posterior: {base:.0f} ESS/s, min over parameters (target >= 2000)")

    scaling = pd.DataFrame({d: ours(campaign, d) for d in (3000, 10000, 30000, 90000)}).T
    scaling.index.name = "draws requested"
    scaling["ESS/s"] = scaling["ess"] / scaling["seconds"]
    scaling["us per kept draw"] = 1e6 * scaling["seconds"] / scaling["kept"]
    print("\nCost of sample_posterior from 3 000 to 90 000 kept draws:")
    print(
        scaling[
            ["seconds", "sampler_seconds", "kept", "ess", "rhat", "ESS/s", "us per kept draw"]
        ].to_string(float_format=lambda v: f"{v:.4g}")
    )
    return table


if __name__ == "__main__":
    main()
