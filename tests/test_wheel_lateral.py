"""The rigid wheel at a slip angle β (soilstats/wheel/lateral.py; issue #43, item 5).

Independent truth:

* β = 0 reproduces the longitudinal model of commit eda135e (before the slip angle existed)
  on a grid, stored in tests/reference/wheel_beta0_eda135e.json, exactly;
* the lateral terms written here again from the cited equations (Ishigami et al. 2007's
  j_y and side-face force with Hegedus's R_b, the shear mobilised on the resultant
  displacement, CMU's sin β) and integrated with scipy ``quad``;
* limits: β → 0 gives no lateral force, β → −β flips it, it grows with β at small β, and the
  resultant shear never exceeds c + σ tan φ.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import quad

from soilstats.wheel import StressAngles, Wheel, wheel_forces
from soilstats.wheel.lateral import (
    CMU_SAND_UNIT_WEIGHT_N_M3,
    LateralSoil,
    combined_shear,
    lateral_displacement,
)
from soilstats.wheel.stress import janosi

SMOOTH = Wheel(radius_m=0.058, width_m=0.05)
GROUSER = Wheel(radius_m=0.058, width_m=0.05, shear_radius_m=0.063, grouser_area_ratio=0.1)
SOIL = {"k": 8e6, "n": 1.46, "c": 1000.0, "phi": 29.0, "K": 0.021}
REFERENCE = Path(__file__).parent / "reference" / "wheel_beta0_eda135e.json"


def test_beta_zero_is_the_longitudinal_model_of_before_exactly():
    ref = json.loads(REFERENCE.read_text())
    angles = StressAngles(*ref["angles"])
    wheels = {"smooth": SMOOTH, "grouser": GROUSER}
    for key, values in ref["values"].items():
        name, mode = key.split("/")
        kw = {"load_N": 22.0} if mode == "load" else {"sinkage_m": 0.015}
        st = wheel_forces(
            ref["params"],
            wheels[name],
            ref["grid"]["slip"],
            law="bernstein",
            angles=angles,
            slip_angle_deg=0.0,
            **kw,
        )
        for q, expected in values.items():
            np.testing.assert_array_equal(getattr(st, q), np.array(expected), err_msg=f"{key} {q}")
        assert np.all(st.lateral_force_N == 0.0)


def test_the_lateral_code_path_at_beta_zero_is_the_longitudinal_one():
    """β = 0 cases evaluated beside β ≠ 0 ones (the lateral code path) agree to 1e-12."""
    slips = np.array([-1.0, -0.5, 0.0, 0.3, 0.9])
    params = SOIL
    for wheel in (SMOOTH, GROUSER):
        for kw in ({"load_N": 22.0}, {"sinkage_m": 0.015}):
            ref = wheel_forces(params, wheel, slips, law="bernstein", **kw)
            mixed = wheel_forces(
                params, wheel, slips, law="bernstein", slip_angle_deg=[[0.0], [30.0]], **kw
            )
            for q in ("sinkage_m", "load_N", "drawbar_pull_N", "torque_Nm"):
                a, b = getattr(ref, q), getattr(mixed, q)[0]
                np.testing.assert_allclose(b, a, rtol=1e-12, atol=1e-12 * np.abs(a).max())
            assert np.all(mixed.lateral_force_N[0] == 0.0)
            assert np.all(mixed.lateral_force_N[1] > 0)


def test_combined_shear_reduces_to_janosi_without_lateral_displacement():
    rng = np.random.default_rng(3)
    sigma, j = rng.uniform(0, 5e4, 200), rng.normal(0, 0.02, 200)
    tx, ty = combined_shear(sigma, j, np.zeros(200), 800.0, 0.55, 0.015)
    np.testing.assert_array_equal(tx, janosi(sigma, j, 800.0, 0.55, 0.015))
    assert np.all(ty == 0)


def test_resultant_shear_never_exceeds_the_strength():
    rng = np.random.default_rng(4)
    sigma = rng.uniform(0, 5e4, 500)
    jx, jy = rng.normal(0, 0.5, 500), rng.normal(0, 0.5, 500)
    jx[:5], jy[:5] = 1e200, -1e200  # a locked wheel's huge displacements: saturated, finite
    tx, ty = combined_shear(sigma, jx, jy, 800.0, 0.55, 0.015, K_y=0.03)
    strength = 800.0 + sigma * 0.55
    assert np.all(np.hypot(tx, ty) <= strength * (1 + 1e-12))
    np.testing.assert_allclose(np.hypot(tx[:5], ty[:5]), strength[:5], rtol=1e-12)
    # Ishigami's independent laws would reach √2 of the strength here; the split does not
    np.testing.assert_allclose(tx[:5], strength[:5] / np.sqrt(2), rtol=1e-12)


# ---------------------------------------------------------------------------------------------
# The cited equations written again, integrated with quad (Bernstein law, smooth or grousered)


def _sigma(theta, t1, tm, t2, k, n, wheel):
    rn = wheel.stress_radius_power(n)
    te = theta if theta >= tm else t1 - (theta - t2) / (tm - t2) * (t1 - tm)
    return k * rn * max(np.cos(te) - np.cos(t1), 0.0) ** n


def _truth(wheel, slip, beta_deg, h, soil, angles, gamma, K_y=None):
    """W, DP, T and F_y at sinkage h, by quad, from the equations of the docstrings' sources."""
    R, r, b = wheel.contact_radius_m, wheel.radius_m, wheel.width_m
    k, n, c, K = soil["k"], soil["n"], soil["c"], soil["K"]
    phi = np.radians(soil["phi"])
    K_y = K if K_y is None else K_y
    beta = np.radians(beta_deg)
    t1 = np.arccos(1 - h / R)
    tm, t2 = (angles.a0 + angles.a1 * slip) * t1, (angles.b0 + angles.b1 * slip) * t1
    locked = slip == -1
    nu = 1.0 - slip if slip >= 0 else (np.inf if locked else 1.0 / (1.0 + slip))

    def tau(theta):
        sig = _sigma(theta, t1, tm, t2, k, n, wheel)
        strength = c + sig * np.tan(phi)
        if locked:  # ω = 0: the displacement is −(travel) only; saturated, along the travel
            dx = -np.cos(beta) * r * (np.sin(t1) - np.sin(theta))
            dy = np.sin(beta) * r * (t1 - theta)
            norm = np.hypot(dx, dy)
            return (0.0, 0.0) if norm == 0 else (strength * dx / norm, strength * dy / norm)
        jx = R * (t1 - theta) - nu * np.cos(beta) * r * (np.sin(t1) - np.sin(theta))
        jy = nu * np.sin(beta) * r * (t1 - theta)  # Ishigami: r(1 − s_I)(θ1 − θ) tan β
        norm = np.hypot(jx, jy)
        if norm == 0:
            return 0.0, 0.0
        mag = strength * (1 - np.exp(-np.hypot(jx / K, jy / K_y)))
        return mag * jx / norm, mag * jy / norm

    xc = np.pi / 4 - phi / 2
    d1 = 1 / np.tan(xc) + np.tan(xc + phi)
    d2 = 1 / np.tan(xc) + (1 / np.tan(xc)) ** 2 / (1 / np.tan(phi))

    def side(theta):  # Ishigami et al. (2007): R_b(h)(R − h cos θ), Hegedus's R_b
        hh = R * (np.cos(theta) - np.cos(t1))
        return d1 * (c * hh + d2 * gamma * hh**2 / 2) * (R - hh * np.cos(theta))

    def integ(f):
        opts = {"limit": 200, "epsabs": 0, "epsrel": 1e-11}
        return quad(f, t2, tm, **opts)[0] + quad(f, tm, t1, **opts)[0]

    def sig(t):
        return _sigma(t, t1, tm, t2, k, n, wheel)

    W = R * b * integ(lambda t: sig(t) * np.cos(t) + tau(t)[0] * np.sin(t))
    DP = R * b * integ(lambda t: tau(t)[0] * np.cos(t) - sig(t) * np.sin(t))
    T = R * R * b * integ(lambda t: tau(t)[0])
    Fy = R * b * integ(lambda t: tau(t)[1]) + np.sin(beta) * integ(side)
    return W, DP, T, Fy


