"""The one home of starting values: closed forms they must satisfy on exact data."""

from __future__ import annotations

import numpy as np

from soilstats.identification.starting_values import (
    janosi_start,
    reece_from_bekker,
    sinkage_start,
)
from soilstats.models import BEKKER, JANOSI, REECE, side_wall_ratio


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
