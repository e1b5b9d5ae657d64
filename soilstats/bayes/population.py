"""Sampling the population (hierarchical) model: every preparation draws its own soil
parameters.

The model — each test reduced to its own fit, the test-level effects marginalised, where
the preparation scatter sits and the priors — is :mod:`soilstats.bayes.population_model`.
Here: its start (the pooled least-squares estimate and a Laplace approximation), the
emcee run, the draws of a *new* preparation a rover Monte Carlo needs, and the ArviZ
groups and notes of the result.
"""

from __future__ import annotations

import json
import warnings
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import xarray as xr
from scipy import optimize

from ..errors import IdentifiabilityError, InputError, ModelError
from ..identification import fit_sinkage, pool_sinkage
from ..models import get_model, model_names
from ._arviz import az
from .data import pooled_problem
from .population_model import POPULATION_MODELS, PopulationModel, reference_rows
from .posterior import _attrs, finish
from .predictive import (
    PREDICTIVE_DRAWS,
    log_likelihood_draws,
    measured_dataset,
    response_dataset,
    spread_draws,
)
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
from .sampler import run_ensemble
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
    step = 1e-2 * np.sqrt(np.clip(np.diag(opt.hess_inv), 1e-12, None)) * scale
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
        check = _band_check(pops, fits, pooled, idata.posterior, run.chain)
        idata.posterior.attrs["calibration"] = check.to_json()
        notes.append(check.sentence)
    units = dict(zip(names, spec.units, strict=True))
    return finish(
        idata, spec.name, "population", names, units, (*var_names, *names), run, notes, lsq
    )


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


def _population_idata(pops: PopulationModel, run, rng, fits: PerTestFits, curves=None):
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
        attrs=_attrs(pops.prior_only)
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


# --- Is the band of a new preparation calibrated on the tests it was learned from? ----------

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


def _band_quantiles(values: np.ndarray, weights: np.ndarray, q, order=None) -> np.ndarray:
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


def _band_check(
    pops: PopulationModel, fits: PerTestFits, pooled, posterior, chain: np.ndarray
) -> BandCalibration:
    """:class:`BandCalibration` of a sinkage population (see there)."""
    from scipy.special import stdtrit

    records, depths = _records(pooled, fits)
    t_count, k_depths = depths.shape
    # Measured ln p of every test at the depths of every test of its plate size: its own
    # (the diagonal blocks) and the tests' own scatter there (sd over ≥ 3 tests).
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

    def mean_of(x) -> float:
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


def _band_verdict(c: dict, measured, own, missed) -> tuple[tuple[str, ...], str]:
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
