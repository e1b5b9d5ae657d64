"""The population (hierarchical) model: every preparation draws its own soil parameters.

Model.  Test t (one preparation) has parameters θ_t ~ N(μ, Σ) around the soil-level mean μ;
Σ = D R D holds the test-to-test scatter (D = diag of the sds, R a correlation matrix).  What
a rover Monte Carlo needs is the posterior predictive of a *new* preparation,
θ_new ~ N(μ, Σ) with (μ, Σ) drawn from their posterior.

Marginalisation (why it is fast).  Instead of sampling every θ_t, each test is reduced to its
own least-squares fit η̂_t with covariance C_t (the paper's Eq. 4 on that test alone).  For
sinkage, one test sees one plate size b_t, so it determines only η_t = (k_t, n_t) with
k_t = kc/b_t + kφ (Bernstein, Eq. 8, on that test) — a *linear* map η_t = A_t θ_t.  With the
Laplace approximation η̂_t | θ_t ~ N(A_t θ_t, C_t), θ_t integrates out in closed form:

    η̂_t ~ N(A_t μ, A_t Σ A_tᵀ + C_t),

so the sampler sees only μ (p), log-sds (p) and correlations (p(p−1)/2): 9 dimensions for
Bekker, 5 for Bernstein, whatever the number of tests.

Priors.  μ: the pooled model's physics priors (:mod:`soilstats.bayes.priors`).  Each sd:
half-Cauchy with scale |θ̂_i| + √T·se_i (the size of the parameter itself: weak).  R: its
Cholesky factor built from canonical partial correlations (as Stan's ``cholesky_corr``), each
with a symmetric Beta(2, 2) prior on (−1, 1) — for two parameters exactly LKJ(η = 2), in
general an LKJ-like prior that shrinks gently towards no correlation.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd
import xarray as xr
from scipy import optimize

from ..fitting import identify
from ..identification import fit_sinkage, pool_sinkage
from ..models import BEKKER, BERNSTEIN, get_model
from ._arviz import az
from .likelihood import PooledProblem
from .posterior import _attrs, finish
from .priors import resolve_priors
from .result import PosteriorResult
from .sampler import run_ensemble

__all__ = ["POPULATION_DRAWS", "sample_population"]

#: Default kept draws: the sds are skewed, so their tail ESS needs more draws than the pooled.
POPULATION_DRAWS = 12000


def _per_test_fits(pooled) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(η̂_t (T, 2), C_t (T, 2, 2), b_t (T,)): Bernstein fit of every test on its own."""
    etas, covs, sizes = [], [], []
    for t in range(len(pooled.groups)):
        m = pooled.test_index == t
        z, p, w = pooled.x["z_m"][m], pooled.y[m], pooled.weights[m]
        lnz, lnp = np.log(z), np.log(np.clip(p, p.max() * 1e-3, None))
        n0, lnk0 = np.polyfit(lnz, lnp, 1, w=np.clip(p, 0, None))
        fit = identify(BERNSTEIN, z, p, [np.exp(lnk0), n0], weights=w)
        etas.append(fit.params.to_numpy())
        covs.append(fit.cov.to_numpy())
        sizes.append(pooled.x["b_m"][m][0])
    return np.array(etas), np.array(covs), np.array(sizes)


def _corr_cholesky(u: np.ndarray, p: int) -> np.ndarray:
    """Cholesky factors (W, p, p) of correlation matrices from unconstrained CPCs u (W, q)."""
    z = np.tanh(u)
    w = u.shape[0]
    chol = np.zeros((w, p, p))
    chol[:, 0, 0] = 1.0
    k = 0
    for i in range(1, p):
        rest = np.ones(w)
        for j in range(i):
            chol[:, i, j] = z[:, k] * np.sqrt(rest)
            rest = rest - chol[:, i, j] ** 2
            k += 1
        chol[:, i, i] = np.sqrt(rest)
    return chol


