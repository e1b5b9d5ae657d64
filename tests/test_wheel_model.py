"""The Wong–Reece rigid-wheel model (soilstats.wheel) against independent truth.

* the pressure–sinkage laws of soilstats.models (the stress is the plate law at the local depth);
* adaptive quadrature (scipy quad) of the same stresses;
* an independent implementation: the CMU authors' MATLAB model (robomechanics/3d-terramechanics,
  commit 55a6e92) run in GNU Octave 7.3;
* Bekker's closed-form static sinkage of a rigid wheel, and the exact small-angle form.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.special import beta as beta_fn

from soilstats.models import BEKKER, BERNSTEIN, REECE
from soilstats.wheel import (
    StressAngles,
    Wheel,
    normal_stress,
    pressure_modulus,
    shear_displacement,
    shear_stress,
    speed_ratio,
    wheel_forces,
)
from soilstats.wheel.forces import contact_forces, gauss_rule
from soilstats.wheel.solve import model_cases

SMOOTH = Wheel(radius_m=0.058, width_m=0.05)
GROUSER = Wheel(radius_m=0.058, width_m=0.05, shear_radius_m=0.063, grouser_area_ratio=0.1)


# --- stresses ----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("law", "model", "params"),
    [
        ("bekker", BEKKER, {"kc": -2.0e3, "kphi": 1.2e6, "n": 1.1}),
        ("bernstein", BERNSTEIN, {"k": 8.0e6, "n": 1.46}),
        ("reece", REECE, {"k1": 2.0e3, "k2": 4.0e6, "n": 0.8}),
    ],
)
def test_front_stress_is_the_plate_law_at_the_local_depth(law, model, params):
    b, r, theta1 = SMOOTH.width_m, SMOOTH.radius_m, 0.7
    theta = np.linspace(0.3, 0.7, 9)  # in front of θm = 0.28
    z = r * (np.cos(theta) - np.cos(theta1))
    x = z if law == "bernstein" else (np.full_like(z, b), z)
    plate = model.func(x, *params.values())
    k_eq = pressure_modulus(law, params, b)
    sigma = normal_stress(theta, theta1, 0.4 * theta1, 0.0, k_eq, params["n"], r ** params["n"])
    np.testing.assert_allclose(sigma, plate, rtol=1e-12)


def test_rear_stress_mirrors_the_front_and_vanishes_at_the_ends():
    theta1, theta_m, theta2 = 0.6, 0.24, -0.12
    args = (theta1, theta_m, theta2, 1e6, 1.2, 0.058**1.2)
    # Wong & Reece: the rear angle θ maps to θe = θ1 − (θ − θ2)/(θm − θ2)(θ1 − θm)
    rear = np.array([-0.1, 0.0, 0.1, 0.2])
    mapped = theta1 - (rear - theta2) / (theta_m - theta2) * (theta1 - theta_m)
    np.testing.assert_allclose(normal_stress(rear, *args), normal_stress(mapped, *args), rtol=1e-12)
    assert normal_stress(theta2, *args) == 0.0 and normal_stress(theta1, *args) == 0.0
    left, right = normal_stress([theta_m - 1e-9, theta_m], *args)
    assert left == pytest.approx(right, rel=1e-6)  # continuous at the maximum
    assert normal_stress(theta_m, *args) == pytest.approx(
        normal_stress(np.linspace(-0.12, 0.6, 721), *args).max()
    )
    assert normal_stress([-0.2, 0.65], *args).tolist() == [0.0, 0.0]  # outside the contact


def test_shear_displacement_driving_skid_locked():
    theta1, theta = 0.5, np.array([0.4, 0.1, -0.1])
    # driving (Wong & Reece 1967): j = r[θ1 − θ − (1 − s)(sin θ1 − sin θ)]
    s = 0.3
    expected = 0.058 * (theta1 - theta - (1 - s) * (np.sin(theta1) - np.sin(theta)))
    np.testing.assert_allclose(shear_displacement(theta, theta1, speed_ratio(s), SMOOTH), expected)
    # skid (Ishigami et al. 2007): j = r[θ1 − θ − (sin θ1 − sin θ)/(1 + s)]
    s = -0.4
    expected = 0.058 * (theta1 - theta - (np.sin(theta1) - np.sin(theta)) / (1 + s))
    np.testing.assert_allclose(shear_displacement(theta, theta1, speed_ratio(s), SMOOTH), expected)
    # the locked wheel is the limit j → −∞: τ = −(c + σ tan φ), fully mobilised backwards
    j = shear_displacement(theta, theta1, speed_ratio(-1.0), SMOOTH)
    assert np.all(j == -np.inf)
    tau = shear_stress(1e4, j, 500.0, 30.0, 0.01)
    np.testing.assert_allclose(tau, -(500.0 + 1e4 * np.tan(np.radians(30.0))))
    # grousers shear on r_s: j = r_s(θ1 − θ) − (1 − s) r (sin θ1 − sin θ) > 0 at s = 0
    j0 = shear_displacement(theta, theta1, speed_ratio(0.0), GROUSER)
    np.testing.assert_allclose(
        j0, 0.063 * (theta1 - theta) - 0.058 * (np.sin(theta1) - np.sin(theta))
    )


def test_speed_ratio_follows_the_cmu_slip_definition():
    # s = (rω − V)/max(rω, V): rω = 10, V = 8 → s = 0.2, ν = 0.8; rω = 8, V = 10 → s = −0.2
    np.testing.assert_allclose(speed_ratio([0.2, -0.2, 0.0, 1.0]), [0.8, 10 / 8, 1.0, 0.0])
    assert speed_ratio(-1.0) == np.inf
    with pytest.raises(ValueError, match="slip"):
        speed_ratio(1.2)


def test_grouser_area_ratio_weights_the_stress_radius():
    assert Wheel(0.058, 0.05, 0.063, 0.0).stress_radius_power(1.3) == pytest.approx(0.058**1.3)
    assert GROUSER.stress_radius_power(1.3) == pytest.approx(0.1 * 0.063**1.3 + 0.9 * 0.058**1.3)
    with pytest.raises(ValueError, match="shear_radius_m"):
        Wheel(0.058, 0.05, shear_radius_m=0.05)


# --- quadrature -------------------------------------------------------------------------------


def _quad_forces(wheel, n, s, theta1, K, angles):
    """W, DP, T by adaptive quadrature of the public stress functions (independent of the rule)."""
    a, b = angles.ratios(s)
    tm, t2 = a * theta1, b * theta1
    nu = speed_ratio(s)

    def sig(th):
        return normal_stress(th, theta1, tm, t2, 8e5, n, wheel.stress_radius_power(n))

    def tau(th):
        return shear_stress(sig(th), shear_displacement(th, theta1, nu, wheel), 500.0, 30.0, K)

    kw = {"points": [tm], "limit": 500, "epsabs": 0.0, "epsrel": 1e-10}
    rb = wheel.contact_radius_m * wheel.width_m
    load = rb * quad(lambda th: sig(th) * np.cos(th) + tau(th) * np.sin(th), t2, theta1, **kw)[0]
    dp = rb * quad(lambda th: tau(th) * np.cos(th) - sig(th) * np.sin(th), t2, theta1, **kw)[0]
    torque = rb * wheel.contact_radius_m * quad(tau, t2, theta1, **kw)[0]
    return load, dp, torque


def _rule_error(wheel, n, s, theta1, K):
    angles = StressAngles(0.4, 0.15, -0.3, 0.0)
    params = {"k": 8e5, "n": n, "c": 500.0, "phi": 30.0, "K": K}
    cases, _ = model_cases(params, wheel, s, "bernstein", angles)
    f = contact_forces(np.array([theta1]), cases, wheel, gauss_rule())
    load, dp, torque = _quad_forces(wheel, n, s, theta1, K, angles)
    return np.array(
        [
            abs(f.load_N[0] - load) / load,
            abs(f.drawbar_pull_N[0] - dp) / load,
            abs(f.torque_Nm[0] - torque) / (load * wheel.contact_radius_m),
        ]
    )


# Two cases by default (a smooth wheel on a typical sand, grousers on a stiffening soil);
# the other four with the slow checks (each ~1.6 s of quad).
GAUSS_CASES = [
    pytest.param(
        wheel,
        n,
        id=f"{n}-{name}",
        marks=() if (name, n) in {("smooth", 0.8), ("grouser", 1.46)} else pytest.mark.slow,
    )
    for n in (0.5, 0.8, 1.46)
    for name, wheel in (("smooth", SMOOTH), ("grouser", GROUSER))
]


@pytest.mark.parametrize(("wheel", "n"), GAUSS_CASES)
def test_gauss_rule_matches_adaptive_quadrature_when_driving_or_locked(wheel, n):
    for s in (-1.0, 0.0, 0.3, 0.9, 1.0):
        for theta1 in (0.05, 0.6, 1.5):
            assert _rule_error(wheel, n, s, theta1, K=0.002).max() < 1e-8, (s, theta1)


def test_gauss_rule_accuracy_in_skid_as_documented():
    worst_small_K = max(
        _rule_error(SMOOTH, n, s, 1.5, K=0.002).max() for n in (0.5, 1.46) for s in (-0.71, -0.48)
    )
    assert 1e-4 < worst_small_K < 1e-2  # the near-kink where j changes sign (docs/wheel.md)
    for s in (-0.9, -0.71, -0.48, -0.24):
        for theta1 in (0.3, 0.8, 1.5):
            assert _rule_error(SMOOTH, 1.0, s, theta1, K=0.02).max() < 1e-4, (s, theta1)


# --- an independent implementation: the CMU authors' model ---------------------------------

# robomechanics/3d-terramechanics @ 55a6e92, terramechanics/{find_sinkage,forces_moments}.m run
# in GNU Octave 7.3.0 for their smooth K10-mini wheel (r = r_s = 58 mm, b = 50 mm, μ = 1) and
# soil (set_soil_params.m 'K10_mini_smooth': k = 8000 kN/m^(n+2), φ = 29°, c = 1 kPa,
# K = 0.021 m, n0 = 1.46) with their tuned β = 0 angles (trench_off_smooth_new.mat:
# a0 = 0.202, a1 = 0.705, b0 = −0.476, b1 = 0), slip-independent exponent (n1 = n2 = 0), trench
# model off, V = 10 mm/s, ω = V/((1 − s) r).  Numerics only were refined in the scratch copy:
# their right-endpoint sum on 20001 (s = 0, 0.23) or 5001 (s ≥ 0.5) angles instead of 101, and
# find_sinkage's force tolerance 1e-7·W instead of 1e-3·W.  Fx is their drawbar pull, −My the
# driving torque; kN and kN·m converted to N and N·m.
CMU_AT_LOAD_22N = {  # slip: (sinkage m, Fx N, -My N·m)
    0.0: (0.0137422982, -1.74152591, 0.117921892),
    0.23: (0.0153369862, 0.568066234, 0.323843232),
    0.5: (0.0187894103, 1.4587981, 0.492256666),
    0.75: (0.0263130498, 0.624407334, 0.630735012),
    0.9: (0.0386160476, -1.43417932, 0.758096952),
}
CMU_AT_SINKAGE_15MM = {  # slip: (Fz N, Fx N, -My N·m)
    0.0: (26.0996086, -2.01630523, 0.155275142),
    0.23: (21.0662399, 0.561476937, 0.307805433),
    0.5: (14.2105105, 1.41924024, 0.315405501),
    0.75: (7.567522, 1.58400155, 0.241469527),
    0.9: (3.91314817, 1.74006297, 0.18694178),
}
CMU_SOIL = {"k": 8.0e6, "n": 1.46, "c": 1000.0, "phi": 29.0, "K": 0.021}
CMU_ANGLES = StressAngles(a0=0.202, a1=0.705, b0=-0.476, b1=0.0)


def test_reproduces_the_cmu_model_at_a_given_load():
    slips = list(CMU_AT_LOAD_22N)
    st = wheel_forces(CMU_SOIL, SMOOTH, slips, law="bernstein", load_N=22.0, angles=CMU_ANGLES)
    ref = np.array(list(CMU_AT_LOAD_22N.values()))
    np.testing.assert_allclose(st.sinkage_m, ref[:, 0], rtol=1e-3)
    # drawbar pull crosses zero: compare on the scale of the load
    np.testing.assert_allclose(st.drawbar_pull_N, ref[:, 1], atol=1e-3 * 22.0)
    np.testing.assert_allclose(st.torque_Nm, ref[:, 2], rtol=1e-3)
    assert np.all(st.status == 0)


def test_reproduces_the_cmu_model_at_a_given_sinkage():
    slips = list(CMU_AT_SINKAGE_15MM)
    st = wheel_forces(CMU_SOIL, SMOOTH, slips, law="bernstein", sinkage_m=0.015, angles=CMU_ANGLES)
    ref = np.array(list(CMU_AT_SINKAGE_15MM.values()))
    np.testing.assert_allclose(st.load_N, ref[:, 0], rtol=1e-3)
    np.testing.assert_allclose(st.drawbar_pull_N, ref[:, 1], atol=1e-3 * ref[:, 0].max())
    np.testing.assert_allclose(st.torque_Nm, ref[:, 2], rtol=1e-3)


# --- Bekker's closed form ---------------------------------------------------------------------


def _static(n, z_over_d, wheel=SMOOTH):
    """(model z, Bekker z0, exact small-angle z) at the load Bekker's formula gives for z/D."""
    kc, kphi, b, d = 1.0e3, 1.0e6, wheel.width_m, wheel.diameter_m
    k = kc / b + kphi
    z = z_over_d * d
    load = (3 - n) / 3 * b * k * np.sqrt(d) * z ** ((2 * n + 1) / 2)
    st = wheel_forces(
        {"kc": kc, "kphi": kphi, "n": n},
        wheel,
        0.0,
        law="bekker",
        load_N=load,
        angles=StressAngles(0.0, 0.0, 0.0, 0.0),  # θm at the bottom, no rear contact, no shear
    )
    bekker = (3 * load / ((3 - n) * b * k * np.sqrt(d))) ** (2 / (2 * n + 1))
    # W = b k ∫ z(x)^n dx on the chord x² = D(z0 − z) gives W = b k √D B(n+1, 1/2) z0^(n+½)/2
    exact = (2 * load / (b * k * np.sqrt(d) * beta_fn(n + 1, 0.5))) ** (2 / (2 * n + 1))
    return float(st.sinkage_m), bekker, exact


