"""``identify``: the paper's weighted nonlinear identification for any model f(x, *params)."""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from typing import Literal

import numpy as np

from ..errors import ConvergenceError, ConvergenceWarning
from ..models import Model
from .jacobian import make_jacobian
from .levenberg_marquardt import gram_matrix, levenberg_marquardt
from .result import FitResult, HealthFlag, epsilon
from .separable import refine_exponent

__all__ = ["RANK_CONDITION_LIMIT", "epsilon", "identify"]

# Above this cond(J) the covariance means nothing and the end point is degenerate (a minimum
# "at infinity" of a rational model, a vanished exponential term …).  The hardest honest
# NIST problems sit at cond(J) ≈ 1e9, degenerate end points at 1e14 and beyond.
RANK_CONDITION_LIMIT = 1e12


def _covariance(
    jac: np.ndarray, rss: float, dof: int, gram: np.ndarray | None = None
) -> tuple[float, np.ndarray]:
    """(cond(J D⁻¹), Cov = s²·(JᵀJ)⁻¹) with s² = RSS/(N − Np) (Eq. 4).

    J is column-equilibrated first (D = column norms), so the condition number measures
    real collinearity, not the units of the parameters.  Below cond 1e4 the inverse comes
    from the p×p Gram matrix (error ~cond²·ε < 1e-8; ``gram`` = JᵀJ if the caller has it);
    above, from the SVD of J D⁻¹, which does not square the condition number (the hard NIST
    sets sit at cond ~1e8).
    """
    n_par = jac.shape[1]
    if gram is None:
        gram = gram_matrix(jac.T)
    if not np.isfinite(gram).all():  # a NaN or inf anywhere in J reaches JᵀJ
        return np.inf, np.full((n_par, n_par), np.nan)
    scale = np.sqrt(gram.diagonal())
    if np.any(scale == 0):
        return np.inf, np.full((n_par, n_par), np.nan)
    s2 = rss / dof if dof > 0 else np.nan
    eig, vecs = np.linalg.eigh(gram / np.outer(scale, scale))
    if eig[0] > 0 and eig[-1] / eig[0] < 1e8:
        cond = float(np.sqrt(eig[-1] / eig[0]))
        inv = (vecs / eig) @ vecs.T
    else:
        _, sv, vt = np.linalg.svd(jac / scale, full_matrices=False)
        cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else np.inf
        inv = (vt.T / sv**2) @ vt
    return cond, inv / np.outer(scale, scale) * s2


