"""``identify``: the paper's weighted nonlinear identification for any model f(x, *params)."""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Sequence
from typing import Literal, NamedTuple, Protocol, TypeGuard, cast

import numpy as np
from numpy.typing import ArrayLike

from ..errors import (
    ConvergenceError,
    ConvergenceWarning,
    IdentifiabilityError,
    InputError,
    StatisticsInputError,
)
from .jacobian import make_jacobian
from .levenberg_marquardt import LMOutcome, gram_matrix, levenberg_marquardt, scaled_svd, small_eigh
from .result import FitResult, HealthFlag, epsilon, function_arguments, input_names_of
from .separable import PowerTerms, refine_exponent, refine_power_law_bare

__all__ = ["RANK_CONDITION_LIMIT", "ModelRecord", "epsilon", "identify"]


class ModelRecord(Protocol):
    """What :func:`identify` reads of a soil model's record (:class:`soilstats.Model`).

    Fitting sits below the models (docs/conventions.md, "Layers": the records' starting
    values and Wong's method use its linear least squares), so it names what it needs of a
    record instead of importing the class; every :class:`~soilstats.Model` is one
    (:func:`_is_record`).
    """

    name: str
    param_names: tuple[str, ...]
    func: Callable[..., np.ndarray]
    jac: Callable[..., np.ndarray]
    separable: Callable | None

    @property
    def unit_of(self) -> dict[str, str]: ...

    @property
    def bounds_of(self) -> dict[str, tuple[float, float]]: ...

    def power_terms(self, x: ArrayLike, weights: ArrayLike) -> PowerTerms | None: ...

    def evaluators(self, x: ArrayLike, weights: ArrayLike) -> tuple[Callable, Callable]: ...


def _is_record(model: object) -> TypeGuard[ModelRecord]:
    """Whether ``model`` is a model record rather than a plain f(x, *params): it has the
    record's closures (two attribute lookups, not a protocol check: identify runs once per
    bootstrap resample)."""
    return hasattr(model, "evaluators") and hasattr(model, "param_names")


# Above this cond(J) the covariance means nothing and the end point is degenerate (a minimum
# "at infinity" of a rational model, a vanished exponential term …).  The hardest honest
# NIST problems sit at cond(J) ≈ 1e9, degenerate end points at 1e14 and beyond.
RANK_CONDITION_LIMIT = 1e12


# Below this cond(J D⁻¹) the covariance is inverted from the p×p scaled Gram matrix, whose
# inverse then carries a relative error ~cond²·ε ≤ 1e-8 (σ to eight digits); above it from
# the SVD of J D⁻¹, which does not square the condition number (the hard NIST sets sit at
# cond ~1e8 and keep their certified σ to ≥ 4 digits that way).
_GRAM_COND = 1e4


def eq4_covariance(
    jac: np.ndarray,
    rss: float,
    dof: int,
    gram: np.ndarray | None = None,
    scaled: tuple | None = None,
) -> tuple[float, np.ndarray]:
    """(cond(J D⁻¹), Cov = s²·(JᵀJ)⁻¹) with s² = RSS/(N − Np) (Eq. 4, J of Eq. 5).

    J (N×p) is column-equilibrated first (D = column norms), so the condition number
    measures real collinearity, not the units of the parameters.  Below cond ``_GRAM_COND``
    the inverse comes from the eigen-decomposition of the p×p Gram matrix D⁻¹JᵀJD⁻¹;
    above, from the SVD of J D⁻¹ (QR first, see :func:`scaled_svd`).

    ``gram`` = JᵀJ and ``scaled`` = the optimiser's (eigenvalues, eigenvectors, SVD or None)
    of those same matrices at the end point (:class:`LMOutcome`), when it has them: the
    last LM iteration has just formed them, so they are not formed again.
    """
    n_par = jac.shape[1]
    if gram is None:
        gram = gram_matrix(jac.T)
    if not math.isfinite(np.add.reduce(gram, axis=None)) and not np.isfinite(gram).all():
        # A NaN or inf anywhere in J reaches JᵀJ.
        return np.inf, np.full((n_par, n_par), np.nan)
    scale = np.sqrt(gram.diagonal())
    if not np.minimum.reduce(scale) > 0:
        return np.inf, np.full((n_par, n_par), np.nan)
    s2 = rss / dof if dof > 0 else np.nan
    svd = None
    if scaled is not None:
        eig, vecs, svd = scaled
    else:
        eig, vecs = small_eigh(gram / (scale[:, None] * scale))
    if eig[0] > 0 and eig[-1] / eig[0] < _GRAM_COND**2:
        cond = math.sqrt(eig[-1] / eig[0])
        inv = (vecs / eig) @ vecs.T
    else:
        sv, vt = svd if svd is not None else scaled_svd(jac.T, scale)
        cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else np.inf
        inv = (vt.T / sv**2) @ vt
    return cond, inv / (scale[:, None] * scale) * s2


