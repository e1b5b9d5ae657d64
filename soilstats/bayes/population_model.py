"""The population (hierarchical) model: every preparation draws its own soil parameters.

This module is the model — its layouts and its marginal log-density; sampling it, and
assembling the result, is :mod:`soilstats.bayes.population`.

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

from collections.abc import Iterable, Mapping

import numpy as np
import pandas as pd

from ..models import MODELS
from ..models.base import Model, PopulationLayout
from ..models.priors import Prior
from .likelihood import PooledProblem
from .transforms import Coordinates

__all__ = ["LAYOUTS", "POPULATION_MODELS", "Layout", "PopulationModel", "reference_rows"]


#: How one soil model maps onto the population model: the record's ``population``
#: (:class:`soilstats.models.base.PopulationLayout`; see the module docstring).
Layout = PopulationLayout


class _Layouts(Mapping):
    """``{model name: Layout}`` of every registered model with a population model, read from
    its record (``Model.population``) when asked."""

    def __getitem__(self, name: str) -> Layout:
        layout = MODELS[name].population if name in MODELS else None
        if layout is None:
            raise KeyError(name)
        return layout

    def __iter__(self):
        return iter([n for n, m in MODELS.items() if m.population is not None])

    def __len__(self) -> int:
        return sum(m.population is not None for m in MODELS.values())


LAYOUTS: Mapping[str, Layout] = _Layouts()
#: The paper's soil models with a population model (a registered model with a
#: ``population`` layout has one too: see :data:`LAYOUTS`).
POPULATION_MODELS = tuple(LAYOUTS)


def reference_rows(design: np.ndarray, covariate: np.ndarray) -> np.ndarray:
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


class PopulationModel:
    """Walker-vectorised log-posterior of v = (u(θ), ln s_ε, ln s_δ, atanh ρ)."""

    def __init__(
        self,
        model: Model,
        layout: Layout,
        eta: np.ndarray,
        cov: np.ndarray,
        design: np.ndarray,
        ln_zref: float,
        priors: tuple[Prior, ...],
        coords: Coordinates,
        *,
        reference_rows: np.ndarray,
        log_flat: tuple[bool, bool] = (True, True),
        ln_zs: float | None = None,
    ) -> None:
        self.model, self.layout, self.eta, self.cov, self.priors = model, layout, eta, cov, priors
        self.coords, self.ln_zref, self.design = coords, ln_zref, design
        # Tests share few design rows (one per plate size or normal pressure): the log of
        # a_tᵀm is taken once per row and walker, then spread over the tests.
        rows, self._row_of_test = np.unique(np.asarray(design, float), axis=0, return_inverse=True)
        self._rows = rows
        self._row_of_test = np.asarray(self._row_of_test).reshape(-1)
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
        inputs = max(len(model.columns), 1)  # the prior needs no data: x of the right shape
        x = np.ones((inputs, 1)) if inputs > 1 else np.ones(1)
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

    def log_priors(self, v: np.ndarray, given: Iterable[str]) -> tuple[np.ndarray, np.ndarray]:
        """(default, given) log prior densities at the rows of ``v``, each in the quantities'
        own scale (no Jacobian of the sampling coordinates): the default is the soil-level
        priors not in ``given``, the log-flat factor, the half-Cauchy scatter scales and the
        Beta(2, 2) correlation; the given one the user's soil-level priors
        (:mod:`soilstats.bayes.prior_sensitivity`)."""
        theta, chosen = self.theta(v), set(given)
        default = self.log_scale_prior(theta)
        user = np.zeros(theta.shape[0])
        for i, (name, prior) in enumerate(zip(self.model.param_names, self.priors, strict=True)):
            if name in chosen:
                user = user + prior.logpdf(theta[:, i])
            else:
                default = default + prior.logpdf(theta[:, i])
        s = np.exp(v[:, self.p : self.p + 2])
        default = default - np.sum(np.log1p((s / self.scales) ** 2), axis=1)
        return default + np.log1p(-(np.tanh(v[:, self.p + 2]) ** 2)), user

    def describe_priors(self) -> str:
        """The soil-level priors in words (notes, ``posterior.attrs['priors']``)."""
        names = self.model.param_names
        own = "; ".join(f"{n}: {p}" for n, p in zip(names, self.priors, strict=True))
        if self.layout.log_second:
            scales = "tau_max at the smallest and largest normal pressure"
        elif self.reference_rows.shape[0] == 1:
            scales = names[0]
        else:
            modulus = self.model.modulus.text if self.model.modulus is not None else "moduli"
            scales = f"the plate modulus {modulus} at the smallest and largest plate"
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
        h0, g, (m00, m01, m11) = self._moments(v, theta)
        h = np.stack([h0, np.broadcast_to(g[:, None], h0.shape)], axis=-1)
        m = np.empty((*h0.shape, 2, 2))
        m[..., 0, 0], m[..., 1, 1] = m00, m11
        m[..., 0, 1] = m[..., 1, 0] = m01
        return h, m

    def _moments(
        self, v: np.ndarray, theta: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """h_t's first row (W, T), g (W,) and the three entries of M_t = B Σ Bᵀ + C_t, each
        broadcast to (W, T): the 2×2 algebra written out, no (W, T, 2, 2) stack."""
        kb = self.layout.linear(theta) @ self._rows.T  # (W, rows)
        g = self.layout.second(theta)
        h0 = np.log(np.where(kb > 0, kb, np.nan)) + (g * self.ln_zref)[:, None]
        h0 = h0[:, self._row_of_test]  # (W, T)
        se, sd, rho = self.scatter(v)
        # B Σ Bᵀ with B = [[1, c], [0, 1]], c = ln z_ref − ln z_s.
        c = self.b[0, 1]
        s01 = rho * se * sd
        a00 = se**2 + 2 * c * s01 + c**2 * sd**2
        a01 = s01 + c * sd**2
        a11 = sd**2
        cov = self.cov
        return (
            h0,
            g,
            (
                a00[:, None] + cov[None, :, 0, 0],
                a01[:, None] + cov[None, :, 0, 1],
                a11[:, None] + cov[None, :, 1, 1],
            ),
        )

    def _marginal(self, v: np.ndarray, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """det M_t and the quadratic form (η̂_t − h_t)ᵀ M_t⁻¹ (η̂_t − h_t) → (W, T) each;
        closed-form 2×2 algebra."""
        h0, g, (m00, m01, m11) = self._moments(v, theta)
        r0 = self.eta[None, :, 0] - h0
        r1 = self.eta[None, :, 1] - g[:, None]
        det = m00 * m11 - m01 * m01
        quad = (m11 * r0 * r0 - 2 * m01 * r0 * r1 + m00 * r1 * r1) / det
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