def test_bekker_static_sinkage_small_sinkage_n_1():
    # n = 1: Bekker's series approximation is exact; only the chord (small-angle) remains
    z_over_d = [0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.3]
    err = np.array([_static(1.0, x)[0] / _static(1.0, x)[1] - 1 for x in z_over_d])
    assert np.all(err > 0) and np.all(np.diff(err) > 0)  # the error grows with z/D
    assert err[0] < 0.0015 and err[1] < 0.0025 and err[3] < 0.011  # 0.10 %, 0.20 %, 1.03 %
    assert 0.07 < err[-1] < 0.08  # 7.5 % at z/D = 0.3


@pytest.mark.parametrize("n", [0.6, 0.8, 1.3, 1.6])
def test_static_sinkage_tends_to_the_exact_small_angle_form(n):
    model, bekker, exact = _static(n, 0.005)
    assert model / exact - 1 == pytest.approx(0.0, abs=2e-3)
    # Bekker's z0 keeps the error of his series approximation (3 − n)/3 of B(n+1, ½)/2
    series = ((3 - n) / 3 / (beta_fn(n + 1, 0.5) / 2)) ** (2 / (2 * n + 1)) - 1
    assert model / bekker - 1 == pytest.approx(series, abs=2e-3)
    assert abs(_static(n, 0.2)[0] / _static(n, 0.2)[2] - 1) > 5 * abs(model / exact - 1)


