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
    python benchmarks/bench_posterior.py --population   # the population part only (~3 min)

Population posteriors (issue #39): for every bundled real campaign and simulated-paper soil01,
the wall and CPU time of the whole ``soilstats posterior --population`` command (imports,
screening, sampling, report, files; target ≤ 10 s of wall time on two cores; best of three
runs), and in process
``sample_population``'s ESS/s (min bulk ESS over the soil-level parameters and the scatter,
over the whole call) beside plain emcee (stretch move, 32 walkers × 3 000 steps, 500 burn-in,
``vectorize=True``) sampling the same log-density (``population_setup(...).pops.log_prob``)
from the same Laplace start.  CPU time is given beside wall time because the machine is
shared: on an idle one they agree.

Ratios from one run on this machine; not a unit test.
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import tempfile
import time
import warnings

import emcee
import numpy as np
import pandas as pd
from bench_identify import paper_size_campaign

from soilstats import load_campaign
from soilstats.bayes import sample_population, sample_posterior
from soilstats.bayes._arviz import az
from soilstats.bayes.data import pooled_problem
from soilstats.bayes.population import population_setup
from soilstats.quality import screen

WALKERS = 32
CLI_REPEATS = 3  # runs of each CLI command; the best counts
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
        "sampler_seconds": post.sampler["runtime_s"],
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


#: (label, CLI arguments, in-process runs: (campaign, model, selection)).
POPULATION_CASES = (
    (
        "GRC-1 51 mm, bernstein",
        "--data grc1-oravec2009 --soil GRC-1 --model bernstein --select radius_m=0.051",
        (("grc1-oravec2009", "bernstein", {"radius_m": 0.051}),),
    ),
    (
        "GRC-1 95 mm, bernstein",
        "--data grc1-oravec2009 --soil GRC-1 --model bernstein --select radius_m=0.095",
        (("grc1-oravec2009", "bernstein", {"radius_m": 0.095}),),
    ),
    (
        "Cullinan prep. 1, bernstein",
        "--data cullinan-sand --soil cullinan-sand --model bernstein "
        "--select sinkage:preparation=1",
        (("cullinan-sand", "bernstein", {"preparation": "1"}),),
    ),
    (
        "CMU all plates, bekker",
        "--data cmu-3d-terramechanics --model bekker",
        (("cmu-3d-terramechanics", "bekker", {}),),
    ),
    (
        "simulated soil01, bekker+janosi",
        "--data simulated-paper --soil soil01 --model bekker+janosi",
        (
            ("simulated-paper", "bekker", {"soil": "soil01"}),
            ("simulated-paper", "janosi", {"soil": "soil01"}),
        ),
    ),
    # The same on both cores: the second model sampled and drawn in a worker process.
    (
        "simulated soil01, bekker+janosi --jobs 2",
        "--data simulated-paper --soil soil01 --model bekker+janosi --jobs 2",
        (),
    ),
)


