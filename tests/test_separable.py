"""Variable projection on the exponent n: same optimum as the full LM, never a verdict."""

from __future__ import annotations

import numpy as np
import pytest

from soilstats import BEKKER, BERNSTEIN, identify
from soilstats.fitting.separable import _reduced, refine_exponent, refine_power_law


def bekker_data(seed=3, radii=(0.025, 0.05, 0.075)):
    rng = np.random.default_rng(seed)
    b = np.repeat(radii, 60)
    z = np.tile(np.linspace(1e-3, 0.04, 60), len(radii))
    p = BEKKER.func((b, z), -9.8e3, 1.2e6, 0.8) * (1 + 0.03 * rng.standard_normal(b.size))
    return np.vstack([b, z]), p


def test_reaches_the_least_squares_optimum_from_a_poor_start():
    x, p = bekker_data()
    w = np.ones(p.size)
    basis, log_z = BEKKER.separable(x, w)
    theta, iterations = refine_exponent(basis, log_z, p, np.array([0.0, 1.0, 1.6]), ftol=1e-15)
    # Independent optimum: the generic LM with a complex-step Jacobian and no model shortcuts.
    generic = identify(lambda x, kc, kphi, n: BEKKER.func(x, kc, kphi, n), x, p, [-9e3, 1.1e6, 0.8])
    assert iterations >= 3
    np.testing.assert_allclose(theta, generic.values, rtol=1e-7)


def test_one_plate_size_leaves_the_start_to_the_full_lm():
    x, p = bekker_data(radii=(0.05,))
    start = np.array([1.0, 2.0, 0.9])
    basis, log_z = BEKKER.separable(x, np.ones(p.size))
    theta, iterations = refine_exponent(basis, log_z, p, start, ftol=1e-15)
    assert iterations == 0 and np.array_equal(theta, start)


def test_identify_result_is_unchanged_by_the_shortcut():
    x, p = bekker_data(seed=5)
    fast = identify(BEKKER, x, p, [-5e3, 1e6, 1.0])
    slow = identify(BEKKER.func, x, p, [-5e3, 1e6, 1.0], jac=BEKKER.jac)
    assert fast.converged and fast.niter <= 2
    np.testing.assert_allclose(fast.values, slow.values, rtol=1e-8)
    np.testing.assert_allclose(fast.stderr_values, slow.stderr_values, rtol=1e-6)
    assert fast.epsilon == pytest.approx(slow.epsilon, rel=1e-10)


def test_batch_reaches_each_rows_own_optimum_and_leaves_singular_rows_unconverged():
    from soilstats.fitting.separable import fit_separable_batch

    x, p = bekker_data(seed=7)
    rng = np.random.default_rng(1)
    weights = rng.uniform(0.2, 2.0, (6, p.size))
    weights[3, 60:] = 0.0  # one plate only: kc and kphi cannot be separated
    basis, log_z = BEKKER.separable(x, np.ones(p.size))
    theta, ok = fit_separable_batch(basis(0.0), log_z, p, weights, 0.6)
    assert ok.tolist() == [True, True, True, False, True, True]
    assert np.isnan(theta[3]).all()
    for i in np.flatnonzero(ok):  # each row against its own weighted fit by the generic LM
        generic = identify(
            lambda x, kc, kphi, n: BEKKER.func(x, kc, kphi, n),
            x,
            p,
            [-9e3, 1.1e6, 0.8],
            weights=weights[i],
        )
        np.testing.assert_allclose(theta[i], generic.values, rtol=1e-6)


def test_bootstrap_blocks_of_resamples_give_the_same_draws(monkeypatch):
    # The bootstrap hands the batch solver blocks of resamples (bounded memory): any block
    # size gives the same estimates.
    from soilstats.identification import bootstrap

    x, p = bekker_data(seed=7)
    test_index = np.repeat(np.arange(18), 10)
    args = (BEKKER, x, p, np.ones(p.size), test_index, np.array([-9.8e3, 1.2e6, 0.8]))
    whole = bootstrap.bootstrap_tests(*args, n_resamples=40, seed=2)
    monkeypatch.setattr(bootstrap, "BATCH_ELEMENTS", 2 * p.size)  # blocks of 2 resamples
    blocks = bootstrap.bootstrap_tests(*args, n_resamples=40, seed=2)
    assert whole.n_failed == blocks.n_failed == 0
    np.testing.assert_allclose(blocks.draws, whole.draws, rtol=1e-12)