# --- solver and outputs -----------------------------------------------------------------------


def test_load_and_sinkage_modes_agree():
    slips = np.array([-1.0, -0.5, 0.0, 0.4, 0.9])
    at_load = wheel_forces(CMU_SOIL, GROUSER, slips, law="bernstein", load_N=20.0)
    at_sink = wheel_forces(CMU_SOIL, GROUSER, slips, law="bernstein", sinkage_m=at_load.sinkage_m)
    np.testing.assert_allclose(at_sink.load_N, 20.0, rtol=1e-8)
    np.testing.assert_allclose(at_sink.drawbar_pull_N, at_load.drawbar_pull_N, rtol=1e-7)
    np.testing.assert_allclose(
        at_load.drawbar_pull_N, at_load.thrust_N - at_load.resistance_N, rtol=1e-12
    )


def test_signs_braking_and_driving():
    st = wheel_forces(CMU_SOIL, SMOOTH, [-1.0, 0.9], law="bernstein", load_N=22.0)
    assert st.drawbar_pull_N[0] < 0 and st.torque_Nm[0] < 0  # locked: resistance, braking torque
    assert st.thrust_N[1] > 0 and st.torque_Nm[1] > 0  # driving
    # locked wheel: τ = −τ_max everywhere, so T = −R² b ∫ (c + σ tan φ) dθ < −c R² b (θ1 − θ2)
    theta1 = float(st.theta1_rad[0])
    assert st.torque_Nm[0] < -1000.0 * 0.058**2 * 0.05 * theta1


