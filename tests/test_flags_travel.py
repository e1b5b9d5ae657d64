"""Flags that travel (#46 item 5): a pooled fit the posterior starts from carries
``aggregation-bias`` when its n lies outside every test's own n, with the test-level σ, so
``PosteriorResult.least_squares_health()`` (and every report of it) names it."""

from __future__ import annotations

import numpy as np
import pandas as pd

from soilstats import Campaign
from soilstats.bayes.data import pooled_problem


def _load_capped(cap_pa: float = 60e3) -> Campaign:
    """Six tests of one soil on one plate, each an exact p = k z (n = 1) with k spread 8x,
    every test stopped at the same pressure: the soft ones run deeper, so the pooled curve
    through all samples bends below every test's own exponent."""
    rng = np.random.default_rng(4)
    radius = 0.05
    area = np.pi * radius**2
    tests, rows = [], []
    for i, k in enumerate(np.geomspace(1e6, 8e6, 6)):
        tid = f"t{i}"
        tests.append(
            {"test_id": tid, "kind": "sinkage", "soil": "s", "shape": "circle", "radius_m": radius}
        )
        z = np.linspace(0.0005, cap_pa / k, 60)
        p = k * z * (1 + 0.002 * rng.standard_normal(z.size))
        rows += [{"test_id": tid, "z_m": a, "force_N": b * area} for a, b in zip(z, p, strict=True)]
    return Campaign.from_frames(pd.DataFrame(tests), pd.DataFrame(rows))


def test_the_pooled_fit_below_every_test_carries_aggregation_bias_with_the_test_sigma():
    _, fit = pooled_problem(_load_capped(), "bernstein")
    flags = [f for f in fit.flags if f.code == "aggregation-bias"]
    assert fit.params["n"] < 0.95  # the tests' own n are 1.00 +/- 0.01
    assert len(flags) == 1
    assert "below all 6 tests' own n" in flags[0].message
    assert "test-level σ of n" in flags[0].message


def test_a_pooled_fit_inside_the_tests_range_carries_none():
    # Every test stopped at the same depth instead: the pooled n is the tests' n.
    rng = np.random.default_rng(5)
    tests, rows = [], []
    for i, k in enumerate(np.geomspace(1e6, 8e6, 6)):
        tid = f"t{i}"
        tests.append(
            {"test_id": tid, "kind": "sinkage", "soil": "s", "shape": "circle", "radius_m": 0.05}
        )
        z = np.linspace(0.0005, 0.03, 60)
        p = k * z ** (1.0 + 0.05 * rng.standard_normal()) * (1 + 0.002 * rng.standard_normal(60))
        rows += [
            {"test_id": tid, "z_m": a, "force_N": b * np.pi * 0.05**2}
            for a, b in zip(z, p, strict=True)
        ]
    campaign = Campaign.from_frames(pd.DataFrame(tests), pd.DataFrame(rows))
    _, fit = pooled_problem(campaign, "bernstein")
    assert not [f for f in fit.flags if f.code == "aggregation-bias"]


def test_the_rezeroing_message_quotes_the_test_level_sigma_without_the_bootstrap():
    """Every test of a soil zeroed 2 mm above the surface: screening re-zeroes them, the fit
    moves far from the one on z as logged, and the flag quotes the move of n in test-level σ
    (the tests' own n) even where the fit has no test bootstrap, as a posterior's start."""
    from soilstats import fit_sinkage
    from soilstats.campaign.schema import DERIVED_COLUMNS
    from soilstats.simulation import simulate

    toe = 2e-3
    spec = {
        "name": "toe",
        "scatter": {"stiffness_cv": 0.1, "n_sd": 0.03},
        "noise": {"force_N": 0.2, "force_offset_N": 0.2},
        "soils": {"loam": {"kc": 1.0e4, "kphi": 2.0e6, "n": 1.1}},
        "series": [
            {
                "name": "plates",
                "kind": "sinkage",
                "soils": ["loam"],
                "plates": [{"shape": "circle", "radius_m": r} for r in (0.025, 0.05, 0.075)],
                "repetitions": 6,
                "points": 150,
                "sinkage_m": 0.03,
                "start_m": -5e-4 - toe,
            }
        ],
    }
    sim = simulate(spec, seed=3).campaign
    tests = sim.tests.drop(columns=list(DERIVED_COLUMNS["tests"]), errors="ignore")
    sink = sim.sinkage.drop(columns=list(DERIVED_COLUMNS["sinkage"]), errors="ignore")
    sink = sink.reset_index(drop=True).assign(z_m=lambda t: t["z_m"] + toe)
    fit = fit_sinkage(Campaign.from_frames(tests, sink), "bernstein", test_resamples=0)
    flags = [f for f in fit.flags if f.code == "rezero-sensitive"]
    assert len(flags) == 1
    assert "Eq. 4 σ" in flags[0].message and "test-level σ (σ = " in flags[0].message


def test_a_plate_size_run_in_time_blocks_is_confounded_with_test_order():
    """Plate size changed only between blocks of the sequence: discover must say its effect
    cannot be told apart from test order; interleaved, it says nothing of the kind."""
    from soilstats.discovery.candidates import enumerate_candidates, relation_text, relations

    def table(b_values):
        return pd.DataFrame(
            {
                "test_id": [f"t{i}" for i in range(12)],
                "soil": "s",
                "sequence": np.arange(1, 13),
                "b_m": b_values,
                "n": np.linspace(0.8, 1.0, 12),
            }
        )

    blocked = table(np.repeat([0.025, 0.05, 0.075], 4))
    cands, _ = enumerate_candidates(blocked, "sinkage")
    found = [r for r in relations(blocked, cands) if r.kind == "time-blocks"]
    assert [(r.finer, r.coarser) for r in found] == [("b_m", "sequence")]
    assert "cannot be told apart from test order" in relation_text(found[0], blocked)
    mixed = table(np.tile([0.025, 0.05, 0.075], 4))
    cands, _ = enumerate_candidates(mixed, "sinkage")
    assert not [r for r in relations(mixed, cands) if r.kind == "time-blocks"]
