"""Priors on one parameter: the densities a soil model's record names as its physics defaults.

A prior is a (possibly truncated, possibly improper) density on one parameter in the
parameter's own unit (φ in degrees).  Each :class:`~soilstats.models.Model` carries its
default prior per parameter (``Model.priors``); :mod:`soilstats.bayes.priors` resolves a
user's overrides against them.  Here, beside the record, so that a model defined in one file
states its priors without importing the sampler.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError

__all__ = ["FLAT", "NON_NEGATIVE", "POSITIVE", "Normal", "Prior", "Uniform"]


@dataclass(frozen=True)
class Prior:
    """Base class: a log-density on one parameter, vectorised over walkers."""

    lower: float = -np.inf
    upper: float = np.inf

    def logpdf(self, x: np.ndarray) -> np.ndarray:
        """Log-density (up to a constant) at ``x``; ``-inf`` outside (lower, upper)."""
        raise NotImplementedError

    def _support(self, x: np.ndarray) -> np.ndarray:
        return (x > self.lower) & (x < self.upper)


@dataclass(frozen=True)
class Uniform(Prior):
    """Flat on the open interval (lower, upper); improper if either end is infinite."""

    closed_lower: bool = False  # include ``lower`` itself (c ≥ 0: cohesionless sand)

    def logpdf(self, x: np.ndarray) -> np.ndarray:
        inside = self._support(x) | (self.closed_lower & (x == self.lower))
        return np.where(inside, 0.0, -np.inf)

    def __str__(self) -> str:
        return f"flat on {'[' if self.closed_lower else '('}{self.lower:g}, {self.upper:g})"


@dataclass(frozen=True)
class Normal(Prior):
    """Normal(mu, sd) truncated to (lower, upper): an informative prior, e.g. from a handbook."""

    mu: float = 0.0
    sd: float = 1.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.sd) and self.sd > 0):
            raise InputError(f"Normal prior needs a finite sd > 0, got sd={self.sd!r}")
        if not np.isfinite(self.mu) or not self.lower < self.upper:  # NaN fails both
            raise InputError(
                f"Normal prior needs a finite mu and lower < upper, got mu={self.mu!r} on "
                f"({self.lower!r}, {self.upper!r})"
            )

    def logpdf(self, x: np.ndarray) -> np.ndarray:
        return np.where(self._support(x), -0.5 * ((x - self.mu) / self.sd) ** 2, -np.inf)

    def __str__(self) -> str:
        return f"normal({self.mu:g}, {self.sd:g}) on ({self.lower:g}, {self.upper:g})"


#: Flat on (0, ∞): a modulus or an exponent that must be positive.
POSITIVE = Uniform(0.0, np.inf)
#: Flat on ℝ: what physics leaves open (Bekker's kc may take either sign).
FLAT = Uniform()
#: Flat on [0, ∞): c ≥ 0 (a cohesionless sand has c = 0).
NON_NEGATIVE = Uniform(0.0, np.inf, closed_lower=True)
