"""``sample_posterior``: the pooled posterior of a soil model's parameters (emcee + ArviZ)."""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterable, Mapping
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np
import xarray as xr

from ..errors import ConvergenceWarning, InputError
from ..fitting.result import HealthFlag
from ..models import get_model
from ..outputs.provenance import source_date
from ._arviz import az
from .data import pooled_problem
from .likelihood import PooledProblem
from .predictive import PREDICTIVE_DRAWS, pooled_groups
from .prior_sensitivity import pooled_sensitivity, warn_influential
from .result import PosteriorResult, chain_diagnostics, diagnose, draws_converge
from .sampler import EnsembleRun, run_ensemble
from .transforms import Coordinates, sampling_coordinates

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign
    from ..campaign.tables import Criterion
    from ..fitting.result import FitResult
    from ..models.base import Model

__all__ = ["DEFAULT_DRAWS", "sample_posterior"]

#: Kept draws over all walkers at the default settings: ESS ≈ draws/τ with τ ≈ 2 steps, and
#: 16 walkers × 375 steps keep the split-R-hat bias (τ − 1)/(2·steps) near 0.003.
DEFAULT_DRAWS = 6000


def sample_posterior(
    campaign: Campaign,
    model: str = "bekker",
    *,
    draws: int = DEFAULT_DRAWS,
    seed: int | None = None,
    progress: bool = False,
    priors: Mapping[str, object] | None = None,
    walkers: int = 16,
    points_per_test: int | None = 100,
    predictive_draws: int | None = PREDICTIVE_DRAWS,
    **selection: Criterion,
) -> PosteriorResult:
    """Sample the posterior of ``model``'s parameters given a campaign's tests (pooled model).

    The likelihood is the paper's weighted objective (Eq. 1, weights 1/max p per test for
    sinkage, Section 2.1) read as Gaussian noise on the weighted residuals with an unknown
    scale σ_w, which is marginalised analytically under the Jeffreys prior (see
    :mod:`soilstats.bayes.likelihood`); priors are physics-only by default
    (:mod:`soilstats.bayes.priors`).  emcee runs a walker-vectorised log-density from the
    least-squares fit; burn-in and thinning follow the measured autocorrelation time.

    Parameters
    ----------
    campaign : Campaign
        From :func:`soilstats.load_campaign`.
    model : str or Model
        A registered sinkage or shear model (``"bekker"``, ``"bernstein"``, ``"reece"``,
        ``"mohr-coulomb"``, ``"janosi"`` or one's own, :func:`soilstats.register_model`):
        its record gives the data, the default priors and the plate-modulus constraint.
    draws : int
        Kept draws over all walkers (default 6000).
    seed : int, optional
        Seed; the same seed gives bit-identical draws.
    progress : bool
        Show a tqdm progress bar.
    priors : mapping, optional
        Per-parameter overrides: ``{"n": (0.5, 2.0)}``, ``{"c": None}`` (flat on ℝ) or a
        :class:`soilstats.bayes.Prior`.
    walkers : int
        emcee walkers (≥ 2 × parameters); each is one ArviZ chain.
    points_per_test : int or None
        Sinkage samples per test (Section 2.1), as for the least-squares fit.
    predictive_draws : int or None
        Most posterior-predictive draws stored, over all walkers (default 200; None: all).
    **selection
        Test-log filters (``soil="soil01"`` …); must leave one soil.

    Returns
    -------
    PosteriorResult
        With ``idata`` (posterior, sample_stats, observed_data, posterior_predictive,
        log_likelihood — see :mod:`soilstats.bayes.predictive`), ``summary()`` and
        ``draws()``.  The replicated data (per sample, seeded from ``seed``) and the
        log-likelihood (per test: ``az.loo`` is leave-one-test-out) are those of the weighted
        Gaussian likelihood, at the joint draws (θ, σ_w), so ``az.plot_ppc``, ``az.loo`` and
        ``az.compare`` apply directly.  If
        R-hat > 1.01 or ESS < 400 for any parameter a
        :class:`~soilstats.errors.ConvergenceWarning` is emitted and ``converged`` is False.
    """
    spec = get_model(model)
    extra = {"points_per_test": points_per_test} if spec.kind == "sinkage" else {}
    problem, fit = pooled_problem(campaign, spec, priors=priors, **extra, **selection)
    if not fit.converged or not np.all(np.isfinite(fit.cov.to_numpy())):
        raise InputError(
            f"the least-squares fit of {spec.name} did not give a usable start and covariance "
            f"({fit.message}); the posterior sampler needs it — see fit_sinkage/fit_shear"
        )
    theta0, cov0 = fit.params.to_numpy(), fit.cov.to_numpy()
    _check_start_in_prior(spec, theta0, problem)
    coords = sampling_coordinates(spec, theta0, cov0, problem.plate_sizes)
    run = run_ensemble(
        target_in(problem, coords),
        coords.to_u(theta0)[0],
        coords.covariance(theta0, cov0),
        draws=draws,
        seed=seed,
        n_walkers=walkers,
        progress=progress,
        description=f"{spec.name} posterior",
        accept=lambda chain: draws_converge(
            dict(
                zip(spec.param_names, np.moveaxis(coords.to_theta_chain(chain), -1, 0), strict=True)
            )
        ),
    )
    run, rss = _back_to_theta(problem, coords, run)
    rng = np.random.default_rng(None if seed is None else [seed, 1])
    idata = _inference_data(problem, run, rss, rng, predictive_draws=predictive_draws)
    result = finish(
        idata,
        problem.model.name,
        "pooled",
        spec.param_names,
        spec.unit_of,
        (*spec.param_names, "sigma_w"),
        run,
        _pooled_notes(problem),
        fit,
    )
    # Do the default priors carry the result? Power-scaling on these draws (no resampling).
    table = pooled_sensitivity(
        result.idata.posterior, spec.param_names, problem.priors, priors or {}
    )
    warn_influential(spec.name, table)
    return replace(result, prior_sensitivity=table)


