"""ArviZ conventions of the posteriors (observed data, replicates, per-test log-likelihood)
and the publication figures of soilstats.report.posterior_figures."""

from __future__ import annotations

import io

import matplotlib
import numpy as np
import pytest
from matplotlib.figure import Figure
from matplotlib.text import Text
from posterior_sim import BEKKER_TRUTH, joint_campaign, sinkage_campaign

from soilstats.bayes import predictive, sample_population, sample_posterior
from soilstats.bayes._arviz import az
from soilstats.bayes.data import pooled_problem
from soilstats.bayes.predictive import PREDICTIVE_DRAWS, spread_draws
from soilstats.models import BEKKER
from soilstats.report.posterior_figures import pair_figure, trace_figure
from soilstats.report.posterior_predictive import predictive_figure

matplotlib.use("Agg")

# Deprecations raised inside ArviZ 0.23 by newer matplotlib and pandas, not by soilstats.
MPL_ALIAS = "ignore:Passing a dict or None as alias_mapping"
PANDAS_INPLACE = "ignore:The inplace keyword in DataFrame.sort_values"
# ArviZ's WAIC warning when a log-likelihood term varies by more than 0.4 over draws: usual
# for one term per test (a whole curve), which is why LOO (with Pareto k) is the check.
WAIC_VARIANCE = "ignore:For one or more samples the posterior variance"

# Sampler variable names that must never reach a reader.
RAW = ("kphi", "kc", "sigma_w", "mu_", "sd_", "eta", "log10", "p_ref", "z_m", "j_m", "b_m")


@pytest.fixture(scope="module")
def campaign():
    # 3 plate sizes x 4 repetitions x 60 samples (Bekker truth), 4 normal pressures x 3 shear
    # tests; noise matched to the weighted likelihood (tests/posterior_sim.py).
    return joint_campaign(np.random.default_rng(11), repetitions=4, points=60)


@pytest.fixture(scope="module")
def bekker(campaign):
    return sample_posterior(campaign, "bekker", seed=1, draws=2000)


@pytest.fixture(scope="module")
def janosi(campaign):
    return sample_posterior(campaign, "janosi", seed=1, draws=2000)


@pytest.fixture(scope="module")
def population(campaign):
    # No preparation scatter was simulated: the sds sit at their boundary 0, where R-hat is
    # borderline at 2000 draws (1.007-1.013 over seeds 1-3, before and after the scatter moved
    # to z_s); 3000 keep the fixture off that edge.
    return sample_population(campaign, "bekker", seed=1, draws=3000)


def test_pooled_groups_have_matching_dims(campaign, bekker):
    idata = bekker.idata
    assert {
        "posterior",
        "sample_stats",
        "observed_data",
        "posterior_predictive",
        "log_likelihood",
    } <= set(idata.groups())
    obs, pp, ll = idata.observed_data, idata.posterior_predictive, idata.log_likelihood
    assert list(obs.data_vars) == list(pp.data_vars) == list(ll.data_vars) == ["y"]
    assert obs["y"].dims == ("obs",)
    assert pp["y"].dims == ("chain", "draw", "obs")
    assert ll["y"].dims == ("chain", "draw", "test")  # one term per test
    assert pp.sizes["obs"] == obs.sizes["obs"]
    assert pp.sizes["chain"] == ll.sizes["chain"] == idata.posterior.sizes["chain"]
    assert pp.sizes["chain"] * pp.sizes["draw"] <= PREDICTIVE_DRAWS
    assert ll.sizes["draw"] == idata.posterior.sizes["draw"]  # every draw kept
    assert np.array_equal(ll["draw"], idata.posterior["draw"]) and ll.attrs["thinned"] == 0
    assert obs["y"].attrs == {"long_name": "pressure", "units": "Pa"}
    # The data are exactly the likelihood's, with test, sample-in-test and inputs.
    problem, _ = pooled_problem(campaign, "bekker", points_per_test=100)
    assert np.array_equal(obs["y"].to_numpy(), problem.y)
    assert np.array_equal(obs["weight"].to_numpy(), problem.w)
    assert np.array_equal(obs["z_m"].to_numpy(), problem.x[1])
    tests = obs["test"].to_numpy()
    assert len(set(tests)) == 12
    for t in set(tests):
        assert np.array_equal(obs["sample"].to_numpy()[tests == t], np.arange(60))
    # The log-likelihood's tests are the observed tests, in order, with their sample counts.
    assert list(ll["test"].to_numpy()) == list(dict.fromkeys(tests))
    assert list(ll["samples"].to_numpy()) == [60] * 12