@pytest.mark.parametrize("wheel", [SMOOTH, GROUSER], ids=["smooth", "grouser"])
@pytest.mark.parametrize(
    ("slip", "beta"),
    [(0.0, 15.0), (0.3, 45.0), (0.9, 90.0), (-1.0, 30.0), (-1.0, 90.0), (0.0, -60.0)],
)
def test_forces_at_a_slip_angle_match_quad_of_the_cited_equations(wheel, slip, beta):
    angles = StressAngles(0.3, 0.2, -0.3, 0.0)
    gamma = 1.6e4
    h = 0.018
    st = wheel_forces(
        SOIL,
        wheel,
        slip,
        law="bernstein",
        sinkage_m=h,
        angles=angles,
        slip_angle_deg=beta,
        lateral=LateralSoil(unit_weight_N_m3=gamma),
    )
    W, DP, T, Fy = _truth(wheel, slip, beta, h, SOIL, angles, gamma)
    scale = abs(W)
    np.testing.assert_allclose(st.load_N, W, rtol=1e-7)
    np.testing.assert_allclose(st.drawbar_pull_N, DP, atol=1e-7 * scale)
    np.testing.assert_allclose(st.torque_Nm, T, atol=1e-7 * scale * wheel.radius_m)
    np.testing.assert_allclose(st.lateral_force_N, Fy, atol=1e-7 * scale)
    assert np.sign(st.lateral_force_N) == np.sign(beta)