class _Population:
    """Walker-vectorised log-posterior of (μ, log sd, atanh CPC)."""

    def __init__(self, model, eta, cov, sizes, priors, scale, plate_sizes):
        self.model, self.eta, self.cov, self.priors = model, eta, cov, priors
        self.p = model.n_params
        # Random effects: kφ and n for Bekker (kc, the plate-size term, is common to all
        # preparations), k and n for Bernstein.
        self.random = np.array([1, 2] if model is BEKKER else [0, 1])
        self.r = self.random.size
        self.q = self.r * (self.r - 1) // 2
        self.scale = scale[self.random]
        t = eta.shape[0]
        if model is BEKKER:  # η = (kc/b + kφ, n)
            self.a = np.zeros((t, 2, 3))
            self.a[:, 0, 0], self.a[:, 0, 1], self.a[:, 1, 2] = 1.0 / sizes, 1.0, 1.0
        else:
            self.a = np.broadcast_to(np.eye(2), (t, 2, 2)).copy()
        x = np.ones((2, 1)) if model is BEKKER else np.ones(1)  # the prior needs no data
        self.pooled_prior = PooledProblem(
            model, x, np.ones(1), np.ones(1), np.zeros(1, int), pd.DataFrame(), priors, plate_sizes
        )

    def unpack(self, v):
        p, r = self.p, self.r
        return v[:, :p], v[:, p : p + r], v[:, p + r :]

    def sigma(self, v) -> np.ndarray:
        _, log_sd, u = self.unpack(v)
        lc = _corr_cholesky(u, self.r) * np.exp(log_sd)[:, :, None]
        out = np.zeros((v.shape[0], self.p, self.p))
        out[:, self.random[:, None], self.random[None, :]] = lc @ np.swapaxes(lc, 1, 2)
        return out

    def log_prob(self, v: np.ndarray) -> np.ndarray:
        with np.errstate(all="ignore"):  # far-out proposals overflow to -inf: rejected
            return self._log_prob(v)

    def _log_prob(self, v: np.ndarray) -> np.ndarray:
        mu, log_sd, u = self.unpack(v)
        lp = self.pooled_prior.log_prior(mu)
        sd = np.exp(log_sd)
        lp = lp + np.sum(log_sd - np.log1p((sd / self.scale) ** 2), axis=1)  # half-Cauchy
        lp = lp + np.sum(2.0 * np.log(np.clip(1.0 - np.tanh(u) ** 2, 1e-300, None)), axis=1)
        ok = np.isfinite(lp)
        if not ok.any():
            return lp
        # M_t = A_t Σ A_tᵀ + C_t (W, T, 2, 2); r_t = η̂_t − A_t μ (W, T, 2); closed-form 2×2.
        s = self.sigma(v[ok])
        m = np.einsum("tij,wjk,tlk->wtil", self.a, s, self.a) + self.cov
        r = self.eta - np.einsum("tij,wj->wti", self.a, mu[ok])
        det = m[..., 0, 0] * m[..., 1, 1] - m[..., 0, 1] * m[..., 1, 0]
        quad = (
            m[..., 1, 1] * r[..., 0] ** 2
            - 2 * m[..., 0, 1] * r[..., 0] * r[..., 1]
            + m[..., 0, 0] * r[..., 1] ** 2
        ) / det
        ll = -0.5 * np.sum(np.log(det) + quad, axis=1)
        lp[ok] = np.where(np.isfinite(ll), lp[ok] + ll, -np.inf)
        return lp


def _laplace(log_prob, x0: np.ndarray, n_mu: int) -> tuple[np.ndarray, np.ndarray]:
    """Mode and inverse negative Hessian (central differences) of ``log_prob``."""
    scale = np.where(np.abs(x0) > 0, np.abs(x0), 1.0)
    scale[n_mu:] = 1.0  # log-sds and atanh-correlations are O(1) already

    def nlp(u):
        return -log_prob((u * scale)[None])[0]

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


def sample_population(
    campaign,
    model: str = "bekker",
    *,
    draws: int = POPULATION_DRAWS,
    seed: int | None = None,
    progress: bool = False,
    priors: Mapping[str, object] | None = None,
    walkers: int = 16,
    points_per_test: int | None = 100,
    **selection,
) -> PosteriorResult:
    """Sample the population model (see the module docstring) of a sinkage soil model.

    Parameters are as for :func:`soilstats.bayes.sample_posterior`.  ``model`` is
    ``"bekker"`` or ``"bernstein"``; the shear models have no population model yet.

    Returns
    -------
    PosteriorResult
        ``kind="population"``.  Its posterior holds ``mu_<name>``, ``sd_<name>``,
        ``corr_<a>_<b>`` and the parameters of a *new* preparation under the plain names
        (``kc``, ``kphi``, ``n``), which :meth:`~PosteriorResult.draws` returns.
    """
    spec = get_model(model)
    if spec not in (BEKKER, BERNSTEIN):
        raise ValueError(
            f"the population model is implemented for 'bekker' and 'bernstein' "
            f"(got {spec.name!r}); use sample_posterior for the pooled model"
        )
    pooled = pool_sinkage(campaign, points_per_test=points_per_test, **selection)
    lsq = fit_sinkage(campaign, spec.name, points_per_test=points_per_test, **selection)
    eta, cov, sizes = _per_test_fits(pooled)
    t = eta.shape[0]
    if t < 3:
        raise ValueError(f"the population model needs at least 3 tests, the selection has {t}")
    theta0, se = lsq.params.to_numpy(), lsq.stderr.to_numpy()
    pops = _Population(
        spec,
        eta,
        cov,
        sizes,
        resolve_priors(spec.name, spec.param_names, priors),
        np.abs(theta0) + np.sqrt(t) * se,
        np.unique(sizes),
    )
    p, q, rnd = pops.p, pops.q, pops.random
    x0 = np.concatenate([theta0, np.log(0.05 * np.abs(theta0) + np.sqrt(t) * se)[rnd], np.zeros(q)])
    centre, cov = _laplace(pops.log_prob, x0, p)
    run = run_ensemble(
        pops.log_prob,
        centre,
        cov,
        draws=draws,
        seed=seed,
        n_walkers=walkers,
        progress=progress,
        moves="laplace",
        tune=200,
        description=f"{spec.name} population",
    )
    rng = np.random.default_rng(None if seed is None else [seed, 2])
    idata = _population_idata(pops, run, rng, spec, pooled)
    names = spec.param_names
    rn = [names[i] for i in rnd]
    corr_names = [f"corr_{rn[i]}_{rn[j]}" for i in range(len(rn)) for j in range(i)]
    var_names = [f"mu_{n}" for n in names] + [f"sd_{n}" for n in rn] + corr_names
    notes = [
        f"Population model: {t} tests, each reduced to its own Bernstein fit (k_t, n_t) with "
        "its covariance; test-level parameters marginalised: eta_t ~ N(A_t mu, A_t Sigma A_t^T "
        "+ C_t).",
        "Priors: mu as the pooled model; sd ~ half-Cauchy(|theta_LS| + sqrt(T) se); "
        "canonical partial correlations ~ Beta(2, 2) on (-1, 1).",
        f"Draws of {', '.join(names)} are a NEW preparation: theta_new ~ N(mu, Sigma), one per "
        "posterior draw of (mu, Sigma) — parameter uncertainty and test-to-test scatter.",
    ]
    units = dict(zip(names, spec.units, strict=True))
    return finish(
        idata, spec.name, "population", names, units, (*var_names, *names), run, notes, lsq
    )


