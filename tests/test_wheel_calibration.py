"""The wheel calibration (issue #43, items 2–4, 6, 7): discrepancy, calibration, held-out
validation and the prediction of a rover team's own wheel, against independent truth —
closed forms, and runs simulated with known inputs and a known discrepancy."""

from __future__ import annotations

import json
import os

import numpy as np
import pandas as pd
import pytest

from soilstats.errors import InputError
from soilstats.wheel import Wheel
from soilstats.wheel.calibration import (
    RunDesign,
    calibrate_wheel,
    fit_discrepancy,
    input_priors,
    load_calibration,
    simulate,
)
from soilstats.wheel.calibration.discrepancy import Discrepancy, repeat_scatter
from soilstats.wheel.calibration.heldout import (
    baseline_predictions,
    heldout_predictions,
    score,
    slip_condition_folds,
    wheel_transfer_folds,
)
from soilstats.wheel.calibration.predict import _slip_for_pull, predict_own_wheel

SLOW = pytest.mark.skipif(not os.environ.get("SOILSTATS_SLOW"), reason="slow: SOILSTATS_SLOW=1")
SMOOTH = Wheel(radius_m=0.058, width_m=0.05, name="smooth")
GROUSER = Wheel(
    radius_m=0.058, width_m=0.05, shear_radius_m=0.063, grouser_area_ratio=0.1, name="grouser"
)
TRUTH = {
    "k": 8e6,
    "n": 1.2,
    "a0": 0.3,
    "a1": 0.3,
    "b0": -0.2,
    "b1": 0.0,
    "datum_mm": 2.0,
    "n1": 0.3,
    "n2": 0.1,
}


def _plate_draws(rng: np.random.Generator, size: int = 2000) -> pd.DataFrame:
    """Bernstein plate draws around the truth (k lognormal 5 %, n normal 0.03)."""
    return pd.DataFrame(
        {
            "k": TRUTH["k"] * np.exp(0.05 * rng.standard_normal(size)),
            "n": TRUTH["n"] + 0.03 * rng.standard_normal(size),
        }
    )


def _design(slips, wheels=("smooth",), repeats=3, load=22.0) -> RunDesign:
    rows = [(w, s, r) for w in wheels for s in slips for r in range(repeats)]
    n = len(rows)
    slip = np.array([s for _, s, _ in rows], float)
    return RunDesign(
        run_id=np.array([f"{w}-{s}-{r}" for w, s, r in rows]),
        wheel=np.array([w for w, _, _ in rows]),
        slip=slip,
        beta_deg=np.zeros(n),
        load_N=np.full(n, load),
        slip_level=slip,
        beta_level=np.zeros(n),
        measured={},
    )


def _simulated(
    design: RunDesign, wheels, seed: int, bump_mm: float = 0.0, noise_mm: float = 0.4
) -> RunDesign:
    """Measured sinkage = the model at the truth + a smooth U-shaped discrepancy
    bump·(s² − 0.3) mm (a shape the model has no term for) + repeat noise."""
    rng = np.random.default_rng(seed)
    params = {k: np.array([v]) for k, v in TRUTH.items()}
    out = simulate(params, design, wheels, "bernstein", n_nodes=16, with_shear=False)
    h = out["sinkage_m"][0] + 1e-3 * bump_mm * (design.slip**2 - 0.3)
    h = h + 1e-3 * noise_mm * rng.standard_normal(len(design))
    return RunDesign(
        **{
            k: getattr(design, k)
            for k in ("run_id", "wheel", "slip", "beta_deg", "load_N", "slip_level", "beta_level")
        },
        measured={"sinkage_m": h},
    )


# --- the discrepancy ---------------------------------------------------------------------


def test_repeat_scatter_is_the_pooled_within_condition_sd():
    values = np.array([1.0, 2.0, 3.0, 10.0, 14.0, 7.0])
    groups = np.array(["a", "a", "a", "b", "b", "c"])
    sd, dof = repeat_scatter(values, groups)
    # closed form: (2·var(1,2,3) + 1·var(10,14)) / 3 = (2·1 + 8) / 3
    assert dof == 3
    assert sd == pytest.approx(np.sqrt(10.0 / 3.0))
    assert repeat_scatter(np.arange(3.0), np.array(["x", "y", "z"]))[1] == 0