def test_grousers_give_thrust_at_zero_rim_slip():
    smooth = wheel_forces(CMU_SOIL, SMOOTH, 0.0, law="bernstein", load_N=22.0)
    grouser = wheel_forces(CMU_SOIL, Wheel(0.058, 0.05, 0.063), 0.0, law="bernstein", load_N=22.0)
    assert grouser.thrust_N > 1.2 * smooth.thrust_N


def test_a_load_the_soil_cannot_carry_is_flagged_not_a_number():
    params = {"k": np.array([8e6, 1e3]), "n": np.array([1.46, 1.46])}
    st = wheel_forces(params, SMOOTH, [0.0, 0.5], law="bernstein", load_N=22.0)
    assert st.status.tolist() == [[0, 0], [1, 1]]
    assert np.all(np.isnan(st.sinkage_m[1])) and np.all(np.isfinite(st.sinkage_m[0]))
    assert np.isnan(st.drawbar_pull_N).all()  # no shear parameters: not predicted at all
    assert not st.with_shear


def test_shapes_broadcast_parameters_times_slips():
    params = {"k": np.full((3, 2), 8e6), "n": 1.46}
    st = wheel_forces(params, SMOOTH, [0.0, 0.2, 0.4, 0.6], law="bernstein", load_N=22.0)
    assert st.sinkage_m.shape == (3, 2, 4)
    np.testing.assert_allclose(st.sinkage_m, np.broadcast_to(st.sinkage_m[0, 0], (3, 2, 4)))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"load_N": 22.0, "sinkage_m": 0.01}, "exactly one"),
        ({"load_N": -1.0}, "positive"),
        ({"load_N": 22.0, "angles": StressAngles(0.4, -1.0)}, "out of order"),
        ({"load_N": 22.0, "slip_angle_deg": 120.0}, r"\[-90, 90\]"),
        ({"load_N": 22.0, "slip_angle_deg": [10.0, 20.0, 30.0]}, "broadcast"),
    ],
)
def test_bad_requests_are_refused(kwargs, match):
    with pytest.raises(ValueError, match=match):
        wheel_forces({"k": 8e6, "n": 1.46}, SMOOTH, [0.0, 0.9], law="bernstein", **kwargs)


