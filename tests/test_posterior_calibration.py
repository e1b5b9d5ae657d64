"""Calibration of the posteriors against simulated truth, and convergence on bundled data.

Small, seeded versions of the checks in ``benchmarks/calibrate_posterior.py`` (which runs
them at full size and prints the figures quoted in docs/posterior.md).  Each can fail: a
miscalibrated likelihood, a wrong Jacobian or a population model that ignores preparation
scatter moves the coverage outside the stated band.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pandas as pd
import pytest
from posterior_calibration import (
    SHEAR_SOIL,
    pooled_coverage,
    population_coverage,
    shear_population_coverage,
)
from pypdf import PdfReader

import soilstats
from soilstats.bayes import sample_population, sample_posterior
from soilstats.bayes.transforms import sampling_coordinates
from soilstats.models import BEKKER, BERNSTEIN


@pytest.mark.slow
def test_pooled_90pct_intervals_cover_truth_90pct():
    # 60 Bekker + 60 Bernstein campaigns with model-matched noise: 300 intervals.  Binomial
    # sd of the rate at 90 % is 1.7 % (more: k and n of one campaign are covered together);
    # the band is ±4 % as the issue asks.
    bekker = pooled_coverage(60, model="bekker", seed=0)
    bernstein = pooled_coverage(60, model="bernstein", seed=0)
    rate = (bekker.hits + bernstein.hits) / (bekker.trials + bernstein.trials)
    assert abs(rate - 0.90) <= 0.04, (bekker, bernstein, rate)
    assert bekker.not_converged + bernstein.not_converged == 0


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::soilstats.errors.DefaultWarning")  # few tests: the
# default priors carry this population (issue #47 item 3 warns so); not this test's subject
def test_population_band_covers_held_out_curves_where_pooled_sigma_does_not():
    # 4 simulated campaigns (soil01, 3 plates, cv 10 % stiffness and sd 0.03 in n between
    # preparations), 4 training repetitions per plate, 10 held-out repetitions per plate:
    # 120 held-out true curves at 12 sinkages each.
    population, pooled_sigma = population_coverage(4, train=4, held_out=10, seed=0)
    assert abs(population.rate - 0.90) <= 0.05, population
    assert pooled_sigma.rate < 0.5, pooled_sigma  # the paper's σ: fit error, not scatter
    assert population.not_converged == 0


@pytest.mark.slow
def test_shear_population_band_covers_held_out_curves_where_pooled_sigma_does_not():
    # 4 simulated shear campaigns (c cv 10 %, phi sd 1 deg, K cv 15 % between preparations),
    # 4 training and 10 held-out repetitions at each of 5 normal pressures: 200 held-out curves.
    population, pooled_sigma, results = shear_population_coverage(4, train=4, held_out=10)
    assert abs(population.rate - 0.90) <= 0.05, population
    assert pooled_sigma.rate < 0.3, pooled_sigma
    assert population.not_converged == 0
    sd_lnk = [float(r.idata.posterior["sd_lnK"].mean()) for r in results]
    assert 0.10 < np.mean(sd_lnk) < 0.20, sd_lnk  # simulated: K_cv = 0.15


def test_shear_population_recovers_the_soil_and_its_scatter():
    # One small campaign: 4 repetitions at 5 normal pressures to learn from, 4 held out.
    population, pooled_sigma, (pop,) = shear_population_coverage(1, train=4, held_out=4, seed=3)
    assert pop.converged, pop.flags
    post = pop.idata.posterior
    assert abs(float(post["mu_phi"].mean()) - SHEAR_SOIL["phi"]) < 1.5
    assert abs(float(post["mu_K"].mean()) / SHEAR_SOIL["K"] - 1) < 0.15
    assert 0.07 < float(post["sd_lnK"].mean()) < 0.3  # simulated K_cv = 0.15
    assert population.rate > 0.75 and pooled_sigma.rate < 0.3, (population, pooled_sigma)
    draws = pop.draws()
    assert list(draws.columns) == ["c", "phi", "K"]
    assert (draws["c"] >= 0).all() and draws["phi"].between(0, 90).all() and (draws["K"] > 0).all()


@pytest.mark.slow  # a shear population run; the sinkage one runs by default: CI runs it
def test_cli_shear_population_writes_new_preparation_draws(tmp_path):
    from soilstats.cli.posterior import main

    out = tmp_path / "out"
    code = main(
        [
            *("--data", "simulated-paper", "--soil", "soil01", "--model", "janosi"),
            *("--population", "--select", "shear:series=grousers", "--out", str(out)),
        ]
    )
    assert code == 0
    summary = pd.read_csv(out / "summary.csv", comment="#", index_col="quantity")
    assert {"mu_c", "mu_phi", "mu_K", "sd_strength", "sd_lnK", "corr_strength_K"} <= set(
        summary.index
    )
    assert summary["r_hat"].max() <= 1.01


def test_population_models_are_those_whose_record_has_a_layout():
    from soilstats.bayes.population import POPULATION_MODELS
    from soilstats.bayes.run_checks import has_population
    from soilstats.models import MODELS

    assert POPULATION_MODELS == ("bekker", "bernstein", "janosi")
    assert [n for n in MODELS if has_population(n)] == list(POPULATION_MODELS)


def test_sampling_coordinates_round_trip_and_exact_jacobian():
    rng = np.random.default_rng(0)
    for model, theta, sizes in (
        (BEKKER, np.array([-9.8e3, 1.2e6, 0.82]), np.array([0.025, 0.05, 0.075])),
        (BERNSTEIN, np.array([1.4e9, 3.3]), np.array([0.05])),
    ):
        p = theta.size
        cov = np.diag((0.05 * np.abs(theta)) ** 2)
        cov[0, -1] = cov[-1, 0] = 0.9 * np.sqrt(cov[0, 0] * cov[-1, -1])
        coords = sampling_coordinates(model, theta, cov, sizes)
        assert not coords.identity
        u = coords.to_u(theta)[0] + 0.01 * rng.standard_normal(p)
        back = coords.to_u(coords.to_theta(u[None]))[0]
        np.testing.assert_allclose(back, u, rtol=1e-12, atol=1e-12)
        # log|det ∂θ/∂u| against a central-difference Jacobian (independent of the formula)
        h = 1e-6
        jac = np.column_stack(
            [
                (coords.to_theta((u + h * e)[None])[0] - coords.to_theta((u - h * e)[None])[0])
                / (2 * h)
                for e in np.eye(p)
            ]
        )
        assert coords.log_jacobian(u[None])[0] == pytest.approx(
            np.log(abs(np.linalg.det(jac))), abs=1e-6
        )
        # z_ref makes the log plate moduli uncorrelated with n on average at the LS estimate
        cu = coords.covariance(theta, cov)
        assert abs(np.mean(cu[:-1, -1])) < 1e-9 * np.sqrt(cu[0, 0] * cu[-1, -1])


@pytest.mark.parametrize(
    ("name", "model", "selection"),
    [
        ("cullinan-sand", "bernstein", {}),  # gave R-hat 1.03 when sampled in (k, n)
        ("simulated-paper", "bernstein", {"soil": "soil02"}),  # gave R-hat 1.08
    ],
)
def test_bundled_pooled_posteriors_converge_at_defaults(name, model, selection):
    post = sample_posterior(soilstats.load_campaign(name), model, seed=0, **selection)
    assert post.converged, post.flags
    d = post.diagnostics
    assert d["r_hat"].max() <= 1.01 and d[["ess_bulk", "ess_tail"]].min().min() >= 400
    # the posterior mean sits on the least-squares estimate (within 2 of its σ)
    for p in post.param_names:
        assert abs(d.loc[p, "mean"] - post.lsq.params[p]) < 2 * post.lsq.stderr[p]


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::soilstats.errors.DefaultWarning")  # few tests: the
# default priors carry this population (issue #47 item 3 warns so); not this test's subject
def test_population_on_cullinan_method_1_converges_and_is_wider_than_pooled():
    camp = soilstats.load_campaign("cullinan-sand")
    pop = sample_population(camp, "bernstein", seed=0, preparation="1")
    pooled = sample_posterior(camp, "bernstein", seed=0, preparation="1")
    assert pop.converged, pop.flags
    # a new preparation scatters far more than one pooled parameter set is uncertain
    assert pop.draws()["n"].std() > 5 * pooled.draws()["n"].std()
    assert {"mu_k", "mu_n", "sd_p_ref", "sd_n", "corr_p_ref_n"} <= set(
        pop.idata.posterior.data_vars
    )


@pytest.mark.slow  # a population from the CLI on real data (3 s): CI runs it
@pytest.mark.filterwarnings("ignore::soilstats.errors.DefaultWarning")  # few tests: the
# default priors carry this population (issue #47 item 3 warns so); not this test's subject
def test_cli_population_with_select_on_real_data(tmp_path):
    from soilstats.bayes._arviz import az
    from soilstats.cli.posterior import main

    out = tmp_path / "out"
    args = ["--data", "cullinan-sand", "--soil", "cullinan-sand", "--model", "bernstein"]
    code = main([*args, "--population", "--select", "sinkage:preparation=1", "--out", str(out)])
    assert code == 0
    draws = pd.read_csv(out / "draws.csv", comment="#")
    assert list(draws.columns) == ["k", "n"] and (draws["k"] > 0).all()
    summary = pd.read_csv(out / "summary.csv", comment="#", index_col="quantity")
    assert {"mu_k", "sd_p_ref", "sd_n", "k", "n"} <= set(summary.index)
    assert summary["r_hat"].max() <= 1.01
    idata = az.from_netcdf(str(out / "posterior.nc"))
    assert idata.posterior.attrs["converged"] == 1
    # The band's own check travels to posterior.json and page 1 (issue #36).
    check = json.loads((out / "posterior.json").read_text())["band_check"]["bernstein"]
    assert 0 <= check["coverage"] <= 1 and check["width"] > 0
    assert _squeeze(check["sentence"]) in _squeeze(
        PdfReader(out / "report.pdf").pages[0].extract_text()
    )
    assert main([*args, "--select", "nosuchcolumn=1", "--out", str(tmp_path / "o2")]) == 2


def _squeeze(text: str) -> str:
    return re.sub(r"[\s\u200b\u00ad]+", "", text)


def test_a_failed_band_check_keeps_pass_every_check_off_page_one():
    from soilstats.report.posterior_pdf import _verdict

    class Clean:
        model_name = "bernstein"

        def least_squares_health(self):
            return []

    record = {"draws_written": 10, "failures": [], "warnings": [], "pooling_warnings": []}
    assert "pass every check" in "".join(map(str, _verdict([Clean()], record)))
    record["band_check"] = {"bernstein": {"failures": ["width"], "sentence": "WIDTH FAILS"}}
    text = "".join(map(str, _verdict([Clean()], record)))
    assert "pass every check" not in text and "band check of bernstein fails (width)" in text


def _crossing_campaign(rng, *, tests=6, z_ref=0.01, sd_p=0.05, sd_n=0.15, b=0.05):
    """Bernstein tests whose curves cross near ``z_ref``: each preparation shifts ln p at
    z_ref by N(0, sd_p²) and n by N(0, sd_n²), independently — as GRC-1's repeat tests do
    (ln p at 4 mm scatters by 0.06, n by 0.19).  Returns the campaign and the truth."""
    k, n = 8.0e5, 1.1
    rows, log = [], []
    z = np.linspace(0.001, 0.03, 80)
    for t in range(tests):
        n_t = n + sd_n * rng.standard_normal()
        ln_p_ref = np.log(k) + n * np.log(z_ref) + sd_p * rng.standard_normal()
        p = np.exp(ln_p_ref + n_t * np.log(z / z_ref))
        p = p + 0.01 * p.max() * rng.standard_normal(z.size)
        tid = f"x{t}"
        log.append(
            {
                "test_id": tid,
                "kind": "sinkage",
                "soil": "s",
                "repetition": t + 1,
                "shape": "circle",
                "radius_m": b,
            }
        )
        rows.append(pd.DataFrame({"test_id": tid, "z_m": z, "force_N": p * np.pi * b * b}))
    camp = soilstats.Campaign.from_frames(pd.DataFrame(log), pd.concat(rows, ignore_index=True))
    return camp, (k, n, z_ref, sd_p, sd_n)


# Six tests leave the default priors borderline-influential (power-scaling sensitivity of
# mu_n ≈ 0.05, issue #47 item 3): the DefaultWarning says so; this test is about the band.
@pytest.mark.filterwarnings("ignore::soilstats.errors.DefaultWarning")
def test_population_band_inside_the_measured_range_is_as_wide_as_the_scatter_of_crossing_curves():
    # Review finding F1: with the scatter placed on ln k (the pressure at z = 1 m), curves that
    # cross inside the measured range need corr(ln k, n) ≈ 1, which the Beta(2, 2) prior on
    # the correlation does not reach with a few tests; the band of a new preparation came out
    # 14–20× wider than the measured repeat scatter on GRC-1 (5 tests), here 4–9× at z_ref.
    from soilstats.identification import fit_sinkage

    camp, (_, _, z_ref, _, _) = _crossing_campaign(np.random.default_rng(0))
    pop = sample_population(camp, "bernstein", seed=0, draws=6000)
    assert pop.converged, pop.flags
    new = pop.draws()
    own = np.array(
        [fit_sinkage(camp, "bernstein", test_id=t).params for t in camp.tests["test_id"]]
    )
    for z in (0.003, z_ref, 0.03):
        measured = np.std(np.log(own[:, 0]) + own[:, 1] * np.log(z), ddof=1)
        band = np.std(np.log(new["k"]) + new["n"] * np.log(z))
        # 6 tests: the predictive carries the uncertainty of the scatter itself, so it is
        # wider than the 6 tests' own scatter (1.7–1.8× over seeds 0–7), not 2–9× as before.
        assert measured < band < 2.5 * measured, (z, band, measured)
    # The result checks its own band (issue #36): both criteria met on these power-law curves,
    # in a structured record other layers read and in the last note.
    from soilstats.bayes.population import band_calibration

    check = band_calibration(pop)
    assert check is not None and check.tests == 6 and check.points == 30
    assert check.calibrated and check.failures == (), check.sentence
    assert 0.8 <= check.coverage <= 1.0 and 1.0 < check.width < 3.0
    assert check.coverage_power_law >= check.coverage - 0.05
    assert pop.notes[-1] == check.sentence and "both criteria met" in check.sentence


def test_band_check_says_which_criterion_fails_and_why():
    from soilstats.bayes.band_check import _band_verdict

    base = dict(
        tests=3,
        points=15,
        coverage=0.9,
        coverage_power_law=0.93,
        coverage_in_sample=0.93,
        width=4.2,
        width_floor=2.05,
        misfit=0.01,
        half_width=0.3,
        pareto_k_max=0.5,
        unreliable_tests=0,
    )
    flat = np.zeros((3, 5))
    failures, sentence = _band_verdict(base, flat, flat, np.zeros((3, 5), bool))
    assert failures == ("width",) and "WIDTH FAILS: 3 tests cannot pin" in sentence
    assert "4.2x" in sentence
    # Measured curves off the power law at shallow sinkages while the tests' own power laws
    # sit inside the band: within-test misfit, named as such.
    misfit = dict(base, tests=6, width=1.5, coverage=0.7, misfit=0.04, half_width=0.2)
    measured = np.zeros((6, 5))
    measured[:, 0] = 1.0
    missed = np.zeros((6, 5), bool)
    missed[:, 0] = True
    failures, sentence = _band_verdict(misfit, measured, np.zeros((6, 5)), missed)
    assert failures == ("coverage",)
    assert (
        "within-test misfit" in sentence
        and "6 of the 6 misses at each test's shallowest" in sentence
    )
    assert "median 1.00 in ln p" in sentence
    # Many tests that scatter more than a normal population: not the misfit's fault.
    wide = dict(base, tests=40, width=5.0, width_floor=1.02, coverage=0.6, coverage_power_law=0.6)
    failures, sentence = _band_verdict(wide, flat, flat, np.ones((40, 5), bool))
    assert "COVERAGE FAILS: the tests scatter more" in sentence
    assert failures == ("width", "coverage") and "differ by more" in sentence


@pytest.mark.slow
def test_population_bands_on_real_repeat_tests_leave_one_test_out():
    # benchmarks/calibrate_population_real.py on two groups whose curves the power law follows
    # (docs/posterior.md, "Population bands on real data"): held-out coverage 80–100 % and a
    # band within 3× the tests' own scatter.
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from calibrate_population_real import GROUPS, check_group
    from tqdm.auto import tqdm

    from soilstats.quality import screen

    wanted = {"GRC-1 51 mm plate", "CMU 100 mm plate, both boxes"}
    with tqdm(disable=True) as bar:
        for group in (g for g in GROUPS if g.label in wanted):
            campaign = screen(soilstats.load_campaign(group.campaign), "clean").campaign
            row = check_group(campaign, group, draws=4000, seed=0, bar=bar)
            assert row.folds == row.tests and row.points == 5 * row.tests, row
            assert 0.8 <= row.coverage <= 1.0 and row.width <= 3.0, row
            assert row.coverage_power_law >= 0.8, row
