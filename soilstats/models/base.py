"""The :class:`Model` record: a soil equation with its analytic Jacobian, names, units, bounds."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

__all__ = ["Model"]


@dataclass(frozen=True)
class Model:
    """A soil model y = f(x, θ) as the identification needs it.

    Attributes
    ----------
    name : str
        Short name used throughout (``"bekker"``, ``"janosi"`` …).
    equation : str
        Where the equation stands in the paper (e.g. ``"Eq. 7"``) and its formula.
    inputs : tuple of str
        Meaning and unit of each row of ``x`` (``x`` is 1-D for one input, shape (k, N) for k).
    param_names, units : tuple of str
        Parameter names (``params`` are indexed by them) and SI units.
    bounds : tuple of (low, high)
        Physically plausible range of each parameter.  Fits are *not* constrained to it
        (a constrained optimum has no valid covariance); a value outside is a health flag.
    func : callable
        ``func(x, *params) -> y`` vectorised over samples.
    jac : callable
        ``jac(x, *params) -> (N, p)`` analytic ∂f/∂θ.
    prepare : callable, optional
        ``prepare(x, w) -> (θ ↦ w·f, θ ↦ (w·∂f/∂θ)ᵀ)``: closures over ``x`` and the weights
        ``w`` (N,) that precompute what does not depend on θ (e.g. ln z, w/b), share work
        between f and its Jacobian, and return the Jacobian as (p, N) rows.  Same values as
        ``func``/``jac``; used by the optimiser where speed matters.
    separable : callable, optional
        For models linear in all parameters but a last exponent n (p = Σ aᵢ·gᵢ(x)·z^n):
        ``separable(x, w) -> (n ↦ U(n), ln z)`` with U the (q, N) weighted basis rows
        w·gᵢ(x)·z^n.  Lets the identification reach the optimum by variable projection
        before its LM (see :mod:`soilstats.fitting.separable`).
    """

    name: str
    equation: str
    inputs: tuple[str, ...]
    output: str
    param_names: tuple[str, ...]
    units: tuple[str, ...]
    bounds: tuple[tuple[float, float], ...]
    func: Callable[..., np.ndarray] = field(repr=False)
    jac: Callable[..., np.ndarray] = field(repr=False)
    prepare: Callable | None = field(default=None, repr=False)
    separable: Callable | None = field(default=None, repr=False)

    def evaluators(self, x, weights) -> tuple[Callable, Callable]:
        """(θ ↦ w·f(x, θ), θ ↦ (w·∂f/∂θ)ᵀ of shape (p, N)) for fixed ``x`` and weights ``w``.

        The model's fast closures where it has them (see ``prepare``), else wrappers of
        ``func`` and ``jac``.
        """
        w = np.asarray(weights, dtype=float)
        if self.prepare is not None:
            return self.prepare(x, w)
        w_col = w[:, None]

        def f_weighted(theta):
            return w * np.asarray(self.func(x, *theta), float)

        def jac_rows(theta):
            return (w_col * np.asarray(self.jac(x, *theta), float)).T

        return f_weighted, jac_rows

    def __call__(self, x, *params) -> np.ndarray:
        return self.func(x, *params)

    @property
    def n_params(self) -> int:
        return len(self.param_names)

    @property
    def unit_of(self) -> dict[str, str]:
        """SI unit of each parameter, by name."""
        return dict(zip(self.param_names, self.units, strict=True))

    @property
    def bounds_of(self) -> dict[str, tuple[float, float]]:
        """Physically plausible range of each parameter, by name."""
        return dict(zip(self.param_names, self.bounds, strict=True))
