"""Variable projection on the exponent n: same optimum as the full LM, never a verdict."""

from __future__ import annotations

import numpy as np
import pytest

from soilstats import BEKKER, identify
from soilstats.fitting.separable import refine_exponent


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
