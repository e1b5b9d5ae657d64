"""``FitResult.eval`` and ``eval_uncertainty`` as lmfit users expect them: the fitted curve,
and its band from the parameter covariance (delta method), checked against statsmodels'
prediction standard errors for a linear model and against Monte Carlo draws of the
parameters for a power law; a campaign fit's band is the test-level one where it rests on
five tests or more."""

from __future__ import annotations

import numpy as np
import pytest
import statsmodels.api as sm

from soilstats import fit_sinkage, identify, load_campaign
from soilstats.models import BERNSTEIN


def test_the_band_of_a_linear_fit_is_statsmodels_prediction_standard_error():
    rng = np.random.default_rng(0)
    x = np.linspace(0, 10, 40)
    y = 3.0 + 0.7 * x + rng.normal(0, 0.5, x.size)
    fit = identify(lambda x, a, b: a + b * x, x, y, [1.0, 1.0])
    ols = sm.OLS(y, sm.add_constant(x)).fit()
    new = np.array([-2.0, 0.0, 4.5, 12.0])
    np.testing.assert_allclose(fit.eval(new), ols.predict(sm.add_constant(new)), rtol=1e-9)
    se = ols.get_prediction(sm.add_constant(new)).se_mean
    np.testing.assert_allclose(fit.eval_uncertainty(new), se, rtol=1e-7)
    np.testing.assert_allclose(fit.eval_uncertainty(new, sigma=2), 2 * se, rtol=1e-7)
    with pytest.raises(ValueError, match="sigma must be positive"):
        fit.eval_uncertainty(new, sigma=0)


def test_the_band_of_a_power_law_matches_monte_carlo_draws_of_its_parameters():
    rng = np.random.default_rng(1)
    z = np.linspace(0.001, 0.03, 60)
    p = 4e6 * z**0.9 * (1 + rng.normal(0, 0.01, z.size))
    fit = identify(BERNSTEIN, z, p, [1e6, 1.0])
    new = np.array([0.005, 0.02, 0.04])
    draws = rng.multivariate_normal(fit.values, fit.covariance, 200_000)
    curves = draws[:, :1] * new[None, :] ** draws[:, 1:]
    np.testing.assert_allclose(fit.eval_uncertainty(new), curves.std(axis=0), rtol=0.02)


def test_a_campaign_fit_band_is_test_level_where_it_rests_on_five_tests():
    """GRC-1's 51 mm plate, five tests: the band is the test bootstrap's (what a new test
    scatters by: several times Eq. 4's here); without the bootstrap it is Eq. 4's."""
    campaign = load_campaign("grc1-oravec2009")
    z = np.array([0.002, 0.004, 0.006])
    fit = fit_sinkage(campaign, "bernstein", radius_m=0.051, test_resamples=200)
    assert fit.n_tests == 5
    tests, samples = fit.eval_uncertainty(z), fit.eval_uncertainty(z, level="samples")
    jac = np.column_stack([z**fit.values[1], fit.values[0] * z ** fit.values[1] * np.log(z)])
    want = np.sqrt(np.einsum("ij,jk,ik->i", jac, fit.covariance_tests, jac))
    np.testing.assert_allclose(tests, want, rtol=1e-9)
    assert (tests > 2 * samples).all()
    plain = fit_sinkage(campaign, "bernstein", radius_m=0.051, test_resamples=0)
    np.testing.assert_allclose(plain.eval_uncertainty(z), samples, rtol=1e-9)
    with pytest.raises(ValueError, match="without the test bootstrap"):
        plain.eval_uncertainty(z, level="tests")


def test_fits_and_studies_show_their_summary_as_tables_in_a_notebook():
    """``_repr_html_``: the parameters with both σ, the health codes and the notes (escaped);
    a study's verdicts and notes."""
    from soilstats.study import load_spec, run_study

    fit = fit_sinkage(
        load_campaign("grc1-oravec2009"), "bernstein", radius_m=0.051, test_resamples=100
    ).annotated(notes=["z < 0 left out <here>"])
    page = fit._repr_html_()
    for name in fit.param_names:
        assert f"<td>{name}</td>" in page and f"{fit.params[name]:.6g}" in page
        assert f"{fit.stderr_tests[name]:.4g}" in page and f"{fit.stderr[name]:.4g}" in page
    assert all(f.code in page for f in fit.flags)
    assert "z &lt; 0 left out &lt;here&gt;" in page and "<here>" not in page
    study = run_study(load_spec("velocity"), load_campaign("simulated-paper"))
    page = study._repr_html_()
    assert "Verdicts" in page and all(v in page for v in study.effects["verdict"])


def test_numbers_are_printed_on_a_scale_that_shows_them():
    """A σ larger than the value no longer hides it: once '(0.0 ± 1.4)e13'."""
    from soilstats.identification.table import format_value

    assert format_value(1.0e11, 1.4e13) == "1e11 ± 1.4e13"
    assert format_value(-2.5e-4, 3.1e-2) == "-0.00025 ± 0.031"
    assert format_value(1.2e6, 3.0e4) == "(1.200 ± 0.030)e6"
    assert format_value(0.8251, 0.0077) == "0.8251 ± 0.0077"


def test_the_parameter_tables_take_a_fit_without_tests():
    """``parameter_table`` and ``format_parameter_table`` take any FitResult: one from
    :func:`identify` has no ``tests`` (a campaign fit's attribute), so its count reads NaN / -
    (it raised AttributeError)."""
    from soilstats.identification import parameter_table
    from soilstats.identification.table import format_parameter_table

    x = np.linspace(0.1, 1.0, 20)
    y = 2.0 * x**1.3 + 0.01 * np.sin(7 * x)
    fit = identify(lambda x, a, b: a * x**b, x, y, [1.0, 1.0], param_names=["a", "b"])
    table = parameter_table({"plain": fit})
    assert list(table["parameter"]) == ["a", "b"] and table["tests"].isna().all()
    lines = format_parameter_table({"plain": fit}).splitlines()
    (tests_row,) = [line for line in lines if line.startswith("tests ")]
    assert tests_row.split() == ["tests", "-"]