def identify(
    model: Callable[..., np.ndarray] | ModelRecord,
    x: ArrayLike,
    y: ArrayLike,
    p0: Sequence[float] | np.ndarray,
    *,
    weights: ArrayLike | None = None,
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

    For a power-law :class:`~soilstats.Model` (Bekker, Bernstein) the start is first moved to
    the optimum by variable projection in the exponent (:func:`~soilstats.fitting.separable
    .refine_power_law`); the LM then runs from there with its own stopping rules — it
    normally confirms convergence in one iteration, whose Jacobian also gives the covariance —
    so the result is the LM's, only reached sooner (a paper-size fit of 3 000 samples in
    about a fifth of a millisecond).

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
        raise InputError(f"on_failure must be 'raise' or 'warn', got {on_failure!r}")
    fast, f, jac, param_names, units, bounds, name = _model_parts(
        model, jac, param_names, units, bounds, name
    )
    y = np.asarray(y, dtype=float).ravel()
    p0 = np.asarray(p0, dtype=float).ravel()
    param_names = _checked_names(param_names, y.size, p0.size)
    data = _weighted_data(y, weights, p0.size)
    jacobian_method = "analytic"
    if jac is None:
        jac, jacobian_method = make_jacobian(f, x, p0)
    record = cast("ModelRecord", model) if fast else None  # fast: a Model record (_model_parts)
    terms = record.power_terms(x, data.w) if record is not None else None
    residual, jacobian, p0 = _objective(record, terms, f, jac, x, data, p0, ftol)
    out = _minimise(residual, jacobian, p0, terms, data, xtol, ftol, gtol, max_iter)
    rss, dof = 2.0 * out.cost, data.n_used - p0.size
    end = _judge_end_point(out, rss, dof, param_names)
    result = FitResult(
        model_name=name,
        param_names=param_names,
        values=out.params,
        stderr_values=end.stderr,
        covariance=end.cov,
        epsilon=(
            epsilon(out.residuals, data.wy, rss=rss)
            if data.kept is None
            else epsilon(out.residuals[data.kept], data.wy[data.kept], rss=rss)
        ),
        rss=rss,
        nobs=data.n_used,
        dof=dof,
        nfev=out.nfev,
        niter=out.niter,
        converged=end.converged,
        message=end.message,
        units=units,
        bounds=bounds,
        jacobian_method=jacobian_method,
        condition_number=end.cond,
        residuals=out.residuals,
        extra_flags=end.flags,
        model_func=f,
        model_jac=jac,
        input_names=input_names_of(model),
        x_data=_as_array(x),
        y_data=y,
    )
    if not result.converged:
        text = f"{name}: identification did not converge — {result.message}"
        if on_failure == "raise":
            raise ConvergenceError(text, result=result)
        warnings.warn(text, ConvergenceWarning, stacklevel=2)
    return result


def _model_parts(
    model: Callable[..., np.ndarray] | ModelRecord,
    jac: Callable[..., np.ndarray] | None,
    param_names: Sequence[str] | None,
    units: dict[str, str] | None,
    bounds: dict[str, tuple[float, float]] | None,
    name: str | None,
) -> tuple:
    """(fast, f, jac, param_names, units, bounds, name) of what the caller passed.

    A :class:`~soilstats.Model` fills what the caller left out (its Jacobian, names, SI
    units, plausible bounds); ``fast`` is True when it brings its own Jacobian too, so its
    precomputed closures (``evaluators``, ``power_terms``) may replace ``func``/``jac``.
    ``units`` and ``bounds`` come back as fresh dicts either way (the result owns them).
    """
    if _is_record(model):
        return (
            jac is None,
            model.func,
            jac or model.jac,
            param_names or model.param_names,
            dict(units) if units else model.unit_of,
            dict(bounds) if bounds else model.bounds_of,
            name or model.name,
        )
    name = name or getattr(model, "__name__", "model")
    if name == "<lambda>":
        name = "model"
    if param_names is None:  # f(x, a, b): the parameters are a and b, as lmfit names them
        param_names = function_arguments(model)[1:] or None
    return False, model, jac, param_names, dict(units or {}), dict(bounds or {}), name


