"""ArviZ's model-checking groups: ``observed_data``, ``posterior_predictive``, ``log_likelihood``.

Both posteriors carry the three groups ArviZ expects, so that ``az.plot_ppc(idata)``,
``az.loo(idata)``, ``az.waic(idata)`` and ``az.compare({...})`` work on what
:func:`~soilstats.bayes.sample_posterior` and :func:`~soilstats.bayes.sample_population`
return (and on the ``posterior.nc`` the CLI writes).  One variable per model, with the same
name in all three groups:

* **pooled** — ``y``: every measured sample the likelihood uses (pressure [Pa] of the sinkage
  tests, shear stress [Pa] of the shear tests), along ``obs`` with the coordinates ``test``
  (test id), ``sample`` (index of the sample within its test), the inputs in SI units
  (``b_m``, ``z_m`` or ``sigma_Pa``, ``j_m``) and ``weight`` (w of Eq. 1).  Replicated data
  are those of the likelihood actually sampled (:mod:`soilstats.bayes.likelihood`),
  y_rep ~ N(f(x, θ), (σ_w/w)²) per sample, at joint posterior draws (θ, σ_w).  The
  log-likelihood is **per test**, dims (``chain``, ``draw``, ``test``): at each draw the sum
  Σ_{i in t} log N(y_i; f(x_i, θ), (σ_w/w_i)²) over the samples of test t.
* **population** — ``eta_hat``: each test's own two-parameter fit (its data in the population
  likelihood), dims (``test``, ``eta``); replicates come from the marginal likelihood
  η̂_t ~ N(h_t, BΣBᵀ + C_t) (fit error included), and the log-likelihood is one term per
  test.  The measured curves are kept in ``constant_data`` (``y``, as above) for plotting.

Why per test.  The samples of one plate or shear test are one measured curve: their
residuals are strongly dependent (preparation, offsets, the curve's own shape), so
leaving out one sample while its neighbours stay tells nothing about a new measurement, and
sample-wise PSIS-LOO would be optimistic with a standard error that counts a curve as
hundreds of independent points.  The unit of exchangeability is the test, so ``az.loo`` here
is leave-one-TEST-out — the same unit as the population model and as soilstats discover's
cross-validation — and ``az.compare`` weighs models by how well they predict a new test.
It is also small: tests × draws values (e.g. 36 × 6000) instead of samples × draws.

Memory.  ``posterior_predictive`` holds at most :data:`PREDICTIVE_DRAWS` draws over all chains
(evenly spaced within each chain; its ``draw`` coordinate gives the posterior draw each came
from).  ``log_likelihood`` holds at most :data:`LOG_LIKELIHOOD_DRAWS` posterior draws and
:data:`LOG_LIKELIHOOD_VALUES` values (beyond either it is thinned evenly within each chain,
its attribute ``thinned`` is 1, and ``az.loo(idata, reff=1.0)`` is the cautious choice).
Observed data and replicates are per sample and the log-likelihood per test, so
``az.loo_pit`` (which pairs them) does not apply; ``az.plot_ppc``, ``az.loo``, ``az.waic``
and ``az.compare`` do (``az.waic`` usually warns: a whole test's term varies more over draws
than WAIC tolerates; LOO with its Pareto k per test is the check).

The pooled variable keeps its name ``y`` (its ``long_name`` attribute says pressure or shear
stress): readers of earlier results and the PDF report look it up by that name.
"""

from __future__ import annotations

import numpy as np
import xarray as xr
from numpy.typing import ArrayLike

from .likelihood import PooledProblem

__all__ = [
    "LOG_LIKELIHOOD_DRAWS",
    "LOG_LIKELIHOOD_VALUES",
    "PREDICTIVE_DRAWS",
    "input_name",
    "log_likelihood_draws",
    "measured_dataset",
    "pooled_groups",
    "response_dataset",
    "spread_draws",
]

#: Most posterior-predictive draws stored (over all chains).
PREDICTIVE_DRAWS = 200
#: Most per-test log-likelihood values (draws × tests) stored before thinning: 32 MB in
#: float64, e.g. 4 000 draws of 1 000 tests.
LOG_LIKELIHOOD_VALUES = 4_000_000
#: Most posterior draws (over all chains) the log-likelihood is evaluated at: the sample size
#: PSIS-LOO is run with by default (Stan's and ArviZ's 4 chains × 1 000 draws), at which its
#: Pareto-k threshold is 0.7 (Vehtari et al. 2024, "Pareto smoothed importance sampling").
#: More draws only cost time and file size (soil01 Bekker: 12 000 draws × 372 tests were
#: 32 MB of posterior.nc and a second of compression).
LOG_LIKELIHOOD_DRAWS = 4_000


