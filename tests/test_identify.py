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