def _as_array(x: ArrayLike) -> np.ndarray | None:
    """The inputs as one float array (None when they do not stack: a model's own object)."""
    try:
        return np.asarray(x, dtype=float)
    except (TypeError, ValueError):
        return None


def _checked_names(param_names: Sequence[str] | None, n_obs: int, n_par: int) -> tuple[str, ...]:
    """The parameter names (``p0``, ``p1`` … where the function does not name them, as
    ``f(x, *p)`` does not), refusing a problem that cannot be
    solved: a name per starting value, and more observations than parameters."""
    param_names = tuple(param_names or (f"p{i}" for i in range(n_par)))
    if len(param_names) != n_par:
        raise InputError(
            f"{len(param_names)} parameter names ({', '.join(param_names)}) for {n_par} "
            "starting values: give one starting value per parameter (or param_names=)"
        )
    if n_obs <= n_par:
        raise IdentifiabilityError(f"{n_obs} observations cannot determine {n_par} parameters")
    return param_names


class _Weighted(NamedTuple):
    """The measurements with Eq. 1's weights: w (N,), w·y (N,), ‖w·y‖², the number of
    samples of non-zero weight and, when some weights are zero, the mask of the others."""

    w: np.ndarray
    wy: np.ndarray
    yy: float
    n_used: int
    kept: np.ndarray | None


def _weighted_data(y: np.ndarray, weights: ArrayLike | None, n_par: int) -> _Weighted:
    """Check y and the weighting vector w_r of Eq. 1 (unit weights by default) and weight y.

    A sample of weight zero is left out: it counts in neither the degrees of freedom of
    Eq. 4's s² nor the N of Eq. 2 (counted, half the samples at weight zero made σ 0.70×
    curve_fit's on the kept ones, and 95 % intervals covered ~60 %).
    """
    n_obs = y.size
    if weights is None:
        w = np.ones(n_obs)
    else:
        w = np.asarray(weights, dtype=float)
        if w.shape != y.shape:
            w = np.broadcast_to(w, y.shape)
    wy = w * y
    yy = _finite_norm(y, w, wy)
    # The minimum is NaN if a weight is, and the comparison then fails as it should.
    if weights is not None and not np.minimum.reduce(w) >= 0:
        raise StatisticsInputError("weights must be finite and non-negative")
    n_used = n_obs if weights is None else int(np.count_nonzero(w))
    if n_used < n_obs and n_used <= n_par:
        raise IdentifiabilityError(
            f"{n_used} observations of non-zero weight cannot determine {n_par} parameters"
        )
    return _Weighted(w, wy, yy, n_used, None if n_used == n_obs else w != 0)


def _finite_norm(y: np.ndarray, w: np.ndarray, wy: np.ndarray) -> float:
    """‖w·y‖², refusing a NaN or inf in y or w with a message that says which.

    One reduction per check, in C (ndarray.min goes through a Python wrapper): ‖w·y‖² (which
    the variable projection needs anyway) is finite when y and w are, unless it overflows,
    and a NaN of y meets even a zero weight as NaN.  The elementwise tests run only when it
    is not, to tell overflow from a NaN and to say which input is at fault.
    """
    yy = float(wy @ wy)
    if not math.isfinite(yy):
        if not np.isfinite(y).all():
            bad = np.flatnonzero(~np.isfinite(y))[:5]
            raise StatisticsInputError(
                f"y holds non-finite values (first at indices {bad.tolist()})"
            )
        if not np.isfinite(w).all():
            raise StatisticsInputError("weights must be finite and non-negative")
    return yy


