"""The pooled likelihood: the paper's weighted objective (Eq. 1) as a Gaussian model.

The least-squares fit of the paper minimises ½‖w·(y − f(x, θ))‖² with w = 1/max(p) per test
(Section 2.1).  Read as a probability model this is

    w_i·(y_i − f(x_i, θ)) ~ N(0, σ_w²)   independently,

i.e. each test's noise scales with its own pressure range (σ_w is dimensionless for the
sinkage weights, in Pa for unit weights).  σ_w is **marginalised analytically** under the
Jeffreys prior p(σ_w) ∝ 1/σ_w:

    p(θ | y) ∝ p(θ) · S(θ)^(−N/2),   S(θ) = Σ_i w_i²·(y_i − f(x_i, θ))²,

so the sampler works in the model's own dimension, and its posterior reproduces the
Student-t intervals of least squares for a linear model.  Draws of σ_w are then taken from
their exact conditional σ_w² | θ, y ~ Inv-Gamma(N/2, S(θ)/2), so (θ, σ_w) is a joint draw.

Pointwise, the same model gives each observation the density

    p(y_i | θ, σ_w) = N(y_i; f(x_i, θ), (σ_w / w_i)²),

which :meth:`PooledProblem.replicate` samples (posterior-predictive data) and
:meth:`PooledProblem.log_likelihood` sums over the samples of each test (per joint draw
(θ, σ_w): one term per test for PSIS-LOO and WAIC, see :mod:`soilstats.bayes.predictive`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ..models import Model
from .priors import Prior

if TYPE_CHECKING:
    from ..models.base import Value

__all__ = ["PooledProblem"]


@dataclass(frozen=True, eq=False)
class PooledProblem:
    """Data, model and priors of a pooled posterior, with a walker-vectorised log-density.

    Attributes
    ----------
    model : Model
        The soil model.
    x : ndarray
        Inputs as the model takes them: (N,) or (k, N).
    y, w : ndarray, shape (N,)
        Measurements (Pa) and the weights w_r of Eq. 1.
    test_index : ndarray of int, shape (N,)
        Row of ``tests`` each sample belongs to.
    tests : DataFrame
        One row per test (``test_id`` …), from the identification's bookkeeping.
    priors : tuple of Prior
        One per parameter.
    plate_sizes : ndarray
        Distinct plate sizes b [m] (sinkage models; used for the kc/b + kφ > 0 constraint).
    inputs : dict
        Every per-sample input of the pooled data by name with its SI unit (``b_m``, ``z_m``
        or ``sigma_Pa``, ``j_m``), including those the model does not take (Mohr–Coulomb's
        shear displacement): coordinates of the stored data and of the figures.
    """

    model: Model
    x: np.ndarray
    y: np.ndarray
    w: np.ndarray
    test_index: np.ndarray
    tests: pd.DataFrame
    priors: tuple[Prior, ...]
    plate_sizes: np.ndarray = field(default_factory=lambda: np.empty(0))
    inputs: dict = field(default_factory=dict)
    if TYPE_CHECKING:  # set by __post_init__ (the power-law ones for power-law models only)
        _wy: np.ndarray = field(init=False)
        _wy2: float = field(init=False)
        _lnz: np.ndarray = field(init=False)
        _F: np.ndarray = field(init=False)
        _G: np.ndarray = field(init=False)
        _m: int = field(init=False)

    def __post_init__(self) -> None:
        # Precomputed pieces of the residual: w·y, and for power-law models ln z (the
        # identification has already excluded z ≤ 0, so the logarithm is finite).
        wy = self.w * self.y
        object.__setattr__(self, "_wy", wy)
        object.__setattr__(self, "_wy2", float(wy @ wy))
        # Power-law models (``Model.power_law``) are linear in their moduli, so S(θ) =
        # Σ(wy)² − 2 kᵀF(n) + kᵀG(n)k with F(n) = Σ wy·a·zⁿ and G(n) = Σ a aᵀ z²ⁿ (a = w·g,
        # g the basis: (1/b, 1) for Bekker, 1 for Bernstein): one exp per sample and walker,
        # the sums by matrix products.  ln z is finite because the identification has
        # excluded z ≤ 0.
        if self.model.power_law is None:
            return
        basis, z = self.model.power_law(self.x)
        z = np.asarray(z, float)
        a = self._weighted_basis(basis)
        object.__setattr__(self, "_lnz", np.log(z))
        object.__setattr__(self, "_F", a * wy[:, None])  # (N, m)
        pairs = np.einsum("ni,nj->nij", a, a).reshape(z.size, -1)
        object.__setattr__(self, "_G", pairs)  # (N, m²)
        object.__setattr__(self, "_m", a.shape[1])

    def _weighted_basis(self, basis: Sequence[Value]) -> np.ndarray:
        """(N, m) a = w·g.  A model whose plate modulus k_b(b; moduli) the record states
        (``Model.modulus``: Bekker's kc/b + kφ) gives each column as that modulus at the
        weighted unit moduli, w/b and w: the same numbers as the expression itself rounds."""
        modulus = self.model.modulus
        if modulus is None or "b_m" not in self.model.columns:
            return np.column_stack([self.w * g for g in basis])
        b = self.x[self.model.columns.index("b_m")]
        m, zero = len(basis), np.zeros_like(self.w)
        unit = [[self.w if j == i else zero for j in range(m)] for i in range(m)]
        rest = [zero] * (len(modulus.params) - m)
        return np.column_stack([modulus.modulus(b, *cols, *rest) for cols in unit])

    @property
    def n_obs(self) -> int:
        return int(self.y.size)

    def weighted_prediction(self, theta: np.ndarray) -> np.ndarray:
        """w·f(x, θ) for each row of ``theta`` (W, p) → (W, N)."""
        return self.w * self.prediction(theta)

    def prediction(self, theta: np.ndarray) -> np.ndarray:
        """f(x, θ) in the measurement's unit (Pa) for each row of ``theta`` → (W, N)."""
        theta = np.atleast_2d(theta)
        cols = [theta[:, i : i + 1] for i in range(theta.shape[1])]
        return np.broadcast_to(
            np.asarray(self.model.func(self.x, *cols), float), (theta.shape[0], self.n_obs)
        )

    def rss(self, theta: np.ndarray) -> np.ndarray:
        """S(θ) = Σ w²(y − f)² for each row of ``theta`` → (W,)."""
        theta = np.atleast_2d(theta)
        if hasattr(self, "_lnz"):
            m = self._m
            k, n = theta[:, :m], theta[:, m]
            zn = np.exp(n[:, None] * self._lnz)  # (W, N): the one costly step
            f = zn @ self._F  # (W, m)
            g = ((zn * zn) @ self._G).reshape(-1, m, m)  # (W, m, m)
            s = self._wy2 - 2.0 * np.einsum("wi,wi->w", k, f) + np.einsum("wi,wij,wj->w", k, g, k)
            # The expansion loses digits only when S ≪ Σ(wy)², i.e. near-noiseless data;
            # recompute those walkers directly.
            close = s < 1e-8 * self._wy2
            if np.any(close):
                s[close] = self._rss_direct(theta[close])
            return s
        return self._rss_direct(theta)

    def _rss_direct(self, theta: np.ndarray) -> np.ndarray:
        r = self._wy - self.weighted_prediction(theta)
        return np.einsum("ij,ij->i", r, r)

    def log_prior(self, theta: np.ndarray) -> np.ndarray:
        """Sum of the parameters' log-priors, with the physical constraints → (W,)."""
        theta = np.atleast_2d(theta)
        out = np.zeros(theta.shape[0])
        for i, prior in enumerate(self.priors):
            out += prior.logpdf(theta[:, i])
        modulus = self.model.modulus
        if self.plate_sizes.size and modulus is not None:
            # Positive pressure on every plate (the record's plate-modulus rule): kc/b + kφ > 0
            # (Bekker), k1 + k2·b > 0 (Reece).
            b = self.plate_sizes[None, :]
            k = modulus.modulus(b, *(theta[:, i : i + 1] for i in range(theta.shape[1])))
            out = np.where(np.all(k > 0, axis=1), out, -np.inf)
        return out

    def log_prob(self, theta: np.ndarray) -> np.ndarray:
        """Log posterior density (σ_w marginalised) for walkers ``theta`` (W, p) → (W,)."""
        theta = np.atleast_2d(theta)
        lp = self.log_prior(theta)
        ok = np.isfinite(lp)
        out = np.full(theta.shape[0], -np.inf)
        if ok.any():
            with np.errstate(all="ignore"):
                s = self.rss(theta[ok])
            good = np.isfinite(s) & (s > 0)
            vals = np.where(
                good, lp[ok] - 0.5 * self.n_obs * np.log(np.where(good, s, 1.0)), -np.inf
            )
            out[ok] = vals
        return out

    def draw_sigma_from_rss(self, s: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """σ_w drawn from Inv-Gamma(N/2, S/2) for given values S(θ) (W,) → (W,)."""
        s = np.asarray(s, float)
        return np.sqrt(s / (2.0 * rng.gamma(0.5 * self.n_obs, 1.0, size=s.shape)))

    @property
    def test_rows(self) -> np.ndarray:
        """Rows of ``tests`` that have samples, in order: the columns of :meth:`log_likelihood`."""
        return np.unique(self.test_index)

    def log_likelihood(self, theta: np.ndarray, sigma: np.ndarray) -> np.ndarray:
        """Log-likelihood of each test, Σ_{i in test} log N(y_i; f(x_i, θ), (σ_w/w_i)²) → (S, T).

        ``theta`` (S, p) and ``sigma`` (S,) are joint posterior draws of the parameters and
        of σ_w; columns are the tests of :attr:`test_rows`.  Draws are evaluated a few at a
        time (about 2¹⁸ values), which bounds the working memory and keeps it in cache.
        """
        theta = np.atleast_2d(np.asarray(theta, float))
        sigma = np.asarray(sigma, float).reshape(-1, 1)
        order = np.argsort(self.test_index, kind="stable")
        _, starts = np.unique(self.test_index[order], return_index=True)
        counts = np.diff(np.append(starts, self.n_obs))
        const = np.add.reduceat(np.log(self.w[order]), starts) - 0.5 * np.log(2 * np.pi) * counts
        # Samples already grouped by test (the usual case): no copy.
        columns = slice(None) if np.array_equal(order, np.arange(self.n_obs)) else order
        out = np.empty((theta.shape[0], starts.size))
        block = max(1, 2**18 // self.n_obs)
        for start in range(0, theta.shape[0], block):
            stop = start + block
            r = self._wy - self.weighted_prediction(theta[start:stop])
            rss = np.add.reduceat((r * r)[:, columns], starts, axis=1)  # S_t(θ), (block, T)
            s = sigma[start:stop]
            out[start:stop] = const - counts * np.log(s) - 0.5 * rss / (s * s)
        return out

    def replicate(
        self, theta: np.ndarray, sigma: np.ndarray, rng: np.random.Generator
    ) -> np.ndarray:
        """Replicated data y_rep ~ N(f(x, θ), (σ_w/w)²), one row per joint draw → (S, N)."""
        theta = np.atleast_2d(np.asarray(theta, float))
        sigma = np.asarray(sigma, float).reshape(-1, 1)
        mean = self.prediction(theta)
        return mean + sigma / self.w * rng.standard_normal(mean.shape)
