"""The one home of starting values: closed forms they must satisfy on exact data."""

from __future__ import annotations

import numpy as np

from soilstats.models import BEKKER, JANOSI, REECE, side_wall_ratio
from soilstats.models.starting_values import (
    janosi_start,
    reece_from_bekker,
    sinkage_start,
)


def test_reece_from_bekker_is_exact_for_one_plate_size():
    b = np.full(50, 0.05)
    z = np.linspace(0.001, 0.03, 50)
    theta = np.array([2.0e4, 8.0e5, 1.1])
    k1, k2, n = reece_from_bekker(theta, b)
    x = np.vstack([b, z])
    np.testing.assert_allclose(REECE.func(x, k1, k2, n), BEKKER.func(x, *theta), rtol=1e-12)


def test_sinkage_start_recovers_an_exact_bekker_law():
    b = np.repeat([0.025, 0.05, 0.1], 40)
    z = np.tile(np.linspace(0.002, 0.04, 40), 3)
    truth = np.array([3.0e4, 1.2e6, 0.9])
    p = BEKKER.func(np.vstack([b, z]), *truth)
    np.testing.assert_allclose(sinkage_start("bekker", b, z, p), truth, rtol=1e-8)
    bern = sinkage_start("bernstein", b[:40], z[:40], p[:40])
    np.testing.assert_allclose(bern, [truth[0] / 0.025 + truth[1], truth[2]], rtol=1e-8)


def test_janosi_start_is_near_the_truth_on_an_exact_curve():
    sigma = np.repeat([5e3, 10e3, 20e3], 100)
    j = np.tile(np.linspace(0.0, 0.08, 100), 3)
    truth = (800.0, 32.0, 0.008)
    tau = JANOSI.func(np.vstack([sigma, j]), *truth)
    c, phi, k = janosi_start(sigma, j, tau)
    assert abs(phi - truth[1]) < 1.0
    assert abs(c - truth[0]) < 0.2 * truth[0]
    assert 0.5 * truth[2] < k < 2.0 * truth[2]


def test_side_wall_ratio_closed_form():
    # a = 3h(ri² + ro²)/(ro³ − ri³): 3·0.01·(0.01 + 0.0225)/(0.003375 − 0.001)
    assert np.isclose(side_wall_ratio(0.1, 0.15, 0.01), 3 * 0.01 * 0.0325 / 0.002375, rtol=1e-14)
    assert side_wall_ratio(0.1, 0.15, 0.0) == 0.0
    np.testing.assert_allclose(side_wall_ratio([0.1, 0.1], [0.15, 0.15], [0.0, 0.01])[1], 0.4105263)


def test_wong_start_is_wongs_estimate_from_the_certified_solver():
    # The start is solved from per-plate sums; the comparison method (wong_bekker /
    # wong_bernstein) by the certified linear solver. Same regression: same n, same k_b.
    from soilstats.models.wong import wong_bekker, wong_bernstein, wong_start

    rng = np.random.default_rng(3)
    b = np.repeat([0.025, 0.05, 0.075], 60)
    z = np.tile(np.linspace(0.001, 0.05, 60), 3)
    p = BEKKER.func(np.vstack([b, z]), -9.8e3, 1.2e6, 0.8) * rng.normal(1, 0.03, b.size)
    p[:3] = -1.0  # no logarithm: excluded by both
    start, certified = wong_start(b, z, p), wong_bekker(b, z, p)[0]
    np.testing.assert_allclose(start[2], certified[2], rtol=1e-11)
    # (kc, kφ): the start's line through the plates' k_b is unweighted, the certified
    # method's is generalised least squares; both go through k_b, so they agree closely.
    np.testing.assert_allclose(start[:2], certified[:2], rtol=1e-3)
    np.testing.assert_allclose(
        wong_start(None, z[:60], p[:60]), wong_bernstein(z[:60], p[:60])[0], rtol=1e-11
    )


def test_wong_start_refuses_what_wongs_method_cannot_do():
    import pytest

    from soilstats.models.wong import wong_start

    z = np.linspace(0.001, 0.05, 20)
    with pytest.raises(ValueError, match="two plate sizes"):
        wong_start(np.full(20, 0.05), z, z)
    with pytest.raises(ValueError, match="more than one sinkage"):
        wong_start(np.repeat([0.025, 0.05], 10), np.full(20, 0.01), np.arange(1.0, 21.0))