# -- the power-law projection of identify (moments, Newton, Halley's last step) ---------------


def random_power_law(seed, model):
    """A random Bekker (1–3 plates) or Bernstein problem, weighted or not, sometimes with
    samples out of contact (z ≤ 0), and a start near the truth as Wong's would be."""
    rng = np.random.default_rng(seed)
    plates = rng.uniform(0.02, 0.1, rng.integers(2, 4) if model is BEKKER else 1)
    m = int(rng.integers(20, 300))
    b = np.repeat(plates, m)
    z = np.tile(np.sort(rng.uniform(1e-4, 0.08, m)), plates.size)
    if seed % 5 == 0:
        z[:3] = [0.0, -1e-4, 0.0]
    truth = np.array([rng.normal(0, 1e4), rng.uniform(2e5, 3e6), rng.uniform(0.3, 2.0)])
    if model is BERNSTEIN:
        truth = truth[1:]
    x = np.vstack([b, z]) if model is BEKKER else z
    y = model.func(x, *truth) * (1 + rng.uniform(1e-3, 0.1) * rng.standard_normal(z.size))
    w = rng.uniform(0.2, 2.0, z.size) if seed % 2 else None
    return x, y, w, truth * rng.uniform(0.8, 1.2, truth.size)


def moments(terms, wy, n, third_order=True):
    """The product [U; V]·[U, V, wy, wy·ln z, W, wy·ln²z]ᵀ of refine_power_law, directly."""
    q, lz = terms.rows.shape[0], terms.log_z
    u = terms.rows * np.exp(n * lz)
    columns = [u, u * lz, wy[None], (wy * lz)[None]]
    if third_order:
        columns += [u * lz * lz, (wy * lz * lz)[None]]
    return (np.vstack(columns[:2]) @ np.vstack(columns).T).ravel().tolist(), q


@pytest.mark.parametrize("model", [BEKKER, BERNSTEIN])
def test_reduced_derivatives_match_finite_differences(model):
    # Slope, curvature (Newton's, exact) and third derivative of the reduced cost, and the
    # derivatives of a(n), against 5-point differences of a direct computation.
    x, y, w, _ = random_power_law(4, model)
    w = np.ones(y.size) if w is None else w
    terms, wy = model.power_terms(x, w), w * y

    def direct(n):
        u = terms.rows * np.exp(n * terms.log_z)
        a = np.linalg.solve(u @ u.T, u @ wy)
        r = wy - a @ u
        return 0.5 * r @ r, a

    def diff(f, n, k, h):
        if k == 1:
            return (-f(n + 2 * h) + 8 * f(n + h) - 8 * f(n - h) + f(n - 2 * h)) / (12 * h)
        if k == 2:
            return (-f(n + 2 * h) + 16 * f(n + h) - 30 * f(n) + 16 * f(n - h) - f(n - 2 * h)) / (
                12 * h * h
            )
        return (f(n + 2 * h) - 2 * f(n + h) + 2 * f(n - h) - f(n - 2 * h)) / (2 * h**3)

    n0 = 0.85
    a, da, d2a, cost, slope, curvature, third, _ = _reduced(*moments(terms, wy, n0), wy @ wy)
    cost_of = lambda n: direct(n)[0]  # noqa: E731
    assert cost == pytest.approx(cost_of(n0), rel=1e-10)
    assert slope == pytest.approx(diff(cost_of, n0, 1, 2e-3), rel=1e-8)
    assert curvature == pytest.approx(diff(cost_of, n0, 2, 2e-3), rel=1e-8)
    assert third == pytest.approx(diff(cost_of, n0, 3, 1e-2), rel=1e-3)
    for i in range(len(a)):
        coefficient = lambda n, i=i: direct(n)[1][i]  # noqa: E731
        assert a[i] == pytest.approx(coefficient(n0), rel=1e-12)
        assert da[i] == pytest.approx(diff(coefficient, n0, 1, 2e-3), rel=1e-8)
        assert d2a[i] == pytest.approx(diff(coefficient, n0, 2, 2e-3), rel=1e-7)
    # Without the third-order columns: the same numbers, and no third derivative.
    newton = _reduced(*moments(terms, wy, n0, third_order=False), wy @ wy)
    assert newton[:2] + newton[3:6] == (a, da, cost, slope, curvature)
    assert np.isnan(newton[6])