def test_skid_at_a_slip_angle_matches_quad_within_the_documented_skid_accuracy():
    """In skid j_x turns sign inside the contact (the known near-kink of the Gauss rule)."""
    angles = StressAngles()
    st = wheel_forces(
        SOIL, SMOOTH, -0.5, law="bernstein", sinkage_m=0.02, angles=angles, slip_angle_deg=20.0
    )
    W, DP, _, Fy = _truth(SMOOTH, -0.5, 20.0, 0.02, SOIL, angles, CMU_SAND_UNIT_WEIGHT_N_M3)
    for got, want in ((st.load_N, W), (st.drawbar_pull_N, DP), (st.lateral_force_N, Fy)):
        assert abs(got - want) < 1e-4 * W


def test_anisotropic_K_y_matches_quad():
    st = wheel_forces(
        SOIL,
        SMOOTH,
        0.2,
        law="bernstein",
        sinkage_m=0.015,
        slip_angle_deg=40.0,
        lateral=LateralSoil(K_y_m=0.05),
    )
    W, DP, _, Fy = _truth(
        SMOOTH, 0.2, 40.0, 0.015, SOIL, StressAngles(), CMU_SAND_UNIT_WEIGHT_N_M3, K_y=0.05
    )
    np.testing.assert_allclose(
        [st.load_N, st.drawbar_pull_N, st.lateral_force_N], [W, DP, Fy], rtol=1e-7, atol=1e-7 * W
    )


def test_load_mode_balances_the_full_vertical_force():
    """Solved for W at β ≠ 0, the quad vertical force at the solved sinkage is the load."""
    st = wheel_forces(SOIL, SMOOTH, [0.0, 0.5], law="bernstein", load_N=22.0, slip_angle_deg=60.0)
    for j, s in enumerate([0.0, 0.5]):
        W, *_ = _truth(
            SMOOTH, s, 60.0, float(st.sinkage_m[j]), SOIL, StressAngles(), CMU_SAND_UNIT_WEIGHT_N_M3
        )
        assert abs(W - 22.0) < 1e-6 * 22.0


