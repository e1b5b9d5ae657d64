"""Sampling the population (hierarchical) model: every preparation draws its own soil
parameters.

The model — each test reduced to its own fit, the test-level effects marginalised, where
the preparation scatter sits and the priors — is :mod:`soilstats.bayes.population_model`.
Here: its start (the pooled least-squares estimate and a Laplace approximation), the
emcee run, the draws of a *new* preparation a rover Monte Carlo needs, and the ArviZ
groups and notes of the result.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
import xarray as xr
from scipy import optimize

from ..errors import IdentifiabilityError, InputError, ModelError
from ..identification import fit_sinkage, pool_sinkage
from ..models import get_model, model_names
from ._arviz import az
from .band_check import BandCalibration, band_calibration, band_check
from .data import pooled_problem
from .population_model import POPULATION_MODELS, PopulationModel, reference_rows
from .posterior import finish, posterior_attrs
from .predictive import (
    PREDICTIVE_DRAWS,
    log_likelihood_draws,
    measured_dataset,
    response_dataset,
    spread_draws,
)
from .prior_sensitivity import sensitivity_table, warn_influential
from .priors import resolve_priors
from .reduction import (
    PerTestFits,
    reference_sinkage,
    scatter_sinkage,
    shear_tests,
    sinkage_tests,
    to_eta,
)
from .result import PosteriorResult, draws_converge
from .sampler import EnsembleRun, run_ensemble
from .transforms import Coordinates, sampling_coordinates

if TYPE_CHECKING:
    from ..campaign.campaign import Campaign
    from ..campaign.tables import Criterion
    from ..fitting.result import FitResult
    from ..identification.pooling import PooledData
    from ..models.base import Model, PopulationLayout
    from .likelihood import PooledProblem

__all__ = [
    "POPULATION_DRAWS",
    "POPULATION_MODELS",
    "BandCalibration",
    "PopulationSetup",
    "band_calibration",
    "population_setup",
    "sample_population",
]

#: Default kept draws: the sds are skewed, so their tail ESS needs more draws than the pooled.
POPULATION_DRAWS = 12000


def laplace_mode(
    log_prob: Callable[[np.ndarray], np.ndarray], x0: np.ndarray, n_mu: int
) -> tuple[np.ndarray, np.ndarray]:
    """Mode and inverse negative Hessian (central differences) of ``log_prob``."""
    scale = np.where(np.abs(x0) > 0, np.abs(x0), 1.0)
    scale[n_mu:] = 1.0  # log-sds and atanh-correlations are O(1) already

    def nlp(u):
        return -log_prob((u * scale)[None])[0]

    def nlp_and_gradient(u):
        # log_prob is vectorised: the central-difference gradient is one call of 2d + 1
        # points, not 2d + 1 calls (soil01 Bekker: 91 points instead of Nelder–Mead's 1 064
        # single evaluations, 0.06 s instead of 0.4 s, the same mode to 1e-6 sd).
        h = 1e-6 * np.maximum(1.0, np.abs(u))
        f = -log_prob(np.vstack([u, u + np.diag(h), u - np.diag(h)]) * scale)
        return f[0], (f[1 : u.size + 1] - f[u.size + 1 :]) / (2 * h)

    # (an infinite density outside the support makes inf − inf in the searches: expected)
    with np.errstate(all="ignore"):
        opt = optimize.minimize(
            nlp_and_gradient, x0 / scale, jac=True, method="BFGS", options={"gtol": 1e-8}
        )
        if not (np.isfinite(opt.fun) and np.max(np.abs(opt.jac)) < 1e-3):
            # Far from the mode or at the edge of the support (-inf): the derivative-free
            # search first, then BFGS from where it stopped.
            opt = optimize.minimize(
                nlp,
                x0 / scale,
                method="Nelder-Mead",
                options={"maxiter": 3000 * x0.size, "xatol": 1e-9, "fatol": 1e-9},
            )
            opt = optimize.minimize(nlp, opt.x, method="BFGS")
    mode, d = opt.x * scale, x0.size
    step = 1e-2 * np.sqrt(np.clip(np.diag(opt.hess_inv), 1e-12, None)) * scale  # type: ignore[arg-type]  # scipy-stubs: BFGS's hess_inv is a matrix (a LinearOperator is L-BFGS-B's)
    e = np.diag(step)
    pts = [mode]
    for i in range(d):
        for j in range(d):
            pts += [mode + e[i] + e[j], mode + e[i] - e[j], mode - e[i] + e[j], mode - e[i] - e[j]]
    f = log_prob(np.array(pts))
    hess = np.array(
        [
            [
                f[1 + 4 * (i * d + j)]
                - f[2 + 4 * (i * d + j)]
                - f[3 + 4 * (i * d + j)]
                + f[4 + 4 * (i * d + j)]
                for j in range(d)
            ]
            for i in range(d)
        ]
    )
    hess /= 4 * np.outer(step, step)
    cov = np.linalg.inv(-0.5 * (hess + hess.T))
    if not np.all(np.isfinite(cov)) or np.any(np.linalg.eigvalsh(cov) <= 0):
        cov = np.asarray(opt.hess_inv) * np.outer(scale, scale)
    return mode, cov


@dataclass(frozen=True)
class PopulationSetup:
    """Everything :func:`sample_population` prepares before sampling: the per-test fits,
    the model's log-density (``pops.log_prob``) and its Laplace approximation (``centre``,
    ``cov``, where the walkers start).  The benchmark samples the same density with plain
    emcee from it."""

    spec: Model
    layout: PopulationLayout
    shear: bool
    problem: PooledProblem | None  # the pooled shear problem (shear) or None
    pooled: PooledData | None  # the pooled sinkage data (sinkage) or None
    lsq: FitResult
    fits: PerTestFits
    pops: PopulationModel
    centre: np.ndarray
    cov: np.ndarray


def population_setup(
    campaign: Campaign,
    model: str | Model,
    *,
    priors: Mapping[str, object] | None = None,
    points_per_test: int | None = 100,
    **selection: Criterion,
) -> PopulationSetup:
    """The population model of ``model`` on the selected tests, ready to sample
    (:class:`PopulationSetup`; arguments as :func:`sample_population`)."""
    spec = get_model(model)
    layout = spec.population
    if layout is None:
        with_layout = [n for n in model_names() if get_model(n).population is not None]
        raise ModelError(
            f"the population model is implemented for {with_layout} "
            f"(got {spec.name!r}); use sample_posterior for the pooled model"
        )
    shear = spec.kind == "shear"
    if shear:
        problem, lsq = pooled_problem(campaign, spec, **selection)
        pooled = None
        fits = shear_tests(problem)
    else:
        problem = None
        pooled = pool_sinkage(campaign, points_per_test=points_per_test, **selection)
        lsq = fit_sinkage(
            campaign, spec, points_per_test=points_per_test, test_resamples=0, **selection
        )
        fits = sinkage_tests(pooled, spec)
    t = len(fits.test_ids)
    if t < 3:
        raise IdentifiabilityError(
            f"the population model needs at least 3 tests with a usable per-test fit; the "
            f"selection has {t} (failed: {fits.failed or 'none'})"
        )
    theta0 = lsq.params.to_numpy()
    if shear:
        ln_zref, ln_zs, coords = 0.0, 0.0, Coordinates()
    else:
        ln_zref = reference_sinkage(fits.params, fits.cov)
        assert pooled is not None  # sinkage: pooled above
        ln_zs = scatter_sinkage(fits, pooled.x["z_m"], ln_zref)
        base = sampling_coordinates(spec, theta0, lsq.cov.to_numpy(), np.unique(fits.covariate))
        coords = base if base.identity else Coordinates(moduli=base.moduli, ln_zref=ln_zref)
    eta, cov = to_eta(fits.params, fits.cov, ln_zref, layout.log_second)
    given = set(priors or {})
    pops = PopulationModel(
        spec,
        layout,
        eta,
        cov,
        fits.design,
        ln_zref,
        resolve_priors(spec, spec.param_names, priors),
        coords,
        reference_rows=reference_rows(fits.design, fits.covariate),
        log_flat=(not given & set(spec.param_names[:-1]), spec.param_names[-1] not in given),
        ln_zs=ln_zs,
    )
    # Start: the pooled LS estimate and the spread of the per-test fits around it.
    with np.errstate(all="ignore"):
        theta_row = theta0[None]
        kb0 = (layout.linear(theta_row) @ fits.design.T)[0]
        g0 = layout.second(theta_row)[0]
        r1 = eta[:, 1] - g0
        r0 = eta[:, 0] - (np.log(np.abs(kb0)) + g0 * ln_zref) - (ln_zref - ln_zs) * r1
        spread = np.log(np.maximum([np.std(r0, ddof=1), np.std(r1, ddof=1)], 1e-3))
        x0 = np.concatenate([coords.to_u(theta0)[0], spread, [0.0]])
    if not (np.all(np.isfinite(x0)) and np.all(kb0 > 0)):
        raise InputError(
            f"the pooled least-squares estimate {dict(zip(spec.param_names, theta0, strict=True))}"
            f" gives a non-positive {layout.per_test[0]} or {layout.per_test[1]} for some test; "
            "the population model cannot start there"
        )
    centre, cov_v = laplace_mode(pops.log_prob, x0, pops.p)
    return PopulationSetup(spec, layout, shear, problem, pooled, lsq, fits, pops, centre, cov_v)


def sample_population(
    campaign: Campaign,
    model: str = "bekker",
    *,
    draws: int = POPULATION_DRAWS,
    seed: int | None = None,
    progress: bool = False,
    priors: Mapping[str, object] | None = None,
    walkers: int = 16,
    points_per_test: int | None = 100,
    **selection: Criterion,
) -> PosteriorResult:
    """Sample the population model (:mod:`soilstats.bayes.population_model`) of a soil model.

    Parameters are as for :func:`soilstats.bayes.sample_posterior`.  ``model`` is
    ``"bekker"``, ``"bernstein"`` or ``"janosi"`` (:data:`POPULATION_MODELS`), or any
    registered model whose record has a ``population`` layout; Mohr–Coulomb alone has no
    per-test curve to scatter and stays a pooled question.  The default prior
    of the soil-level parameters is flat in the log of the measured scales
    (:mod:`.population_model`, "Priors"); a prior given in ``priors`` for any linear
    modulus (kc, kφ; k; c, φ), or for Janosi's K, replaces that group's log-flat factor.

    Returns
    -------
    PosteriorResult
        ``kind="population"``.  Its posterior holds ``mu_<name>`` (the soil-level parameters:
        a median preparation), the scatter between preparations — ``sd_p_ref`` (sd of ln p at
        the sinkage z_s where the tests scatter least, ≈ the coefficient of variation of the
        pressure there; z_s [m] is ``exp(posterior.attrs["ln_zs"])``), ``sd_n`` and
        ``corr_p_ref_n`` for sinkage; ``sd_strength`` (≈ the CV of c + σ tan φ), ``sd_lnK``
        (≈ the CV of K) and ``corr_strength_K`` for shear — and the parameters of a *new*
        preparation under the plain names (``kc``, ``kphi``, ``n`` / ``c``, ``phi``, ``K``),
        which :meth:`~PosteriorResult.draws` returns.  ``observed_data``,
        ``posterior_predictive`` and ``log_likelihood`` hold ``eta_hat``, each test's own fit
        (one log-likelihood term per test), ``constant_data`` the measured curves
        (:mod:`soilstats.bayes.predictive`).  For sinkage, ``posterior.attrs["calibration"]``
        holds the band check of the result (:class:`BandCalibration`, read with
        :func:`band_calibration`): the 90 % band of a new preparation against the tests it
        was learned from (importance-weighted leave-one-test-out coverage, width against
        their own scatter), which criterion fails and why; its sentence is the last note.
    """
    setup = population_setup(
        campaign, model, priors=priors, points_per_test=points_per_test, **selection
    )
    spec, layout, shear, fits, pops, lsq = (
        setup.spec,
        setup.layout,
        setup.shear,
        setup.fits,
        setup.pops,
        setup.lsq,
    )
    t, ln_zref, centre, cov_v = len(fits.test_ids), pops.ln_zref, setup.centre, setup.cov
    problem, pooled = setup.problem, setup.pooled
    run = run_ensemble(
        pops.log_prob,
        centre,
        cov_v,
        draws=draws,
        seed=seed,
        n_walkers=walkers,
        progress=progress,
        moves="laplace",
        tune=200,
        # The soil-level parameters of T tests have t-like tails with about T − 1 degrees
        # of freedom: a proposal with tails as heavy keeps the independence move's
        # importance ratio bounded (GRC-1 51 mm, 5 tests: min tail ESS 1 392 → 2 767 at seed 0).
        proposal_dof=float(np.clip(t - 1, 3, 10)),
        description=f"{spec.name} population",
        accept=lambda chain: draws_converge(pops.summaries(chain)),
    )
    rng = np.random.default_rng(None if seed is None else [seed, 2])
    if shear:
        assert problem is not None  # shear: the pooled problem
        curves = response_dataset(problem)
    else:
        assert pooled is not None  # sinkage: the pooled data
        curves = measured_dataset(
            y=pooled.y,
            weight=pooled.weights,
            test_index=pooled.test_index,
            test_ids=pooled.tests["test_id"],
            inputs=pooled.x,
            kind="sinkage",
        )
    # The measured curves of the tests the model uses (for plots; the likelihood sees
    # each test through its own fit, observed_data).
    curves = curves.isel(obs=np.isin(curves["test"].to_numpy(), fits.test_ids))
    curves = curves.assign_coords(obs=np.arange(curves.sizes["obs"]))
    idata = _population_idata(pops, run, rng, fits, curves)
    names = spec.param_names
    var_names = [f"mu_{n}" for n in names] + list(layout.scatter)
    notes = _population_notes(pops, fits, ln_zref)
    if not shear:
        assert pooled is not None  # population_setup pools every sinkage population
        check = band_check(pops, fits, pooled, idata.posterior, run.chain)
        idata.posterior.attrs["calibration"] = check.to_json()
        notes.append(check.sentence)
    units = dict(zip(names, spec.units, strict=True))
    result = finish(
        idata, spec.name, "population", names, units, (*var_names, *names), run, notes, lsq
    )
    # Do the default priors carry the result? Power-scaling on these draws (no resampling).
    given = tuple(n for n in names if n in (priors or {}))
    log_default, log_given = pops.log_priors(run.chain.reshape(-1, run.chain.shape[-1]), given)
    quantities = {q: idata.posterior[q].to_numpy().ravel() for q in (*var_names, *names)}
    table = sensitivity_table(quantities, log_default, log_given, given)
    warn_influential(spec.name, table)
    return replace(result, prior_sensitivity=table)


def _population_notes(pops: PopulationModel, fits: PerTestFits, ln_zref: float) -> list[str]:
    layout, names = pops.layout, pops.model.param_names
    a, b = layout.per_test
    if layout.log_second:
        reduced = f"Eq. 13 fit at its own normal pressure ({a}_t, {b}_t)"
        coords = f"coordinates (ln {a}_t, ln {b}_t)"
    else:
        reduced = f"Bernstein fit ({a}_t, {b}_t)"
        coords = (
            f"coordinates (ln {a}_t + {b}_t ln z_ref, {b}_t) with "
            f"z_ref = {np.exp(ln_zref) * 1e3:.3g} mm"
        )
    s_e, s_d, rho = layout.scatter
    notes = [
        f"Population model: {len(fits.test_ids)} tests (preparations), each reduced to its own "
        f"{reduced} with its Eq. 4 covariance, in {coords}; test-level effects marginalised: "
        f"{layout.scatter_note}, (eps, delta) ~ N(0, Sigma)"
        + (
            "."
            if layout.log_second
            else f"; {s_e} is the sd of ln p at z_s = {np.exp(pops.ln_zs) * 1e3:.3g} mm, where "
            "the tests' curves scatter least inside the measured range."
        ),
        f"Priors: {pops.describe_priors()}; {s_e} ~ half-Cauchy(1), "
        f"{s_d} ~ half-Cauchy({pops.scales[1]:.3g}); {rho} ~ Beta(2, 2) on (-1, 1).",
        f"Draws of {', '.join(names)} are a NEW preparation (the scatter above applied to one "
        "posterior draw of the soil-level parameters each) — parameter uncertainty and "
        "test-to-test scatter together.",
    ]
    if fits.failed:
        notes.append(f"Left out (per-test fit failed): {', '.join(fits.failed)}.")
    return notes


def _population_idata(
    pops: PopulationModel,
    run: EnsembleRun,
    rng: np.random.Generator,
    fits: PerTestFits,
    curves: xr.Dataset | None = None,
) -> Any:  # an az.InferenceData (Any: ArviZ sets its groups as attributes at run time)
    chains, draws, dim = run.chain.shape
    flat = run.chain.reshape(-1, dim)
    mu = pops.theta(flat)
    scatter = pops.scatter(flat)
    new = pops.new_preparation(flat, rng)
    names = pops.model.param_names
    shape = (chains, draws)
    data = {f"mu_{n}": mu[:, i].reshape(shape) for i, n in enumerate(names)}
    data |= {n: x.reshape(shape) for n, x in zip(pops.layout.scatter, scatter, strict=True)}
    data |= {n: new[:, i].reshape(shape) for i, n in enumerate(names)}
    coords = {"chain": np.arange(chains), "draw": np.arange(draws)}
    posterior = xr.Dataset(
        {k: (("chain", "draw"), v) for k, v in data.items()},
        coords=coords,
        attrs=posterior_attrs(pops.prior_only)
        | {
            "kind": "population",
            "ln_zref": pops.ln_zref,
            "ln_zs": pops.ln_zs,
            "priors": pops.describe_priors(),
        },
    )
    stats = xr.Dataset({"lp": (("chain", "draw"), run.log_prob)}, coords=coords)
    test_ids = np.asarray(fits.test_ids, dtype=str)
    per_test = list(pops.layout.per_test)
    test_coords = {"test": test_ids, pops.layout.covariate: ("test", fits.covariate)}
    observed = xr.Dataset(
        {"eta_hat": (("test", "eta"), fits.params)}, coords=test_coords | {"eta": per_test}
    )
    # Posterior predictive: replicated per-test fits from the marginal likelihood (a new
    # preparation at each test's plate size or normal pressure, plus that test's fit error),
    # thinned to PREDICTIVE_DRAWS; drawn after the new preparations, so those do not change.
    sub = spread_draws(draws, chains, PREDICTIVE_DRAWS)
    pick = run.chain[:, sub].reshape(-1, dim)
    with np.errstate(all="ignore"):
        rep = pops.replicate(pick, rng)
    ppc = xr.Dataset(
        {"eta_hat": (("chain", "draw", "test", "eta"), rep.reshape(chains, sub.size, -1, 2))},
        coords={"chain": np.arange(chains), "draw": sub, "eta": per_test} | test_coords,
        attrs={"draws_of_posterior": draws, "model": "eta_hat_t ~ N(h_t, B Sigma B' + C_t)"},
    )
    # At most LOG_LIKELIHOOD_DRAWS draws and LOG_LIKELIHOOD_VALUES values, as the pooled
    # model's (soilstats.bayes.predictive): thinned evenly within each chain beyond them.
    keep = log_likelihood_draws(draws, chains, len(test_ids))
    ll = pops.log_likelihood(run.chain[:, keep].reshape(-1, dim), fits.params)
    log_lik = xr.Dataset(
        {"eta_hat": (("chain", "draw", "test"), ll.reshape(chains, keep.size, -1))},
        coords={"chain": np.arange(chains), "draw": keep} | test_coords,
        attrs={
            "model": "one term per test (leave-one-test-out)",
            "draws_of_posterior": draws,
            "thinned": int(keep.size < draws),
        },
    )
    # The groups as keywords: Any, as arviz's signature types its own options, not groups.
    groups: dict[str, Any] = {
        "observed_data": observed,
        "posterior_predictive": ppc,
        "log_likelihood": log_lik,
    }
    if curves is not None:
        groups["constant_data"] = curves
    return az.InferenceData(posterior=posterior, sample_stats=stats, **groups)