def cli_seconds(args: str) -> tuple[float, float]:
    """(wall, CPU) seconds of one ``soilstats posterior ARGS --population`` in a new process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        done = subprocess.run(
            [
                sys.executable,
                "-m",
                "soilstats",
                "posterior",
                *args.split(),
                "--population",
                "--out",
                os.path.join(out, "o"),
            ],
            capture_output=True,
            text=True,
        )
        wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise RuntimeError(f"soilstats posterior {args} failed: {done.stderr[-500:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def population_ours(campaign, model: str, selection: dict, seed: int = 0) -> dict:
    t0 = time.perf_counter()
    result = sample_population(campaign, model, seed=seed, **selection)
    seconds = time.perf_counter() - t0
    names = [v for v in result.var_names if v not in result.param_names]
    d = result.diagnostics.loc[names]
    return {
        "seconds": seconds,
        "kept": result.sampler["kept"],
        "ess": float(d["ess_bulk"].min()),
        "rhat": float(d["r_hat"].max()),
        "converged": result.converged,
    }


def population_emcee(campaign, model: str, selection: dict, seed: int = 0) -> dict:
    """Plain emcee (stretch, vectorised) on the same density, from the same start."""
    t0 = time.perf_counter()
    setup = population_setup(campaign, model, **selection)
    pops = setup.pops
    rng = np.random.default_rng(seed)
    start = rng.multivariate_normal(setup.centre, setup.cov * 1e-2, size=WALKERS)
    sampler = emcee.EnsembleSampler(WALKERS, start.shape[1], pops.log_prob, vectorize=True)
    state = emcee.State(start, random_state=np.random.RandomState(seed).get_state())
    sampler.run_mcmc(state, STEPS)
    seconds = time.perf_counter() - t0
    summaries = pops.summaries(np.swapaxes(sampler.get_chain(discard=BURN), 0, 1))
    ess = az.ess(summaries, method="bulk")
    rhat = az.rhat(summaries)
    return {
        "seconds": seconds,
        "kept": WALKERS * (STEPS - BURN),
        "ess": min(float(ess[n]) for n in summaries),
        "rhat": max(float(rhat[n]) for n in summaries),
        "converged": None,
    }


def population_main() -> pd.DataFrame:
    """Population posteriors: CLI times and ESS/s against plain emcee (module docstring)."""
    campaigns = {}
    rows, cli = [], []
    sample_population(load_campaign("cullinan-sand"), "bernstein", draws=2000, preparation="1")
    for label, args, runs in POPULATION_CASES:
        # Best of CLI_REPEATS runs (the first also pays cold file caches): wall time is the
        # criterion, CPU time beside it says whether a shared machine inflated the wall.
        times = [cli_seconds(args) for _ in range(CLI_REPEATS)]
        wall, cpu = min(times)
        cli.append({"command": label, "wall s": wall, "CPU s": cpu, "<= 10 s": wall <= 10})
        for name, model, selection in runs:
            if name not in campaigns:
                campaigns[name] = screen(load_campaign(name), "clean").campaign
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                ours = population_ours(campaigns[name], model, selection)
                plain = population_emcee(campaigns[name], model, selection)
            for who, r in (("sample_population", ours), ("emcee stretch", plain)):
                rows.append({"case": f"{label.split(',')[0]}: {model}", "sampler": who, **r})
    cli = pd.DataFrame(cli).set_index("command")
    print("soilstats posterior ... --population (whole command, new process; target <= 10 s):")
    print(cli.to_string(float_format=lambda v: f"{v:.2f}"))
    table = pd.DataFrame(rows)
    table["ESS/s"] = table["ess"] / table["seconds"]
    print(
        "\nIn process: min bulk ESS over mu_*, sd_*, corr_* per second of the whole call "
        f"(plain emcee: {WALKERS} walkers x {STEPS} steps, {BURN} burn-in, vectorize=True)"
    )
    cols = ["case", "sampler", "seconds", "kept", "ess", "rhat", "ESS/s"]
    print(table[cols].to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    return table


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


def smoke() -> None:
    """``--smoke``: each contender once at tiny sizes, seconds — that the script still runs
    (tests/test_benchmarks.py); its numbers mean nothing."""
    global STEPS, BURN
    STEPS, BURN = 200, 50
    campaign = paper_size_campaign()
    problem, fit = pooled_problem(campaign, "bekker")
    print("sample_posterior", ours(campaign, 500))
    print("emcee", plain_emcee(problem, fit, vectorize=True))
    label, args, runs = POPULATION_CASES[0]
    print(label, "CLI (wall, CPU) s:", cli_seconds(args))
    name, model, selection = runs[0]
    campaign = load_campaign(name)
    print("sample_population", population_ours(campaign, model, selection))
    print("population emcee", population_emcee(campaign, model, selection))


if __name__ == "__main__":
    if "--smoke" in sys.argv[1:]:
        smoke()
    elif "--population" in sys.argv[1:]:
        population_main()
    else:
        main()
        print()
        population_main()