def _population_idata(pops: _Population, run, rng, spec, pooled):
    chains, draws, dim = run.chain.shape
    flat = run.chain.reshape(-1, dim)
    mu = pops.unpack(flat)[0]
    sigma = pops.sigma(flat)
    names = spec.param_names
    rnd = pops.random
    sub_sigma = sigma[:, rnd[:, None], rnd[None, :]]
    chol = np.linalg.cholesky(sub_sigma)
    new = mu.copy()
    new[:, rnd] += np.einsum("wij,wj->wi", chol, rng.standard_normal((mu.shape[0], rnd.size)))
    sd = np.sqrt(np.einsum("wii->wi", sub_sigma))
    corr = sub_sigma / sd[:, :, None] / sd[:, None, :]
    rn = [names[i] for i in rnd]
    shape = (chains, draws)
    data = {}
    for i, n in enumerate(names):
        data[f"mu_{n}"] = mu[:, i].reshape(shape)
    for i, n in enumerate(rn):
        data[f"sd_{n}"] = sd[:, i].reshape(shape)
    for i in range(len(rn)):
        for j in range(i):
            data[f"corr_{rn[i]}_{rn[j]}"] = corr[:, i, j].reshape(shape)
    for i, n in enumerate(names):
        data[n] = new[:, i].reshape(shape)
    coords = {"chain": np.arange(chains), "draw": np.arange(draws)}
    problem = PooledProblem(
        spec,
        np.vstack([pooled.x["b_m"], pooled.x["z_m"]]) if spec is BEKKER else pooled.x["z_m"],
        pooled.y,
        pooled.weights,
        pooled.test_index,
        pooled.groups,
        pops.priors,
    )
    posterior = xr.Dataset(
        {k: (("chain", "draw"), v) for k, v in data.items()},
        coords=coords,
        attrs=_attrs(problem) | {"kind": "population"},
    )
    stats = xr.Dataset({"lp": (("chain", "draw"), run.log_prob)}, coords=coords)
    test_ids = pooled.groups["test_id"].astype(str).to_numpy()
    observed = xr.Dataset(
        {"eta_hat": (("test", "eta"), pops.eta)},
        coords={
            "test": test_ids,
            "eta": ["k", "n"],
            "b_m": (
                "test",
                pops.a[:, 0, 0] ** -1 if spec is BEKKER else np.full(len(test_ids), np.nan),
            ),
        },
    )
    # Posterior predictive: a new preparation's (k, n) at each test's plate, no fit error.
    k = min(8, draws)
    sub = np.linspace(0, draws - 1, k).astype(int)
    pick = new.reshape(chains, draws, -1)[:, sub].reshape(-1, pops.p)
    eta_new = np.einsum("tij,wj->wti", pops.a, pick).reshape(chains, k, len(test_ids), 2)
    ppc = xr.Dataset(
        {"eta_hat": (("chain", "draw", "test", "eta"), eta_new)},
        coords={"chain": np.arange(chains), "draw": sub, "test": test_ids, "eta": ["k", "n"]},
    )
    return az.InferenceData(
        posterior=posterior, sample_stats=stats, observed_data=observed, posterior_predictive=ppc
    )
