"""Posterior sampling (issue #5): reproducibility, the linear case, flags and the CLI."""

from __future__ import annotations

import html
import json

import numpy as np
import pandas as pd
import pytest
from posterior_sim import joint_campaign

from soilstats.bayes import joint_draws, sample_posterior, simulator_parameters
from soilstats.bayes._arviz import az
from soilstats.identification import fit_shear


@pytest.fixture(scope="module")
def campaign():
    return joint_campaign(np.random.default_rng(11), repetitions=4, points=60)


def test_same_seed_gives_bit_identical_draws(campaign):
    a = sample_posterior(campaign, "bekker", seed=5).draws()
    b = sample_posterior(campaign, "bekker", seed=5).draws()
    c = sample_posterior(campaign, "bekker", seed=6).draws()
    pd.testing.assert_frame_equal(a, b, check_exact=True)
    assert not a.equals(c)


def test_mohr_coulomb_flat_priors_match_least_squares(campaign):
    # Linear model, flat priors, sigma marginalised under 1/sigma: the posterior of
    # (c, tan phi) is Student-t with dof N - 2 around the LS estimate with scale = its
    # standard error, so mean = estimate and sd = stderr * sqrt(dof / (dof - 2)).
    fit = fit_shear(campaign, "mohr-coulomb")
    post = sample_posterior(
        campaign, "mohr-coulomb", seed=1, draws=16000, priors={"c": None, "phi": None}
    )
    d = post.draws()
    factor = np.sqrt(fit.dof / (fit.dof - 2))
    for name in ("c", "phi"):
        mcse = post.diagnostics.loc[name, "mcse_mean"]
        # the posterior's width is Eq. 4's σ (samples as the unit), not the test-level one
        assert abs(d[name].mean() - fit.params[name]) < 4 * mcse + 1e-3 * fit.stderr_eq4[name]
        assert d[name].std() == pytest.approx(fit.stderr_eq4[name] * factor, rel=0.05)


def test_result_groups_summary_and_convergence(campaign):
    post = sample_posterior(campaign, "janosi", seed=2)
    assert post.converged, post.flags
    groups = set(post.idata.groups())
    assert {"posterior", "sample_stats", "observed_data", "posterior_predictive"} <= groups
    text = post.summary()
    assert "90% equal-tailed" in text and "Convergence: OK" in text
    assert post.diagnostics["r_hat"].max() <= 1.01
    assert post.diagnostics[["ess_bulk", "ess_tail"]].min().min() >= 400
    doc = json.loads(json.dumps(post.to_dict(), allow_nan=False))
    assert doc["converged"] is True and set(doc["params"]) == set(post.param_names)
    # The run time is runtime_s; its old key "seconds" is written too until 0.3.0.
    assert doc["sampler"]["runtime_s"] == doc["sampler"]["seconds"] > 0
    assert f"draws kept, {post.sampler['runtime_s']:.2f} s" in text
    # Converged: no flags, under the new key and (until 0.3.0) the old one alike.
    assert post.flags == () and doc["flags"] == [] == doc["problems"]
    assert post.idata.posterior.attrs["convergence_flags"] == "none"
    page = post._repr_html_()  # a notebook's view: the same table and verdict
    assert "convergence</b>: OK" in page and all(f"<td>{n}</td>" in page for n in post.var_names)
    assert doc["stderr"]["K"] == pytest.approx(post.diagnostics.loc["K", "sd"])


