"""The population (hierarchical) model: every preparation draws its own soil parameters.

Model.  Test t (one preparation) has its own sinkage curve p = k_t(b)·z^(n_t) with

    k_t(b) = (kc/b + kφ)·exp(ε_t)   (Bekker, Eq. 7;  Bernstein, Eq. 8: k_t = k·exp(ε_t)),
    n_t    = n + δ_t,               (ε_t, δ_t) ~ N(0, Σ),   Σ = [[s_ε², ρ s_ε s_δ], [·, s_δ²]],

i.e. a preparation scales kc and kφ by one common log-normal stiffness factor and shifts the
exponent n (the simulator's preparation scatter, docs/simulator.md).  Moduli stay positive for
every preparation.  A rover Monte Carlo needs the posterior predictive of a *new* preparation:
(kc, kφ, n)_new = (kc·e^ε, kφ·e^ε, n + δ), (ε, δ) ~ N(0, Σ), with (kc, kφ, n, Σ) drawn from
their posterior.

Marginalisation (why it is fast and low-dimensional).  Each test is first reduced to its own
weighted least-squares Bernstein fit (Eq. 8, weights 1/max p as Eq. 9), written in the
coordinates η_t = (ln k_t + n_t·ln z_ref, n_t) in which that fit is close to normal
(:mod:`soilstats.bayes.transforms`), with covariance C_t from Eq. 4 by the delta method.
With the Laplace approximation η̂_t | (ε_t, δ_t) ~ N(h_t + B·(ε_t, δ_t), C_t), where
h_t = (ln(kc/b_t + kφ) + n·ln z_ref, n) and B = [[1, ln z_ref], [0, 1]], the test-level
effects integrate out in closed form:

    η̂_t ~ N(h_t(kc, kφ, n), B Σ Bᵀ + C_t),

so the sampler sees only the soil-level parameters and Σ — 6 dimensions for Bekker
(kc, kφ, n, ln s_ε, ln s_δ, atanh ρ), 5 for Bernstein — however many tests there are, and one
log-density costs one 2×2 determinant per test and walker.  The soil-level parameters are
sampled in the log-modulus coordinates of :mod:`soilstats.bayes.transforms` (exact Jacobian).

Priors.  (kc, kφ, n): the pooled model's physics priors (:mod:`soilstats.bayes.priors`).
s_ε, s_δ: half-Cauchy with scale 1 (a factor e between preparations) and |n̂| (weak).  ρ: a
symmetric Beta(2, 2) on (−1, 1), i.e. LKJ(η = 2) for a 2×2 correlation matrix.

What it assumes: scatter between tests is preparation scatter; a test's own curve is well
described by the model (the per-test fit's ε of Eq. 2 is its check); tests whose per-test fit
fails are left out and named in the notes.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd
import xarray as xr
from scipy import optimize

from ..identification import fit_sinkage, pool_sinkage
from ..identification.per_test import TEST_FIT_ERRORS, fit_bernstein_test
from ..models import BEKKER, BERNSTEIN, get_model
from ._arviz import az
from .likelihood import PooledProblem
from .posterior import _attrs, finish
from .priors import resolve_priors
from .result import PosteriorResult, draws_converge
from .sampler import run_ensemble
from .transforms import Coordinates, sampling_coordinates

__all__ = ["POPULATION_DRAWS", "sample_population"]

#: Default kept draws: the sds are skewed, so their tail ESS needs more draws than the pooled.
POPULATION_DRAWS = 12000
#: Scatter quantities of the population model, in the order of the sampled vector.
SCATTER = ("sd_stiffness", "sd_n", "corr_stiffness_n")


def _per_test_fits(pooled) -> tuple[np.ndarray, np.ndarray, np.ndarray, list, list]:
    """Bernstein fit (Eq. 8) of every test on its own.

    Returns (k̂_t, n̂_t) (T, 2), their covariances (T, 2, 2), plate sizes b_t (T,), the ids
    of the tests used and the ids of tests whose fit failed (left out).
    """
    etas, covs, sizes, kept, failed = [], [], [], [], []
    for t, tid in enumerate(pooled.tests["test_id"].astype(str)):
        m = pooled.test_index == t
        z, p, w = pooled.x["z_m"][m], pooled.y[m], pooled.weights[m]
        try:
            fit = fit_bernstein_test(z, p, w, name=f"bernstein {tid}")
        except TEST_FIT_ERRORS:  # reported below as left out, as fit_per_test reports it
            failed.append(tid)
            continue
        cov = fit.cov.to_numpy()
        if not (fit.params["k"] > 0 and np.all(np.isfinite(cov))):
            failed.append(tid)
            continue
        etas.append(fit.params.to_numpy())
        covs.append(cov)
        sizes.append(pooled.x["b_m"][m][0])
        kept.append(tid)
    return np.array(etas), np.array(covs), np.array(sizes), kept, failed


def _reference_sinkage(kn: np.ndarray, cov: np.ndarray) -> float:
    """ln z_ref: the median over tests of the value decorrelating ln k̂_t and n̂_t."""
    return float(np.median(-cov[:, 0, 1] / kn[:, 0] / cov[:, 1, 1]))


def _to_eta(kn: np.ndarray, cov: np.ndarray, ln_zref: float):
    """(k, n) fits and covariances → η = (ln k + n ln z_ref, n) and delta-method covariances."""
    eta = np.column_stack([np.log(kn[:, 0]) + kn[:, 1] * ln_zref, kn[:, 1]])
    jac = np.zeros_like(cov)
    jac[:, 0, 0] = 1.0 / kn[:, 0]
    jac[:, 0, 1] = ln_zref
    jac[:, 1, 1] = 1.0
    return eta, jac @ cov @ np.swapaxes(jac, 1, 2)


class _Population:
    """Walker-vectorised log-posterior of v = (u(kc, kφ, n), ln s_ε, ln s_δ, atanh ρ)."""

    def __init__(self, model, eta, cov, sizes, ln_zref, priors, coords: Coordinates, n_scale):
        self.model, self.eta, self.cov, self.priors = model, eta, cov, priors
        self.coords, self.ln_zref = coords, ln_zref
        self.p = model.n_params
        self.m = self.p - 1  # moduli (kc, kφ) or (k)
        # Plate modulus of test t is design[t] · moduli.
        self.design = (
            np.column_stack([1.0 / sizes, np.ones_like(sizes)])
            if model is BEKKER
            else (np.ones((sizes.size, 1)))
        )
        self.b = np.array([[1.0, ln_zref], [0.0, 1.0]])
        self.scales = np.array([1.0, max(abs(n_scale), 0.1)])
        x = np.ones((2, 1)) if model is BEKKER else np.ones(1)  # the prior needs no data
        self.prior_only = PooledProblem(
            model,
            x,
            np.ones(1),
            np.ones(1),
            np.zeros(1, int),
            pd.DataFrame(),
            priors,
            np.unique(sizes),
        )

    @property
    def dim(self) -> int:
        return self.p + 3

    def theta(self, v: np.ndarray) -> np.ndarray:
        """Soil-level (kc, kφ, n) or (k, n) for each row of ``v``."""
        return self.coords.to_theta(v[:, : self.p])

    def scatter(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(s_ε, s_δ, ρ) for each row of ``v``."""
        return np.exp(v[:, self.p]), np.exp(v[:, self.p + 1]), np.tanh(v[:, self.p + 2])

    def sigma(self, v: np.ndarray) -> np.ndarray:
        """Σ of (ε, δ) for each row of ``v`` → (W, 2, 2)."""
        se, sd, rho = self.scatter(v)
        out = np.empty((v.shape[0], 2, 2))
        out[:, 0, 0], out[:, 1, 1] = se**2, sd**2
        out[:, 0, 1] = out[:, 1, 0] = rho * se * sd
        return out

    def log_prob(self, v: np.ndarray) -> np.ndarray:
        with np.errstate(all="ignore"):  # far-out proposals overflow to -inf: rejected
            return self._log_prob(np.atleast_2d(v))

    def _log_prob(self, v: np.ndarray) -> np.ndarray:
        theta = self.theta(v)
        out = np.full(v.shape[0], -np.inf)
        ok = np.all(np.isfinite(theta), axis=1)
        if not ok.any():
            return out
        v, theta = v[ok], theta[ok]
        lp = self.prior_only.log_prior(theta) + self.coords.log_jacobian(v[:, : self.p])
        log_s = v[:, self.p : self.p + 2]
        s = np.exp(log_s)
        lp = lp + np.sum(log_s - np.log1p((s / self.scales) ** 2), axis=1)  # half-Cauchy
        lp = lp + 2.0 * np.log(np.clip(1.0 - np.tanh(v[:, self.p + 2]) ** 2, 1e-300, None))
        # h_t (W, T, 2) and M_t = B Σ Bᵀ + C_t (W, T, 2, 2); closed-form 2×2 algebra.
        kb = theta[:, : self.m] @ self.design.T  # (W, T)
        n = theta[:, self.m]
        h0 = np.log(np.where(kb > 0, kb, np.nan)) + n[:, None] * self.ln_zref
        r0 = self.eta[None, :, 0] - h0
        r1 = self.eta[None, :, 1] - n[:, None]
        bsb = self.b @ self.sigma(v) @ self.b.T  # (W, 2, 2)
        m = bsb[:, None] + self.cov[None]
        det = m[..., 0, 0] * m[..., 1, 1] - m[..., 0, 1] * m[..., 1, 0]
        quad = (m[..., 1, 1] * r0**2 - 2 * m[..., 0, 1] * r0 * r1 + m[..., 0, 0] * r1**2) / det
        ll = -0.5 * np.sum(np.log(det) + quad, axis=1)
        out[ok] = np.where(np.isfinite(ll) & np.isfinite(lp), lp + ll, -np.inf)
        return out

    def summaries(self, chain: np.ndarray) -> dict[str, np.ndarray]:
        """Soil-level parameters and scatter of a chain (walkers, draws, dim), by name."""
        flat = chain.reshape(-1, self.dim)
        theta = self.theta(flat)
        se, sd, rho = self.scatter(flat)
        shape = chain.shape[:2]
        names = [f"mu_{n}" for n in self.model.param_names]
        out = {n: theta[:, i].reshape(shape) for i, n in enumerate(names)}
        return out | dict(zip(SCATTER, (x.reshape(shape) for x in (se, sd, rho)), strict=True))

    def new_preparation(self, v: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """θ of a new preparation, one per row of ``v``: moduli·e^ε, n + δ."""
        theta = self.theta(v)
        chol = np.linalg.cholesky(self.sigma(v))
        e = np.einsum("wij,wj->wi", chol, rng.standard_normal((v.shape[0], 2)))
        out = theta.copy()
        out[:, : self.m] *= np.exp(e[:, :1])
        out[:, self.m] += e[:, 1]
        return out


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
        ``kind="population"``.  Its posterior holds ``mu_<name>`` (the soil-level parameters:
        a median preparation), ``sd_stiffness`` (sd of the log stiffness factor e^ε, ≈ the
        coefficient of variation of kc and kφ between preparations), ``sd_n``,
        ``corr_stiffness_n``, and the parameters of a *new* preparation under the plain names
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
    kn, kn_cov, sizes, test_ids, failed = _per_test_fits(pooled)
    t = kn.shape[0]
    if t < 3:
        raise ValueError(
            f"the population model needs at least 3 tests with a usable per-test fit; the "
            f"selection has {t} (failed: {failed or 'none'})"
        )
    ln_zref = _reference_sinkage(kn, kn_cov)
    eta, cov = _to_eta(kn, kn_cov, ln_zref)
    theta0 = lsq.params.to_numpy()
    base = sampling_coordinates(spec, theta0, lsq.cov.to_numpy(), np.unique(sizes))
    coords = base if base.identity else Coordinates(moduli=base.moduli, ln_zref=ln_zref)
    pops = _Population(
        spec,
        eta,
        cov,
        sizes,
        ln_zref,
        resolve_priors(spec.name, spec.param_names, priors),
        coords,
        theta0[-1],
    )
    # Start: the pooled LS estimate and the spread of the per-test fits around it.
    kb0 = pops.design @ theta0[: pops.m]
    r1 = eta[:, 1] - theta0[-1]
    r0 = eta[:, 0] - (np.log(np.abs(kb0)) + theta0[-1] * ln_zref) - ln_zref * r1
    spread = np.log(np.maximum([np.std(r0, ddof=1), np.std(r1, ddof=1)], 1e-3))
    x0 = np.concatenate([coords.to_u(theta0)[0], spread, [0.0]])
    if not np.all(np.isfinite(x0)):
        raise ValueError(
            f"the pooled least-squares estimate {dict(zip(spec.param_names, theta0, strict=True))}"
            " gives a non-positive plate modulus; the population model cannot start there"
        )
    centre, cov_v = _laplace(pops.log_prob, x0, pops.p)
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
        description=f"{spec.name} population",
        accept=lambda chain: draws_converge(pops.summaries(chain)),
    )
    rng = np.random.default_rng(None if seed is None else [seed, 2])
    idata = _population_idata(pops, run, rng, spec, pooled, kn, sizes, test_ids)
    names = spec.param_names
    var_names = [f"mu_{n}" for n in names] + list(SCATTER)
    notes = [
        f"Population model: {t} tests (preparations), each reduced to its own Bernstein fit "
        "(k_t, n_t) with its Eq. 4 covariance, in coordinates (ln k_t + n_t ln z_ref, n_t) "
        f"with z_ref = {np.exp(ln_zref) * 1e3:.3g} mm; test-level effects marginalised: "
        "k_t(b) = (kc/b + kphi) exp(eps_t), n_t = n + delta_t, (eps, delta) ~ N(0, Sigma).",
        "Priors: (kc, kphi, n) as the pooled model; sd_stiffness ~ half-Cauchy(1), "
        f"sd_n ~ half-Cauchy({pops.scales[1]:.3g}); corr ~ Beta(2, 2) on (-1, 1).",
        f"Draws of {', '.join(names)} are a NEW preparation: moduli x exp(eps), n + delta, "
        "one per posterior draw — parameter uncertainty and test-to-test scatter together.",
    ]
    if failed:
        notes.append(f"Left out (per-test fit failed): {', '.join(failed)}.")
    units = dict(zip(names, spec.units, strict=True))
    return finish(
        idata, spec.name, "population", names, units, (*var_names, *names), run, notes, lsq
    )