def test_conditional_is_the_gaussian_process_posterior():
    d = Discrepancy(
        "sinkage_m",
        amplitude=2.0,
        length_slip=0.4,
        length_beta_deg=360.0,
        noise=0.3,
        wheel_amplitude=0.5,
    )
    x = np.column_stack([np.linspace(-1, 1, 7), np.zeros(7), np.zeros(7)])
    r = np.sin(3 * x[:, 0])[None, :]
    xn = np.array([[0.1, 0.0, 0.0], [0.1, 0.0, 1.0]])  # the same slip, a second wheel
    mean, var = d.conditional(x, r, xn)

    # independent: the joint normal written out, with the kernel from its definition
    def k(a, b):
        same = a[:, None, 2] == b[None, :, 2]
        se = np.exp(-0.5 * ((a[:, None, 0] - b[None, :, 0]) / 0.4) ** 2)
        return (4.0 + 0.25 * same) * se

    kxx = k(x, x) + 0.09 * np.eye(7)
    kx = k(x, xn[:1])
    assert mean[0, 0] == pytest.approx((kx.T @ np.linalg.solve(kxx, r[0]))[0])
    assert var[0] == pytest.approx(4.25 - (kx.T @ np.linalg.solve(kxx, kx))[0, 0])
    # a wheel the runs never saw: its own part stays at full variance τ_w² on top
    kx_new = 4.0 * np.exp(-0.5 * ((x[:, 0] - 0.1) / 0.4) ** 2)[:, None]
    assert var[1] == pytest.approx(4.25 - (kx_new.T @ np.linalg.solve(kxx, kx_new))[0, 0])
    assert var[1] > var[0]


def test_discrepancy_hyperparameters_recovered_from_a_known_process():
    rng = np.random.default_rng(3)
    slips = np.repeat(np.linspace(-1, 1, 15), 4)
    x = np.column_stack([slips, np.zeros_like(slips), np.zeros_like(slips)])
    truth = Discrepancy("sinkage_m", 3.0, 0.5, 360.0, 0.3, float("nan"))
    cov = truth.covariance(x)
    estimates = []
    for _ in range(30):
        r = np.linalg.cholesky(cov) @ rng.standard_normal(len(x))
        estimates.append(fit_discrepancy("sinkage_m", x, r, floor=1e-3))
    assert np.median([e.length_slip for e in estimates]) == pytest.approx(0.5, rel=0.3)
    assert np.median([e.noise for e in estimates]) == pytest.approx(0.3, rel=0.15)
    assert np.median([e.amplitude for e in estimates]) == pytest.approx(3.0, rel=0.5)
    assert all(np.isnan(e.wheel_amplitude) for e in estimates)  # one wheel: not estimable


# --- inputs ------------------------------------------------------------------------------


def test_input_priors_take_the_users_and_refuse_unknown_names():
    p = input_priors({"c": ("normal", 800.0, 200.0), "K": ("lognormal", 0.02, 0.5)})
    assert p["c_kPa"].mean == pytest.approx(0.8) and p["c_kPa"].sd == pytest.approx(0.2)
    assert p["log_K"].mean == pytest.approx(np.log(0.02))
    assert "user prior" in p["c_kPa"].source and "Wong" in input_priors()["a0"].source
    with pytest.raises(InputError, match="no wheel input named 'zeta'"):
        input_priors({"zeta": ("normal", 0, 1)})


# --- calibration on runs simulated with known inputs --------------------------------------


@pytest.fixture(scope="module")
def simulated_calibration():
    rng = np.random.default_rng(11)
    wheels = {"smooth": SMOOTH, "grouser": GROUSER}
    design = _simulated(
        _design([-0.6, -0.3, 0.0, 0.25, 0.5, 0.75], wheels=("smooth", "grouser")), wheels, seed=1
    )
    plates = _plate_draws(rng)
    cal = calibrate_wheel(design, wheels, plates, "bernstein", draws=2000, seed=2)
    return design, wheels, plates, cal