def test_summary_describes_the_draws_handed_out_with_equal_tailed_intervals(campaign):
    # Review finding F3: the summary's interval of k started at a draw with n < 0 that
    # draws.csv leaves out, and an HDI of a modulus spanning decades collapses onto its
    # smallest draw.  The summary now describes the rows a user is handed, equal-tailed.
    post = sample_posterior(campaign, "janosi", seed=2)
    every = post.draws()
    handed = every[every["K"] > every["K"].median()]  # as if the rest failed a support rule
    table = post.summary_table(0.9, handed)
    assert list(table.columns[2:4]) == ["eti_5%", "eti_95%"]
    row = table.loc["K"]
    assert row["mean"] == pytest.approx(handed["K"].mean())
    assert row["eti_5%"] == pytest.approx(np.quantile(handed["K"], 0.05))
    assert row["eti_5%"] > every["K"].median()
    # Quantities not handed out, and every diagnostic, are the chains' own.
    plain = post.summary_table(0.9)
    assert plain.loc["K", "eti_95%"] == pytest.approx(np.quantile(every["K"], 0.95))
    pd.testing.assert_series_equal(table["r_hat"], plain["r_hat"])
    # Equal-tailed: the interval of ln K is the log of K's (an HDI's is not).
    assert np.log(plain.loc["K", "eti_5%"]) == pytest.approx(np.quantile(np.log(every["K"]), 0.05))
    assert "over the" in post.summary(handed_out=handed)


def test_not_converged_is_loud(campaign):
    from soilstats.errors import ConvergenceWarning

    with pytest.warns(ConvergenceWarning, match="NOT converged"):
        post = sample_posterior(campaign, "bekker", seed=3, draws=64)
    assert not post.converged
    assert "NOT CONVERGED" in post.summary() and "NOT CONVERGED" in post._repr_html_()
    assert post.flags and all(html.escape(str(f)) in post._repr_html_() for f in post.flags)
    # Each failed check is a health flag with a documented code (docs/posterior.md), shown
    # as a fit's flags are; the old name problems (the messages) still answers, with a
    # FutureWarning, and its JSON key and netCDF attribute are still written, until 0.3.0.
    from soilstats.bayes.result import CONVERGENCE_CODES

    assert {f.code for f in post.flags} <= set(CONVERGENCE_CODES)
    assert all(f"  ! [{f.code}] {f.message}" in post.summary() for f in post.flags)
    doc = post.to_dict()
    assert doc["flags"] == [{"code": f.code, "message": f.message} for f in post.flags]
    assert doc["problems"] == [f["message"] for f in doc["flags"]]
    with pytest.warns(FutureWarning, match=r"PosteriorResult\.problems is renamed .*\.flags"):
        assert post.problems == tuple(f.message for f in post.flags)
    attrs = post.idata.posterior.attrs
    assert attrs["converged"] == 0
    assert attrs["convergence_flags"] == "; ".join(str(f) for f in post.flags)
    assert attrs["convergence_problems"] == "; ".join(f.message for f in post.flags)
    # Its numbers are refused, not handed out quietly; asked for explicitly, they come.
    from soilstats.errors import ConvergenceError

    shear = sample_posterior(campaign, "janosi", seed=1)
    for take in (
        post.draws,
        lambda: post.draws(100, seed=0),
        post.interval,
        lambda: post.interval(kind="hdi"),
        lambda: joint_draws(post, shear, 100, seed=0),
    ):
        with pytest.raises(ConvergenceError, match=r"did not converge \(.*(R-hat|ess)"):
            take()
    assert len(post.draws(100, seed=0, allow_unconverged=True)) == 100
    assert len(joint_draws(post, shear, 100, seed=0, allow_unconverged=True)) == 100


def test_joint_draws_and_simulator_format(campaign):
    sink = sample_posterior(campaign, "bekker", seed=1)
    shear = sample_posterior(campaign, "janosi", seed=1)
    joint = joint_draws(sink, shear, 500, seed=0)
    assert list(joint.columns) == ["kc", "kphi", "n", "c", "phi", "K"]
    sim = simulator_parameters(joint)
    assert sim["Mohr_friction"].between(0, 90).all()
    assert np.array_equal(sim["Bekker_Kphi"], joint["kphi"])