def test_partial_shear_parameters_are_refused():
    with pytest.raises(ValueError, match="all three"):
        wheel_forces({"k": 8e6, "n": 1.46, "phi": 30.0}, SMOOTH, 0.0, law="bernstein", load_N=22.0)


def test_a_solve_that_does_not_converge_is_flagged():
    from soilstats.wheel.solve import solve_entry_angle

    cases, _ = model_cases(CMU_SOIL, SMOOTH, [0.0, 0.5], "bernstein", StressAngles())
    theta1, status = solve_entry_angle(22.0, cases, SMOOTH, max_iter=1)
    assert status.tolist() == [2, 2] and np.isnan(theta1).all()
    theta1, status = solve_entry_angle(22.0, cases, SMOOTH)
    assert status.tolist() == [0, 0] and np.all((theta1 > 0) & (theta1 < np.pi / 2))


@pytest.mark.parametrize("beta_deg", [0.0, 40.0])
def test_stacked_wheels_solve_as_each_wheel_alone(beta_deg):
    """Cases of two wheels (different r, r_s, b) stacked into one batch solve to the θ1 and
    forces of one solve per wheel (the calibration's one-solve-per-model-call path)."""
    from soilstats.wheel.forces import stack_cases, stackable
    from soilstats.wheel.solve import solve_entry_angle

    wide = Wheel(radius_m=0.09, width_m=0.12, shear_radius_m=0.095, grouser_area_ratio=0.3)
    params = {"kc": 900.0, "kphi": np.array([6e5, 8e5]), "n": 1.1, "c": 300.0, "phi": 31.0}
    params["K"] = 0.012
    rule = gauss_rule(10)
    parts, alone = [], []
    for wheel, slips, load in ((GROUSER, [-0.4, 0.0, 0.6], 25.0), (wide, [0.2, 0.9], 60.0)):
        cases, _ = model_cases(params, wheel, np.array(slips), "bekker", StressAngles())
        if beta_deg:
            cases = cases.at_slip_angle(np.deg2rad(beta_deg), None, 13000.0)
        theta1, status = solve_entry_angle(np.full(len(cases), load), cases, wheel, rule)
        alone.append((theta1, contact_forces(theta1, cases, wheel, rule), load))
        parts.append((cases, wheel))
    assert stackable(parts[0][0]) == stackable(parts[1][0]) is not None
    stacked = stack_cases(parts)
    load = np.concatenate([np.full(len(c), a[2]) for (c, _), a in zip(parts, alone, strict=True)])
    theta1, status = solve_entry_angle(load, stacked, GROUSER, rule)  # the wheel is unused
    assert np.all(status == 0)
    forces = contact_forces(theta1, stacked, GROUSER, rule)
    expect_theta = np.concatenate([a[0] for a in alone])
    np.testing.assert_allclose(theta1, expect_theta, rtol=1e-13)
    for name in ("load_N", "thrust_N", "resistance_N", "torque_Nm", "lateral_force_N"):
        expect = np.concatenate([getattr(a[1], name) for a in alone])
        np.testing.assert_allclose(getattr(forces, name), expect, rtol=1e-12, atol=1e-12)
    # the wheels really differ: the wide wheel's load is carried at another θ1
    assert not np.allclose(alone[0][0][:2], alone[1][0][:2], rtol=1e-3)


def test_cases_of_different_kinds_are_not_stacked():
    """Shear on one wheel's cases and not on the other's: a clear error, never a silent mix."""
    from soilstats.errors import InputError
    from soilstats.wheel.forces import stack_cases, stackable

    with_shear, _ = model_cases(
        {"k": 8e5, "n": 1.0, "c": 0.0, "phi": 30.0, "K": 0.01},
        SMOOTH,
        0.2,
        "bernstein",
        StressAngles(),
    )
    without, _ = model_cases({"k": 8e5, "n": 1.0}, GROUSER, 0.2, "bernstein", StressAngles())
    assert stackable(with_shear) != stackable(without)
    with pytest.raises(InputError, match="differ in 'c'"):
        stack_cases([(with_shear, SMOOTH), (without, GROUSER)])