def test_shear_groups_name_the_shear_stress(janosi):
    obs = janosi.idata.observed_data
    assert obs["y"].attrs["long_name"] == "shear stress"
    assert {"test", "sample", "sigma_Pa", "j_m", "weight"} <= set(obs.coords)


def test_population_groups_have_matching_dims(population):
    idata = population.idata
    obs, pp, ll = idata.observed_data, idata.posterior_predictive, idata.log_likelihood
    assert obs["eta_hat"].dims == ("test", "eta")
    assert pp["eta_hat"].dims == ("chain", "draw", "test", "eta")
    assert ll["eta_hat"].dims == ("chain", "draw", "test")
    assert pp.sizes["chain"] * pp.sizes["draw"] <= PREDICTIVE_DRAWS
    # Every draw up to LOG_LIKELIHOOD_DRAWS over all chains (this run kept 12 000), spread.
    chains, draws = idata.posterior.sizes["chain"], idata.posterior.sizes["draw"]
    expect = predictive.log_likelihood_draws(draws, chains, obs.sizes["test"])
    assert list(ll["draw"].to_numpy()) == list(expect)
    assert ll.attrs["thinned"] == int(expect.size < draws)
    assert list(pp["test"].to_numpy()) == list(obs["test"].to_numpy())
    curves = idata.constant_data
    assert set(curves["test"].to_numpy()) == set(obs["test"].to_numpy())
    assert curves["y"].attrs["long_name"] == "pressure"
    assert np.all(np.isfinite(pp["eta_hat"].to_numpy())) and np.all(np.isfinite(ll["eta_hat"]))


@pytest.mark.filterwarnings(WAIC_VARIANCE)
def test_loo_and_waic_are_finite(bekker, janosi, population):
    for res in (bekker, janosi, population):
        loo = az.loo(res.idata, pointwise=True)  # no warning: filterwarnings = error
        assert np.isfinite(loo["elpd_loo"]) and np.isfinite(loo["se"])
        assert float(loo.pareto_k.max()) < 0.7
        assert loo.loo_i.dims == ("test",)  # leave-one-test-out
    # WAIC runs on the pooled posteriors and agrees with LOO; its variance warning (one term
    # per test) is why LOO's Pareto k above is the check.
    for res in (bekker, janosi):
        waic, loo = az.waic(res.idata), az.loo(res.idata)
        assert np.isfinite(waic["elpd_waic"])
        assert abs(waic["elpd_waic"] - loo["elpd_loo"]) < 0.1 * loo["se"]
    # The effective number of parameters: kc, kphi, n and sigma_w.
    assert 2.5 < az.loo(bekker.idata)["p_loo"] < 6.0


@pytest.mark.filterwarnings(PANDAS_INPLACE)
def test_compare_ranks_the_true_model_first():
    # Bekker data on three plate sizes: Bernstein (one k for every plate) is the wrong model.
    # LOO is leave-one-test-out, so the standard error of the difference comes from the
    # spread of the per-test differences: 30 tests (10 per plate) make it a usable estimate.
    camp = sinkage_campaign(np.random.default_rng(12), repetitions=10, points=60)
    fits = {m: sample_posterior(camp, m, seed=1, draws=2000) for m in ("bernstein", "bekker")}
    for res in fits.values():
        loo = az.loo(res.idata, pointwise=True)
        assert loo.loo_i.sizes["test"] == 30 and float(loo.pareto_k.max()) < 0.7
    table = az.compare({m: r.idata for m, r in fits.items()})
    assert table.index[0] == "bekker"
    assert table.loc["bernstein", "elpd_diff"] > 3 * table.loc["bernstein", "dse"]


@pytest.mark.filterwarnings(MPL_ALIAS)
def test_plot_ppc_runs(bekker, population):
    import matplotlib.pyplot as plt

    for res in (bekker, population):
        axes = az.plot_ppc(res.idata, num_pp_samples=20, random_seed=0)
        assert np.ravel(axes).size >= 1
        plt.close("all")