def test_cli_writes_all_outputs(campaign, tmp_path):
    from soilstats.cli.posterior import main

    folder = campaign.save(tmp_path / "camp")
    out = tmp_path / "out"
    code = main(
        [
            "--data",
            str(folder),
            "--soil",
            "sim-sand",
            "--model",
            "bekker+janosi",
            "--seed",
            "1",
            "--out",
            str(out),
            "--simulator",
            "chrono-scm",
            "--prior",
            "n=0.5:2",
            "--scm-elastic-K",
            "5e7",
        ]
    )
    assert code == 0
    for name in (
        "posterior.nc",
        "posterior_janosi.nc",
        "draws.csv",
        "summary.csv",
        "posterior.json",
        "report.pdf",
        "chrono-scm.csv",
        "chrono-scm.json",
    ):
        assert (out / name).exists(), name
    record = json.loads((out / "posterior.json").read_text())
    assert "n: flat on (0.5, 2)" in record["priors"]["bekker"]
    assert record["support"]["passed"] and not record["forced"]
    # Issue #47 item 3: the options left out are the defaults the run rests on (page 1 too).
    defaults = record["defaults"]
    assert "--seed" not in defaults and "--model" not in defaults and "--out" not in defaults
    assert defaults.get("--quality") == "clean", defaults  # the screening the draws rest on
    from pypdf import PdfReader

    page = " ".join(PdfReader(out / "report.pdf").pages[0].extract_text().split())
    assert ("Settings left at their defaults" in page) == bool(defaults)
    for option in defaults:
        assert option in page
    scm = json.loads((out / "chrono-scm.json").read_text())
    assert scm["stated_inputs"]["elastic_K"] == {
        "value": 5e7,
        "unit": "Pa/m",
        "source": "stated by user",
    }
    assert scm["stated_inputs"]["damping_R"]["value"] == 3e4
    assert scm["seed"] == 1 and scm["soil"] == "sim-sand" and scm["version"]
    sim = pd.read_csv(out / "chrono-scm.csv", comment="#")
    assert (sim["elastic_K"] == 5e7).all() and (sim["damping_R"] == 3e4).all()
    idata = az.from_netcdf(str(out / "posterior.nc"))
    assert "kc" in idata.posterior
    provenance = json.loads(idata.posterior.attrs["soilstats_provenance"])
    assert provenance["seed"] == 1 and provenance["command"].startswith("soilstats posterior")
    draws = pd.read_csv(out / "draws.csv", comment="#")
    assert list(draws.columns) == ["kc", "kphi", "n", "c", "phi", "K"]


@pytest.mark.slow  # a whole CLI run (2.4 s): CI runs it
def test_cli_draws_csv_rows_are_in_random_order_not_walker_by_walker(campaign, tmp_path):
    # A user who reads the first N rows must get a fair sample, not one walker's
    # autocorrelated run: the lag-1 autocorrelation of the rows is that of independent draws.
    import arviz as az

    from soilstats.cli.posterior import main

    folder = campaign.save(tmp_path / "camp")
    out = tmp_path / "out"
    args = ["--data", str(folder), "--soil", "sim-sand", "--model", "bekker", "--seed", "2"]
    assert main([*args, "--out", str(out)]) == 0
    draws = pd.read_csv(out / "draws.csv", comment="#")
    post = az.from_netcdf(str(out / "posterior.nc")).posterior
    stacked = post["n"].to_numpy().reshape(-1)
    assert len(draws) == stacked.size  # all written (this posterior is inside the support)
    np.testing.assert_allclose(np.sort(draws["n"]), np.sort(stacked), rtol=1e-9)  # %.10g
    for column in draws:
        x = draws[column].to_numpy()
        lag1 = np.corrcoef(x[:-1], x[1:])[0, 1]
        assert abs(lag1) < 4 / np.sqrt(x.size), (column, lag1)


