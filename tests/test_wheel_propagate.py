"""predict_wheel: draws through the wheel model, correlations kept, priors never invented."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from soilstats.errors import SoilstatsWarning
from soilstats.wheel import StressAngles, Wheel, WheelPrediction, predict_wheel, wheel_forces

WHEEL = Wheel(radius_m=0.058, width_m=0.05, name="CMU smooth")
SHEAR_PRIORS = {"phi": ("normal", 30, 3), "c": ("uniform", 0, 1000), "K": ("lognormal", 0.01, 0.5)}
SLIPS = [-0.5, 0.0, 0.3, 0.6]


def _bekker_draws(n=400, seed=0, kc_sd=8000.0):
    """kc and kφ perfectly anticorrelated so that kc/b + kφ is the same in every draw."""
    rng = np.random.default_rng(seed)
    kc = rng.normal(-2000.0, kc_sd, n)
    kphi = 1.2e6 - kc / WHEEL.width_m
    return pd.DataFrame({"kc": kc, "kphi": kphi, "n": np.full(n, 1.1)})


def test_rows_are_used_whole_correlations_kept():
    # The sinkage depends on kc and kφ only through kc/b + kφ (a linear response), which the
    # perfect anticorrelation holds fixed: every draw gives the same sinkage, band width 0.
    # Shuffling the columns independently breaks the pairing and the band opens wide.
    draws = _bekker_draws()
    with pytest.warns(SoilstatsWarning, match="not predicted"):
        kept = predict_wheel(draws, WHEEL, 22.0, SLIPS)
    band = kept.band("sinkage_m")
    assert np.all((band["upper"] - band["lower"]) < 1e-9 * band["median"])
    shuffled = draws.assign(kphi=np.random.default_rng(1).permutation(draws["kphi"].to_numpy()))
    with pytest.warns(SoilstatsWarning):
        broken = predict_wheel(shuffled, WHEEL, 22.0, SLIPS)
    wide = broken.band("sinkage_m")
    assert np.all((wide["upper"] - wide["lower"]) > 0.05 * wide["median"])


def test_each_output_is_the_model_applied_to_its_own_row():
    rng = np.random.default_rng(3)
    draws = pd.DataFrame(
        {
            "k": rng.lognormal(np.log(8e6), 0.2, 50),
            "n": rng.normal(1.46, 0.05, 50),
            "c": rng.uniform(0, 1000, 50),
            "phi": rng.normal(29, 2, 50),
            "K": rng.lognormal(np.log(0.02), 0.3, 50),
            "unused": rng.normal(size=50),
        }
    )
    pred = predict_wheel(draws, WHEEL, 22.0, SLIPS, law="bernstein")
    samples = pred.samples.set_index(["draw", "slip"])
    for i in (0, 17, 49):
        row = draws.iloc[i][["k", "n", "c", "phi", "K"]].to_dict()
        single = wheel_forces(row, WHEEL, SLIPS, law="bernstein", load_N=22.0)
        got = samples.loc[i]
        np.testing.assert_allclose(got["sinkage_m"], single.sinkage_m, rtol=1e-9)
        np.testing.assert_allclose(
            got["drawbar_pull_N"], single.drawbar_pull_N, rtol=1e-7, atol=1e-9
        )
        np.testing.assert_allclose(got["torque_Nm"], single.torque_Nm, rtol=1e-7)
    # the bands are the quantiles of the per-draw outputs
    dp = pred.samples.pivot(index="draw", columns="slip", values="drawbar_pull_N")
    band = pred.band("drawbar_pull_N")
    np.testing.assert_allclose(band["lower"], dp.quantile(0.05).to_numpy(), rtol=1e-12)
    np.testing.assert_allclose(band["median"], dp.median().to_numpy(), rtol=1e-12)
    assert set(pred.sources.values()) == {"posterior draws"}
    assert "unused" not in pred.sources


def test_shear_priors_are_sampled_seeded_and_labelled():
    draws = _bekker_draws(200, kc_sd=500.0)
    a = predict_wheel(draws, WHEEL, 22.0, SLIPS, priors=SHEAR_PRIORS, seed=5)
    b = predict_wheel(draws, WHEEL, 22.0, SLIPS, priors=SHEAR_PRIORS, seed=5)
    c = predict_wheel(draws, WHEEL, 22.0, SLIPS, priors=SHEAR_PRIORS, seed=6)
    pd.testing.assert_frame_equal(a.bands, b.bands)
    assert not np.allclose(a.band("torque_Nm")["upper"], c.band("torque_Nm")["upper"])
    assert a.sources["kc"] == "posterior draws"
    assert a.sources["phi"] == "user prior normal(30, 3)"
    assert a.sources["K"] == "user prior lognormal(0.01, 0.5)"
    assert not a.unpredictable
    assert {"sinkage_m", "drawbar_pull_N", "torque_Nm", "lateral_force_N"} == set(
        a.bands["quantity"]
    )
    # drawbar pull rises with slip from the skid side; the band has width from the priors
    dp = a.band("drawbar_pull_N")
    assert dp["median"].is_monotonic_increasing and np.all(dp["upper"] > dp["lower"])


def test_without_shear_parameters_sinkage_only_and_a_loud_reason():
    with pytest.warns(SoilstatsWarning, match="drawbar pull and torque are not predicted"):
        pred = predict_wheel(_bekker_draws(100), WHEEL, 22.0, SLIPS)
    assert set(pred.bands["quantity"]) == {"sinkage_m"}
    assert pred.bands[["median", "lower", "upper"]].notna().all().all()
    for q in ("drawbar_pull_N", "torque_Nm"):
        assert "c [Pa], phi [deg] and K [m]" in pred.unpredictable[q]
        with pytest.raises(ValueError, match="not predicted"):
            pred.band(q)
    text = pred.summary()
    assert "NOT PREDICTED: drawbar_pull_N" in text and "NOT PREDICTED: torque_Nm" in text
    assert pred.samples["drawbar_pull_N"].isna().all()


def test_a_load_the_soil_cannot_carry_is_flagged_per_draw():
    draws = pd.DataFrame({"k": [8e6, 8e6, 2e3, 8e6], "n": [1.46, 1.46, 1.46, 1.46]})
    with pytest.warns(SoilstatsWarning, match="1 of 4 draws cannot carry"):
        pred = predict_wheel(draws, WHEEL, 22.0, SLIPS, priors=SHEAR_PRIORS)
    assert pred.not_carried["draw"].unique().tolist() == [2]
    bad = pred.samples[pred.samples["draw"] == 2]
    assert (bad["status"] == "not_carried").all() and bad["sinkage_m"].isna().all()
    assert (pred.bands["n_used"] == 3).all() and (pred.bands["n_not_carried"] == 1).all()
    assert any("draws 2" in note and "cannot carry" in note for note in pred.notes)


def test_prior_only_prediction_and_per_slip_loads():
    priors = {
        "k": ("lognormal", 8e6, 0.1),
        "n": ("truncnormal", 1.46, 0.05, 1.0, 2.0),
        **SHEAR_PRIORS,
    }
    loads = [18.0, 20.0, 22.0, 24.0]
    driving = [0.0, 0.3, 0.6, 0.9]
    pred = predict_wheel(None, WHEEL, loads, driving, priors=priors, n_samples=300, seed=2)
    assert pred.law == "bernstein" and pred.n_draws == 300
    assert all(v.startswith("user prior") for v in pred.sources.values())
    assert pred.load_N == tuple(loads)
    assert pred.band("sinkage_m")["median"].is_monotonic_increasing  # more load, more slip


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"priors": {"kc": ("normal", 0, 1)}}, "also given a prior"),
        ({"priors": {"phi": ("normal", 30, 3)}}, "c \\[Pa\\], phi \\[deg\\] and K \\[m\\]"),
        ({"priors": {**SHEAR_PRIORS, "gamma": ("normal", 1, 1)}}, "not parameters"),
        ({"priors": {**SHEAR_PRIORS, "phi": ("normal", 30, 40)}}, "outside the support"),
        ({"priors": {**SHEAR_PRIORS, "phi": ("beta", 1, 2)}}, "kind one of"),
        ({"law": "reece"}, "soilstats does not invent them"),
    ],
)
def test_bad_requests_say_what_is_wrong(kwargs, match):
    with pytest.raises(ValueError, match=match):
        predict_wheel(_bekker_draws(50), WHEEL, 22.0, SLIPS, **kwargs)


def test_law_is_inferred_and_ambiguity_refused():
    both = _bekker_draws(20).assign(k=8e6)
    with pytest.raises(ValueError, match="cannot tell"):
        predict_wheel(both, WHEEL, 22.0, SLIPS, priors=SHEAR_PRIORS)
    pred = predict_wheel(both, WHEEL, 22.0, SLIPS, law="bernstein", priors=SHEAR_PRIORS)
    assert pred.law == "bernstein" and "kc" not in pred.sources


def test_summary_and_strict_json():
    pred = predict_wheel(
        _bekker_draws(100, kc_sd=500.0),
        Wheel(0.058, 0.05, 0.063, 0.1, name="CMU grouser"),
        22.0,
        SLIPS,
        priors=SHEAR_PRIORS,
        angles=StressAngles(0.273, 0.673, -0.664, -0.177),
        draws_source="population draws",
    )
    assert isinstance(pred, WheelPrediction)
    doc = json.loads(json.dumps(pred.to_dict(), allow_nan=False))
    assert doc["wheel"]["shear_radius_m"] == 0.063 and doc["units"]["phi"] == "deg"
    assert doc["sources"]["kc"] == "population draws"
    assert len(doc["bands"]) == 4 * len(SLIPS) and doc["prob"] == 0.9
    text = pred.summary()
    for needle in (
        "CMU grouser",
        "r_s = 63 mm",
        "W = 22 N",
        "phi [deg]: user prior normal(30, 3)",
        "sinkage_m median [5%, 95%]",
        "slip angle 0",
    ):
        assert needle in text, needle