def _objective(
    model: ModelRecord | None,
    terms: PowerTerms | None,
    f: Callable,
    jac: Callable,
    x: ArrayLike,
    data: _Weighted,
    p0: np.ndarray,
    ftol: float,
) -> tuple[Callable, Callable, np.ndarray]:
    """(θ ↦ r(θ) = w·(y − f(x, θ)), θ ↦ (∂(w·f)/∂θ)ᵀ as (p, N) rows, start): Eq. 1's
    residuals and Eq. 5's Jacobian as the optimiser wants them.

    ``terms`` (a power law: Bekker, Bernstein): ln z taken once, shared by the variable
    projection that finds the start and by the LM's closures.  ``model`` (a Model without a
    caller's Jacobian): its own closures, with the weights folded into precomputed arrays, f
    and J sharing their common factors, J built row-wise; a separable model's start is moved
    to its best exponent first.  Otherwise wrappers of the caller's ``f`` and ``jac``.
    """
    if terms is not None:
        return _residual_of(data.wy, terms.f), terms.jacobian_block, p0
    if model is not None:
        f_weighted, jac_weighted = model.evaluators(x, data.w)
        if model.separable is not None:
            basis, log_z = model.separable(x, data.w)
            p0, _ = refine_exponent(basis, log_z, data.wy, p0, ftol=ftol)
        return _residual_of(data.wy, f_weighted), jac_weighted, p0
    w, wy, n_obs, n_par = data.w, data.wy, data.w.size, p0.size
    w_col = w[:, None]

    def residual(theta: np.ndarray) -> np.ndarray:
        return wy - w * np.asarray(f(x, *theta), float).ravel()

    def jacobian(theta: np.ndarray) -> np.ndarray:
        return (w_col * np.asarray(jac(x, *theta), float).reshape(n_obs, n_par)).T

    return residual, jacobian, p0


def _residual_of(wy: np.ndarray, f_weighted: Callable) -> Callable:
    """θ ↦ w·y − w·f(x, θ), from the weighted model θ ↦ w·f(x, θ)."""

    def residual(theta: np.ndarray) -> np.ndarray:
        return wy - f_weighted(theta)

    return residual


def _minimise(
    residual: Callable[[np.ndarray], np.ndarray],
    jacobian: Callable[[np.ndarray], np.ndarray],
    p0: np.ndarray,
    terms: PowerTerms | None,
    data: _Weighted,
    xtol: float,
    ftol: float,
    gtol: float,
    max_iter: int,
) -> LMOutcome:
    """The LM of Eq. 1 from ``p0`` (for a power law, from its variable-projection optimum).

    Trial steps may leave the model's domain (overflow, log of a negative): that is a
    rejected step, handled by the optimiser, not a warning for the user.
    """
    with np.errstate(all="ignore"):
        if terms is not None:
            p0, _ = refine_power_law_bare(terms, data.wy, p0, ftol=ftol, yy=data.yy)
        return levenberg_marquardt(
            residual,
            jacobian,
            p0,
            xtol=xtol,
            ftol=ftol,
            gtol=gtol,
            max_iter=max_iter,
            spare_row=terms is not None,
        )


class _EndPoint(NamedTuple):
    """The verdict on the optimiser's end point: whether it stands, why, the health flags
    raised, cond(J D⁻¹), the covariance (Eq. 4) and σ (Eq. 3)."""

    converged: bool
    message: str
    flags: tuple[HealthFlag, ...]
    cond: float
    cov: np.ndarray
    stderr: np.ndarray


def _judge_end_point(
    out: LMOutcome, rss: float, dof: int, param_names: tuple[str, ...]
) -> _EndPoint:
    """Covariance and σ at the end point, and whether the parameters are determined there.

    A parameter with σ > 1e8·|θ| (:func:`_undetermined`) or a rank-deficient Jacobian
    (cond > ``RANK_CONDITION_LIMIT`` after column scaling; then no covariance at all) marks
    the fit as not converged, with a message and a health flag saying why.
    """
    converged, message = out.converged, out.reason
    cond, cov = eq4_covariance(out.jacobian, rss, dof, out.gram, out.scaled)
    stderr = np.sqrt(cov.diagonal())
    flags: list[HealthFlag] = []
    undetermined = _undetermined(stderr, out.params, param_names)
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
        cov = np.full((len(param_names), len(param_names)), np.nan)
        stderr = cov.diagonal().copy()
    return _EndPoint(converged, message, tuple(flags), cond, cov, stderr)


def _undetermined(
    stderr: np.ndarray, values: np.ndarray, param_names: Sequence[str]
) -> list[str]:
    """Names of the parameters whose σ exceeds 1e8 × |θ|.

    Column scaling makes cond(J) blind to a parameter whose column has vanished (BoxBOD
    from start 1 runs b2 to where exp(−b2·x) ≈ 0): its σ then dwarfs its value.  A
    product, not σ/|θ|, so the common case needs no errstate; the exact test (finite
    ratio) runs only when something is that large.
    """
    if not any(s > 1e8 * abs(v) for s, v in zip(stderr.tolist(), values.tolist(), strict=True)):
        return []
    with np.errstate(divide="ignore", invalid="ignore"):
        relative_sd = stderr / np.abs(values)
    big = np.isfinite(relative_sd) & (relative_sd > 1e8)
    return [param_names[k] for k in np.flatnonzero(big).tolist()]
