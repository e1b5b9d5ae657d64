"""Variable projection for the power-law sinkage models: a better start for Levenberg–Marquardt.

Bekker (Eq. 7) and Bernstein (Eq. 8) are *linear* in all parameters but the exponent n:
p = Σ a_i·g_i(x)·z^n with (a_1, a_2) = (kc, kφ), g = (1/b, 1) for Bekker, a_1 = k, g = 1 for
Bernstein.  For fixed n the a_i follow from a q×q linear solve, so the weighted least-squares
problem of Eq. 1 reduces to one dimension in n (Golub & Pereyra 1973).  Gauss–Newton on that
reduced functional, with Kaufman's Jacobian, reaches the optimum from Wong's start in a few
cheap iterations; :func:`soilstats.identify` then runs its full LM from there, which confirms
convergence with its own stopping rules in one iteration and supplies the covariance (Eq. 4).
The minimum is the same — only the path to it is shorter.

:func:`refine_exponent` takes any basis n ↦ U(n); :func:`refine_power_law`, which
``identify`` uses for Bekker and Bernstein, does the same from the moments of
:class:`~soilstats.models.base.PowerLawTerms` in scalar arithmetic, with Newton steps and a
last Halley step that needs no evaluation (two passes over the data from Wong's start).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike

from .levenberg_marquardt import gram_matrix

__all__ = ["PowerTerms", "refine_exponent", "refine_power_law"]


class PowerTerms(Protocol):
    """What the variable projection and :func:`soilstats.identify` read of a power-law
    model's weighted terms, :class:`soilstats.models.base.PowerLawTerms`. Fitting sits below
    the models (docs/conventions.md, "Layers"), so it names what it needs of the class
    instead of importing it."""

    rows: np.ndarray
    log_z: np.ndarray

    def basis(self, n: float) -> np.ndarray: ...

    def f(self, theta: ArrayLike) -> np.ndarray: ...

    def jacobian_block(self, theta: ArrayLike) -> np.ndarray: ...


#: Two basis columns count as collinear (one plate size, say) when the 2×2 Gram determinant
#: falls below this fraction of the product of its diagonal: the same test in every solver.
_COLLINEAR = 1e-13


def _solve_small(gram: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """gram⁻¹·rhs for q ≤ 2 in closed form (numpy's solve costs more than the arithmetic)."""
    q = gram.shape[0]
    if q == 1:
        return rhs / gram[0, 0]
    if q == 2:
        (g00, g01), (_, g11) = gram
        det = g00 * g11 - g01 * g01
        if not det > _COLLINEAR * g00 * g11:  # collinear basis columns (or NaN)
            raise np.linalg.LinAlgError("singular basis")
        return np.array([g11 * rhs[0] - g01 * rhs[1], g00 * rhs[1] - g01 * rhs[0]]) / det
    return np.linalg.solve(gram, rhs)


def _project(rows: np.ndarray, wy: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """Linear coefficients a(n), residual r = wy − aᵀU, ½‖r‖², and the q×q Gram matrix."""
    gram = gram_matrix(rows)
    a = _solve_small(gram, rows @ wy)
    r = wy - a @ rows
    return a, r, 0.5 * float(r @ r), gram


def refine_exponent(
    basis: Callable[[float], np.ndarray],
    log_z: np.ndarray,
    wy: np.ndarray,
    theta0: np.ndarray,
    *,
    ftol: float,
    max_iter: int = 50,
) -> tuple[np.ndarray, int]:
    """Minimise ½‖wy − a(n)ᵀU(n)‖² over the exponent n (the last parameter of ``theta0``).

    Parameters
    ----------
    basis : callable
        n ↦ U(n), the (q, N) weighted basis rows w·g_i(x)·z^n.
    log_z : numpy.ndarray
        ln z (N,), so that ∂U/∂n = U·ln z.
    wy : numpy.ndarray
        Weighted measurements w·y (N,).
    theta0 : numpy.ndarray
        Start (a_1 … a_q, n); only n is used.
    ftol : float
        Stop when the predicted reduction of the cost falls below ``ftol`` × cost.

    Returns
    -------
    (theta, iterations)
        The best (a_1 … a_q, n) reached — ``theta0`` itself when the reduced problem cannot
        be solved (singular basis, non-finite values).  Never a verdict: the full LM that
        follows decides convergence.
    """
    best = np.asarray(theta0, dtype=float)
    n = float(best[-1])
    iteration = 0
    try:
        with np.errstate(all="ignore"):
            rows = basis(n)
            a, r, cost, gram = _project(rows, wy)
            if not math.isfinite(cost):
                return best, 0
            for iteration in range(1, max_iter + 1):  # noqa: B007 (reported)
                # ∂(aᵀU)/∂n = (fitted)·ln z; its part orthogonal to the basis is Kaufman's
                # Jacobian of the reduced residual, and −r·v is the exact gradient (r ⟂ U).
                v = (wy - r) * log_z
                pv = v - _solve_small(gram, rows @ v) @ rows
                curvature = float(pv @ pv)
                slope = -float(r @ v)
                if not (curvature > 0 and math.isfinite(curvature) and math.isfinite(slope)):
                    break
                # A thousandth of the LM's tolerance: one more (quadratically convergent, cheap)
                # step, so the LM that follows finds nothing left to do.
                if 0.5 * slope * slope / curvature <= 1e-3 * ftol * cost:
                    break
                step = -slope / curvature
                for _ in range(40):  # halve until the cost decreases
                    rows_t = basis(n + step)
                    a_t, r_t, cost_t, gram_t = _project(rows_t, wy)
                    if math.isfinite(cost_t) and cost_t < cost:
                        break
                    step *= 0.5
                else:
                    break
                n, rows, a, r, cost, gram = n + step, rows_t, a_t, r_t, cost_t, gram_t
            if np.all(np.isfinite(a)):
                best = np.append(a, n)
    except np.linalg.LinAlgError:
        pass  # a singular basis: the full LM starts from the last good point instead
    return best, iteration


# Resolution of the reduced cost and curvature, which are differences of moment sums: a
# few hundred ulps of the terms they are taken from.
_ROUNDING = 256 * np.finfo(float).eps


def _reduced(mom: list, q: int, yy: float) -> tuple | None:
    """The reduced problem at one exponent n, from its moments (q ≤ 2 linear coefficients).

    ``mom`` is the row-major product [U; V]·[U, V, wy, wy·ln z, W, wy·ln²z]ᵀ with the rows
    U = w·g·z^n, V = U·ln z and W = V·ln z (see :func:`refine_power_law`), or only its
    first 2q + 2 columns (no third derivative then).  Its entries are the moments
    Mₖ = Σ UᵢUⱼ·lnᵏz (M₀ = U·U, M₁ = U·V, M₂ = V·V, M₃ = V·W) and Rₖ = Σ Uᵢ·wy·lnᵏz
    (R₀ = U·wy, R₁ = U·wy·ln z, R₂ = V·wy·ln z, R₃ = V·wy·ln²z), from which everything
    follows in q×q arithmetic, written out for q = 1 and 2 (a′ = da/dn; Mₖ′ = 2Mₖ₊₁ and
    Rₖ′ = Rₖ₊₁ since U ∝ z^n).  yy = ‖wy‖².

    Returns (a, a′, a″, cost, slope, curvature, third, resolution), or None when the basis
    columns are collinear (one plate size) or a moment is not finite:

    * a = M₀⁻¹R₀, the linear least-squares coefficients at this n; a′ = M₀⁻¹d with
      d = R₁ − 2M₁a; a″ = M₀⁻¹(d′ − 2M₁a′) with d′ = R₂ − 4M₂a − 2M₁a′;
    * cost = ½‖wy − aᵀU‖² = ½(yy − 2aᵀR₀ + aᵀM₀a) (the full quadratic, stationary in a, so
      the rounding error of a enters squared);
    * slope = dcost/dn = −rᵀv with v = ∂(aᵀU)/∂n = aᵀV, i.e. −(aᵀR₁ − aᵀM₁a);
    * curvature: the exact d²cost/dn² = 2aᵀM₂a − aᵀR₂ − dᵀa′ (Newton) while it is at least
      half Kaufman's Gauss–Newton term ‖v − proj_U v‖² = aᵀM₂a − (M₁a)ᵀM₀⁻¹(M₁a), which it
      replaces far from the optimum (where the exact one may be small or negative); 0 when
      v lies in span(U) to rounding (n not determined);
    * third: d³cost/dn³ = 4a′ᵀM₂a + 4aᵀM₃a − a′ᵀR₂ − aᵀR₃ − d′ᵀa′ − dᵀa″ with the exact
      curvature and the W columns, else NaN (for Halley's correction of the last step, see
      :func:`refine_power_law`);
    * resolution: the rounding level of cost, below which two costs cannot be told apart.
    """
    if not math.isfinite(sum(mom)):
        return None
    nan = math.nan
    width = len(mom) // (2 * q)
    third_order = width == 3 * q + 3
    if q == 1:
        g, h, r0, r1 = mom[0:4]
        k, r2 = mom[width + 1], mom[width + 3]
        m3, r3 = (mom[width + 4], mom[width + 5]) if third_order else (nan, nan)
        if not g > 0:
            return None
        a = r0 / g
        fitted = a * a * g
        cost = 0.5 * (yy - 2.0 * a * r0 + fitted)
        m1a, m2a = h * a, k * a
        slope = -(a * r1 - a * m1a)
        vv = a * m2a
        gauss_newton = vv - m1a * m1a / g
        d = r1 - 2.0 * m1a
        da = d / g
        exact = 2.0 * vv - a * r2 - d * da
        resolution = _ROUNDING * (yy + abs(a * r0) + fitted)
        if not gauss_newton > _ROUNDING * vv:  # v in span(U) to rounding
            return (a,), (da,), (nan,), cost, slope, 0.0, nan, resolution
        if exact < 0.5 * gauss_newton:
            return (a,), (da,), (nan,), cost, slope, gauss_newton, nan, resolution
        m1da = h * da
        dd = r2 - 4.0 * m2a - 2.0 * m1da
        d2a = (dd - 2.0 * m1da) / g
        third = 4.0 * da * m2a + 4.0 * a * m3 * a - da * r2 - a * r3 - dd * da - d * d2a
        return (a,), (da,), (d2a,), cost, slope, exact, third, resolution
    # q = 2: rows U₀, U₁, V₀, V₁ against columns U₀, U₁, V₀, V₁, wy, wyl (, W₀, W₁, wyl2);
    # M₁ and M₂ are symmetric, so each is read once.
    u1, v0, v1 = width, 2 * width, 3 * width  # where the rows U₁, V₀, V₁ start
    g00, g01, h00, h01, r0, s0 = mom[0:6]
    g11, h11, r1, s1 = mom[u1 + 1], mom[u1 + 3], mom[u1 + 4], mom[u1 + 5]
    k00, k01, t0 = mom[v0 + 2], mom[v0 + 3], mom[v0 + 5]
    k11, t1 = mom[v1 + 3], mom[v1 + 5]
    if third_order:
        m00, m01, u0 = mom[v0 + 6], mom[v0 + 7], mom[v0 + 8]
        m10, m11, w1 = mom[v1 + 6], mom[v1 + 7], mom[v1 + 8]
    else:
        m00 = m01 = m10 = m11 = u0 = w1 = nan
    det = g00 * g11 - g01 * g01
    if not det > _COLLINEAR * g00 * g11:  # collinear basis columns: the test of _solve_small
        return None
    a0 = (g11 * r0 - g01 * r1) / det
    a1 = (g00 * r1 - g01 * r0) / det
    fitted = a0 * (g00 * a0 + g01 * a1) + a1 * (g01 * a0 + g11 * a1)
    cost = 0.5 * (yy - 2.0 * (a0 * r0 + a1 * r1) + fitted)
    b0, b1 = h00 * a0 + h01 * a1, h01 * a0 + h11 * a1  # M₁a = U·v
    e0, e1 = k00 * a0 + k01 * a1, k01 * a0 + k11 * a1  # M₂a
    slope = -(a0 * s0 + a1 * s1 - (a0 * b0 + a1 * b1))
    vv = a0 * e0 + a1 * e1  # ‖v‖²
    gauss_newton = vv - (g11 * b0 * b0 - 2.0 * g01 * b0 * b1 + g00 * b1 * b1) / det
    d0, d1 = s0 - 2.0 * b0, s1 - 2.0 * b1
    da0, da1 = (g11 * d0 - g01 * d1) / det, (g00 * d1 - g01 * d0) / det
    exact = 2.0 * vv - (a0 * t0 + a1 * t1) - (d0 * da0 + d1 * da1)
    resolution = _ROUNDING * (yy + abs(a0 * r0) + abs(a1 * r1) + fitted)
    # The projection's rounding grows with the conditioning of M₀ (column-scaled).
    if not gauss_newton > _ROUNDING * vv * (g00 * g11 / det):
        return (a0, a1), (da0, da1), (nan, nan), cost, slope, 0.0, nan, resolution
    if exact < 0.5 * gauss_newton:
        return (a0, a1), (da0, da1), (nan, nan), cost, slope, gauss_newton, nan, resolution
    f0, f1 = h00 * da0 + h01 * da1, h01 * da0 + h11 * da1  # M₁a′
    dd0, dd1 = t0 - 4.0 * e0 - 2.0 * f0, t1 - 4.0 * e1 - 2.0 * f1  # d′
    c0, c1 = dd0 - 2.0 * f0, dd1 - 2.0 * f1
    d2a0, d2a1 = (g11 * c0 - g01 * c1) / det, (g00 * c1 - g01 * c0) / det
    m3a = a0 * (m00 * a0 + m01 * a1) + a1 * (m10 * a0 + m11 * a1)  # aᵀM₃a
    third = (
        4.0 * (da0 * e0 + da1 * e1)
        + 4.0 * m3a
        - (da0 * t0 + da1 * t1)
        - (a0 * u0 + a1 * w1)
        - (dd0 * da0 + dd1 * da1)
        - (d0 * d2a0 + d1 * d2a1)
    )
    return (a0, a1), (da0, da1), (d2a0, d2a1), cost, slope, exact, third, resolution


def refine_power_law(
    terms: PowerTerms, wy: np.ndarray, theta0: np.ndarray, *, ftol: float, max_iter: int = 50
) -> tuple[np.ndarray, int]:
    """:func:`refine_exponent` for a :class:`~soilstats.models.base.PowerLawTerms` model, fast.

    The same reduced problem (a(n) projected out, a one-dimensional search in n with step
    halving, the same stopping rule) with three differences that matter at the paper's
    problem size (3 000 samples), where the time goes to numpy calls, not arithmetic:

    * one evaluation at an exponent n costs z^n, the rows U = w·g·z^n, V = U·ln z and
      W = V·ln z, and one matrix product [U; V]·[U, V, W, wy, wy·ln z, wy·ln²z]ᵀ holding
      every moment (see :func:`_reduced`); the q×q solves and the derivatives of the reduced
      cost are scalar arithmetic;
    * the steps are Newton's on the reduced cost (its exact second derivative comes from
      the same moments), quadratically convergent where Gauss–Newton is only linear for a
      non-zero residual;
    * the last step is taken without an evaluation once it can be computed to rounding:
      Halley's (third-order) correction of the Newton step, with a(n) followed to second
      order, when the term it leaves — estimated as (Halley − Newton)²/Newton, the next
      term of the same series, with a tenfold margin — reduces the cost by less than
      1e-3·``ftol``.  From Wong's start that saves one of three evaluations, and the start
      handed to the LM sits at the optimum to rounding.

    Cost and curvature come out as differences of moment sums, resolved to a few hundred
    ulps of ‖wy‖² (``resolution`` of :func:`_reduced`).  A step whose predicted reduction is
    below that resolution is judged by the slope instead (|slope| must fall), which has no
    such cancellation, so the last steps are not lost to noise.  None of this decides
    convergence: the LM that follows does, from its own residuals and Jacobian.

    Parameters
    ----------
    terms : PowerLawTerms
        The model's weighted basis rows and ln z for this fit.
    wy : numpy.ndarray
        Weighted measurements w·y (N,).
    theta0 : numpy.ndarray
        Start (a_1 … a_q, n); only n is used.
    ftol : float
        Stop when the predicted reduction of the cost falls below 1e-3·``ftol`` × cost.

    Returns
    -------
    (theta, iterations)
        As :func:`refine_exponent`: the best (a_1 … a_q, n) reached, ``theta0`` itself when
        the reduced problem cannot be solved; never a verdict (the LM that follows decides).
    """
    with np.errstate(all="ignore"):
        return _refine_power_law(terms, wy, theta0, ftol=ftol, max_iter=max_iter)


def _moment_evaluator(rows, log_z, wy, yy):
    """The reduced problem of :func:`_refine_power_law` at an exponent n, as
    ``evaluate(n, third_order)`` → :func:`_reduced`'s tuple (buffers allocated once)."""
    q, size = rows.shape
    # Rows U, V, W (refilled per n), then the fixed wy, wy·ln z and wy·ln²z: every moment
    # of the reduced problem is an entry of [U; V]·bufᵀ, one BLAS gemm.
    buf = np.empty((3 * q + 3, size))
    u_rows, v_rows, w_rows = buf[:q], buf[q : 2 * q], buf[2 * q + 2 : 3 * q + 2]
    buf[2 * q] = wy
    np.multiply(wy, log_z, out=buf[2 * q + 1])
    np.multiply(buf[2 * q + 1], log_z, out=buf[3 * q + 2])
    uv, newton_columns = buf[: 2 * q], buf[: 2 * q + 2]
    # V = U·ln z and W = V·ln z as flat products with ln z repeated q times: a contiguous
    # product of q·N numbers costs ~40 % less than the broadcast of ln z over q rows.
    log_zq = np.concatenate((log_z,) * q) if q > 1 else log_z
    u_flat, v_flat, w_flat = (rows_.reshape(-1) for rows_ in (u_rows, v_rows, w_rows))
    pairs = tuple(zip(rows, u_rows, strict=True))  # (w·gᵢ, Uᵢ) row views, made once
    zn = np.empty(size)

    def evaluate(n: float, third_order: bool) -> tuple | None:
        np.exp(np.multiply(log_z, n, out=zn), out=zn)  # z^n
        for row, u in pairs:
            np.multiply(row, zn, out=u)
        np.multiply(u_flat, log_zq, out=v_flat)
        if not third_order:
            return _reduced((uv @ newton_columns.T).ravel().tolist(), q, yy)
        np.multiply(v_flat, log_zq, out=w_flat)
        # Two operands that differ (a slice and the whole): numpy calls gemm, not the syrk
        # it uses for x @ x.T, which OpenBLAS is slow at for a long inner dimension.
        return _reduced((uv @ buf.T).ravel().tolist(), q, yy)

    return evaluate


def refine_power_law_bare(
    terms: PowerTerms,
    wy: np.ndarray,
    theta0: ArrayLike,
    *,
    ftol: float,
    max_iter: int = 50,
    yy: float | None = None,
) -> tuple[np.ndarray, int]:
    """:func:`refine_power_law` without its ``np.errstate``, for a caller that has one
    (:func:`soilstats.identify` around its whole fit); ``yy`` is ‖wy‖² when the caller has
    it (else computed)."""
    return _refine_power_law(terms, wy, theta0, ftol=ftol, max_iter=max_iter, yy=yy)


def _refine_power_law(terms, wy, theta0, *, ftol, max_iter=50, yy=None):
    """The body of :func:`refine_power_law_bare` (its loop kept whole: tests/test_sizes.py)."""
    best = np.asarray(theta0, dtype=float)
    rows, log_z = terms.rows, terms.log_z
    q = rows.shape[0]
    if q > 2 or best.size != q + 1:
        return refine_exponent(terms.basis, log_z, wy, best, ftol=ftol, max_iter=max_iter)
    if yy is None:
        yy = float(wy @ wy)
    tolerance = 1e-3 * ftol
    evaluate = _moment_evaluator(rows, log_z, wy, yy)
    n = float(best[-1])
    # Third-order moments only where Halley's step may finish: not at the start, whose
    # Newton step is seldom the last (Wong's start is typically a σ away).
    state = evaluate(n, False)
    if state is None or not math.isfinite(state[3]):
        return best, 0
    iteration = 0
    for iteration in range(1, max_iter + 1):  # noqa: B007 (reported)
        coefficients, da, d2a, cost, slope, curvature, third, resolution = state
        if not (curvature > 0 and math.isfinite(curvature) and math.isfinite(slope)):
            break
        step = -slope / curvature
        predicted = -0.5 * slope * step
        halley = step / (1.0 + 0.5 * step * third / curvature)
        # What Halley's step leaves (the next term of its series), with a tenfold margin.
        left = 10.0 * (halley - step) ** 2 / abs(step) if step else 0.0
        if predicted <= tolerance * cost or 0.5 * curvature * left * left <= tolerance * cost:
            # The optimum is within this step, to rounding: take it without an evaluation,
            # a(n) followed to second order (Newton's step and first order when Halley's
            # correction is not available or not small against the step).
            if not abs(halley - step) <= abs(step):
                halley, d2a = step, [0.0] * q
            if abs(halley) <= 1e-3 * (abs(n) + 1.0):
                coefficients = [
                    c + halley * (dc + 0.5 * halley * d2c)
                    for c, dc, d2c in zip(coefficients, da, d2a, strict=True)
                ]
                n += halley
            break
        for _ in range(40):  # halve until the cost decreases
            trial = evaluate(n + step, abs(step) <= 1e-2 * (abs(n) + 1.0))
            if trial is not None and math.isfinite(trial[3]):
                if trial[3] < cost:
                    break
                if predicted <= resolution and abs(trial[4]) < abs(slope):
                    break
            step *= 0.5
        else:
            break
        n, state = n + step, trial
    else:
        coefficients = state[0]
    if all(math.isfinite(c) for c in coefficients) and math.isfinite(n):
        best = np.array([*coefficients, n])
    return best, iteration


def solve_rows(gram: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """gram_b⁻¹·rhs_b for every row b (q ≤ 2 in closed form); NaN for a singular row, which
    the caller then reports as not converged (one collinear resample must not sink the rest)."""
    q = gram.shape[-1]
    if q == 1:
        return rhs / gram[:, 0]
    if q == 2:
        g00, g01, g11 = gram[:, 0, 0], gram[:, 0, 1], gram[:, 1, 1]
        det = g00 * g11 - g01 * g01
        det = np.where(det > _COLLINEAR * g00 * g11, det, np.nan)
        return (
            np.column_stack([g11 * rhs[:, 0] - g01 * rhs[:, 1], g00 * rhs[:, 1] - g01 * rhs[:, 0]])
            / det[:, None]
        )
    return np.linalg.solve(gram, rhs[..., None])[..., 0]


#: Rows × samples a caller should hand :func:`fit_separable_batch` per call: bounds its memory
#: (a few MB whatever the campaign's size) and keeps the arrays in cache (100k beat 1M by 20 %).
BATCH_ELEMENTS = 100_000


def fit_separable_batch(
    basis0: np.ndarray,
    log_z: np.ndarray,
    y: np.ndarray,
    weights: np.ndarray,
    n0: float,
    *,
    ftol: float = 1e-14,
    max_iter: int = 50,
) -> tuple[np.ndarray, np.ndarray]:
    """Weighted least squares of p = aᵀg(x)·z^n for many weightings at once (rows of
    ``weights``): the bootstrap's resamples, each refitted exactly.

    The same reduced problem as :func:`refine_exponent` (a(n) projected out, Gauss–Newton in n
    with Kaufman's Jacobian, step halving), vectorised over rows: one pass over the (B, N)
    arrays per iteration instead of B small fits.

    Parameters
    ----------
    basis0 : numpy.ndarray
        (q, N) the unweighted basis g_i(x) (1/b and 1 for Bekker, 1 for Bernstein).
    log_z : numpy.ndarray
        ln z (N,).
    y : numpy.ndarray
        Measurements (N,).
    weights : numpy.ndarray
        (B, N) per-row sample weights w (Eq. 1); a zero weight leaves the sample out.
    n0 : float
        Start of the exponent for every row.
    ftol : float
        A row has converged when the predicted reduction of its cost is ≤ ``ftol`` × cost.

    Returns
    -------
    (theta, converged)
        (B, q + 1) estimates (a_1 … a_q, n) and a (B,) mask; rows that did not converge (or
        met a singular basis) hold NaN and are the caller's to refit another way.
    """
    weights = np.asarray(weights, float)
    rows_b, q = weights.shape[0], basis0.shape[0]
    n = np.full(rows_b, float(n0))
    theta = np.full((rows_b, q + 1), np.nan)
    converged = np.zeros(rows_b, bool)
    active = np.arange(rows_b)
    wy_all = weights * y

    def project(idx, n_idx):
        we = np.exp(np.multiply.outer(n_idx, log_z))
        we *= weights[idx]
        u = we[:, None, :] * basis0[None]  # (B, q, N) weighted basis rows w·g·z^n
        gram = np.einsum("bkn,bln->bkl", u, u)
        wy = wy_all[idx]
        a = solve_rows(gram, np.einsum("bkn,bn->bk", u, wy))
        fitted = np.einsum("bk,bkn->bn", a, u)
        r = wy - fitted
        return u, gram, a, fitted, r, 0.5 * np.einsum("bn,bn->b", r, r)

    with np.errstate(all="ignore"):
        u, gram, a, fitted, r, cost = project(active, n)
        for _ in range(max_iter):
            v = fitted * log_z
            coef = solve_rows(gram, np.einsum("bkn,bn->bk", u, v))
            pv = v - np.einsum("bk,bkn->bn", coef, u)
            curvature = np.einsum("bn,bn->b", pv, pv)
            slope = -np.einsum("bn,bn->b", r, v)
            sane = np.isfinite(cost) & np.isfinite(slope) & (curvature > 0)
            done = sane & (0.5 * slope**2 / curvature <= ftol * cost)
            theta[active[done]] = np.column_stack([a[done], n[active[done]]])
            converged[active[done]] = True
            keep = sane & ~done
            active, u, gram, a, fitted, r, cost = (
                active[keep],
                u[keep],
                gram[keep],
                a[keep],
                fitted[keep],
                r[keep],
                cost[keep],
            )
            if not active.size:
                break
            step = -slope[keep] / curvature[keep]
            pending = np.ones(active.size, bool)
            for _ in range(40):  # halve each row's step until its cost decreases
                idx = np.flatnonzero(pending)
                trial = project(active[idx], n[active[idx]] + step[idx])
                better = np.isfinite(trial[5]) & (trial[5] < cost[idx])
                took = idx[better]
                n[active[took]] += step[took]
                for arr, new in zip((u, gram, a, fitted, r, cost), trial, strict=True):
                    arr[took] = new[better]
                pending[took] = False
                step[idx[~better]] *= 0.5
                if not pending.any():
                    break
            # A row whose step never reduced its cost is left unconverged: the caller refits
            # it another way rather than trusting a point the criterion has not accepted.
            moved = ~pending
            active, u, gram, a, fitted, r, cost = (
                x[moved] for x in (active, u, gram, a, fitted, r, cost)
            )
            if not active.size:
                break
    return theta, converged
