"""The :class:`Model` record: a soil equation with its analytic Jacobian, names, units, bounds."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

__all__ = ["Model", "PowerLawTerms", "separable_from_power_law"]


class PowerLawTerms:
    """w·f(x, θ) = Σᵢ aᵢ·w·gᵢ(x)·z^n for fixed inputs x and weights w, θ = (a₁ … a_q, n).

    The form of Bekker (Eq. 7: g = (1/b, 1), a = (kc, kφ)) and Bernstein (Eq. 8: g = 1,
    a = k), with z the sinkage in m: linear in every parameter but the exponent n.  Everything
    that does not depend on θ is computed once here and shared by the optimiser's closures and
    the variable projection of :func:`soilstats.fitting.separable.refine_power_law`, so one
    fit takes ln z once.

    Samples without contact (z ≤ 0) give p = 0 and a zero Jacobian row (z^n has no real value
    there): their weight is folded to zero in ``rows`` and their ln z set to 0.

    Attributes
    ----------
    rows : numpy.ndarray
        (q, N) weighted basis rows Uᵢ = w·gᵢ(x)·[z > 0], so that w·f = (aᵀU)·z^n.
    log_z : numpy.ndarray
        (N,) ln z (0 where z ≤ 0), so that ∂(w·f)/∂n = w·f·ln z.
    """

    __slots__ = ("_block", "_f", "_key", "_n", "_zn", "log_z", "rows")

    def __init__(self, g: Sequence, z, w) -> None:
        z = np.asarray(z, dtype=float)
        w = np.asarray(w, dtype=float)
        # The usual case, one reduction (in C: ndarray.min goes through a Python wrapper);
        # a NaN fails it and is masked below.
        if np.minimum.reduce(z) > 0:
            self.log_z = np.log(z)
        else:
            contact = z > 0
            self.log_z = np.log(np.where(contact, z, 1.0))
            w = np.where(contact, w, 0.0)
        rows = np.empty((len(g), z.size))
        for i, g_i in enumerate(g):
            np.multiply(w, g_i, out=rows[i])
        self.rows = rows
        self._n = self._zn = self._key = self._f = self._block = None

    def power(self, n: float) -> np.ndarray:
        """z^n (N,), the last one kept: f, J and the projection ask for the same n in turn."""
        if n != self._n:
            self._zn = np.exp(self.log_z * n)
            self._n = n
        return self._zn

    def basis(self, n: float) -> np.ndarray:
        """U(n) = rows·z^n, (q, N): the weighted basis of the linear parameters."""
        return self.rows * self.power(n)

    def f(self, theta) -> np.ndarray:
        """w·f(x, θ) = aᵀU(n), (N,) in the units of w·p.

        U(n) is formed in the first rows of the Jacobian's array, which J at the same θ —
        what the optimiser asks for next — then completes with one product.
        """
        theta = np.asarray(theta, dtype=float)
        key = theta.tolist()
        q = len(key) - 1
        block = np.empty((q + 2, self.log_z.size))
        zn = self.power(key[-1])
        for i in range(q):  # row by row: cheaper than numpy's broadcast of zn over q rows
            np.multiply(self.rows[i], zn, out=block[i])
        value = theta[:q] @ block[:q]  # Σ aᵢ·Uᵢ in one BLAS call
        self._key, self._f, self._block = key, value, block
        return value

    def jacobian_block(self, theta) -> np.ndarray:
        """(q + 2, N): the rows of (w·∂f/∂θ)ᵀ — Uᵢ(n) and w·f·ln z — and a last row that is
        the caller's to overwrite (the optimiser puts the residuals there, so that JᵀJ and
        Jᵀr come from one matrix product; see :func:`~soilstats.fitting.levenberg_marquardt
        .levenberg_marquardt`).  A new array per θ: an earlier J is never overwritten."""
        theta = np.asarray(theta, dtype=float)
        # The optimiser asks for J at the point it has just evaluated: reuse U and w·f.
        if theta.tolist() != self._key:
            self.f(theta)
        block, q = self._block, theta.size - 1
        np.multiply(self._f, self.log_z, out=block[q])
        return block

    def jac(self, theta) -> np.ndarray:
        """(w·∂f/∂θ)ᵀ, (q + 1, N): rows Uᵢ·z^n and w·f·ln z."""
        theta = np.asarray(theta, dtype=float)
        return self.jacobian_block(theta)[: theta.size]


def separable_from_power_law(power_law: Callable, x, weights) -> tuple[Callable, np.ndarray]:
    """``Model.separable`` of a power-law model, from its ``power_law``: (n ↦ U(n), ln z)."""
    g, z = power_law(x)
    terms = PowerLawTerms(g, z, weights)
    return terms.basis, terms.log_z


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
        before its LM (see :mod:`soilstats.fitting.separable`); for a power-law model,
        :func:`separable_from_power_law` (the batched bootstrap uses it).
    power_law : callable, optional
        For the same models, ``power_law(x) -> (g, z)``: the q basis functions gᵢ(x) (arrays
        of shape (N,) or scalars) and the sinkage z (N,).  Gives :class:`PowerLawTerms`, from
        which the identification takes its closures and its variable projection (one ln z
        per fit, the projection in scalar arithmetic on precomputed moments).
    linear_form : callable, optional
        For models linear in their parameters after a change of variables (Mohr–Coulomb:
        c and tan φ): ``linear_form(x) -> (X, to_params)`` with the (N, p) design X and
        ``to_params`` mapping (B, p) coefficients of X to (B, p) model parameters.  The
        bootstrap then solves every resample in closed form, as the fit itself is solved.
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
    power_law: Callable | None = field(default=None, repr=False)
    linear_form: Callable | None = field(default=None, repr=False)

    def power_terms(self, x, weights) -> PowerLawTerms | None:
        """:class:`PowerLawTerms` of a power-law model for ``x`` and weights, else None."""
        if self.power_law is None:
            return None
        g, z = self.power_law(x)
        return PowerLawTerms(g, z, weights)

    def evaluators(self, x, weights) -> tuple[Callable, Callable]:
        """(θ ↦ w·f(x, θ), θ ↦ (w·∂f/∂θ)ᵀ of shape (p, N)) for fixed ``x`` and weights ``w``.

        The model's fast closures where it has them (see ``prepare`` and ``power_law``), else
        wrappers of ``func`` and ``jac``.
        """
        w = np.asarray(weights, dtype=float)
        if self.prepare is not None:
            return self.prepare(x, w)
        if self.power_law is not None:
            terms = self.power_terms(x, w)
            return terms.f, terms.jac
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
