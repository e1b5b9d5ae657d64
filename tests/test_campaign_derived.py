"""Derived quantities against closed forms worked by hand (values beside each assertion)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from soilstats.campaign import derived as d
from soilstats.campaign import load_campaign

PI = math.pi


@pytest.fixture
def small(write_campaign, campaign_frames):
    return load_campaign(write_campaign(**campaign_frames))


def test_test_columns_of_fixture_campaign(small):
    t = small.tests.set_index("test_id")
    # circle r = 0.05 m: b = r, A = π r² = 0.0025 π m², l/w = 1
    assert t.loc["c1", "b_m"] == 0.05
    assert t.loc["c1", "area_m2"] == pytest.approx(0.0025 * PI, rel=1e-15)
    assert t.loc["c1", "aspect_ratio"] == 1.0
    # rectangle 0.1 m × 0.3 m: b = width, A = 0.03 m², l/w = 3
    assert t.loc["r1", "b_m"] == 0.1
    assert t.loc["r1", "area_m2"] == pytest.approx(0.03, rel=1e-15)
    assert t.loc["r1", "aspect_ratio"] == pytest.approx(3.0, rel=1e-15)
    # ring r_i = 0.1, r_o = 0.15: A = π (0.0225 − 0.01) = 0.0125 π m²
    assert t.loc["s1", "ring_area_m2"] == pytest.approx(0.0125 * PI, rel=1e-14)
    # not applicable → NaN
    assert np.isnan(t.loc["s1", ["b_m", "area_m2", "aspect_ratio"]].to_numpy(float)).all()
    assert np.isnan(t.loc[["c1", "r1"], "ring_area_m2"].to_numpy(float)).all()
    assert list(t["n_samples"]) == [3, 2, 2]


def test_pressure_eq6(small):
    s = small.sinkage
    c1 = s[s["test_id"] == "c1"]
    # F = 30.5 N on A = 0.0025 π m²: p = 30.5 / (0.0025 π) = 3883.38... Pa
    assert c1["pressure_Pa"].iloc[2] == pytest.approx(30.5 / (0.0025 * PI), rel=1e-15)
    assert c1["pressure_Pa"].iloc[0] == pytest.approx(-2.5 / (0.0025 * PI), rel=1e-15)
    r1 = s[s["test_id"] == "r1"]
    assert list(r1["pressure_Pa"]) == pytest.approx([0.0, 20 / 0.03], rel=1e-15)


def test_shear_quantities_eq12_eq14(small):
    row = small.shear.iloc[1]  # α = 0.1 rad, T = 40 N m, N = 505 N
    ri, ro = 0.1, 0.15
    assert row["sigma_Pa"] == pytest.approx(505 / (PI * (ro**2 - ri**2)), rel=1e-14)
    # τ = 3 T / (2π (r_o³ − r_i³)) = 120 / (2π · 0.002375) = 8041.6... Pa
    assert row["tau_Pa"] == pytest.approx(120 / (2 * PI * 0.002375), rel=1e-13)
    # j = (r_o + r_i)/2 · α = 0.125 · 0.1 = 0.0125 m
    assert row["j_m"] == pytest.approx(0.0125, rel=1e-15)


def test_eq12_is_the_torque_of_a_uniform_stress():
    # Provenance of Eq. 12: a uniform τ over the annulus gives T = ∫ τ r · 2π r dr.
    tau = d.shear_stress(40.0, 0.1, 0.15)
    torque, _ = quad(lambda r: tau * r * 2 * PI * r, 0.1, 0.15)
    assert torque == pytest.approx(40.0, rel=1e-12)


def test_functions_are_vectorised_and_pure():
    shape = np.array(["circle", "rectangle", None], dtype=object)
    radius = np.array([0.05, np.nan, np.nan])
    width = np.array([np.nan, 0.1, np.nan])
    length = np.array([np.nan, 0.3, np.nan])
    area = d.plate_area(shape, radius, width, length)
    np.testing.assert_allclose(area[:2], [0.0025 * PI, 0.03], rtol=1e-15)
    assert np.isnan(area[2])
    np.testing.assert_array_equal(d.bekker_b(shape, radius, width)[:2], [0.05, 0.1])
    np.testing.assert_allclose(d.aspect_ratio(shape, width, length)[:2], [1.0, 3.0])
    np.testing.assert_allclose(d.pressure([1.0, -2.0], [0.5, 0.5]), [2.0, -4.0])
    np.testing.assert_allclose(d.circle_area([1.0, 2.0]), [PI, 4 * PI])
    np.testing.assert_allclose(d.ring_area(0.0, 1.0), PI)
    np.testing.assert_allclose(d.normal_pressure(PI, 0.0, 1.0), 1.0)
    np.testing.assert_allclose(d.shear_deformation([0.0, 2.0], 0.1, 0.3), [0.0, 0.4])
    assert radius[0] == 0.05 and np.isnan(radius[1])  # inputs untouched


def test_cullinan_area_is_the_archive_plate():
    c = load_campaign("cullinan-sand")
    # radius_m = √(0.018/π) to 6 decimals: A = π · 0.075694² ≈ 0.018 m² (README of the data)
    np.testing.assert_allclose(c.tests["area_m2"], 0.018, rtol=2e-5)
    np.testing.assert_allclose(
        c.sinkage["pressure_Pa"], c.sinkage["force_N"] / (PI * 0.075694**2), rtol=1e-15
    )
