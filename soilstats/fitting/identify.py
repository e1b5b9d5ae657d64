"""``identify``: the paper's weighted nonlinear identification for any model f(x, *params)."""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from typing import Literal

import numpy as np
import pandas as pd

from ..errors import ConvergenceError, ConvergenceWarning
from ..models import Model
from .jacobian import make_jacobian
from .levenberg_marquardt import levenberg_marquardt
from .result import FitResult, HealthFlag

__all__ = ["epsilon", "identify", "RANK_CONDITION_LIMIT"]

# Above this cond(J) the covariance means nothing and the end point is degenerate (a minimum
# "at infinity" of a rational model, a vanished exponential term …).  The hardest honest
# NIST problems sit at cond(J) ≈ 1e9, degenerate end points at 1e14 and beyond.
RANK_CONDITION_LIMIT = 1e12


def epsilon(residuals: np.ndarray, y: np.ndarray) -> float:
    """Fit quality ε = 1 − √(Σe²/(N−2)) / (Σ|y|/N) (Eq. 2); 1 is a perfect fit."""
    residuals = np.asarray(residuals, float)
    y = np.asarray(y, float)
    n = y.size
    if n <= 2:
        return np.nan
    return float(1.0 - np.sqrt(residuals @ residuals / (n - 2)) / (np.abs(y).sum() / n))


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
    notes: Sequence[str] = (),
    extra_flags: Sequence[HealthFlag] = (),
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
    if isinstance(model, Model):
        f, jac = model.func, jac or model.jac
        param_names = param_names or model.param_names
        units = units or dict(zip(model.param_names, model.units, strict=True))
        bounds = bounds or dict(zip(model.param_names, model.bounds, strict=True))
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

    def residual(theta: np.ndarray) -> np.ndarray:
        with np.errstate(all="ignore"):
            return wy - w * np.asarray(f(x, *theta), float).ravel()

    def jacobian(theta: np.ndarray) -> np.ndarray:
        with np.errstate(all="ignore"):
            return w[:, None] * np.asarray(jac(x, *theta), float).reshape(n_obs, n_par)

    out = levenberg_marquardt(
        residual, jacobian, p0, xtol=xtol, ftol=ftol, gtol=gtol, max_iter=max_iter
    )
    rss = 2.0 * out.cost
    dof = n_obs - n_par
    converged = out.converged
    message = out.reason
    if np.all(np.isfinite(out.jacobian)):
        _, s, vt = np.linalg.svd(out.jacobian, full_matrices=False)
        cond = float(s[0] / s[-1]) if s[-1] > 0 else np.inf
    else:
        s, vt, cond = None, None, np.inf
    flags = list(extra_flags)
    if cond > RANK_CONDITION_LIMIT:
        converged = False
        message = (
            f"{message}; but the Jacobian at the end point is rank-deficient "
            f"(cond = {cond:.2g} > {RANK_CONDITION_LIMIT:.0e}): the parameters are not "
            "determined there (typically a degenerate minimum at infinity); try other "
            "starting values"
        )
        flags.append(HealthFlag("rank-deficient", f"cond(J) = {cond:.3g}"))
        cov = np.full((n_par, n_par), np.nan)
    else:
        # Cov = s²·(JᵀJ)⁻¹ = s²·V Σ⁻² Vᵀ: the SVD avoids squaring cond(J) (Eq. 4).
        cov = (vt.T / s**2) @ vt * (rss / dof if dof > 0 else np.nan)
    stderr = np.sqrt(np.diag(cov))
    result = FitResult(
        model_name=name,
        params=pd.Series(out.params, index=param_names, name="value"),
        stderr=pd.Series(stderr, index=param_names, name="stderr"),
        cov=pd.DataFrame(cov, index=param_names, columns=param_names),
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
        notes=tuple(notes),
    )
    if not converged:
        text = f"{name}: identification did not converge — {message}"
        if on_failure == "raise":
            raise ConvergenceError(text, result=result)
        warnings.warn(text, ConvergenceWarning, stacklevel=2)
    return result
