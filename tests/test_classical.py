"""Ensemble averaging and Wong's classical procedure: closed forms and the published GRC-1 fits."""

from __future__ import annotations

import tomllib

import numpy as np
import pandas as pd
import pytest

from soilstats.campaign import Campaign, load_campaign
from soilstats.data import bundled_path
from soilstats.errors import CampaignError
from soilstats.identification.classical import PlateWindow, classical_bekker
from soilstats.identification.ensemble import ensemble_curve

KC, KPHI, N = 8.0e3, 9.0e5, 1.1  # SI: N/m^(n+1), N/m^(n+2)
SIZES = (0.04, 0.06, 0.1)


def _campaign(rows_by_test: dict[str, tuple[float, np.ndarray, np.ndarray]]) -> Campaign:
    tests = pd.DataFrame(
        {
            "test_id": list(rows_by_test),
            "kind": "sinkage",
            "soil": "s",
            "shape": "circle",
            "radius_m": [b for b, _, _ in rows_by_test.values()],
        }
    )
    sinkage = pd.concat(
        pd.DataFrame({"test_id": tid, "z_m": z, "force_N": p * np.pi * b**2})
        for tid, (b, z, p) in rows_by_test.items()
    )
    return Campaign.from_frames(tests, sinkage)


def _bekker_repeats(z_scale=(1.0,), samples=(60,)) -> Campaign:
    """Exact Bekker curves; repeats differ in their sampling, not in the soil."""
    rows = {}
    for b in SIZES:
        for r, count in enumerate(samples):
            z = np.linspace(2e-4, 0.03, count) ** 1.0
            rows[f"b{b}-{r}"] = (b, z, (KC / b + KPHI) * z**N)
    return _campaign(rows)


def test_ensemble_of_one_power_law_is_that_power_law():
    campaign = _bekker_repeats(samples=(80, 57, 131))
    b = SIZES[0]
    ids = [t for t in campaign.tests["test_id"] if t.startswith(f"b{b}-")]
    curve = ensemble_curve(campaign, ids, p_max=20e3, step=250.0)
    truth = (curve.pressure_Pa / (KC / b + KPHI)) ** (1 / N)
    inside = curve.pressure_Pa > 2e3  # away from the steep foot of z ~ p^(1/n)
    np.testing.assert_allclose(curve.z_m[inside], truth[inside], rtol=2e-4)
    assert curve.z_sd_m[inside].max() < 1e-3 * curve.z_m[inside].max()
    assert not curve.extrapolated.any()
    beyond = ensemble_curve(campaign, ids, p_max=curve.sampled_max_Pa * 1.2)
    assert beyond.extrapolated.any() and not beyond.extrapolated[0]


def test_pressure_that_does_not_rise_is_named_or_dropped_and_counted():
    b = 0.05
    z = np.linspace(1e-3, 0.02, 30)
    p = (KC / b + KPHI) * z**N
    p_bad = p.copy()
    p_bad[11] = p_bad[10]  # a stalled load reading
    campaign = _campaign({"a": (b, z, p), "bad": (b, z, p_bad)})
    with pytest.raises(CampaignError) as err:
        ensemble_curve(campaign, ["a", "bad"], p_max=10e3)
    assert "'bad'" in str(err.value) and "row 42" in str(err.value)  # 30 rows of 'a' first
    curve = ensemble_curve(campaign, ["a", "bad"], p_max=10e3, non_increasing="drop")
    assert curve.dropped == {"a": 0, "bad": 1}


@pytest.mark.parametrize("exponent", ["averaged", "common"])
@pytest.mark.parametrize("weighting", ["pressure-squared", "uniform"])
def test_classical_recovers_exact_bekker(exponent, weighting):
    campaign = _bekker_repeats(samples=(60, 45))
    windows = [PlateWindow(b, p_max=(KC / b + KPHI) * 0.02**N, p_min=1e3) for b in SIZES]
    fit = classical_bekker(campaign, windows, exponent=exponent, weighting=weighting, step=100.0)
    np.testing.assert_allclose(fit.params[["kc", "kphi", "n"]], [KC, KPHI, N], rtol=2e-3)
    np.testing.assert_allclose(fit.plate_exponents, N, rtol=2e-3)
    assert "No standard deviations" in fit.summary()
    assert fit.to_dict()["plates"][0]["points"] == int(fit.points.iloc[0])


def test_every_plate_needs_a_window():
    campaign = _bekker_repeats(samples=(30, 30))
    with pytest.raises(ValueError, match="no pressure window"):
        classical_bekker(campaign, {SIZES[0]: 5e3, SIZES[1]: 5e3})


@pytest.mark.parametrize("window", ["lunar", "entire"])
def test_grc1_published_fits_are_reproduced_from_the_raw_channels(window):
    """Oravec (2009) Figures 5.52 and 5.53, to <= 1e-3 relative (ours: <= 3e-5)."""
    folder = bundled_path("grc1-oravec2009")
    published = tomllib.loads((folder / "published.toml").read_text())
    table = published[window]
    windows = {
        b: (lo * 1e3, hi * 1e3)
        for b, lo, hi in zip(published["b_m"], table["p_min_kPa"], table["p_max_kPa"], strict=True)
    }
    fit = classical_bekker(
        load_campaign("grc1-oravec2009"), windows, step=published["step_kPa"] * 1e3
    )
    assert int(fit.points.sum()) == table["points"]
    deviation = fit.relative_deviation({k: table[k] for k in ("n", "kc", "kphi")})
    assert (deviation <= 1e-3).all(), deviation
