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
  and pointwise log-likelihood are those of the likelihood actually sampled
  (:mod:`soilstats.bayes.likelihood`): y_rep ~ N(f(x, θ), (σ_w/w)²) and
  log N(y_i; f(x_i, θ), (σ_w/w_i)²) at joint posterior draws (θ, σ_w).
* **population** — ``eta_hat``: each test's own two-parameter fit (its data in the population
  likelihood), dims (``test``, ``eta``); replicates come from the marginal likelihood
  η̂_t ~ N(h_t, BΣBᵀ + C_t) (fit error included), and the log-likelihood is one term per
  test (leave-one-test-out).  The measured curves are kept in ``constant_data`` (``y``, as
  above) for plotting.

Memory.  ``posterior_predictive`` holds at most :data:`PREDICTIVE_DRAWS` draws over all chains
(evenly spaced within each chain; its ``draw`` coordinate gives the posterior draw each came
from).  ``log_likelihood`` holds every posterior draw unless draws × observations would exceed
:data:`LOG_LIKELIHOOD_VALUES`; then it is thinned evenly within each chain, but keeps at least
:data:`LOG_LIKELIHOOD_MIN_DRAWS` draws (PSIS needs about that many for a reliable Pareto k).
When thinned, ArviZ's default relative efficiency (posterior ESS / stored draws) exceeds 1;
``az.loo(idata, reff=1.0)`` is then the cautious choice.  The groups' attributes say which.
Because the two groups keep different draws, ``az.loo_pit`` (which pairs them) does not apply.

The pooled variable keeps its name ``y`` (its ``long_name`` attribute says pressure or shear
stress): readers of earlier results and the PDF report look it up by that name.
"""

from __future__ import annotations

import math

import numpy as np
import xarray as xr

from .likelihood import PooledProblem

__all__ = [
    "LOG_LIKELIHOOD_MIN_DRAWS",
    "LOG_LIKELIHOOD_VALUES",
    "PREDICTIVE_DRAWS",
    "measured_dataset",
    "pooled_groups",
    "response_dataset",
    "spread_draws",
]

#: Most posterior-predictive draws stored (over all chains).
PREDICTIVE_DRAWS = 200
#: Most pointwise log-likelihood values (draws × observations) stored before thinning:
#: 32 MB in float64, e.g. ~1100 of 6000 draws for 36 tests of 100 samples.
LOG_LIKELIHOOD_VALUES = 4_000_000
#: Fewest log-likelihood draws kept when thinning (over all chains).
LOG_LIKELIHOOD_MIN_DRAWS = 1000

#: Measured response of each kind of test: long name and unit of ``y``.
RESPONSES = {"sinkage": ("pressure", "Pa"), "shear": ("shear stress", "Pa")}


def spread_draws(draws: int, chains: int, total: int | None, *, at_least: bool = False):
    """Indices of the draws to keep in every chain: about ``total`` over all chains, evenly
    spaced within each chain (at least one per chain; all when ``total`` is None or not
    smaller).  ``at_least`` rounds the per-chain count up instead of down."""
    if total is None or total >= draws * chains:
        return np.arange(draws)
    per = math.ceil(total / chains) if at_least else total // chains
    per = min(draws, max(1, per))
    return np.unique(np.linspace(0, draws - 1, per).round().astype(int))


def _input_name(label: str) -> str:
    """``"b [m]"`` → ``"b_m"`` (the pooled data's own naming)."""
    name, _, unit = label.partition(" ")
    return f"{name}_{unit.strip('[]')}" if unit else name


def response_kind(problem: PooledProblem) -> str:
    """``"sinkage"`` or ``"shear"`` from the model's output."""
    return "shear" if problem.model.output.startswith("tau") else "sinkage"


def measured_dataset(*, y, weight, test_index, test_ids, inputs: dict, kind: str) -> xr.Dataset:
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
        _input_name(label): row
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
    log_likelihood_draws: int | None = None,
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
    log_likelihood_draws : int or None
        Log-likelihood draws over all chains (None: the memory rule of the module docstring).
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

    if log_likelihood_draws is None:
        budget = max(LOG_LIKELIHOOD_MIN_DRAWS, LOG_LIKELIHOOD_VALUES // max(problem.n_obs, 1))
    else:
        budget = log_likelihood_draws
    keep = spread_draws(draws, chains, budget, at_least=True)
    ll = problem.log_likelihood(theta[:, keep].reshape(-1, p), sigma[:, keep].reshape(-1))
    log_lik = xr.Dataset(
        {"y": (("chain", "draw", "obs"), ll.reshape(chains, keep.size, -1))},
        coords={"chain": np.arange(chains), "draw": keep} | obs_coords,
        attrs={
            "draws_of_posterior": draws,
            "thinned": int(keep.size < draws),
            "model": "log N(y_i; f(x_i, theta), (sigma_w / w_i)^2) at joint draws",
        },
    )
    return {"observed_data": observed, "posterior_predictive": ppc, "log_likelihood": log_lik}