@SLOW
def test_calibration_holds_the_planted_inputs(simulated_calibration):
    _, _, _, cal = simulated_calibration
    table = cal.parameter_table()
    # runs simulated from the model itself: every input the runs inform holds its truth in
    # the 90 % interval (the plate prior is centred on the truth)
    for name, truth in (
        ("a0", TRUTH["a0"]),
        ("a1", TRUTH["a1"]),
        ("b0", TRUTH["b0"]),
        ("n1", TRUTH["n1"]),
        ("n2", TRUTH["n2"]),
        ("n", TRUTH["n"]),
    ):
        assert table.loc[name, "q05"] <= truth <= table.loc[name, "q95"], (name, table)
    # nothing is missing from the model: the discrepancy stays far below the sinkage
    # (mm), and the scatter is the planted repeat noise (0.4 mm)
    assert cal.discrepancy["sinkage_m"].amplitude < 1e-3
    assert cal.discrepancy["sinkage_m"].noise == pytest.approx(0.4e-3, rel=0.35)


@SLOW
def test_saved_calibration_predicts_what_the_live_one_does(simulated_calibration, tmp_path):
    design, _, _, cal = simulated_calibration
    cal.to_netcdf(tmp_path / "wheel_calibration.nc")
    again = load_calibration(tmp_path / "wheel_calibration.nc")
    a = cal.predict(design, seed=5)
    b = again.predict(design, seed=5)
    pd.testing.assert_frame_equal(a, b)
    assert again.names == cal.names and again.discrepancy == cal.discrepancy


@SLOW
def test_calibrated_band_covers_its_own_runs_and_is_narrower_than_the_prior(
    simulated_calibration,
):
    design, _, _, cal = simulated_calibration
    pred = cal.predict(design, seed=1)
    h = design.measured["sinkage_m"]
    inside = (h >= pred["sinkage_m_lower"]) & (h <= pred["sinkage_m_upper"])
    assert inside.mean() >= 0.8
    assert np.median(pred["sinkage_m_upper"] - pred["sinkage_m_lower"]) < 10e-3


@SLOW
def test_a_new_wheel_needs_the_wheel_part_stated_after_a_one_wheel_calibration():
    rng = np.random.default_rng(4)
    wheels = {"smooth": SMOOTH}
    design = _simulated(_design([-0.5, 0.0, 0.3, 0.6]), wheels, seed=4)
    cal = calibrate_wheel(design, wheels, _plate_draws(rng), "bernstein", draws=800, seed=1)
    other = _design([0.0], wheels=("grouser",), repeats=1)
    with pytest.raises(InputError, match="not in the calibration"):
        cal.predict(other, wheels={"grouser": GROUSER})
    narrow = cal.predict(
        other, wheels={"grouser": GROUSER}, wheel_amplitude={"sinkage_m": 1e-4}, n_draws=300
    )
    wide = cal.predict(
        other, wheels={"grouser": GROUSER}, wheel_amplitude={"sinkage_m": 5e-3}, n_draws=300
    )
    width = lambda p: float(p["sinkage_m_upper"].iloc[0] - p["sinkage_m_lower"].iloc[0])  # noqa: E731
    assert width(wide) > width(narrow) + 5e-3


# --- held out ------------------------------------------------------------------------------


