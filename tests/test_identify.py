"""identify(): interval coverage, weighting, ε (Eq. 2), health flags and input errors."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from soilstats import BEKKER, BERNSTEIN, ConvergenceError, identify
from soilstats.fitting import epsilon


@pytest.mark.slow
def test_95_percent_intervals_cover_truth_95_percent():
    """i.i.d. Gaussian noise matching the model: coverage 95 ± 3 % over 400 data sets."""
    rng = np.random.default_rng(20261121)
    truth = np.array([-9.8e3, 1.2e6, 0.8])
    b = np.repeat([0.025, 0.05, 0.075], 60)
    z = np.tile(np.linspace(0.002, 0.06, 60), 3)
    x = np.vstack([b, z])
    clean = BEKKER.func(x, *truth)
    noise_sd = 0.03 * clean.max()
    hits = np.zeros(3)
    n_sets = 400
    for _ in range(n_sets):
        y = clean + rng.normal(0, noise_sd, clean.size)
        fit = identify(BEKKER, x, y, truth * [0.5, 1.3, 1.2])
        ci = fit.conf_int(0.05)
        hits += (ci["lower"].to_numpy() <= truth) & (truth <= ci["upper"].to_numpy())
    coverage = hits / n_sets
    assert np.all(np.abs(coverage - 0.95) <= 0.03), coverage


def test_weights_scale_residuals_as_eq1():
    """Weighted fit equals the unweighted fit of the scaled problem (w·y against w·f)."""
    rng = np.random.default_rng(1)
    z = np.linspace(0.001, 0.05, 80)
    y = BERNSTEIN.func(z, 5e5, 1.1) * (1 + 0.02 * rng.standard_normal(80))
    w = np.where(z < 0.025, 3.0, 0.5)
    weighted = identify(BERNSTEIN, z, y, [1e5, 1.0], weights=w)

    def scaled(xw, k, n):
        return xw[1] * BERNSTEIN.func(xw[0], k, n)

    plain = identify(scaled, np.vstack([z, w]), w * y, [1e5, 1.0])
    np.testing.assert_allclose(weighted.params, plain.params, rtol=1e-9)
    np.testing.assert_allclose(weighted.stderr, plain.stderr, rtol=1e-6)
    assert weighted.epsilon == pytest.approx(plain.epsilon, rel=1e-9)


def test_epsilon_closed_form():
    y = np.array([1.0, -2.0, 3.0, 4.0])
    e = np.array([0.1, -0.1, 0.2, 0.0])
    expected = 1 - np.sqrt(np.sum(e**2) / 2) / (np.sum(np.abs(y)) / 4)
    assert epsilon(e, y) == pytest.approx(expected)
    assert epsilon(np.zeros(4), y) == 1.0


def test_stderr_equals_linear_regression_for_a_linear_model():
    rng = np.random.default_rng(3)
    x = np.linspace(0, 10, 50)
    y = 2.0 + 0.5 * x + rng.normal(0, 0.3, 50)
    fit = identify(lambda x, a, b: a + b * x, x, y, [0.0, 0.0])
    ref = stats.linregress(x, y)
    assert fit.params.iloc[1] == pytest.approx(ref.slope, rel=1e-10)
    assert fit.stderr.iloc[1] == pytest.approx(ref.stderr, rel=1e-8)
    assert fit.stderr.iloc[0] == pytest.approx(ref.intercept_stderr, rel=1e-8)


def test_health_flags_report_correlation_and_bounds():
    z = np.linspace(0.001, 0.05, 60)
    b = np.repeat([0.05, 0.051], 30)  # nearly one plate size: kc and kphi barely separable
    x = np.vstack([b, np.tile(z[:30], 2)])
    y = BEKKER.func(x, 5e3, 8e5, 1.0) * (1 + 0.01 * np.random.default_rng(2).standard_normal(60))
    fit = identify(BEKKER, x, y, [1e3, 1e6, 1.0])
    codes = {flag.code for flag in fit.flags}
    assert "high-correlation" in codes
    text = fit.summary()
    assert "corr(kc, kphi)" in text and "Health:" in text and "Notes:" in text
    negative = identify(BERNSTEIN, z, -BERNSTEIN.func(z, 1e5, 1.0), [-1e4, 1.0])
    assert any(flag.code == "outside-bounds" and "k =" in flag.message for flag in negative.flags)


def test_params_indexable_by_name_and_frozen():
    z = np.linspace(0.001, 0.05, 30)
    fit = identify(BERNSTEIN, z, BERNSTEIN.func(z, 2e5, 0.7) + 1.0, [1e5, 1.0])
    assert fit.params["n"] == pytest.approx(0.7, rel=1e-3)
    assert set(fit.stderr.index) == {"k", "n"}
    with pytest.raises(AttributeError):
        fit.epsilon = 0.0  # type: ignore[misc]


def test_bad_input_is_refused_clearly():
    x = np.linspace(0, 1, 10)
    with pytest.raises(ValueError, match="non-finite"):
        identify(lambda x, a: a * x, x, np.r_[np.nan, x[1:]], [1.0])
    with pytest.raises(ValueError, match="cannot determine"):
        identify(lambda x, a, b, c: a * x, x[:3], x[:3], [1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match="on_failure"):
        identify(lambda x, a: a * x, x, x, [1.0], on_failure="ignore")


def test_unidentifiable_parameter_raises_convergence_error():
    x = np.linspace(0, 1, 20)
    with pytest.raises(ConvergenceError, match="rank-deficient"):
        identify(lambda x, a, b: (a + b) * x, x, 2 * x, [1.0, 0.5])


# -- linear algebra of the LM and of Eq. 4 -----------------------------------------------------


def collinear_rows(n_obs, n_par, gap, seed=0):
    """(p, N) rows of Jᵀ with columns of very different scale and two nearly equal ones:
    cond(J D⁻¹) ~ 1/gap."""
    rng = np.random.default_rng(seed)
    rows = rng.standard_normal((n_par, n_obs)) * np.logspace(-3, 4, n_par)[:, None]
    rows[-1] = rows[-2] * 7.0 + gap * np.abs(rows[-2]).max() * rng.standard_normal(n_obs)
    return rows


@pytest.mark.parametrize("shape", [(5000, 8), (300, 3), (6, 8)])
def test_qr_then_svd_gives_the_svd_of_the_scaled_jacobian(shape):
    from soilstats.fitting.levenberg_marquardt import scaled_svd

    n_obs, n_par = shape
    rows = collinear_rows(n_obs, n_par, 1e-7)
    scale = np.sqrt((rows * rows).sum(axis=1))
    _, sv_ref, vt_ref = np.linalg.svd(rows.T / scale, full_matrices=False)
    for layout in (rows, np.asfortranarray(rows)):  # rows of a C or an F array
        sv, vt = scaled_svd(layout, scale)
        assert sv.shape == sv_ref.shape and vt.shape == vt_ref.shape
        # Backward stable both: each singular value to rounding of the largest one.
        np.testing.assert_allclose(sv, sv_ref, rtol=0, atol=1e-13 * sv_ref[0])
        # Right singular vectors up to sign (the singular values here are distinct).
        for k in range(sv.size):
            sign = np.sign(vt[k] @ vt_ref[k])
            np.testing.assert_allclose(sign * vt[k], vt_ref[k], atol=1e-10 * sv_ref[0] / sv_ref[k])


def test_covariance_of_an_ill_conditioned_jacobian_matches_the_plain_svd():
    from soilstats.fitting.identify import eq4_covariance

    rows = collinear_rows(4000, 6, 1e-6)  # cond ~1e7: the SVD branch of Eq. 4
    scale = np.sqrt((rows * rows).sum(axis=1))
    cond, cov = eq4_covariance(rows.T, rss=3.0, dof=4000 - 6)
    _, sv, vt = np.linalg.svd(rows.T / scale, full_matrices=False)
    reference = (vt.T / sv**2) @ vt / np.outer(scale, scale) * 3.0 / (4000 - 6)
    assert cond == pytest.approx(sv[0] / sv[-1], rel=1e-8) and cond > 1e6
    # Two backward-stable computations: they differ by ~cond·ε, relative to each σᵢσⱼ.
    sd = np.sqrt(np.diag(reference))
    assert np.abs((cov - reference) / np.outer(sd, sd)).max() < 1e-7
    # The eigen branch (well conditioned) against the explicit inverse.
    rows = collinear_rows(4000, 3, 0.5)
    cond, cov = eq4_covariance(rows.T, rss=3.0, dof=4000 - 3)
    reference = np.linalg.inv(rows @ rows.T) * 3.0 / (4000 - 3)
    assert cond < 1e4
    np.testing.assert_allclose(cov, reference, rtol=1e-10)


def test_gram_and_gradient_agree_on_every_path():
    from soilstats.fitting.levenberg_marquardt import _gram_and_gradient

    for n_obs, n_par in ((3000, 3), (40_000, 3), (3000, 6)):
        rows = collinear_rows(n_obs, n_par, 0.3)
        r = np.random.default_rng(1).standard_normal(n_obs)
        gram_ref, g_ref = rows @ rows.T, rows @ r
        block = np.vstack([rows, np.zeros(n_obs)])
        for gram, g in (
            _gram_and_gradient(rows, r),  # one gemm (small) or dot products (large)
            _gram_and_gradient(np.asfortranarray(rows), r),
            _gram_and_gradient(block[:n_par], r, block),  # the residuals in a spare row
        ):
            np.testing.assert_allclose(gram, gram_ref, rtol=1e-12)
            np.testing.assert_allclose(g, g_ref, rtol=1e-10, atol=1e-12 * np.abs(g_ref).max())
        np.testing.assert_array_equal(block[n_par], r)


def test_spare_row_jacobian_gives_the_same_fit():
    from soilstats.fitting.levenberg_marquardt import levenberg_marquardt

    rng = np.random.default_rng(2)
    b = np.repeat([0.03, 0.06], 200)
    z = np.tile(np.linspace(1e-3, 0.05, 200), 2)
    y = BEKKER.func((b, z), -9e3, 1.2e6, 0.8) * (1 + 0.02 * rng.standard_normal(b.size))
    terms = BEKKER.power_terms(np.vstack([b, z]), np.ones(b.size))
    start = np.array([-5e3, 1e6, 1.0])
    plain = levenberg_marquardt(lambda t: y - terms.f(t), terms.jac, start)
    spare = levenberg_marquardt(
        lambda t: y - terms.f(t), terms.jacobian_block, start, spare_row=True
    )
    assert plain.converged and spare.converged and plain.niter == spare.niter > 3
    np.testing.assert_allclose(spare.params, plain.params, rtol=1e-13)
    assert spare.jacobian.shape == plain.jacobian.shape == (b.size, 3)


def test_every_stopping_rule_of_the_lm_says_why_it_stopped():
    """Each way out of the loop gives its own reason and converged flag, and hands Eq. 4 the
    Gram matrix and decomposition only where they belong to the end point."""
    from soilstats.fitting.levenberg_marquardt import levenberg_marquardt

    x = np.linspace(0.1, 1.0, 20)
    y = 3 * x + 0.01 * np.sin(40 * x)

    def rows(theta):
        return x[None, :].copy()

    def line(theta):
        return y - theta[0] * x

    exact = levenberg_marquardt(lambda t: 3 * x - t[0] * x, rows, [3.0])
    assert (exact.reason, exact.converged, exact.nfev) == ("zero residual", True, 1)
    flat = levenberg_marquardt(line, rows, [1.0], gtol=1.0)
    assert (flat.reason, flat.converged, flat.nfev) == ("gradient below gtol=1", True, 1)
    # Converged without a last step: the end point's JᵀJ and decomposition go to Eq. 4.
    done = levenberg_marquardt(line, rows, [1.0])
    assert done.reason == "predicted cost reduction below ftol=1e-14" and done.converged
    assert done.gram is not None and done.scaled is not None
    assert done.params[0] == pytest.approx(float(x @ y / (x @ x)), rel=1e-9)
    small = levenberg_marquardt(line, rows, [1.0], ftol=0.0)
    assert small.reason == "step below xtol=1e-12" and small.converged
    # Stopped after a step: the Gram matrix of the point before it is not handed on.
    curve = levenberg_marquardt(
        lambda t: y - t[0] * np.exp(t[1] * x),
        lambda t: np.vstack([np.exp(t[1] * x), t[0] * x * np.exp(t[1] * x)]),
        [1.0, 0.0],
        max_iter=1,
    )
    assert curve.reason == "iteration limit (1) reached" and not curve.converged
    assert (curve.niter, curve.njev, curve.gram, curve.scaled) == (1, 2, None, None)
    nan_jac = levenberg_marquardt(line, lambda t: np.full((1, x.size), np.nan), [1.0])
    assert nan_jac.reason == "the Jacobian is not finite" and not nan_jac.converged
    start = levenberg_marquardt(lambda t: np.full(x.size, np.nan), rows, [1.0])
    assert start.reason == "the model is not finite at the starting values"
    assert (start.converged, start.njev, start.cost) == (False, 0, np.inf)

    def finite_at_one_only(theta):  # every trial step leaves the model's domain
        return 1e140 * y - (x if theta[0] == 1.0 else np.nan)

    stuck = levenberg_marquardt(finite_at_one_only, rows, [1.0], xtol=0.0, ftol=0.0)
    assert stuck.reason == "no step reduces the cost (damping exhausted)"
    assert not stuck.converged and stuck.params[0] == 1.0 and stuck.nfev > 10


def test_eigh_without_numpys_wrapper_matches_numpy():
    from soilstats.fitting.levenberg_marquardt import small_eigh

    a = np.random.default_rng(3).standard_normal((5, 5))
    a = a @ a.T
    eig, vecs = small_eigh(a)
    eig_ref, vecs_ref = np.linalg.eigh(a)
    np.testing.assert_allclose(eig, eig_ref, rtol=1e-13)
    np.testing.assert_allclose(np.abs(vecs), np.abs(vecs_ref), atol=1e-12)


def test_bad_weights_are_refused_clearly():
    x = np.linspace(0.1, 1, 10)
    y = 2 * x

    def line(x, a):
        return a * x

    for weights in (np.r_[np.nan, np.ones(9)], np.r_[np.inf, np.ones(9)], np.r_[-1.0, np.ones(9)]):
        with pytest.raises(ValueError, match="weights must be finite and non-negative"):
            identify(line, x, y, [1.0], weights=weights)
    # A NaN measurement is refused even where its weight is zero.
    with pytest.raises(ValueError, match="non-finite"):
        identify(line, x, np.r_[np.nan, y[1:]], [1.0], weights=np.r_[0.0, np.ones(9)])
    # A scalar weight is broadcast.
    assert identify(line, x, y + 0.01 * np.sin(40 * x), [1.0], weights=2.0).converged


def test_epsilon_from_a_known_rss_is_the_same_number():
    e = np.array([0.1, -0.1, 0.2, 0.0])
    y = np.array([1.0, -2.0, 3.0, 4.0])
    assert epsilon(e, y, rss=float(e @ e)) == epsilon(e, y)


def test_zero_weights_leave_samples_out_of_dof_and_epsilon():
    """A sample of weight zero is not an observation: the fit equals the one without it —
    estimates, σ (Eq. 4's s² over N − Np of the kept samples), ε (Eq. 2) and N — and σ
    equals curve_fit's on the kept samples. Counting them made σ 0.70× too small here."""
    from scipy.optimize import curve_fit

    rng = np.random.default_rng(0)
    z = np.linspace(0.002, 0.05, 40)
    p = 2e5 * z**0.9 * (1 + 0.03 * rng.normal(size=z.size))
    w = np.ones(z.size)
    w[::2] = 0.0
    keep = w > 0

    def power(z, k, n):
        return k * z**n

    for model in (BERNSTEIN, power):  # the model's fast path and a plain callable
        weighted = identify(model, z, p, [1e5, 1.0], weights=w)
        subset = identify(model, z[keep], p[keep], [1e5, 1.0])
        assert (weighted.nobs, weighted.dof) == (subset.nobs, subset.dof) == (20, 18)
        np.testing.assert_allclose(weighted.values, subset.values, rtol=1e-8)
        np.testing.assert_allclose(weighted.stderr_values, subset.stderr_values, rtol=1e-6)
        assert weighted.epsilon == pytest.approx(subset.epsilon, rel=1e-12)
    _, pcov = curve_fit(power, z[keep], p[keep], p0=[1e5, 1.0])
    np.testing.assert_allclose(weighted.stderr_values, np.sqrt(np.diag(pcov)), rtol=1e-5)
    with pytest.raises(ValueError, match="2 observations of non-zero weight cannot determine 2"):
        identify(BERNSTEIN, z, p, [1e5, 1.0], weights=np.r_[1.0, 1.0, np.zeros(38)])