def test_replicates_follow_the_likelihood(campaign, bekker):
    # y_rep = f(x, theta_s) + sigma_s / w * e: standardised residuals are N(0, 1), and the
    # mean over draws of y_rep is the mean fitted curve over the same draws, to noise / sqrt(S).
    idata = bekker.idata
    pp = idata.posterior_predictive["y"]
    post = idata.posterior.sel(draw=pp["draw"])
    obs = idata.observed_data
    x = (obs["b_m"].to_numpy(), obs["z_m"].to_numpy())
    theta = [post[n].to_numpy().reshape(-1, 1) for n in BEKKER.param_names]
    fitted = BEKKER.func(x, *theta)  # (S, N)
    sigma = post["sigma_w"].to_numpy().reshape(-1, 1)
    w = obs["weight"].to_numpy()
    rep = pp.to_numpy().reshape(fitted.shape)
    z = (rep - fitted) * w / sigma
    assert abs(z.mean()) < 0.02 and abs(z.std() - 1) < 0.02
    s = rep.shape[0]
    scaled = (rep.mean(axis=0) - fitted.mean(axis=0)) * w / np.sqrt(np.mean(sigma**2)) * np.sqrt(s)
    assert 0.85 < np.sqrt(np.mean(scaled**2)) < 1.15
    # ... and the fitted curve is the truth's, within a fraction of the noise.
    truth = BEKKER.func(x, *BEKKER_TRUTH.values())
    assert np.max(np.abs(fitted.mean(axis=0) - truth) * w) < 0.01


def test_log_likelihood_is_the_weighted_gaussian_summed_per_test(bekker):
    from scipy import stats

    idata = bekker.idata
    obs = idata.observed_data
    tests = obs["test"].to_numpy()
    for chain, draw in ((3, 17), (0, 0), (-1, -1)):
        post = idata.posterior.isel(chain=chain, draw=draw)
        x = (obs["b_m"].to_numpy(), obs["z_m"].to_numpy())
        f = BEKKER.func(x, *(float(post[n]) for n in BEKKER.param_names))
        scale = float(post["sigma_w"]) / obs["weight"].to_numpy()
        pointwise = stats.norm.logpdf(obs["y"].to_numpy(), f, scale)
        got = idata.log_likelihood["y"].isel(chain=chain, draw=draw)
        for t in set(tests):
            expect = pointwise[tests == t].sum()
            assert float(got.sel(test=t)) == pytest.approx(expect, rel=1e-10), t


@pytest.mark.slow  # two population runs: CI runs it
def test_same_seed_same_groups(campaign, population):
    a = sample_posterior(campaign, "janosi", seed=4, draws=800)
    b = sample_posterior(campaign, "janosi", seed=4, draws=800)
    for group in ("posterior_predictive", "log_likelihood"):
        assert getattr(a.idata, group).identical(getattr(b.idata, group)), group
    c = sample_posterior(campaign, "janosi", seed=5, draws=800)
    assert not np.array_equal(
        a.idata.posterior_predictive["y"].to_numpy(), c.idata.posterior_predictive["y"].to_numpy()
    )
    again = sample_population(campaign, "bekker", seed=1, draws=3000)
    assert again.idata.posterior_predictive.identical(population.idata.posterior_predictive)
    assert again.idata.posterior.equals(population.idata.posterior)  # attrs: a time stamp


def test_thinning_keeps_draws_of_the_posterior(campaign, bekker, monkeypatch):
    # A log-likelihood budget of 12 tests x 320 draws (the default allows 4e6 values).
    monkeypatch.setattr(predictive, "LOG_LIKELIHOOD_VALUES", 12 * 320)
    res = sample_posterior(campaign, "bekker", seed=1, draws=2000, predictive_draws=50)
    ll = res.idata.log_likelihood
    chains = ll.sizes["chain"]
    assert res.idata.posterior_predictive.sizes["draw"] * chains <= 50
    assert ll.sizes["draw"] * chains == 320 and ll.attrs["thinned"] == 1
    # The same posterior (seeded alike) and, at the kept draws, the same log-likelihood.
    assert res.idata.posterior.equals(bekker.idata.posterior)
    full = bekker.idata.log_likelihood["y"].sel(draw=ll["draw"])
    np.testing.assert_array_equal(full.to_numpy(), ll["y"].to_numpy())
    assert list(spread_draws(10, 4, None)) == list(range(10))
    assert list(spread_draws(10, 4, 8)) == [0, 9]
    assert list(spread_draws(10, 4, 3)) == [0]