def test_heldout_folds_never_see_the_runs_they_predict(monkeypatch):
    design = _design([-0.5, 0.0, 0.5], wheels=("smooth", "grouser"))
    seen = []

    class Fake:
        converged = True

        def __init__(self, train):
            self.train = train

        def predict(self, test, **_):
            return pd.DataFrame(
                {
                    "run_id": test.run_id,
                    "sinkage_m_median": 0.0,
                    "sinkage_m_lower": -1.0,
                    "sinkage_m_upper": 1.0,
                }
            )

    def fake_calibrate(train, *a, **k):
        seen.append(set(train.run_id))
        return Fake(train)

    monkeypatch.setattr("soilstats.wheel.calibration.heldout.calibrate_wheel", fake_calibrate)
    design = RunDesign(
        **{
            k: getattr(design, k)
            for k in ("run_id", "wheel", "slip", "beta_deg", "load_N", "slip_level", "beta_level")
        },
        measured={"sinkage_m": np.zeros(len(design))},
    )
    for scheme, folds in (
        ("slip_condition", slip_condition_folds(design)),
        ("wheel_transfer", wheel_transfer_folds(design)),
    ):
        seen.clear()
        frame = heldout_predictions(design, {}, pd.DataFrame(), "bernstein", folds, scheme=scheme)
        for (label, mask), train_ids in zip(folds, seen, strict=True):
            held = set(design.run_id[mask])
            assert held and not held & train_ids, label
            if scheme == "slip_condition":  # every repeat of the slip out, both wheels
                level = float(label.removeprefix("s="))
                assert held == set(design.run_id[design.slip_level == level])
                assert {w for w in design.wheel[mask]} == {"smooth", "grouser"}
        assert len(frame) == sum(int(m.sum()) for _, m in folds)


def test_baseline_interpolates_the_kept_residuals_across_slip():
    design = _design([-0.5, 0.0, 0.5, 0.9], repeats=1)
    measured = np.array([1.0, 2.0, 4.0, 5.0])
    design = RunDesign(
        **{
            k: getattr(design, k)
            for k in ("run_id", "wheel", "slip", "beta_deg", "load_N", "slip_level", "beta_level")
        },
        measured={"sinkage_m": measured},
    )
    base = baseline_predictions(
        design, {"sinkage_m": np.zeros(4)}, slip_condition_folds(design), scheme="slip_condition"
    )
    got = dict(zip(base["run_id"], base["sinkage_m_median"], strict=True))
    assert got["smooth-0.0-0"] == pytest.approx(1.0 + (4.0 - 1.0) * 0.5)  # halfway
    assert got["smooth-0.9-0"] == pytest.approx(4.0)  # beyond the kept slips: constant
    s = score(base.assign(sinkage_m_lower=0.0, sinkage_m_upper=10.0), "sinkage_m")
    assert s["runs"] == 4 and s["coverage_90"] == 1.0


# --- a rover team's own wheel --------------------------------------------------------------


def test_slip_for_pull_interpolates_each_draw():
    slips = np.array([0.0, 0.2, 0.4])
    dp = np.array([[-2.0, 2.0, 6.0], [-4.0, -2.0, 2.0], [-5.0, -4.0, -3.0]])
    out = _slip_for_pull(dp, slips, 0.0, 0.9)
    # draw 1 crosses at 0.1, draw 2 at 0.3, draw 3 never
    assert out["p_unreachable"] == pytest.approx(1 / 3)
    assert out["median"] == pytest.approx(0.2)


def test_plates_only_prediction_is_marked_and_carries_the_input_priors():
    rng = np.random.default_rng(8)
    pred = predict_own_wheel(
        Wheel(0.1, 0.08, name="own"),
        40.0,
        [0.0, 0.3, 0.6],
        plate_draws=_plate_draws(rng),
        law="bernstein",
        priors={"c": ("uniform", 0, 1500), "phi": ("normal", 30, 3), "K": ("lognormal", 0.01, 0.5)},
        pull_N=1.0,
        n_draws=400,
    )
    assert pred.band_kind.startswith("PARAMETER UNCERTAINTY ONLY")
    assert "17 %" in pred.band_kind
    assert set(pred.bands["quantity"]) == {"sinkage_m", "drawbar_pull_N", "torque_Nm"}
    # P(DP < 0) is the share of the joint draws with negative pull at that slip
    dp = pred.draws.pivot(index="draw", columns="slip", values="drawbar_pull_N")
    for r in pred.p_drawbar_pull_negative.itertuples():
        col = dp[r.slip].dropna()
        assert r.p == pytest.approx(float((col < 0).mean()))
    assert "a0" in pred.sources and "prior" in pred.sources["a0"]
    doc = json.loads(json.dumps(pred.to_dict(), default=float))
    assert {"bands", "p_drawbar_pull_negative", "slip_for_pull", "sources"} <= set(doc)