def finish(
    idata: Any,  # arviz.InferenceData: Any, as PosteriorResult.idata says why
    model_name: str,
    kind: str,
    param_names: Iterable[str],
    units: dict[str, str],
    var_names: Iterable[str],
    run: EnsembleRun,
    notes: Iterable[str],
    lsq: FitResult | None,
) -> PosteriorResult:
    """Wrap up a run: its convergence flags, the loud warning if not converged, the result."""
    sampler = {
        "walkers": run.chain.shape[0],
        "steps": run.steps,
        "burn": run.burn,
        "thin": run.thin,
        "kept": run.chain.shape[0] * run.chain.shape[1],
        "tau": run.tau,
        "tau_max": float(np.max(run.tau)),
        "acceptance": float(np.mean(run.acceptance)),
        "runtime_s": run.runtime_s,
        "seconds": run.runtime_s,  # the old name of runtime_s, written until 0.3.0
        "evaluations": run.evaluations,
        "tau_reliable": run.tau_reliable,
        "extended": run.extended,
    }
    chains = chain_diagnostics(idata, var_names)
    flags = diagnose(chains)
    if not run.tau_reliable:
        flags = (
            *flags,
            HealthFlag(
                "short-chain",
                f"kept chain shorter than 50 autocorrelation times "
                f"(tau = {sampler['tau_max']:.1f} steps): tau itself is uncertain",
            ),
        )
    messages = "; ".join(f.message for f in flags)
    idata.posterior.attrs["converged"] = int(not flags)
    idata.posterior.attrs["convergence_flags"] = "; ".join(map(str, flags)) or "none"
    idata.posterior.attrs["convergence_problems"] = messages or "none"  # old name, until 0.3.0
    if flags:
        warnings.warn(
            f"{model_name} posterior NOT converged: "
            + messages
            + " — increase draws, or check the model and priors; result.converged is False",
            ConvergenceWarning,
            stacklevel=3,
        )
    return PosteriorResult(
        idata=idata,
        model_name=model_name,
        kind=kind,
        param_names=tuple(param_names),
        units=units,
        var_names=tuple(var_names),
        flags=flags,
        sampler=sampler,
        notes=tuple(notes),
        lsq=lsq,
        _chains=chains,
    )


def _pooled_notes(problem: PooledProblem) -> list[str]:
    g = problem.tests
    priors = "; ".join(
        f"{n}: {p}" for n, p in zip(problem.model.param_names, problem.priors, strict=True)
    )
    modulus = problem.model.modulus  # the plate-modulus constraint of the prior, if any
    notes = [
        f"Pooled model: {len(g)} tests, {problem.n_obs} samples; w(y - f) ~ N(0, sigma_w^2) "
        "with the least-squares weights (1/max per test for sinkage and Janosi, 1 for "
        "Mohr-Coulomb), sigma_w marginalised under p(sigma_w) ~ 1/sigma_w, then drawn from "
        "its conditional.",
        f"Priors: {priors}"
        + (f"; {modulus.text} > 0 on every plate." if modulus is not None else "."),
        "The pooled posterior describes how well the pooled data pin ONE parameter set; it "
        "shrinks with more tests. For a new preparation of the soil use the population model.",
    ]
    return notes