def test_log_likelihood_holds_at_most_the_draws_loo_is_run_with(bekker):
    # Every draw where there are fewer than LOG_LIKELIHOOD_DRAWS (the fixture's 2000) ...
    assert bekker.idata.log_likelihood.sizes["draw"] == bekker.idata.posterior.sizes["draw"]
    assert bekker.idata.log_likelihood.attrs["thinned"] == 0
    # ... else about that many, evenly spread within each chain, and never more values
    # than LOG_LIKELIHOOD_VALUES (soil01: 16 walkers x 750 draws, 372 tests).
    most = predictive.LOG_LIKELIHOOD_DRAWS
    keep = predictive.log_likelihood_draws(750, 16, 372)
    assert most - 16 < 16 * keep.size <= most and keep[0] == 0 and keep[-1] == 749
    wide = predictive.log_likelihood_draws(750, 16, 5000)
    assert 16 * wide.size * 5000 <= predictive.LOG_LIKELIHOOD_VALUES
    assert predictive.log_likelihood_draws(100, 16, 372).size == 100


def test_netcdf_round_trip_keeps_loo_and_figures(bekker, tmp_path):
    path = tmp_path / "posterior.nc"
    bekker.idata.to_netcdf(str(path))
    back = az.from_netcdf(str(path))
    assert float(az.loo(back)["elpd_loo"]) == pytest.approx(float(az.loo(bekker.idata)["elpd_loo"]))
    fig, caption = predictive_figure(back)
    assert isinstance(fig, Figure) and "pressure" in caption


def _texts(fig: Figure) -> list[Text]:
    fig.savefig(io.BytesIO(), format="png", dpi=50)  # lay out and create the tick labels
    return [t for t in fig.findobj(Text) if t.get_text().strip()]


def _check_figure(fig, caption, units):
    assert isinstance(fig, Figure)
    assert fig.get_size_inches() == pytest.approx((6.3, 4.0))
    texts = _texts(fig)
    assert min(t.get_fontsize() for t in texts) >= 8
    words = " ".join(t.get_text() for t in texts)
    assert not [raw for raw in RAW if raw in words], words
    labels = " ".join(ax.get_xlabel() + " " + ax.get_ylabel() for ax in fig.axes)
    for unit in units:
        assert unit in labels, (unit, labels)
    assert caption.endswith(".") and len(caption.split(". ")) >= 2
    assert not [raw for raw in ("sigma_w", "mu_", "log10", "kphi") if raw in caption]


@pytest.mark.parametrize("make", [trace_figure, pair_figure], ids=["trace", "pair"])
def test_parameter_figures_show_physical_parameters_with_units(make, bekker, janosi, population):
    for res, units in (
        (bekker, ("kN/m$^{n+1}$", "kN/m$^{n+2}$", "(–)")),
        (janosi, ("(kPa)", "(°)", "(mm)")),
        (population, ("kN/m$^{n+1}$",)),
    ):
        fig, caption = make(res)
        _check_figure(fig, caption, units)
        assert "Units:" in caption
    fig, caption = make(bekker, max_params=2)
    assert "first 2 of the 3 parameters" in caption
    assert "new preparation" in make(population)[1]


def test_trace_and_pair_contents(bekker):
    fig, caption = trace_figure(bekker)
    chains = bekker.idata.posterior.sizes["chain"]
    trace_axes = fig.axes[0::2]
    assert len(trace_axes) == 3 and all(len(ax.lines) == chains for ax in trace_axes)
    assert f"{chains} emcee walkers" in caption and "R-hat" in caption
    fig, caption = pair_figure(bekker)
    r = np.corrcoef(bekker.draws()["kphi"], bekker.draws()["n"])[0, 1]
    printed = " ".join(t.get_text() for t in _texts(fig))
    assert f"r = {r:+.2f}".replace("-", "\u2212") in printed
    assert "correlation coefficient" in caption


