"""The wheel model against an independent formulation written here (issue #43 item 9).

σ, j and τ are written from the equations of docs/wheel.md ("The model") in plain Python —
Bekker's law at the local depth with CMU's grouser area ratio μ, Wong & Reece's rear mirror,
Janosi–Hanamoto shear with the signed displacement of skid and the fully mobilised backward
shear of a locked wheel — and integrated with scipy ``quad``; the load-controlled entry angle
is found with ``brentq`` on that integral.  Nothing of soilstats.wheel.stress is called.

Cases the other tests lacked: a grousered wheel (r_s > r, μ < 1) and a locked wheel at a given
load; skid torque with a tolerance relative to the torque's own scale R² b ∫|τ| dθ (the torque
were all the shear one way), not to W·R, which hid errors where τ changes sign.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq

from soilstats.wheel import StressAngles, Wheel, wheel_forces

SOIL = {"kc": -2.0e4, "kphi": 1.2e6, "n": 1.1, "c": 800.0, "phi": 31.0}
ANGLES = {"a0": 0.4, "a1": 0.15, "b0": -0.2, "b1": 0.0}
SMOOTH = {"r": 0.058, "rs": 0.058, "mu": 1.0, "b": 0.05}
GROUSER = {"r": 0.058, "rs": 0.063, "mu": 0.3, "b": 0.05}  # r_s > r, μ < 1


def independent(theta1: float, s: float, K: float, wheel: dict) -> dict:
    """W [N], DP [N], T [N·m] and the torque scale R² b ∫|τ| dθ [N·m], written from
    docs/wheel.md: W = R b ∫(σ cos θ + τ sin θ), DP = R b ∫(τ cos θ − σ sin θ), T = R² b ∫τ."""
    r, rs, mu, b = wheel["r"], wheel["rs"], wheel["mu"], wheel["b"]
    tm = (ANGLES["a0"] + ANGLES["a1"] * s) * theta1
    t2 = (ANGLES["b0"] + ANGLES["b1"] * s) * theta1
    k_eq = SOIL["kc"] / b + SOIL["kphi"]
    tan_phi = np.tan(np.radians(SOIL["phi"]))
    locked = s == -1.0
    nu = 1.0 - s if s >= 0 else (np.inf if locked else 1.0 / (1.0 + s))

    def sigma(t):
        te = t if t >= tm else theta1 - (t - t2) / (tm - t2) * (theta1 - tm)  # rear mirror
        d = max(np.cos(te) - np.cos(theta1), 0.0)  # local depth / R
        return mu * k_eq * (rs * d) ** SOIL["n"] + (1 - mu) * k_eq * (r * d) ** SOIL["n"]

    def tau(t):
        tau_max = SOIL["c"] + sigma(t) * tan_phi
        if locked:
            return -tau_max
        j = rs * (theta1 - t) - nu * r * (np.sin(theta1) - np.sin(t))
        return np.sign(j) * tau_max * (1.0 - np.exp(-abs(j) / K))

    kw = {"points": [tm], "limit": 400, "epsabs": 0.0, "epsrel": 1e-11}
    rb = rs * b
    return {
        "W": rb * quad(lambda t: sigma(t) * np.cos(t) + tau(t) * np.sin(t), t2, theta1, **kw)[0],
        "DP": rb * quad(lambda t: tau(t) * np.cos(t) - sigma(t) * np.sin(t), t2, theta1, **kw)[0],
        "T": rb * rs * quad(tau, t2, theta1, **kw)[0],
        "T_scale": rb * rs * quad(lambda t: abs(tau(t)), t2, theta1, **kw)[0],
    }


def model(wheel: dict, s: float, K: float, **mode) -> object:
    w = Wheel(wheel["r"], wheel["b"], wheel["rs"], wheel["mu"])
    params = {**SOIL, "K": K}
    return wheel_forces(params, w, s, law="bekker", angles=StressAngles(**ANGLES), **mode)


@pytest.mark.parametrize("s", [-1.0, -0.71, -0.24, 0.0, 0.3, 0.9])
def test_a_grousered_wheel_at_a_given_sinkage(s):
    h, K = 0.015, 0.02
    state = model(GROUSER, s, K, sinkage_m=h)
    truth = independent(np.arccos(1 - h / GROUSER["rs"]), s, K, GROUSER)
    assert state.load_N == pytest.approx(truth["W"], rel=1e-7)
    assert abs(state.drawbar_pull_N - truth["DP"]) < 1e-7 * truth["W"]
    assert abs(state.torque_Nm - truth["T"]) < 1e-5 * truth["T_scale"]
    if s == 0.0:  # r_s > r: the tips shear the soil forward at zero rim slip
        assert truth["T"] > 0 and state.torque_Nm > 0


@pytest.mark.parametrize("wheel", [SMOOTH, GROUSER], ids=["smooth", "grouser"])
def test_a_locked_wheel_at_a_given_load(wheel):
    load, K = 22.0, 0.02
    theta1 = brentq(lambda t: independent(t, -1.0, K, wheel)["W"] - load, 1e-3, 0.5 * np.pi,
                    xtol=1e-13)  # fmt: skip
    truth = independent(theta1, -1.0, K, wheel)
    state = model(wheel, -1.0, K, load_N=load)
    assert state.status == 0
    assert state.sinkage_m == pytest.approx(wheel["rs"] * (1 - np.cos(theta1)), rel=1e-7)
    assert state.drawbar_pull_N == pytest.approx(truth["DP"], rel=1e-6)
    assert state.torque_Nm == pytest.approx(truth["T"], rel=1e-6)
    # locked: τ = −τ_max everywhere, so the torque is its own scale, braking
    assert truth["T"] == pytest.approx(-truth["T_scale"], rel=1e-12)


# K/r = 0.34 and 0.034; where j changes sign inside the contact the rule resolves τ's turn
# to ~1e-5 and ~2e-3 of the torque's scale (docs/wheel.md, "Quadrature").
@pytest.mark.parametrize(("K", "tolerance"), [(0.02, 1e-4), (0.002, 5e-3)])
def test_skid_torque_relative_to_its_own_scale(K, tolerance):
    worst = 0.0
    for h in (0.003, 0.015, 0.04):
        for s in (-0.71, -0.48, -0.24, -0.1):
            truth = independent(np.arccos(1 - h / SMOOTH["rs"]), s, K, SMOOTH)
            state = model(SMOOTH, s, K, sinkage_m=h)
            error = abs(float(state.torque_Nm) - truth["T"]) / truth["T_scale"]
            assert error < tolerance, (h, s, error)
            worst = max(worst, error)
    assert worst > tolerance / 100  # the sign change is in the cases: the check can fail
