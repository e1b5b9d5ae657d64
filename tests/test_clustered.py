"""The per-test-sum refits of the cluster bootstrap equal exact weighted least squares."""

from __future__ import annotations

import numpy as np
import pytest

from soilstats import BEKKER, BERNSTEIN
from soilstats.fitting.clustered import fit_clustered_resamples
from soilstats.fitting.separable import fit_separable_batch


def _tests(seed, sizes, n_tests=18, points=40):
    """Bekker data with per-test scatter; z from 0.5 to 60 mm (ln z spans 4.8)."""
    rng = np.random.default_rng(seed)
    b, z, p, w, test = [], [], [], [], []
    for i in range(n_tests):
        size = sizes[i % len(sizes)]
        zi = np.sort(rng.uniform(5e-4, 0.06, points))
        kphi, n = 1.2e6 * rng.normal(1, 0.1), 0.8 + rng.normal(0, 0.03)
        pi = (-9.8e3 / size + kphi) * zi**n * (1 + rng.normal(0, 0.01, points))
        b.append(np.full(points, size)), z.append(zi), p.append(pi)
        w.append(np.full(points, 1 / pi.max())), test.append(np.full(points, i))
    return (np.concatenate(v) for v in (b, z, p, w, test))


def _counts(seed, rows, n_tests):
    rng = np.random.default_rng(seed)
    counts = np.zeros((rows, n_tests))
    np.add.at(counts, (np.arange(rows)[:, None], rng.integers(0, n_tests, (rows, n_tests))), 1)
    return counts


@pytest.mark.parametrize("model", [BEKKER, BERNSTEIN])
def test_resample_refits_equal_exact_variable_projection(model):
    b, z, p, w, test = _tests(1, (0.025, 0.05, 0.075))
    x = z if model is BERNSTEIN else np.vstack([b, z])
    basis, log_z = model.separable(x, np.ones_like(w))
    g = basis(0.0)
    counts = _counts(2, 150, test.max() + 1)
    first = np.unique(test, return_index=True)[1]
    theta, ok = fit_clustered_resamples(g[:, first].T, log_z, p, w, test, counts, 0.8)
    exact, ok_exact = fit_separable_batch(g, log_z, p, w * np.sqrt(counts[:, test]), 0.8)
    assert ok.all() and ok_exact.all()
    np.testing.assert_allclose(theta, exact, rtol=1e-9)
    # and the estimates do move between resamples (the comparison is not of constants)
    assert np.std(theta[:, -1]) > 1e-3


def test_singular_and_far_resamples_are_left_to_the_caller():
    b, z, p, w, test = _tests(3, (0.025, 0.05))
    x = np.vstack([b, z])
    basis, log_z = BEKKER.separable(x, np.ones_like(w))
    g = basis(0.0)
    first = np.unique(test, return_index=True)[1]
    counts = _counts(4, 3, test.max() + 1)
    counts[0] = 0
    counts[0, ::2] = 1  # only the 25 mm plates: kc and kφ are not separable
    theta, ok = fit_clustered_resamples(g[:, first].T, log_z, p, w, test, counts, 0.8)
    assert not ok[0] and np.isnan(theta[0]).all()
    assert ok[1:].all()
    # a start far from the optimum (|δn|·ln-range beyond the Taylor reach) is not trusted
    theta, ok = fit_clustered_resamples(g[:, first].T, log_z, p, w, test, counts[1:], 3.0)
    assert not ok.any()