@pytest.mark.slow  # two CLI posterior runs: CI runs it
def test_cli_writes_nothing_when_not_converged_unless_forced(campaign, tmp_path, monkeypatch):
    from soilstats.bayes import result
    from soilstats.cli.posterior import main

    folder = campaign.save(tmp_path / "camp")
    args = ["--data", str(folder), "--soil", "sim-sand", "--model", "bekker", "--draws"]
    out = tmp_path / "out"
    with monkeypatch.context() as m:  # enough draws, but an R-hat no chain can reach
        m.setattr(result, "RHAT_MAX", 0.5)
        assert main([*args, str(result.ESS_MIN), "--out", str(out)]) == 2
    assert not out.exists() or not any(out.iterdir())
    assert main([*args, "64", "--out", str(out), "--force"]) == 1
    record = json.loads((out / "posterior.json").read_text())
    assert record["forced"] and "not converged" in record["failures"][0]
    draws = pd.read_csv(out / "draws.csv", comment="#")
    assert np.isfinite(draws.to_numpy()).all() and (draws["n"] > 0).all()


def test_cli_refuses_draws_below_the_ess_floor_before_sampling(
    campaign, tmp_path, capsys, monkeypatch
):
    """Fewer draws than the ESS the convergence check needs can only fail it, after all the
    sampling: refused up front (exit 2, nothing sampled), naming the floor."""
    from soilstats.bayes import result, run_sampling
    from soilstats.cli import posterior

    folder = campaign.save(tmp_path / "camp")
    few = result.ESS_MIN - 1
    argv = ["--data", str(folder), "--soil", "sim-sand", "--model", "bekker"]
    sampled = []
    real_run = run_sampling._run
    monkeypatch.setattr(
        run_sampling, "_run", lambda *a, **k: sampled.append(1) or real_run(*a, **k)
    )
    assert posterior.main([*argv, "--draws", str(few), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert f"--draws {few} is below {result.ESS_MIN}" in err and "--force" in err
    assert not sampled and not (tmp_path / "o").exists()


@pytest.mark.slow  # a CLI posterior run: CI runs it
def test_cli_warns_when_contact_widths_leave_the_tested_plates(campaign, tmp_path, capsys):
    """Bekker's kc/b + kphi at contact widths beyond the plates tested is extrapolated: a
    WARNING on stderr and in posterior.json, naming both ranges; none inside them, nor for
    a model without a size term."""
    from soilstats.cli import posterior

    b = campaign.tests.loc[campaign.tests["kind"] == "sinkage", "b_m"]
    tested = (float(b.min()), float(b.max()))
    wide = (2 * tested[1], 4 * tested[1])
    folder = campaign.save(tmp_path / "camp")
    argv = ["--data", str(folder), "--soil", "sim-sand", "--model", "bekker", "--seed", "1"]
    out = tmp_path / "out"
    assert (
        posterior.main([*argv, "--contact-width", f"{wide[0]}:{wide[1]}", "--out", str(out)]) == 0
    )
    ranges = f"{wide[0]:g}–{wide[1]:g} m leaves the plate sizes tested (b = {tested[0]:g}–"
    assert ranges in capsys.readouterr().err
    record = json.loads((out / "posterior.json").read_text())
    assert any(ranges in w and "kc/b + kphi" in w for w in record["warnings"])
    from soilstats.bayes.run_checks import extrapolation_warnings as warned

    assert warned(tested, tested, ["bekker"]) == []
    assert warned(wide, tested, ["bernstein", "janosi"]) == []
    assert warned((tested[0] / 2, tested[1]), tested, ["bekker", "janosi"])


def test_cli_refuses_a_prior_for_no_parameter_before_sampling(campaign, tmp_path):
    from soilstats.cli.posterior import main

    folder = campaign.save(tmp_path / "camp")
    code = main(
        [
            "--data",
            str(folder),
            "--soil",
            "sim-sand",
            "--model",
            "bekker",
            "--prior",
            "nn=0:2",
            "--out",
            str(tmp_path / "o"),
        ]
    )
    assert code == 2 and not (tmp_path / "o").exists()


def test_cli_refuses_a_priors_table_for_no_model_before_sampling(campaign, tmp_path, capsys):
    """A [bekkr] table used to be ignored: the run went on with bekker's default priors."""
    from soilstats.cli.posterior import main

    folder = campaign.save(tmp_path / "camp")
    table = tmp_path / "priors.toml"
    table.write_text('[bekkr]\nn = "uniform:0.5:1.5"\n[janosi]\nK = "uniform:0.001:0.1"\n')
    argv = ["--data", str(folder), "--soil", "sim-sand", "--model", "bekker"]
    code = main([*argv, "--priors", str(table), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2 and not (tmp_path / "o").exists()
    assert "priors.toml: tables ['bekkr'] name no model" in err and "[bekker]?" in err


def test_a_run_whose_autocorrelation_time_is_not_finite_is_reported_not_raised(monkeypatch):
    """Walkers that overflow leave emcee's τ NaN; the sampler used it for its burn-in and
    raised 'cannot convert float NaN to integer'. It now keeps a short stretch and reports
    τ not reliable, which the posterior turns into 'not converged'."""
    import emcee

    from soilstats.bayes import sampler

    real = emcee.autocorr.integrated_time
    calls = []

    def nan_first(chain, **kw):
        calls.append(1)
        return np.full(chain.shape[-1], np.nan) if len(calls) == 1 else real(chain, **kw)

    monkeypatch.setattr(emcee.autocorr, "integrated_time", nan_first)
    run = sampler.run_ensemble(
        lambda t: -0.5 * np.sum(t * t, axis=1),
        np.zeros(2),
        np.eye(2),
        draws=160,
        seed=0,
        tune=50,
        accept=lambda chain: False,
    )
    assert run.chain.shape == (16, 10, 2) and run.extended == 0
    assert run.burn == run.steps - 10 and run.thin == 1


def test_the_models_of_one_run_draw_from_different_streams():
    """Two models sampled with one seed drew the same random numbers: rows of their draws
    with the same index were coupled (Spearman 0.9 between kphi and phi). The CLI gives the
    first model the seed and each later one its own from SeedSequence([seed, index])."""
    from soilstats.bayes.run_checks import model_seed

    assert model_seed(7, 0) == 7
    assert model_seed(7, 1) == model_seed(7, 1) != 7
    assert len({model_seed(s, i) for s in range(50) for i in range(2)}) == 100
    expected = np.random.SeedSequence([7, 1]).generate_state(1, np.uint32)[0]
    assert model_seed(7, 1) == expected


def test_a_start_outside_the_prior_names_the_parameter_its_value_and_the_prior():
    # GRC-1's pooled Bekker optimum has kphi < 0; the sampler used to say only that it could
    # not place walkers.
    from soilstats import load_campaign

    with pytest.raises(ValueError, match=r"kphi = -1\.4\d*e\+05 \(prior: flat on \(0, inf\)\)"):
        sample_posterior(load_campaign("grc1-oravec2009"), "bekker", seed=0)


@pytest.mark.slow  # a posterior and a CLI run: CI runs it
def test_a_posterior_carries_the_health_of_the_fit_it_started_from(tmp_path, capsys):
    # GRC-1's small plates fail in bearing; the posterior's record used to say nothing of it.
    from soilstats import load_campaign
    from soilstats.cli.posterior import main

    grc = load_campaign("grc1-oravec2009")
    post = sample_posterior(grc, "bernstein", seed=0)
    codes = {f["code"] for f in post.to_dict()["least_squares_health"]}
    assert "bearing-failure" in codes
    out = tmp_path / "out"
    args = ["--data", "grc1-oravec2009", "--soil", "GRC-1", "--model", "bernstein"]
    assert main([*args, "--out", str(out), "--force"]) in (0, 1)
    record = json.loads((out / "posterior.json").read_text())
    assert "bearing-failure" in {f["code"] for f in record["least_squares_health"]["bernstein"]}
    assert "least-squares fit these draws start from is flagged" in capsys.readouterr().err
    # ... and so does its report (it used to show the flags nowhere).
    from test_reports import _squeeze, pdf_text

    text = pdf_text(out / "report.pdf")
    for flag in record["least_squares_health"]["bernstein"]:
        assert _squeeze(flag["message"]) in text, flag["code"]
    assert "Startfitflagged" in text


# The population's Laplace start meets overflow on GRC-1 (the CLI counts it as a numerical
# warning, which pytest's error filter would otherwise raise before the CLI can record it).
@pytest.mark.slow  # two population runs: CI runs it
@pytest.mark.filterwarnings("default::RuntimeWarning")
@pytest.mark.filterwarnings("ignore::soilstats.errors.DefaultWarning")  # few tests: the
# default priors carry this population (issue #47 item 3 warns so); not this test's subject
def test_population_draws_of_a_model_flagged_plate_exponents_are_refused(tmp_path, capsys):
    """GRC-1's plates disagree on Bekker's n (identify: plate-exponents, ANOVA p = 4e-6); a
    population posterior would hand that misfit out as scatter between preparations, so
    nothing is written unless forced (and then marked FORCED)."""
    from soilstats.cli.main import main

    args = ["posterior", "grc1-oravec2009", "--soil", "GRC-1", "--model", "bekker"]
    args += ["--population", "--draws", "400", "--seed", "1"]
    assert main([*args, "--out", str(tmp_path / "refused")]) == 2
    err = capsys.readouterr().err
    assert "flagged plate-exponents" in err and "plate sizes disagree on the exponent" in err
    assert not (tmp_path / "refused" / "draws.csv").exists()
    assert main([*args, "--force", "--out", str(tmp_path / "forced")]) == 1
    record = json.loads((tmp_path / "forced" / "posterior.json").read_text())
    assert record["forced"] and any("plate-exponents" in f for f in record["failures"])


@pytest.mark.slow  # two CLI runs and a worker process: CI runs it
def test_cli_jobs_2_samples_the_second_model_in_a_worker_with_identical_outputs(
    campaign, tmp_path, monkeypatch
):
    import arviz as az

    from soilstats.bayes import run_sampling
    from soilstats.cli.posterior import main

    started = []
    real = run_sampling.in_one_worker

    def spying(function, item):
        if function.__name__ == "_sample_and_draw":  # (not the warm-up's imports)
            started.append(item[1])
        return real(function, item)

    monkeypatch.setattr(run_sampling, "in_one_worker", spying)  # where the run looks it up
    folder = campaign.save(tmp_path / "camp")
    outs = {}
    for jobs in (1, 2):
        outs[jobs] = tmp_path / f"jobs{jobs}"
        args = ["--data", str(folder), "--soil", "sim-sand", "--model", "bekker+janosi"]
        args += ["--seed", "3", "--draws", "3000", "--out", str(outs[jobs]), "--jobs", str(jobs)]
        assert main(args) == 0
    assert started == ["janosi"]  # only --jobs 2 started a worker, for the second model
    for name in ("draws.csv", "summary.csv"):
        body = [
            [line for line in (outs[j] / name).read_text().splitlines() if "command" not in line]
            for j in (1, 2)
        ]
        assert body[0] == body[1], name
    for name in ("posterior.nc", "posterior_janosi.nc"):
        a, b = (az.from_netcdf(str(outs[j] / name)) for j in (1, 2))
        for group in a.groups():
            for var in a[group].data_vars:
                np.testing.assert_array_equal(a[group][var].to_numpy(), b[group][var].to_numpy())
    pdf = [(outs[j] / "report.pdf").stat().st_size for j in (1, 2)]
    assert abs(pdf[0] - pdf[1]) < 200  # the same figures; the command line differs