def log_likelihood_draws(draws: int, chains: int, tests: int) -> np.ndarray:
    """The draws (indices within each chain) the log-likelihood group holds: at most
    :data:`LOG_LIKELIHOOD_DRAWS` over all chains and :data:`LOG_LIKELIHOOD_VALUES` values,
    evenly spaced within each chain."""
    return spread_draws(
        draws, chains, min(LOG_LIKELIHOOD_DRAWS, LOG_LIKELIHOOD_VALUES // max(tests, 1))
    )


#: Measured response of each kind of test: long name and unit of ``y``.
RESPONSES = {"sinkage": ("pressure", "Pa"), "shear": ("shear stress", "Pa")}


def spread_draws(draws: int, chains: int, total: int | None) -> np.ndarray:
    """Indices of the draws to keep in every chain: about ``total`` over all chains, evenly
    spaced within each chain (at least one per chain; all when ``total`` is None or not
    smaller)."""
    if total is None or total >= draws * chains:
        return np.arange(draws)
    per = min(draws, max(1, total // chains))
    return np.unique(np.linspace(0, draws - 1, per).round().astype(int))


def input_name(label: str) -> str:
    """``"b [m]"`` → ``"b_m"`` (the pooled data's own naming)."""
    name, _, unit = label.partition(" ")
    return f"{name}_{unit.strip('[]')}" if unit else name


def response_kind(problem: PooledProblem) -> str:
    """``"sinkage"`` or ``"shear"`` from the model's output."""
    return "shear" if problem.model.output.startswith("tau") else "sinkage"


def measured_dataset(
    *,
    y: ArrayLike,
    weight: ArrayLike,
    test_index: ArrayLike,
    test_ids: ArrayLike,
    inputs: dict,
    kind: str,
) -> xr.Dataset:
    """Measured samples as ``y`` along ``obs``, with the coordinates ``test`` (test id),
    ``sample`` (index within its test), the inputs by name and ``weight``.

    ``test_index`` gives each sample's row of ``test_ids``; ``kind`` is ``"sinkage"`` or
    ``"shear"`` (the response's name and unit).
    """
    index = np.asarray(test_index, int)
    n = index.size
    sample = np.zeros(n, int)
    for t in np.unique(index):
        where = np.flatnonzero(index == t)
        sample[where] = np.arange(where.size)
    ids = np.asarray(test_ids).astype(str)
    coords = {"obs": np.arange(n), "test": ("obs", ids[index]), "sample": ("obs", sample)}
    for name, values in inputs.items():
        coords[name] = ("obs", np.asarray(values, float))
    coords["weight"] = ("obs", np.asarray(weight, float))
    long_name, unit = RESPONSES[kind]
    data = xr.DataArray(
        np.asarray(y, float), dims="obs", attrs={"long_name": long_name, "units": unit}
    )
    return xr.Dataset({"y": data}, coords=coords)


def response_dataset(problem: PooledProblem) -> xr.Dataset:
    """The samples a pooled likelihood uses, as :func:`measured_dataset`."""
    inputs = problem.inputs or {
        input_name(label): row
        for label, row in zip(problem.model.inputs, np.atleast_2d(problem.x), strict=True)
    }
    return measured_dataset(
        y=problem.y,
        weight=problem.w,
        test_index=problem.test_index,
        test_ids=problem.tests["test_id"],
        inputs=inputs,
        kind=response_kind(problem),
    )


def pooled_groups(
    problem: PooledProblem,
    theta: np.ndarray,
    sigma: np.ndarray,
    rng: np.random.Generator,
    *,
    predictive_draws: int | None = PREDICTIVE_DRAWS,
) -> dict[str, xr.Dataset]:
    """``observed_data``, ``posterior_predictive`` and ``log_likelihood`` of a pooled posterior.

    Parameters
    ----------
    problem : PooledProblem
        Data and model of the run.
    theta : ndarray, shape (chains, draws, p)
        Posterior draws of the parameters.
    sigma : ndarray, shape (chains, draws)
        The joint draws of σ_w.
    rng : numpy.random.Generator
        Source of the replicated data's noise (the only random step).
    predictive_draws : int or None
        Most replicated draws over all chains (None: every draw).
    """
    chains, draws, p = theta.shape
    observed = response_dataset(problem)
    obs_coords = {k: v for k, v in observed.coords.items()}
    attrs = dict(observed["y"].attrs)

    sub = spread_draws(draws, chains, predictive_draws)
    flat = theta[:, sub].reshape(-1, p)
    rep = problem.replicate(flat, sigma[:, sub].reshape(-1), rng)
    ppc = xr.Dataset(
        {"y": (("chain", "draw", "obs"), rep.reshape(chains, sub.size, -1), attrs)},
        coords={"chain": np.arange(chains), "draw": sub} | obs_coords,
        attrs={"draws_of_posterior": draws, "model": "y ~ N(f(x, theta), (sigma_w / w)^2)"},
    )

    rows = problem.test_rows
    keep = log_likelihood_draws(draws, chains, rows.size)
    ll = problem.log_likelihood(theta[:, keep].reshape(-1, p), sigma[:, keep].reshape(-1))
    test_ids = np.asarray(problem.tests["test_id"]).astype(str)[rows]
    samples = np.bincount(problem.test_index)[rows]
    log_lik = xr.Dataset(
        {"y": (("chain", "draw", "test"), ll.reshape(chains, keep.size, -1))},
        coords={"chain": np.arange(chains), "draw": keep, "test": test_ids}
        | {"samples": ("test", samples)},
        attrs={
            "draws_of_posterior": draws,
            "thinned": int(keep.size < draws),
            "model": "sum over each test's samples of log N(y_i; f(x_i, theta), "
            "(sigma_w / w_i)^2) at joint draws (leave-one-test-out)",
        },
    )
    return {"observed_data": observed, "posterior_predictive": ppc, "log_likelihood": log_lik}
