"""Sampling coordinates: where the power-law posteriors are close to normal.

The pressure–sinkage models (Bekker, Eq. 7; Bernstein, Eq. 8) are p = k_b·zⁿ with a plate
modulus k_b = kc/b + kφ (Bekker) or k_b = k (Bernstein).  Over the sinkages of a test (a few
cm, z ≪ 1 m) k and n trade off almost perfectly: the least-squares correlation of k and n is
typically 0.999, and for a soft soil with a large n the posterior of k is skewed (k is
log-normal-like with a relative sd of 10 % or more).  A sampler proposing in (k, n) then
mixes slowly: this is what gave R-hat 1.03–1.08 on Cullinan sand and soil02.

The sampler therefore works in the coordinates

    u_i = ln k_{b_i} + n·ln z_ref   (i = 1, …, m),      u_{m+1} = n,

where k_{b_i} are the plate moduli at the smallest and largest plate (Bekker, m = 2) or k
itself (Bernstein, m = 1) — any power law of the model record (``Model.power_law``), whose
basis at those plates gives them — and z_ref is chosen so that, at the least-squares estimate, every
u_i is uncorrelated with n (ln z_ref = −Cov(ln k_b, n)/Var(n), delta method on the Eq. 4
covariance).  exp(u_i) is the pressure at the reference sinkage on plate b_i, a quantity the
data pin directly.  The map is smooth and one-to-one on k_b > 0, so for Bekker the
constraint kc/b + kφ > 0 on every plate holds by construction (k_b is linear in 1/b, positive
at both extremes).

The density is transformed exactly: log p_u(u) = log p_θ(θ(u)) + log|det ∂θ/∂u|, with
log|det ∂θ/∂u| = Σ_i ln k_{b_i} − ln|det M| (M the linear map (kc, kφ) → (k_{b_1}, k_{b_2})).
The priors of :mod:`soilstats.bayes.priors` stay defined on θ; nothing is approximated.
Other models (Reece, Janosi, Mohr–Coulomb) are sampled in their own parameters.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, cast

import numpy as np

from ..models import Model

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

__all__ = ["Coordinates", "sampling_coordinates"]


@dataclass(frozen=True)
class Coordinates:
    """A one-to-one map between model parameters θ and sampling coordinates u.

    The identity unless ``moduli`` is given.  With ``moduli`` (the (m, m) matrix M taking
    the model's moduli to the plate moduli) the first m entries of u are
    ln(M·k) + n·ln z_ref and the last is n.

    Attributes
    ----------
    moduli : ndarray or None
        M; None for the identity.
    ln_zref : float
        ln of the reference sinkage z_ref [m].
    """

    moduli: np.ndarray | None = None
    ln_zref: float = 0.0
    _inverse: np.ndarray | None = field(default=None, repr=False)
    _log_det: float = 0.0

    def __post_init__(self) -> None:
        if self.moduli is not None:
            m = np.asarray(self.moduli, float)
            object.__setattr__(self, "_inverse", np.linalg.inv(m))
            object.__setattr__(self, "_log_det", float(np.log(abs(np.linalg.det(m)))))

    @property
    def identity(self) -> bool:
        return self.moduli is None

    def to_theta(self, u: np.ndarray) -> np.ndarray:
        """θ for each row of ``u`` (W, p)."""
        u = np.atleast_2d(u)
        if self.moduli is None:  # the identity
            return u
        m = self.moduli.shape[0]
        n = u[:, m]
        kb = np.exp(u[:, :m] - n[:, None] * self.ln_zref)
        return np.column_stack([kb @ cast(np.ndarray, self._inverse).T, n])

    def to_theta_chain(self, u: np.ndarray) -> np.ndarray:
        """θ for a chain ``u`` of any leading shape (..., p)."""
        u = np.asarray(u, float)
        return self.to_theta(u.reshape(-1, u.shape[-1])).reshape(u.shape)

    def to_u(self, theta: np.ndarray) -> np.ndarray:
        """u for each row of ``theta`` (W, p); NaN where a plate modulus is ≤ 0."""
        theta = np.atleast_2d(np.asarray(theta, float))
        if self.moduli is None:  # the identity
            return theta
        m = self.moduli.shape[0]
        kb = theta[:, :m] @ self.moduli.T
        with np.errstate(invalid="ignore", divide="ignore"):
            lk = np.where(kb > 0, np.log(np.where(kb > 0, kb, 1.0)), np.nan)
        return np.column_stack([lk + theta[:, m : m + 1] * self.ln_zref, theta[:, m]])

    def log_jacobian(self, u: np.ndarray) -> np.ndarray:
        """log|det ∂θ/∂u| for each row of ``u`` (W, p) → (W,)."""
        u = np.atleast_2d(u)
        if self.moduli is None:  # the identity
            return np.zeros(u.shape[0])
        m = self.moduli.shape[0]
        return np.sum(u[:, :m], axis=1) - m * u[:, m] * self.ln_zref - self._log_det

    def jacobian(self, theta: np.ndarray) -> np.ndarray:
        """∂u/∂θ (p, p) at one parameter vector (for the delta-method covariance of u)."""
        theta = np.asarray(theta, float)
        p = theta.size
        if self.moduli is None:  # the identity
            return np.eye(p)
        m = self.moduli.shape[0]
        kb = self.moduli @ theta[:m]
        out = np.zeros((p, p))
        out[:m, :m] = self.moduli / kb[:, None]
        out[:m, m] = self.ln_zref
        out[m, m] = 1.0
        return out

    def covariance(self, theta: np.ndarray, cov: np.ndarray) -> np.ndarray:
        """Delta-method covariance of u at ``theta`` from the covariance ``cov`` of θ."""
        j = self.jacobian(theta)
        return j @ np.asarray(cov, float) @ j.T


def _plate_moduli(model: Model, plate_sizes: ArrayLike) -> np.ndarray | None:
    """M: the power law's basis g(b) (``Model.power_law``) at the smallest and largest plate,
    one row per plate, so that M·a are the plate moduli (Bekker: rows (1/b, 1)); one row for
    a model with one modulus (Bernstein: M = 1).  None where the model is no power law or the
    plates cannot separate its moduli (one plate size, or more than two moduli)."""
    if model.power_law is None:
        return None
    b = np.asarray(plate_sizes, float)
    q = model.n_params - 1
    if q == 1:
        ends = b[:1] if b.size else np.ones(1)
    elif q == 2 and b.size >= 2:
        ends = np.array([b.min(), b.max()])
    else:
        return None
    data = {"b_m": ends, "z_m": np.ones(ends.size)}
    basis, _ = model.power_law(model.x_from(data) if model.columns else ends)
    return np.column_stack([np.broadcast_to(np.asarray(g, float), ends.shape) for g in basis])


def sampling_coordinates(
    model: Model, theta: np.ndarray, cov: np.ndarray, plate_sizes: np.ndarray
) -> Coordinates:
    """The coordinates the sampler should use for ``model`` (see the module docstring).

    Parameters
    ----------
    model : Model
        The soil model.
    theta, cov : ndarray
        Least-squares estimate and its covariance (Eq. 4), used to choose z_ref.
    plate_sizes : ndarray
        Distinct plate sizes b [m] of the data (Bekker: the smallest and largest are used).

    Returns
    -------
    Coordinates
        Log-modulus coordinates for Bekker and Bernstein when every plate modulus is
        positive at ``theta``; the identity otherwise.
    """
    theta = np.asarray(theta, float)
    moduli = _plate_moduli(model, plate_sizes)
    if moduli is None:
        return Coordinates()
    m = moduli.shape[0]
    kb = moduli @ theta[:m]
    if not np.all(kb > 0) or not np.all(np.isfinite(cov)):
        return Coordinates()
    # Cov(ln k_b, n) by the delta method; ln z_ref makes the mean of them vanish.
    grad = moduli / kb[:, None]  # ∂ ln k_b / ∂(moduli)
    cov_lk_n = grad @ np.asarray(cov, float)[:m, m]
    var_n = float(cov[m, m])
    ln_zref = float(-np.mean(cov_lk_n) / var_n) if var_n > 0 else 0.0
    return Coordinates(moduli=moduli, ln_zref=ln_zref)
