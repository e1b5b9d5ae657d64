"""An independence Metropolis–Hastings move built from the Laplace approximation.

Near the least-squares optimum the posterior of a well-identified soil model is close to the
normal N(θ̂, Cov) of the paper's Eq. 4.  Proposing *independently* of the current walker from a
multivariate Student-t with that centre and an inflated scale gives nearly independent
successive draws (the ideal proposal of Tierney 1994, "Markov chains for exploring posterior
distributions", Ann. Stat. 22:1701, Sec. 2.3.3); the heavier-than-normal tails keep the
importance ratio bounded so the chain stays geometrically ergodic.  The move is exact
Metropolis–Hastings (emcee's :class:`~emcee.moves.MHMove` with the Hastings factor
ln q(x) − ln q(x′)), so where the approximation is poor it only mixes slower — it never biases.
emcee's differential-evolution moves are mixed in to keep the ensemble moving in that case.
"""

from __future__ import annotations

import numpy as np
from emcee.moves import MHMove
from numpy.typing import ArrayLike

__all__ = ["StudentIndependenceMove"]


class StudentIndependenceMove(MHMove):
    """Propose x′ ~ t_ν(centre, scale²·cov) for every walker, independently of x.

    Parameters
    ----------
    centre : ndarray, shape (p,)
        Proposal centre (the least-squares estimate θ̂).
    cov : ndarray, shape (p, p)
        Proposal covariance before scaling (the LS covariance of Eq. 4).
    dof : float
        Degrees of freedom ν of the Student-t proposal (heavier tails for smaller ν).
    scale : float
        Inflation of the proposal's scale relative to ``cov``.
    """

    def __init__(
        self, centre: ArrayLike, cov: ArrayLike, *, dof: float = 10.0, scale: float = 1.0
    ) -> None:
        self.centre = np.asarray(centre, float)
        self.scale = float(scale)
        self.chol = np.linalg.cholesky(np.asarray(cov, float)) * scale
        self.dof = float(dof)
        self.dim = self.centre.size
        super().__init__(self._propose, ndim=self.dim)

    def refit(self, centre: ArrayLike, cov: ArrayLike) -> None:
        """Move the proposal to a new centre and covariance (between runs, never within)."""
        self.centre = np.asarray(centre, float)
        self.chol = np.linalg.cholesky(np.asarray(cov, float)) * self.scale

    def log_density(self, x: np.ndarray) -> np.ndarray:
        """Log proposal density at ``x`` (W, p) up to a constant."""
        u = np.linalg.solve(self.chol, (x - self.centre).T).T
        return -0.5 * (self.dof + self.dim) * np.log1p(np.einsum("ij,ij->i", u, u) / self.dof)

    def sample(self, count: int, random: np.random.RandomState) -> np.ndarray:
        """``count`` proposals using emcee's RandomState ``random``."""
        normal = random.randn(count, self.dim)
        chi2 = random.chisquare(self.dof, size=count)
        return self.centre + (normal @ self.chol.T) * np.sqrt(self.dof / chi2)[:, None]

    def _propose(
        self, coords: np.ndarray, random: np.random.RandomState
    ) -> tuple[np.ndarray, np.ndarray]:
        proposal = self.sample(coords.shape[0], random)
        return proposal, self.log_density(coords) - self.log_density(proposal)