def test_lateral_displacement_is_ishigamis_with_the_heading_slip():
    """j_y = r(1 − s_I)(θ1 − θ) tan β with Ishigami's heading slip 1 − s_I = ν cos β."""
    theta, t1, nu, beta = np.linspace(-0.2, 0.5, 8), 0.5, 0.7, np.radians(35.0)
    s_ishigami = 1 - nu * np.cos(beta)
    expected = 0.058 * (1 - s_ishigami) * (t1 - theta) * np.tan(beta)
    np.testing.assert_allclose(lateral_displacement(theta, t1, nu, beta, 0.058), expected)


# ---------------------------------------------------------------------------------------------
# Limits


@pytest.mark.parametrize("kw", [{"load_N": 22.0}, {"sinkage_m": 0.015}])
def test_limits_zero_at_zero_odd_in_beta_growing_at_small_beta(kw):
    slips = np.array([-1.0, -0.5, 0.0, 0.5, 0.9])
    betas = np.array([1e-4, 2.0, 5.0, 10.0, 15.0])
    st = wheel_forces(SOIL, SMOOTH, slips, law="bernstein", slip_angle_deg=betas[:, None], **kw)
    neg = wheel_forces(SOIL, SMOOTH, slips, law="bernstein", slip_angle_deg=-betas[:, None], **kw)
    fy = st.lateral_force_N
    # β → 0: F_y → 0 in proportion to β (the slope at 1e-4° is that of 2°, within 10 %)
    slope_small, slope_2 = fy[0] / 1e-4, fy[1] / 2.0
    np.testing.assert_allclose(slope_small, slope_2, rtol=0.1)
    assert np.all(np.abs(fy[0]) < 1e-3)
    # β → −β: F_y flips; sinkage, drawbar pull and torque are even in β
    np.testing.assert_allclose(neg.lateral_force_N, -fy, rtol=1e-12, atol=1e-15)
    for q in ("sinkage_m", "drawbar_pull_N", "torque_Nm", "load_N"):
        np.testing.assert_allclose(getattr(neg, q), getattr(st, q), rtol=1e-12)
    # grows with β at small β, at every slip
    assert np.all(np.diff(fy, axis=0) > 0)


def test_without_shear_parameters_the_lateral_force_is_not_a_number():
    st = wheel_forces(
        {"k": 8e6, "n": 1.46}, SMOOTH, 0.0, law="bernstein", load_N=22.0, slip_angle_deg=30.0
    )
    assert np.isnan(st.lateral_force_N) and np.isfinite(st.sinkage_m)


def test_side_force_grows_with_unit_weight_and_vanishes_without_soil():
    kw = {"law": "bernstein", "sinkage_m": 0.02, "slip_angle_deg": 45.0}
    soil0 = {**SOIL, "c": 0.0}
    none = wheel_forces(soil0, SMOOTH, 0.2, lateral=LateralSoil(unit_weight_N_m3=0.0), **kw)
    some = wheel_forces(soil0, SMOOTH, 0.2, lateral=LateralSoil(unit_weight_N_m3=1.5e4), **kw)
    more = wheel_forces(soil0, SMOOTH, 0.2, lateral=LateralSoil(unit_weight_N_m3=3.0e4), **kw)
    assert none.side_force_N == 0.0
    np.testing.assert_allclose(more.side_force_N, 2 * some.side_force_N, rtol=1e-12)  # c = 0
    np.testing.assert_allclose(some.lateral_shear_N, none.lateral_shear_N)


@pytest.mark.parametrize("bad", [{"unit_weight_N_m3": -1.0}, {"K_y_m": 0.0}])
def test_bad_lateral_soil_is_refused(bad):
    with pytest.raises(ValueError, match="must be"):
        LateralSoil(**bad)


# ---------------------------------------------------------------------------------------------
# predict_wheel carries β


