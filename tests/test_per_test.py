"""fit_per_test: one parameter set per test, checked against each test's simulated truth."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from soilstats import ConvergenceWarning, fit_per_test
from soilstats.campaign import Campaign
from soilstats.simulation import simulate

SPEC = {
    "name": "per-test",
    "scatter": {"stiffness_cv": 0.15, "n_sd": 0.03, "c_cv": 0.05, "phi_sd_deg": 0.5, "K_cv": 0.2},
    "soils": {"sand": {"kc": -9.8e3, "kphi": 1.2e6, "n": 0.8, "c": 100.0, "phi": 30.0, "K": 0.01}},
    "series": [
        {
            "name": "plates",
            "kind": "sinkage",
            "soils": ["sand"],
            "plates": [{"shape": "circle", "radius_m": 0.05}, {"shape": "circle", "radius_m": 0.1}],
            "repetitions": 6,
        },
        {
            "name": "ring",
            "kind": "shear",
            "soils": ["sand"],
            "rings": [{"r_inner_m": 0.1, "r_outer_m": 0.15}],
            "normal_pressure_Pa": [4e3, 12e3],
            "repetitions": 4,
        },
    ],
}


@pytest.fixture(scope="module")
def simulated():
    return simulate(SPEC, seed=11)


def test_sinkage_tests_recover_their_own_drawn_parameters(simulated):
    fits = fit_per_test(simulated.campaign, "sinkage")
    truth = simulated.test_truth.set_index("test_id").loc[fits["test_id"]]
    k_true = truth["kc"].to_numpy() / fits["b_m"].to_numpy() + truth["kphi"].to_numpy()
    assert len(fits) == 12 and fits["converged"].all()
    # The drawn scatter (15 % in k, 0.03 in n) is far larger than these tolerances, so a fit
    # that returned the soil-level value instead of the test's own would fail.
    np.testing.assert_allclose(fits["k"], k_true, rtol=0.03)
    np.testing.assert_allclose(fits["n"], truth["n"], atol=0.005)
    assert (fits["n_stderr"] > 0).all() and (fits["epsilon"] > 0.95).all()


def test_shear_tests_give_plateau_and_K_of_each_test(simulated):
    fits = fit_per_test(simulated.campaign, "shear")
    truth = simulated.test_truth.set_index("test_id").loc[fits["test_id"]]
    # τ_max = c + σ tan φ with the apparent (recorded) c, φ of each test and its set pressure
    tau_true = truth["c"] + truth["normal_pressure_Pa"] * np.tan(np.radians(truth["phi"]))
    assert len(fits) == 8 and fits["converged"].all() and fits["steady"].all()
    np.testing.assert_allclose(fits["tau_max"], tau_true, rtol=0.03)
    np.testing.assert_allclose(fits["K"], truth["K"], rtol=0.15)
    np.testing.assert_allclose(fits["tau_ss_Pa"], fits["tau_max"], rtol=0.03)


def test_a_failed_test_keeps_its_row_and_warns():
    tests = pd.DataFrame(
        {
            "test_id": ["good", "flat"],
            "kind": "sinkage",
            "soil": "s",
            "shape": "circle",
            "radius_m": 0.05,
        }
    )
    z = np.linspace(1e-3, 0.03, 50)
    frames = [
        pd.DataFrame({"test_id": "good", "z_m": z, "force_N": 1e6 * z**0.9 * np.pi * 0.05**2}),
        pd.DataFrame({"test_id": "flat", "z_m": z[:2], "force_N": [0.0, 0.0]}),
    ]
    campaign = Campaign.from_frames(tests, pd.concat(frames, ignore_index=True))
    with pytest.warns(ConvergenceWarning, match="1 of 2 per-test sinkage fits.*flat"):
        fits = fit_per_test(campaign, "sinkage")
    flat = fits.set_index("test_id").loc["flat"]
    assert not flat["converged"] and np.isnan(flat["k"]) and "samples" in flat["message"]
    assert fits.set_index("test_id").loc["good", "n"] == pytest.approx(0.9, abs=1e-6)