def _population_idata(pops: _Population, run, rng, spec, pooled, kn, sizes, test_ids):
    chains, draws, dim = run.chain.shape
    flat = run.chain.reshape(-1, dim)
    mu = pops.theta(flat)
    se, sd, rho = pops.scatter(flat)
    new = pops.new_preparation(flat, rng)
    names = spec.param_names
    shape = (chains, draws)
    data = {f"mu_{n}": mu[:, i].reshape(shape) for i, n in enumerate(names)}
    data |= {
        "sd_stiffness": se.reshape(shape),
        "sd_n": sd.reshape(shape),
        "corr_stiffness_n": rho.reshape(shape),
    }
    data |= {n: new[:, i].reshape(shape) for i, n in enumerate(names)}
    coords = {"chain": np.arange(chains), "draw": np.arange(draws)}
    problem = PooledProblem(
        spec,
        np.vstack([pooled.x["b_m"], pooled.x["z_m"]]) if spec is BEKKER else pooled.x["z_m"],
        pooled.y,
        pooled.weights,
        pooled.test_index,
        pooled.tests,
        pops.priors,
    )
    posterior = xr.Dataset(
        {k: (("chain", "draw"), v) for k, v in data.items()},
        coords=coords,
        attrs=_attrs(problem) | {"kind": "population", "ln_zref": pops.ln_zref},
    )
    stats = xr.Dataset({"lp": (("chain", "draw"), run.log_prob)}, coords=coords)
    test_ids = np.asarray(test_ids, dtype=str)
    observed = xr.Dataset(
        {"eta_hat": (("test", "eta"), kn)},
        coords={"test": test_ids, "eta": ["k", "n"], "b_m": ("test", sizes)},
    )
    # Posterior predictive: a new preparation's (k_b, n) at each test's plate, no fit error.
    k = min(8, draws)
    sub = np.linspace(0, draws - 1, k).astype(int)
    pick = new.reshape(chains, draws, -1)[:, sub].reshape(-1, pops.p)
    kb = pick[:, : pops.m] @ pops.design.T  # (W', T)
    eta_new = np.stack([kb, np.broadcast_to(pick[:, -1:], kb.shape)], axis=-1)
    ppc = xr.Dataset(
        {"eta_hat": (("chain", "draw", "test", "eta"), eta_new.reshape(chains, k, -1, 2))},
        coords={"chain": np.arange(chains), "draw": sub, "test": test_ids, "eta": ["k", "n"]},
    )
    return az.InferenceData(
        posterior=posterior, sample_stats=stats, observed_data=observed, posterior_predictive=ppc
    )