def identify(
    model: Callable[..., np.ndarray] | Model,
    x,
    y,
    p0: Sequence[float],
    *,
    weights=None,
    jac: Callable[..., np.ndarray] | None = None,
    param_names: Sequence[str] | None = None,
    units: dict[str, str] | None = None,
    bounds: dict[str, tuple[float, float]] | None = None,
    xtol: float = 1e-12,
    ftol: float = 1e-15,
    gtol: float = 1e-15,
    max_iter: int = 1000,
    on_failure: Literal["raise", "warn"] = "raise",
    name: str | None = None,
) -> FitResult:
    """Weighted Levenberg–Marquardt identification (Eq. 1) with σ from the covariance.

    Minimises ½‖w·(y − f(x, θ))‖² and returns estimates, σ (Eq. 3), the covariance
    (Eq. 4 with the Jacobian of Eq. 5) and ε (Eq. 2).

    Parameters
    ----------
    model : callable or Model
        ``f(x, *params) -> y``.  A :class:`soilstats.Model` brings its own Jacobian, names,
        units and plausible bounds.
    x : array_like
        Controlled inputs, shape (N,) or (k, N) (e.g. the (b, z) rows of Eq. 11).
    y : array_like
        Measurements, shape (N,).
    p0 : sequence of float
        Starting values.
    weights : array_like, optional
        The weighting vector w_r of Eq. 1 (multiplies residuals; unit weights by default).
    jac : callable, optional
        ``jac(x, *params) -> (N, p)``, ∂f/∂θ.  Without it, a complex-step derivative is used
        (exact to rounding for models built from numpy functions), falling back to Ridders'
        extrapolated differences when the model cannot take complex input.
    on_failure : {"raise", "warn"}
        Non-convergence or a degenerate end point raises :class:`ConvergenceError` (the
        default) or, with ``"warn"``, emits a :class:`ConvergenceWarning` and returns a result
        whose ``converged`` is False — never a quiet number.

    Returns
    -------
    FitResult
    """
    if on_failure not in ("raise", "warn"):
        raise ValueError(f"on_failure must be 'raise' or 'warn', got {on_failure!r}")
    fast = False
    if isinstance(model, Model):
        if jac is None:
            fast = True
        f, jac = model.func, jac or model.jac
        param_names = param_names or model.param_names
        units = units or model.unit_of
        bounds = bounds or model.bounds_of
        name = name or model.name
    else:
        f = model
        name = name or getattr(model, "__name__", "model")
    y = np.asarray(y, dtype=float).ravel()
    p0 = np.asarray(p0, dtype=float).ravel()
    n_obs, n_par = y.size, p0.size
    param_names = tuple(param_names or (f"p{i}" for i in range(n_par)))
    if len(param_names) != n_par:
        raise ValueError(f"{len(param_names)} parameter names given for {n_par} starting values")
    if n_obs <= n_par:
        raise ValueError(f"{n_obs} observations cannot determine {n_par} parameters")
    if not np.all(np.isfinite(y)):
        bad = np.flatnonzero(~np.isfinite(y))[:5]
        raise ValueError(f"y holds non-finite values (first at indices {bad.tolist()})")
    w = np.ones(n_obs) if weights is None else np.broadcast_to(np.asarray(weights, float), y.shape)
    if not np.all(np.isfinite(w)) or np.any(w < 0):
        raise ValueError("weights must be finite and non-negative")

    jacobian_method = "analytic"
    if jac is None:
        jac, jacobian_method = make_jacobian(f, x, p0)

    wy = w * y
    if fast:
        # The model's own closures: weights folded into precomputed arrays, f and J sharing
        # their common factors, J built row-wise as the optimiser wants it.
        f_weighted, jacobian = model.evaluators(x, w)
        if model.separable is not None:
            basis, log_z = model.separable(x, w)
            p0, _ = refine_exponent(basis, log_z, wy, p0, ftol=ftol)

        def residual(theta: np.ndarray) -> np.ndarray:
            return wy - f_weighted(theta)

    else:
        w_col = w[:, None]

        def residual(theta: np.ndarray) -> np.ndarray:
            return wy - w * np.asarray(f(x, *theta), float).ravel()

        def jacobian(theta: np.ndarray) -> np.ndarray:
            return (w_col * np.asarray(jac(x, *theta), float).reshape(n_obs, n_par)).T

    # Trial steps may leave the model's domain (overflow, log of a negative): that is a
    # rejected step, handled by the optimiser, not a warning for the user.
    with np.errstate(all="ignore"):
        out = levenberg_marquardt(
            residual, jacobian, p0, xtol=xtol, ftol=ftol, gtol=gtol, max_iter=max_iter
        )
    rss = 2.0 * out.cost
    dof = n_obs - n_par
    converged = out.converged
    message = out.reason
    cond, cov = _covariance(out.jacobian, rss, dof, out.gram)
    flags: list[HealthFlag] = []
    with np.errstate(divide="ignore", invalid="ignore"):
        relative_sd = np.sqrt(np.diag(cov)) / np.abs(out.params)
    # Column scaling makes cond(J) blind to a parameter whose column has vanished (BoxBOD
    # from start 1 runs b2 to where exp(−b2·x) ≈ 0): its σ then dwarfs its value.
    undetermined = [
        param_names[k] for k in np.flatnonzero(np.isfinite(relative_sd) & (relative_sd > 1e8))
    ]
    if undetermined and cond <= RANK_CONDITION_LIMIT:
        converged = False
        message = (
            f"{message}; but {', '.join(undetermined)} is not determined at the end point "
            "(σ exceeds 1e8 × its value: the model no longer depends on it, typically a "
            "degenerate minimum at infinity); try other starting values"
        )
        flags.append(HealthFlag("undetermined", f"σ/|θ| > 1e8 for {', '.join(undetermined)}"))
    if cond > RANK_CONDITION_LIMIT:
        converged = False
        message = (
            f"{message}; but the Jacobian at the end point is rank-deficient "
            f"(cond = {cond:.2g} > {RANK_CONDITION_LIMIT:.0e} after column scaling): the "
            "parameters are not determined there (typically a degenerate minimum at "
            "infinity); try other starting values"
        )
        flags.append(HealthFlag("rank-deficient", f"cond(J) = {cond:.3g}"))
        cov = np.full((n_par, n_par), np.nan)
    result = FitResult(
        model_name=name,
        param_names=param_names,
        values=out.params,
        stderr_values=np.sqrt(np.diag(cov)),
        covariance=cov,
        epsilon=epsilon(out.residuals, wy),
        rss=rss,
        nobs=n_obs,
        dof=dof,
        nfev=out.nfev,
        niter=out.niter,
        converged=converged,
        message=message,
        units=dict(units or {}),
        bounds=dict(bounds or {}),
        jacobian_method=jacobian_method,
        condition_number=cond,
        residuals=out.residuals,
        extra_flags=tuple(flags),
    )
    if not converged:
        text = f"{name}: identification did not converge — {message}"
        if on_failure == "raise":
            raise ConvergenceError(text, result=result)
        warnings.warn(text, ConvergenceWarning, stacklevel=2)
    return result