def target_in(problem: PooledProblem, coords: Coordinates) -> Callable[[np.ndarray], np.ndarray]:
    """The log posterior density in the sampling coordinates u (vectorised over walkers).

    log p_u(u) = log p(θ(u) | y) + log|det ∂θ/∂u| (:mod:`soilstats.bayes.transforms`).
    """
    if coords.identity:
        return problem.log_prob

    def log_prob(u: np.ndarray) -> np.ndarray:
        with np.errstate(all="ignore"):  # far-out proposals overflow: rejected below
            theta = coords.to_theta(u)
        ok = np.all(np.isfinite(theta), axis=1)
        out = np.full(theta.shape[0], -np.inf)
        if ok.any():
            out[ok] = problem.log_prob(theta[ok]) + coords.log_jacobian(u[ok])
        return out

    return log_prob


def _back_to_theta(
    problem: PooledProblem, coords: Coordinates, run: EnsembleRun
) -> tuple[EnsembleRun, np.ndarray]:
    """The run's chain and log density in model parameters, and S(θ) of every kept draw.

    S(θ) is recovered from the stored log density, ln S = 2·(log p(θ) − lp_θ)/N,
    rather than recomputed (that would cost one more likelihood pass over every draw).
    """
    chains, draws, dim = run.chain.shape
    u = run.chain.reshape(-1, dim)
    theta = coords.to_theta(u)
    lp = run.log_prob.reshape(-1) - coords.log_jacobian(u)  # density of θ, not of u
    ln_s = 2.0 * (problem.log_prior(theta) - lp) / problem.n_obs
    run = replace(run, chain=theta.reshape(chains, draws, dim), log_prob=lp.reshape(chains, draws))
    return run, np.exp(ln_s).reshape(chains, draws)


def _inference_data(
    problem: PooledProblem,
    run: EnsembleRun,
    rss: np.ndarray,
    rng: np.random.Generator,
    *,
    predictive_draws: int | None = PREDICTIVE_DRAWS,
) -> object:
    names = problem.model.param_names
    chains, draws, _ = run.chain.shape
    # σ_w first, from the same generator as before: the posterior does not depend on what
    # the model-checking groups draw afterwards.
    sigma = problem.draw_sigma_from_rss(rss.reshape(-1), rng).reshape(chains, draws)
    coords = {"chain": np.arange(chains), "draw": np.arange(draws)}
    posterior = xr.Dataset(
        {n: (("chain", "draw"), run.chain[:, :, i]) for i, n in enumerate(names)}
        | {"sigma_w": (("chain", "draw"), sigma)},
        coords=coords,
        attrs=posterior_attrs(problem),
    )
    stats = xr.Dataset({"lp": (("chain", "draw"), run.log_prob)}, coords=coords)
    # Keywords of InferenceData: Any, as arviz's signature types its options, not its groups.
    groups: dict[str, Any] = pooled_groups(
        problem, run.chain, sigma, rng, predictive_draws=predictive_draws
    )
    return az.InferenceData(posterior=posterior, sample_stats=stats, **groups)


def _check_start_in_prior(spec: Model, theta0: np.ndarray, problem: PooledProblem) -> None:
    """Raise, naming the parameter, its least-squares value and the prior, when the start
    lies outside the priors' support (the walkers could not be placed; GRC-1's Bekker kφ is
    −1.4e5 against a prior on (0, ∞))."""
    outside = [
        f"{name} = {value:.4g} (prior: {prior})"
        for name, value, prior in zip(spec.param_names, theta0, problem.priors, strict=True)
        if not np.isfinite(prior.logpdf(np.array([value]))[0])
    ]
    if not outside and np.isfinite(problem.log_prior(theta0[None])[0]):
        return
    modulus = spec.modulus.text if spec.modulus is not None else "of the model"
    why = "; ".join(outside) or f"the plate moduli {modulus} are not positive on every plate"
    raise InputError(
        f"the least-squares estimate of {spec.name} lies outside the prior's support: {why}. "
        "The data put the optimum where the physics priors forbid it (see the fit's health "
        "flags: soilstats identify); window the records, choose another model, or state a "
        "prior that allows it (--prior NAME=LO:HI)"
    )


def posterior_attrs(problem: PooledProblem) -> dict:
    """The posterior group's attributes. No clock is read: ``created_at`` only where
    ``SOURCE_DATE_EPOCH`` sets it, so that the same run writes a byte-identical file."""
    date = source_date()
    return ({"created_at": date} if date else {}) | {
        "inference_library": "emcee",
        "model": problem.model.name,
        "equation": problem.model.equation,
        "units": "; ".join(
            f"{n} [{u}]"
            for n, u in zip(problem.model.param_names, problem.model.units, strict=True)
        ),
        "priors": "; ".join(
            f"{n}: {p}" for n, p in zip(problem.model.param_names, problem.priors, strict=True)
        ),
    }