@pytest.mark.parametrize("model", [BEKKER, BERNSTEIN])
def test_scalar_projection_reaches_the_optimum_of_the_array_form(model):
    for seed in range(12):
        x, y, w, start = random_power_law(seed, model)
        w = np.ones(y.size) if w is None else w
        terms, wy = model.power_terms(x, w), w * y
        fast, iterations = refine_power_law(terms, wy, start, ftol=1e-15)
        basis, log_z = model.separable(x, w)
        reference, _ = refine_exponent(basis, log_z, wy, start, ftol=1e-15)
        assert 1 <= iterations <= 6
        np.testing.assert_allclose(fast, reference, rtol=1e-7)


def test_scalar_projection_from_a_poor_start_and_a_singular_basis():
    x, p = bekker_data()
    w = np.ones(p.size)
    theta, iterations = refine_power_law(
        BEKKER.power_terms(x, w), p, np.array([0.0, 1.0, 1.6]), ftol=1e-15
    )
    generic = identify(lambda x, kc, kphi, n: BEKKER.func(x, kc, kphi, n), x, p, [-9e3, 1.1e6, 0.8])
    assert iterations >= 3
    np.testing.assert_allclose(theta, generic.values, rtol=1e-7)
    # One plate size: kc and kphi cannot be separated; the start is handed back untouched.
    x, p = bekker_data(radii=(0.05,))
    w = np.ones(p.size)
    start = np.array([1.0, 2.0, 0.9])
    theta, iterations = refine_power_law(BEKKER.power_terms(x, w), p, start, ftol=1e-15)
    assert iterations == 0 and np.array_equal(theta, start)
    # A start the model cannot be evaluated at: handed back too (the LM then says so).
    theta, iterations = refine_power_law(
        BEKKER.power_terms(x, w), p, np.array([1.0, 2.0, np.nan]), ftol=1e-15
    )
    assert iterations == 0 and np.isnan(theta[-1])


@pytest.mark.parametrize("model", [BEKKER, BERNSTEIN])
def test_fast_path_agrees_with_the_general_lm(model):
    # The power-law path (variable projection, then the LM's confirmation) against the plain
    # weighted LM of Eq. 1 with the analytic Jacobian and tolerances at rounding level.  The
    # optimum itself is only defined to ~1e-7 σ in float64 (points that far apart have costs
    # equal to 1e-15), so that, not 1e-10 relative, is the agreement to ask for.
    for seed in range(20):
        x, y, w, start = random_power_law(seed, model)
        fast = identify(model, x, y, start, weights=w)
        general = identify(
            model.func, x, y, start, weights=w, jac=model.jac, ftol=1e-30, gtol=1e-30, xtol=1e-15
        )
        assert fast.converged and fast.niter <= 2
        assert np.all(np.abs(fast.values - general.values) <= 1e-6 * general.stderr_values)
        np.testing.assert_allclose(fast.stderr_values, general.stderr_values, rtol=1e-6)
        assert fast.rss == pytest.approx(general.rss, rel=1e-12)
        assert fast.epsilon == pytest.approx(general.epsilon, rel=1e-12)
        # A shift of 1e-6 σ moves each fitted value by less than 1e-6 of the residual sd.
        scale = np.sqrt(general.rss / general.dof)
        np.testing.assert_allclose(fast.residuals, general.residuals, rtol=0, atol=1e-6 * scale)


@pytest.mark.parametrize("model", [BEKKER, BERNSTEIN])
def test_power_law_terms_match_the_model_and_its_jacobian(model):
    x, y, w, start = random_power_law(5, model)  # seed 5: samples out of contact
    terms = model.power_terms(x, w if w is not None else np.ones(y.size))
    weights = w if w is not None else 1.0
    np.testing.assert_allclose(terms.f(start), weights * model.func(x, *start), rtol=1e-13)
    block = terms.jacobian_block(start)
    assert block.shape == (start.size + 1, y.size)
    np.testing.assert_allclose(
        block[:-1].T, np.asarray(weights)[..., None] * model.jac(x, *start), rtol=1e-13, atol=0
    )
    np.testing.assert_array_equal(terms.jac(start), block[:-1])
    z = x[1] if model is BEKKER else x
    assert np.all(terms.f(start)[z <= 0] == 0) and np.all(block[:-1, z <= 0] == 0)
