"""The wheel asks the model record (issue #43 item 1): a plate law registered through its record
alone — here one with a sinkage offset, p = k·(z − z0)^n, which is no power law in z — reaches
wheel_forces, predict_wheel and validate_wheel, and its stress on the wheel is the law at the
local depth (checked against the law written here and scipy quad of the load integral)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy.integrate import quad

import soilstats
from soilstats.models import get_model, unregister_model
from soilstats.models.base import PlatePowerLaw
from soilstats.models.priors import FLAT, POSITIVE
from soilstats.wheel import (
    PARAM_UNITS,
    SINKAGE_LAWS,
    StressAngles,
    Wheel,
    predict_wheel,
    pressure_modulus,
    validate_wheel,
    wheel_forces,
)
from soilstats.wheel.solve import model_cases

NAME = "offset-plate"
SMOOTH = Wheel(radius_m=0.058, width_m=0.05)
GROUSER = Wheel(radius_m=0.058, width_m=0.05, shear_radius_m=0.063, grouser_area_ratio=0.3)
SOIL = {"k": 9.0e6, "z0": 0.002, "n": 1.3}


def offset_law(z, k, z0, n):
    """p = k·(z − z0)^n beyond the offset, 0 before it (Pa; z, z0 in m)."""
    d = np.maximum(np.asarray(z, float) - z0, 0.0)
    return k * d**n


def offset_jac(z, k, z0, n):
    d = np.maximum(np.asarray(z, float) - z0, 0.0)
    dn = d**n
    with np.errstate(divide="ignore", invalid="ignore"):
        lnd = np.where(d > 0, np.log(np.where(d > 0, d, 1.0)), 0.0)
        dz0 = np.where(d > 0, -k * n * d ** (n - 1), 0.0)
    return np.column_stack([dn, dz0, k * dn * lnd])


def plate_hook(b, z, k, z0, n):
    return offset_law(z, k, z0, n)


@pytest.fixture
def offset_model():
    model = soilstats.register_model(
        soilstats.Model(
            name=NAME,
            equation="p = k * (z - z0)^n",
            inputs=("z [m]",),
            output="p [Pa]",
            columns=("z_m",),
            kind="sinkage",
            param_names=("k", "z0", "n"),
            units=("N/m^(n+2)", "m", "-"),
            bounds=((0, np.inf), (-0.05, 0.05), (0, 5)),
            func=offset_law,
            jac=offset_jac,
            priors={"k": POSITIVE, "z0": FLAT, "n": POSITIVE},
            plate_pressure=plate_hook,
        )
    )
    yield model
    unregister_model(NAME)


def test_the_registry_views_name_the_new_law_and_drop_it_when_unregistered(offset_model):
    assert SINKAGE_LAWS[NAME] == ("k", "z0", "n")
    assert PARAM_UNITS["z0"] == "m"
    assert {"bekker", "bernstein", "reece"} <= set(SINKAGE_LAWS)
    with pytest.raises(ValueError, match="no power law"):
        pressure_modulus(NAME, SOIL, 0.05)
    unregister_model(NAME)
    assert NAME not in SINKAGE_LAWS
    with pytest.raises(ValueError, match="unknown pressure-sinkage law"):
        wheel_forces(SOIL, SMOOTH, 0.2, law=NAME, sinkage_m=0.01)
    soilstats.register_model(offset_model)


def test_built_in_power_laws_keep_their_fast_path_and_default_hooks_agree():
    b, z = 0.05, np.linspace(0.001, 0.03, 7)
    for name, params in (
        ("bekker", (-2.0e4, 1.2e6, 1.1)),
        ("bernstein", (8.0e6, 1.46)),
        ("reece", (2.0e3, 4.0e6, 0.8)),
    ):
        model = get_model(name)
        assert isinstance(model.plate_law(), PlatePowerLaw)
        x = z if name == "bernstein" else (np.full_like(z, b), z)
        np.testing.assert_allclose(
            model.pressure_under_plate(b, z, *params), model.func(x, *params)
        )
    # the default derived from power_law (no explicit hook) is Bekker's kc/b + kφ
    bare = soilstats.Model(**{**_fields(get_model("bekker")), "plate_pressure": None})
    np.testing.assert_allclose(bare.plate_modulus(0.05, -2.0e4, 1.2e6, 1.1), -2.0e4 / 0.05 + 1.2e6)


def _fields(model):
    from dataclasses import fields

    return {f.name: getattr(model, f.name) for f in fields(model)}


@pytest.mark.parametrize("wheel", [SMOOTH, GROUSER], ids=["smooth", "grouser"])
def test_stress_on_the_wheel_is_the_offset_law_at_the_local_depth(offset_model, wheel):
    angles = StressAngles()
    cases, _ = model_cases(SOIL, wheel, np.array([0.2]), NAME, angles)
    assert cases.plate is not None
    depth = np.linspace(0.0, 0.02, 11)[None, :]  # cos θe − cos θ1
    sigma = cases.plate(depth, cases.plate_params)
    rs, r, mu = wheel.contact_radius_m, wheel.radius_m, wheel.grouser_area_ratio
    truth = mu * offset_law(rs * depth, **SOIL) + (1 - mu) * offset_law(r * depth, **SOIL)
    np.testing.assert_allclose(sigma, truth, rtol=1e-13)
    assert sigma[0, 0] == 0 and sigma[0, 1] == 0  # above the offset: no pressure

    # the load at a given sinkage against quad of R b ∫ σ cos θ dθ, σ written here
    h, slip = 0.012, 0.2
    state = wheel_forces(SOIL, wheel, slip, law=NAME, sinkage_m=h, angles=angles)
    t1 = np.arccos(1 - h / rs)
    a, b2 = angles.ratios(slip)
    tm, t2 = float(a) * t1, float(b2) * t1

    def sig(theta):
        te = theta if theta >= tm else t1 - (theta - t2) / (tm - t2) * (t1 - tm)
        d = np.cos(te) - np.cos(t1)
        return mu * offset_law(rs * d, **SOIL) + (1 - mu) * offset_law(r * d, **SOIL)

    load = (
        rs
        * wheel.width_m
        * (
            quad(lambda t: sig(t) * np.cos(t), tm, t1, limit=200)[0]
            + quad(lambda t: sig(t) * np.cos(t), t2, tm, limit=200)[0]
        )
    )
    # σ has a kink where the local depth passes z0, which the 16-node rule (made for the
    # (θ1 − θ)^n end of a power law) resolves to ~3e-4 of W; more nodes converge on quad
    assert state.load_N == pytest.approx(load, rel=1e-3)
    fine = wheel_forces(SOIL, wheel, slip, law=NAME, sinkage_m=h, angles=angles, n_nodes=128)
    assert fine.load_N == pytest.approx(load, rel=2e-5)


def test_offset_law_runs_through_predict_and_validate(offset_model):
    rng = np.random.default_rng(3)
    draws = pd.DataFrame(
        {
            "k": 9.0e6 * np.exp(0.1 * rng.standard_normal(300)),
            "z0": 0.002 + 0.0005 * rng.standard_normal(300),
            "n": 1.3 + 0.03 * rng.standard_normal(300),
        }
    )
    priors = {"phi": ("normal", 30, 2), "c": ("uniform", 0, 500), "K": ("lognormal", 0.01, 0.3)}
    pred = predict_wheel(draws, SMOOTH, 20.0, [0.0, 0.3], law=NAME, priors=priors, seed=1)
    assert pred.law == NAME and np.isfinite(pred.bands["median"]).all()
    # the offset deepens the wheel: more sinkage than the same law without it
    no_offset = predict_wheel(
        draws.assign(z0=0.0), SMOOTH, 20.0, [0.0, 0.3], law=NAME, priors=priors, seed=1
    )
    sink = pred.bands[pred.bands["quantity"] == "sinkage_m"]["median"].to_numpy()
    base = no_offset.bands[no_offset.bands["quantity"] == "sinkage_m"]["median"].to_numpy()
    assert np.all(sink > base + 0.0015)

    # runs simulated with the offset law itself at the median soil: the validation predicts them
    slips = np.array([0.0, 0.2, 0.5, 0.0, 0.2, 0.5])
    loads = np.full(6, 20.0)
    truth = wheel_forces(SOIL, SMOOTH, slips, law=NAME, load_N=loads)
    runs = pd.DataFrame(
        {
            "run_id": [f"r{i}" for i in range(6)],
            "wheel": "smooth",
            "slip": slips,
            "W_N": loads,
            "sinkage_m": truth.sinkage_m,
        }
    )
    res = validate_wheel(
        None,
        runs,
        wheels={"smooth": SMOOTH},
        draws=draws,
        law=NAME,
        extension=False,
        sensitivity=False,
    )
    assert res.law == NAME
    assert res.coverage["beta_0"]["coverage_90"] == 1.0
    assert abs(res.bias["beta_0"]["mean_m"]) < 5e-4
