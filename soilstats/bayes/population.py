"""The population (hierarchical) model: every preparation draws its own soil parameters.

Sinkage model.  Test t (one preparation) has its own sinkage curve p = k_t(b)·z^(n_t) with

    k_t(b) = (kc/b + kφ)·exp(ε_t − δ_t·ln z_s)   (Bekker, Eq. 7;  Bernstein, Eq. 8: k·…),
    n_t    = n + δ_t,               (ε_t, δ_t) ~ N(0, Σ),   Σ = [[s_ε², ρ s_ε s_δ], [·, s_δ²]],

i.e. a preparation scales kc and kφ by one common log-normal stiffness factor and shifts the
exponent n (the simulator's preparation scatter, docs/simulator.md); ε_t is the shift of
ln p at the sinkage z_s, p_t(b, z_s) = p(b, z_s)·e^(ε_t), so s_ε (``sd_p_ref``) is about
the coefficient of variation of the pressure there.  Moduli stay positive for every
preparation.

Where the scatter sits.  Any z_s gives the same family of curves, but not the same prior:
ρ ~ Beta(2, 2) keeps |ρ| away from 1, i.e. it favours level and exponent scatter that are
independent *at z_s*.  Measured preparations often differ in n while their curves cross
inside the measured range (GRC-1, 51 mm plate: ln p at 4.2 mm scatters by 0.06, n by 0.19).
With z_s = 1 m, two hundred times the depth tested (Eq. 8's k), that is ln k's sd ≈ 1 with
corr(ln k, n) ≈ 0.999, which the prior does not reach with 5 tests: the predictive band of a
new preparation came out 14–20× wider than the measured repeat scatter.  z_s is therefore
where the tests' own curves scatter least, inside the measured range
(:func:`reduction.scatter_sinkage`): there the data, too, say level and exponent vary
independently.

Shear model (Janosi–Hanamoto, Eq. 13).  Test t runs at one normal pressure σ_t, so it
identifies only its own strength τ_max,t and modulus K_t (Eq. 13 at one σ):

    τ_max,t = (c + σ_t·tan φ)·exp(ε_t),   K_t = K·exp(δ_t),   (ε_t, δ_t) ~ N(0, Σ),

i.e. a preparation scales the whole Mohr–Coulomb envelope (c and tan φ) by one common
log-normal strength factor and K by its own; a single test cannot tell a change of c from a
change of φ, so the model does not pretend to.  c, tan φ and K stay positive for every
preparation.

A rover Monte Carlo needs the posterior predictive of a *new* preparation: (kc·e^ε, kφ·e^ε,
n + δ), or (c·e^ε, atan(tan φ·e^ε), K·e^δ), with the soil-level parameters and Σ drawn from
their posterior.

Marginalisation (why it is fast and low-dimensional). Each test is first reduced to its own
weighted least-squares fit (:mod:`soilstats.bayes.reduction`) — Bernstein (Eq. 8, weights
1/max p as Eq. 9) or Eq. 13 at one σ (weights 1/max τ) — written in coordinates η_t in which
that fit is close to normal: (ln k_t + n_t·ln z_ref, n_t) for sinkage
(:mod:`soilstats.bayes.transforms`), (ln τ_max,t, ln K_t) for shear; its covariance C_t
comes from Eq. 4 by the delta method. With the Laplace approximation η̂_t | (ε_t, δ_t) ~
N(h_t + B·(ε_t, δ_t), C_t), where h_t = (ln(a_tᵀm) + g·ln z_ref, g) with the linear moduli m
= (kc, kφ), (k) or (c, tan φ), their design row a_t = (1/b_t, 1), (1) or (1, σ_t), g = n or
ln K, and B = [[1, ln z_ref − ln z_s], [0, 1]] (z_ref = z_s = 1 for shear), the test-level
effects integrate out in closed form:

    η̂_t ~ N(h_t, B Σ Bᵀ + C_t),

so the sampler sees only the soil-level parameters and Σ — 6 dimensions for Bekker and
Janosi (ln s_ε, ln s_δ, atanh ρ besides the three soil parameters), 5 for Bernstein — however
many tests there are, and one log-density costs one 2×2 determinant per test and walker.
Bekker and Bernstein moduli are sampled in the log-modulus coordinates of
:mod:`soilstats.bayes.transforms` (exact Jacobian); Janosi's (c, φ, K) as they are.

Priors.  Soil-level parameters: the pooled model's physics support
(:mod:`soilstats.bayes.priors`), and by default flat in the logarithm of each positive scale
the tests measure — the plate moduli at the smallest and largest plate (Bekker), k
(Bernstein), the strengths τ_max(σ) = c + σ tan φ at the smallest and largest normal pressure
and K (Janosi); n stays flat.  Why not flat in the moduli themselves, as the pooled model:
the moduli enter the marginal likelihood through their logarithm u, and a density flat in a
modulus is e^u in u; integrating u then leaves e^{s²/(2T)} (s the scatter sd, T tests), which
grows faster than any prior on s decays — the posterior is improper, and the sampler either
runs off to overflowing moduli or sits in a local mode (docs/posterior.md).  Flat in u leaves
a likelihood in s that decays as s^{1−T}: proper for T ≥ 3 (the model's minimum).  A prior
the caller gives for any parameter of a group (the linear moduli; n or K) replaces that
group's log-flat factor: the caller's priors are then the prior.

s_ε, s_δ: half-Cauchy with scale 1 (a factor e between preparations), for sinkage s_δ with
scale |n̂| (weak).  ρ: a symmetric Beta(2, 2) on (−1, 1),
i.e. LKJ(η = 2) for a 2×2 correlation matrix.

What it assumes: scatter between tests is preparation scatter; a test's own curve is well
described by the model (the per-test fit's ε of Eq. 2 is its check); tests whose per-test fit
fails are left out and named in the notes.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
import pandas as pd
import xarray as xr
from scipy import optimize

from ..identification import fit_sinkage, pool_sinkage
from ..models import BEKKER, JANOSI, get_model
from ..models.shear import RAD_PER_DEG
from ._arviz import az
from .data import pooled_problem
from .likelihood import PooledProblem
from .posterior import _attrs, finish
from .predictive import PREDICTIVE_DRAWS, measured_dataset, response_dataset, spread_draws
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

__all__ = ["POPULATION_DRAWS", "POPULATION_MODELS", "sample_population"]

#: Default kept draws: the sds are skewed, so their tail ESS needs more draws than the pooled.
POPULATION_DRAWS = 12000


@dataclass(frozen=True)
class _Layout:
    """How one soil model maps onto the population model (see the module docstring).

    ``linear(θ)`` → the moduli m that enter a test's first per-test parameter linearly
    (a_tᵀm); ``second(θ)`` → g, the soil-level value of the second per-test coordinate;
    ``assemble(m, g)`` → θ back.  ``log_second``: the per-test fit's second parameter enters
    η as its logarithm (K) rather than as it is (n).
    """

    per_test: tuple[str, str]  # names of the per-test fit's two parameters
    scatter: tuple[str, str, str]  # names of s_ε, s_δ, ρ in the posterior
    covariate: str  # per-test quantity of the design row: b_m or sigma_Pa
    log_second: bool
    #: log dθ_linear/d(moduli): the moduli m are the parameters themselves (sinkage), or
    #: (c, tan φ) of (c, φ [deg]) — ln dtanφ/dφ = −2 ln cos φ + const.
    linear_log_jacobian: Callable[[np.ndarray], np.ndarray]
    linear: Callable[[np.ndarray], np.ndarray]
    second: Callable[[np.ndarray], np.ndarray]
    assemble: Callable[[np.ndarray, np.ndarray], np.ndarray]
    scatter_note: str


_SINKAGE = dict(
    per_test=("k", "n"),
    scatter=("sd_p_ref", "sd_n", "corr_p_ref_n"),
    covariate="b_m",
    log_second=False,
    linear_log_jacobian=lambda theta: np.zeros(theta.shape[0]),
    linear=lambda theta: theta[:, :-1],
    second=lambda theta: theta[:, -1],
    assemble=lambda m, g: np.column_stack([m, g]),
)
_LAYOUTS = {
    "bekker": _Layout(
        **_SINKAGE,
        scatter_note="k_t(b) = (kc/b + kphi) exp(eps_t - delta_t ln z_s), n_t = n + delta_t",
    ),
    "bernstein": _Layout(
        **_SINKAGE, scatter_note="k_t = k exp(eps_t - delta_t ln z_s), n_t = n + delta_t"
    ),
    "janosi": _Layout(
        per_test=("tau_max", "K"),
        scatter=("sd_strength", "sd_lnK", "corr_strength_K"),
        covariate="sigma_Pa",
        log_second=True,
        linear_log_jacobian=lambda theta: -2.0 * np.log(np.cos(theta[:, 1] * RAD_PER_DEG)),
        linear=lambda theta: np.column_stack([theta[:, 0], np.tan(theta[:, 1] * RAD_PER_DEG)]),
        second=lambda theta: np.log(theta[:, 2]),
        assemble=lambda m, g: np.column_stack(
            [m[:, 0], np.arctan(m[:, 1]) / RAD_PER_DEG, np.exp(g)]
        ),
        scatter_note="tau_max,t = (c + sigma_t tan phi) exp(eps_t), K_t = K exp(delta_t)",
    ),
}
#: Soil models with a population model.
POPULATION_MODELS = tuple(_LAYOUTS)


def _reference_rows(design: np.ndarray, covariate: np.ndarray) -> np.ndarray:
    """The design rows a_ref whose scales a_refᵀm the default prior is flat in the log of:
    those of the smallest and largest positive b or σ of the tests, or the one row of a
    model with one linear modulus (Bernstein).  As many rows as moduli, so the prior is
    homogeneous of degree −m in m: flat in the log of their common scale."""
    if design.shape[1] == 1:
        return design[:1]
    positive = np.flatnonzero(covariate > 0)
    if positive.size == 0:  # (σ = 0 only: c alone is measured; flat in ln c)
        positive = np.arange(covariate.size)
    ends = positive[[np.argmin(covariate[positive]), np.argmax(covariate[positive])]]
    return design[ends]


class _Population:
    """Walker-vectorised log-posterior of v = (u(θ), ln s_ε, ln s_δ, atanh ρ)."""

    def __init__(
        self,
        model,
        layout: _Layout,
        eta,
        cov,
        design,
        ln_zref,
        priors,
        coords: Coordinates,
        *,
        reference_rows: np.ndarray,
        log_flat: tuple[bool, bool] = (True, True),
        ln_zs: float | None = None,
    ):
        self.model, self.layout, self.eta, self.cov, self.priors = model, layout, eta, cov, priors
        self.coords, self.ln_zref, self.design = coords, ln_zref, design
        # Σ sits on (ln p at z_s, n); B carries it to η's (ln p at z_ref, n).  Shear: z_s = z_ref.
        self.ln_zs = ln_zref if ln_zs is None else ln_zs
        self.b = np.array([[1.0, ln_zref - self.ln_zs], [0.0, 1.0]])
        self.reference_rows = reference_rows
        # Whether the default log-flat factor applies to the linear moduli, and to K (a
        # caller's prior on a group replaces it; module docstring, "Priors").
        self.log_flat_linear, self.log_flat_second = log_flat[0], log_flat[1] and layout.log_second
        self.p = model.n_params
        # Half-Cauchy scales: a factor e for a modulus; |n̂| for an exponent.
        g_hat = float(np.median(eta[:, 1]))
        self.scales = np.array([1.0, 1.0 if layout.log_second else max(abs(g_hat), 0.1)])
        x = np.ones((2, 1)) if model in (BEKKER, JANOSI) else np.ones(1)  # the prior needs no data
        self.prior_only = PooledProblem(
            model, x, np.ones(1), np.ones(1), np.zeros(1, int), pd.DataFrame(), priors
        )

    @property
    def dim(self) -> int:
        return self.p + 3

    def theta(self, v: np.ndarray) -> np.ndarray:
        """Soil-level parameters for each row of ``v``."""
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
        lp = (
            self.prior_only.log_prior(theta)
            + self.log_scale_prior(theta)
            + self.coords.log_jacobian(v[:, : self.p])
        )
        log_s = v[:, self.p : self.p + 2]
        s = np.exp(log_s)
        lp = lp + np.sum(log_s - np.log1p((s / self.scales) ** 2), axis=1)  # half-Cauchy
        lp = lp + 2.0 * np.log(np.clip(1.0 - np.tanh(v[:, self.p + 2]) ** 2, 1e-300, None))
        det, quad = self._marginal(v, theta)
        ll = -0.5 * np.sum(np.log(det) + quad, axis=1)
        out[ok] = np.where(np.isfinite(ll) & np.isfinite(lp), lp + ll, -np.inf)
        return out

    def log_scale_prior(self, theta: np.ndarray) -> np.ndarray:
        """The default prior's log-flat factor on θ (W, p) → (W,): −Σ ln(a_refᵀm) plus the
        Jacobian of m in θ for the linear moduli, −ln K for Janosi (module docstring)."""
        out = np.zeros(theta.shape[0])
        if self.log_flat_linear:
            scales = self.layout.linear(theta) @ self.reference_rows.T  # (W, m)
            positive = np.all(scales > 0, axis=1)
            logs = np.log(np.where(scales > 0, scales, 1.0))
            out += np.where(
                positive, self.layout.linear_log_jacobian(theta) - logs.sum(axis=1), -np.inf
            )
        if self.log_flat_second:
            out -= self.layout.second(theta)  # g = ln K: 1/K on K
        return out

    def describe_priors(self) -> str:
        """The soil-level priors in words (notes, ``posterior.attrs['priors']``)."""
        names = self.model.param_names
        own = "; ".join(f"{n}: {p}" for n, p in zip(names, self.priors, strict=True))
        if self.layout.log_second:
            scales = "tau_max at the smallest and largest normal pressure"
        elif self.reference_rows.shape[0] == 1:
            scales = names[0]
        else:
            scales = "the plate modulus kc/b + kphi at the smallest and largest plate"
        parts = []
        if self.log_flat_linear:
            parts.append(f"flat in ln of {scales}")
        if self.log_flat_second:
            parts.append(f"flat in ln {names[-1]}")
        if not parts:
            return own
        return f"{own}; times the population default: {' and '.join(parts)}"

    def _mean_cov(self, v: np.ndarray, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """h_t (W, T, 2) and M_t = B Σ Bᵀ + C_t (W, T, 2, 2) of the marginal likelihood."""
        kb = self.layout.linear(theta) @ self.design.T  # (W, T)
        g = self.layout.second(theta)
        h0 = np.log(np.where(kb > 0, kb, np.nan)) + g[:, None] * self.ln_zref
        h = np.stack([h0, np.broadcast_to(g[:, None], h0.shape)], axis=-1)
        bsb = self.b @ self.sigma(v) @ self.b.T  # (W, 2, 2)
        return h, bsb[:, None] + self.cov[None]

    def _marginal(self, v: np.ndarray, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """det M_t and the quadratic form (η̂_t − h_t)ᵀ M_t⁻¹ (η̂_t − h_t) → (W, T) each;
        closed-form 2×2 algebra."""
        h, m = self._mean_cov(v, theta)
        r0 = self.eta[None, :, 0] - h[..., 0]
        r1 = self.eta[None, :, 1] - h[..., 1]
        det = m[..., 0, 0] * m[..., 1, 1] - m[..., 0, 1] * m[..., 1, 0]
        quad = (m[..., 1, 1] * r0**2 - 2 * m[..., 0, 1] * r0 * r1 + m[..., 0, 0] * r1**2) / det
        return det, quad

    def _from_eta(self, eta: np.ndarray) -> np.ndarray:
        """η (..., 2) → the per-test fit's parameters (first, second), as in ``params``."""
        g = eta[..., 1]
        second = np.exp(g) if self.layout.log_second else g
        return np.stack([np.exp(eta[..., 0] - g * self.ln_zref), second], axis=-1)

    def log_likelihood(self, v: np.ndarray, params: np.ndarray) -> np.ndarray:
        """Pointwise log-likelihood of each test's fit ``params`` (T, 2) → (W, T).

        The bivariate normal density of η̂_t under the marginal likelihood, carried over to
        the per-test fit's own parameters (k̂_t, n̂_t) or (τ̂_max,t, K̂_t) by the Jacobian
        |∂η/∂params| = 1/k̂_t (1/(τ̂_max,t K̂_t) for shear), so it is a density of what
        ``observed_data`` stores.
        """
        with np.errstate(all="ignore"):
            det, quad = self._marginal(v, self.theta(v))
        log_jac = -np.log(params[:, 0])
        if self.layout.log_second:
            log_jac = log_jac - np.log(params[:, 1])
        return -np.log(2.0 * np.pi) - 0.5 * (np.log(det) + quad) + log_jac[None]

    def replicate(self, v: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Replicated per-test fits, η̂_t ~ N(h_t, B Σ Bᵀ + C_t), as parameters → (W, T, 2)."""
        h, m = self._mean_cov(v, self.theta(v))
        chol = np.linalg.cholesky(m)
        eta = h + np.einsum("wtij,wtj->wti", chol, rng.standard_normal(h.shape))
        return self._from_eta(eta)

    def summaries(self, chain: np.ndarray) -> dict[str, np.ndarray]:
        """Soil-level parameters and scatter of a chain (walkers, draws, dim), by name."""
        flat = chain.reshape(-1, self.dim)
        theta = self.theta(flat)
        scatter = self.scatter(flat)
        shape = chain.shape[:2]
        names = [f"mu_{n}" for n in self.model.param_names]
        out = {n: theta[:, i].reshape(shape) for i, n in enumerate(names)}
        return out | {
            n: x.reshape(shape) for n, x in zip(self.layout.scatter, scatter, strict=True)
        }

    def new_preparation(self, v: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """θ of a new preparation, one per row of ``v``: moduli·e^(ε − δ ln z_s), g + δ."""
        theta = self.theta(v)
        chol = np.linalg.cholesky(self.sigma(v))
        e = np.einsum("wij,wj->wi", chol, rng.standard_normal((v.shape[0], 2)))
        linear = self.layout.linear(theta) * np.exp(e[:, :1] - e[:, 1:] * self.ln_zs)
        return self.layout.assemble(linear, self.layout.second(theta) + e[:, 1])


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
    """Sample the population model (see the module docstring) of a soil model.

    Parameters are as for :func:`soilstats.bayes.sample_posterior`.  ``model`` is
    ``"bekker"``, ``"bernstein"`` or ``"janosi"`` (:data:`POPULATION_MODELS`); Mohr–Coulomb
    alone has no per-test curve to scatter and stays a pooled question.  The default prior
    of the soil-level parameters is flat in the log of the measured scales (module docstring,
    "Priors"); a prior given in ``priors`` for any linear modulus (kc, kφ; k; c, φ), or for
    Janosi's K, replaces that group's log-flat factor.

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
        (:mod:`soilstats.bayes.predictive`).
    """
    spec = get_model(model)
    if spec.name not in _LAYOUTS:
        raise ValueError(
            f"the population model is implemented for {list(POPULATION_MODELS)} "
            f"(got {spec.name!r}); use sample_posterior for the pooled model"
        )
    layout = _LAYOUTS[spec.name]
    if spec is JANOSI:
        problem, lsq = pooled_problem(campaign, spec.name, **selection)
        fits = shear_tests(problem)
    else:
        pooled = pool_sinkage(campaign, points_per_test=points_per_test, **selection)
        lsq = fit_sinkage(campaign, spec.name, points_per_test=points_per_test, **selection)
        fits = sinkage_tests(pooled, spec)
    t = len(fits.test_ids)
    if t < 3:
        raise ValueError(
            f"the population model needs at least 3 tests with a usable per-test fit; the "
            f"selection has {t} (failed: {fits.failed or 'none'})"
        )
    theta0 = lsq.params.to_numpy()
    if spec is JANOSI:
        ln_zref, ln_zs, coords = 0.0, 0.0, Coordinates()
    else:
        ln_zref = reference_sinkage(fits.params, fits.cov)
        ln_zs = scatter_sinkage(fits, pooled.x["z_m"], ln_zref)
        base = sampling_coordinates(spec, theta0, lsq.cov.to_numpy(), np.unique(fits.covariate))
        coords = base if base.identity else Coordinates(moduli=base.moduli, ln_zref=ln_zref)
    eta, cov = to_eta(fits.params, fits.cov, ln_zref, layout.log_second)
    given = set(priors or {})
    pops = _Population(
        spec,
        layout,
        eta,
        cov,
        fits.design,
        ln_zref,
        resolve_priors(spec.name, spec.param_names, priors),
        coords,
        reference_rows=_reference_rows(fits.design, fits.covariate),
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
        raise ValueError(
            f"the pooled least-squares estimate {dict(zip(spec.param_names, theta0, strict=True))}"
            f" gives a non-positive {layout.per_test[0]} or {layout.per_test[1]} for some test; "
            "the population model cannot start there"
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
    if spec is JANOSI:
        curves = response_dataset(problem)
    else:
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
    units = dict(zip(names, spec.units, strict=True))
    return finish(
        idata, spec.name, "population", names, units, (*var_names, *names), run, notes, lsq
    )


def _population_notes(pops: _Population, fits: PerTestFits, ln_zref: float) -> list[str]:
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


def _population_idata(pops: _Population, run, rng, fits: PerTestFits, curves=None):
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
    log_lik = xr.Dataset(
        {
            "eta_hat": (
                ("chain", "draw", "test"),
                pops.log_likelihood(flat, fits.params).reshape(chains, draws, -1),
            )
        },
        coords=coords | test_coords,
        attrs={"model": "one term per test (leave-one-test-out)", "thinned": 0},
    )
    groups = {"observed_data": observed, "posterior_predictive": ppc, "log_likelihood": log_lik}
    if curves is not None:
        groups["constant_data"] = curves
    return az.InferenceData(posterior=posterior, sample_stats=stats, **groups)