def test_predict_wheel_carries_the_slip_angle_into_a_lateral_force_band():
    import pandas as pd

    from soilstats.wheel import predict_wheel

    rng = np.random.default_rng(7)
    draws = pd.DataFrame(
        {"k": rng.lognormal(np.log(8e6), 0.2, 200), "n": rng.normal(1.46, 0.05, 200)}
    )
    priors = {"c": ("uniform", 0, 2000), "phi": ("normal", 29, 2), "K": ("lognormal", 0.02, 0.3)}
    slips = [0.0, 0.5]
    pred = predict_wheel(draws, SMOOTH, 22.0, slips, priors=priors, slip_angle_deg=[30.0, 60.0])
    assert pred.slip_angle_deg == (30.0, 60.0)
    band = pred.band("lateral_force_N")
    samples = pred.samples.pivot(index="draw", columns="slip", values="lateral_force_N")
    np.testing.assert_allclose(band["median"], samples.median().to_numpy(), rtol=1e-12)
    # each draw's value is the model applied to that row alone at that slip's β
    row = {k: float(v) for k, v in draws.iloc[5].items()}
    values = pred.samples[pred.samples["draw"] == 5]
    for j, (s, b) in enumerate(zip(slips, (30.0, 60.0), strict=True)):
        full = {**row, **_prior_row(pred, 5)}
        st = wheel_forces(full, SMOOTH, s, law="bernstein", load_N=22.0, slip_angle_deg=b)
        np.testing.assert_allclose(values["lateral_force_N"].iloc[j], st.lateral_force_N)
    assert (band["lower"] > 0).all()
    text = pred.summary()
    assert "slip angle β = 30°–60° (per slip)" in text and "lateral_force_N" in text
    assert "side-face bulldozing" in " ".join(pred.notes)
    assert pred.to_dict()["slip_angle_deg"] == [30.0, 60.0]
    zero = predict_wheel(draws, SMOOTH, 22.0, slips, priors=priors)
    assert (zero.band("lateral_force_N")[["median", "lower", "upper"]] == 0).all().all()
    assert "lateral_force_N" not in zero.summary()
    with pytest.raises(ValueError, match="one per slip"):
        predict_wheel(draws, SMOOTH, 22.0, slips, priors=priors, slip_angle_deg=[1.0, 2.0, 3.0])


def _prior_row(pred, i):
    """The prior draws of c, φ, K of row i, regenerated as predict_wheel draws them."""
    from soilstats.bayes.stated_priors import sample_priors

    priors = {"c": ("uniform", 0, 2000), "phi": ("normal", 29, 2), "K": ("lognormal", 0.02, 0.3)}
    values = sample_priors(priors, pred.n_draws, pred.seed)
    return {k: float(v[i]) for k, v in values.items()}


# ---------------------------------------------------------------------------------------------
# The CMU runs at s ≈ 0: the figures docs/wheel.md reports (a sanity figure, not a target)


@pytest.mark.parametrize(
    ("name", "wheel", "ratio", "slope_meas"),
    [("smooth", SMOOTH, 0.59, 0.596), ("grouser", GROUSER, 0.54, 0.651)],
)
def test_cmu_runs_at_zero_slip_as_documented(name, wheel, ratio, slope_meas):
    import pandas as pd

    from soilstats.data import bundled_path

    runs = pd.read_csv(bundled_path("cmu-3d-terramechanics") / "wheel.csv")
    runs = runs[(runs["wheel"] == name) & (runs["slip"].abs() <= 0.05)]
    st = wheel_forces(
        SOIL,
        wheel,
        runs["slip"].to_numpy(),
        law="bernstein",
        load_N=runs["W_N"].to_numpy(),
        slip_angle_deg=runs["beta_cmd_deg"].to_numpy(),
    )
    b = runs["beta_cmd_deg"].to_numpy() > 0
    got = np.median(st.lateral_force_N[b] / runs["lateral_force_N"].to_numpy()[b])
    assert round(got, 2) == ratio
    beta = runs["beta_cmd_deg"].to_numpy()[b]
    measured = np.polyfit(beta, 1e3 * runs["sinkage_m"].to_numpy()[b], 1)[0]
    predicted = np.polyfit(beta, 1e3 * st.sinkage_m[b], 1)[0]
    assert round(measured, 3) == slope_meas
    assert -0.06 < predicted < -0.04  # the model's sinkage falls with β: the wrong trend