def test_predictive_figure_draws_each_test_against_its_physical_input(bekker, janosi, population):
    for res, units, x_max in (
        (bekker, ("sinkage $z$ (mm)", "pressure $p$ (kPa)"), 50.0),
        (janosi, ("shear displacement $j$ (mm)", "shear stress $\\tau$ (kPa)"), 80.0),
        (population, ("sinkage $z$ (mm)",), 50.0),
    ):
        fig, caption = predictive_figure(res)
        _check_figure(fig, caption, units)
        lines = [line for ax in fig.axes for line in ax.lines]
        tests = len(set(res.idata.observed_data["test"].to_numpy()))
        assert len(lines) == tests  # one line per test, no concatenation
        for line in lines:
            x = np.asarray(line.get_xdata())
            assert np.all(np.diff(x) > 0) and x.max() == pytest.approx(x_max, rel=0.02)
        assert "(kPa)" in caption and "(mm)" in caption
    _, caption = predictive_figure(janosi)
    assert "normal pressure" in caption and "measurement noise is included" in caption
    _, caption = predictive_figure(population)
    assert "new preparation" in caption


def test_predictive_figure_caps_panels_and_tests_and_says_so(bekker):
    fig, caption = predictive_figure(bekker, max_panels=2, max_tests=1)
    assert len([ax for ax in fig.axes if ax.lines]) == 2
    assert "2 of the 3 levels of plate size b are shown" in caption
    assert "2 of the 12 tests are shown" in caption


def test_population_log_likelihood_and_replicates_are_the_marginal_model():
    # A hand-made Bernstein population: 3 tests with their own fits (k_t, n_t) and
    # covariances; one draw v of the soil level (k, n) and of the scatter (s_eps, s_delta, rho)
    # of (ln p at z_s, n).  A test's fit in η = (ln p at z_ref, n) then scatters around h by
    # (ε + δ (ln z_ref − ln z_s), δ) plus its own error C_t.
    from posterior_sim import POPULATION_FITS as params
    from posterior_sim import POPULATION_LN_ZREF as ln_zref
    from posterior_sim import bernstein_population
    from scipy import stats

    ln_zs = ln_zref + 0.8
    pops = bernstein_population(ln_zs=ln_zs)
    eta, eta_cov = pops.eta, pops.cov
    k, n, s_eps, s_delta, rho = 8.5e5, 1.07, 0.1, 0.04, 0.3
    v = np.array([[k, n, np.log(s_eps), np.log(s_delta), np.arctanh(rho)]])
    b = np.array([[1.0, ln_zref - ln_zs], [0.0, 1.0]])
    sigma = np.array([[s_eps**2, rho * s_eps * s_delta], [rho * s_eps * s_delta, s_delta**2]])
    h = np.array([np.log(k) + n * ln_zref, n])
    for t in range(3):
        m = b @ sigma @ b.T + eta_cov[t]
        expect = stats.multivariate_normal(h, m).logpdf(eta[t]) - np.log(params[t, 0])
        assert pops.log_likelihood(v, params)[0, t] == pytest.approx(expect, rel=1e-12)
    # Replicates: in eta coordinates, mean h and covariance B Sigma B' + C_t.
    rep = pops.replicate(np.repeat(v, 40000, axis=0), np.random.default_rng(0))
    r = rep[:, 1]  # the second test
    rep_eta = np.column_stack([np.log(r[:, 0]) + r[:, 1] * ln_zref, r[:, 1]])
    m = b @ sigma @ b.T + eta_cov[1]
    white = np.linalg.solve(np.linalg.cholesky(m), (rep_eta - h).T)
    assert np.all(np.abs(white.mean(axis=1)) < 0.03)
    np.testing.assert_allclose(np.cov(white), np.eye(2), atol=0.03)
    # A new preparation: ln p at z_s and n scatter by Σ around the soil's (no fit error).
    new = pops.new_preparation(np.repeat(v, 40000, axis=0), np.random.default_rng(1))
    shift = np.column_stack(
        [np.log(new[:, 0]) + new[:, 1] * ln_zs - (np.log(k) + n * ln_zs), new[:, 1] - n]
    )
    white = np.linalg.solve(np.linalg.cholesky(sigma), shift.T)
    assert np.all(np.abs(white.mean(axis=1)) < 0.03)
    np.testing.assert_allclose(np.cov(white), np.eye(2), atol=0.03)
