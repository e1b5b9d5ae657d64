"""The Python API at lmfit's level (issue #47 item 4): named inputs to ``eval``, a function's
own argument names as parameter names, lmfit's ``aic``/``bic``/``redchi`` (checked against
statsmodels' likelihood, which differs from lmfit's by a known constant), correlations in
the notebook view, ``plot_fit``/``plot_residuals``, ``run_study`` by name, and
``export_simulator`` refusing as the CLI does and reading the CLI's prior strings."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pandas as pd
import pytest
import statsmodels.api as sm

from soilstats import fit_sinkage, identify, load_campaign, run_study
from soilstats.bayes.export import SimulatorConstraintError, export_simulator
from soilstats.errors import InputError
from soilstats.models import BEKKER, BERNSTEIN
from soilstats.study import load_spec


def _linear(seed: int = 0, weighted: bool = False):
    rng = np.random.default_rng(seed)
    x = np.linspace(0, 10, 40)
    w = np.linspace(0.5, 2.0, x.size) if weighted else np.ones(x.size)
    y = 3.0 + 0.7 * x + rng.normal(0, 0.5, x.size) / w
    return x, y, w


@pytest.mark.parametrize("weighted", [False, True])
def test_aic_bic_redchi_are_lmfits_and_differ_from_statsmodels_by_the_gaussian_constant(
    weighted,
):
    x, y, w = _linear(weighted=weighted)
    fit = identify(lambda x, a, b: a + b * x, x, y, [1.0, 1.0], weights=w)
    # statsmodels' WLS weights are 1/variance: our residual weights squared.
    ols = sm.WLS(y, sm.add_constant(x), weights=w**2).fit()
    n, k = x.size, 2
    # -2 ln L (Gaussian, σ² at its MLE) = N ln(χ²/N) + N (1 + ln 2π) − Σ ln w²; lmfit keeps
    # only the first term.
    constant = n * (1 + np.log(2 * np.pi)) - np.sum(np.log(w**2))
    assert fit.chisqr == pytest.approx(ols.ssr, rel=1e-9)
    assert fit.redchi == pytest.approx(ols.ssr / (n - k), rel=1e-9)
    assert fit.aic == pytest.approx(ols.aic - constant, rel=1e-9)
    assert fit.bic == pytest.approx(ols.bic - constant, rel=1e-9)
    assert fit.aic == pytest.approx(n * np.log(ols.ssr / n) + 2 * k, rel=1e-12)
    assert "AIC" in fit.summary() and "Reduced chi^2" in fit.summary()


def test_a_plain_functions_parameters_take_its_argument_names():
    x, y, _ = _linear()
    fit = identify(lambda x, a, b: a + b * x, x, y, [1.0, 1.0])
    assert fit.param_names == ("a", "b") and fit.input_names == ("x",)
    assert fit.params["b"] == pytest.approx(np.polyfit(x, y, 1)[0], rel=1e-9)
    np.testing.assert_allclose(fit.eval(x=[0.0, 1.0]), fit.params["a"] + [0, fit.params["b"]])

    def f(*theta):  # no names to read: p0, p1
        return theta[1] + theta[2] * theta[0]

    assert identify(f, x, y, [1.0, 1.0]).param_names == ("p0", "p1")
    with pytest.raises(InputError, match=r"2 parameter names \(a, b\) for 3 starting values"):
        identify(lambda x, a, b: a + b * x, x, y, [1.0, 1.0, 1.0])


def test_eval_takes_named_inputs_and_says_what_a_two_input_law_needs():
    b = np.repeat([0.05, 0.1], 30)
    z = np.tile(np.linspace(0.002, 0.03, 30), 2)
    p = BEKKER.func(np.vstack([b, z]), 2e4, 8e5, 0.9)
    fit = identify(BEKKER, np.vstack([b, z]), p, [1e4, 1e6, 1.0])
    grid = np.linspace(0.005, 0.02, 4)
    truth = (2e4 / 0.1 + 8e5) * grid**0.9
    np.testing.assert_allclose(fit.eval(b=0.1, z=grid), truth, rtol=1e-8)
    np.testing.assert_allclose(fit.eval((np.full(4, 0.1), grid)), truth, rtol=1e-8)
    assert fit.eval_uncertainty(b=0.1, z=grid).shape == (4,)
    with pytest.raises(InputError, match=r"needs 2 inputs \(b, z\).*eval\(b=…, z=…\)"):
        fit.eval(grid)
    with pytest.raises(InputError, match=r"missing \['b'\]"):
        fit.eval(z=grid)
    with pytest.raises(InputError, match=r"unknown \['q'\]"):
        fit.eval(b=0.1, z=grid, q=1)
    bern = identify(BERNSTEIN, z, 3e6 * z**0.8, [1e6, 1.0])
    np.testing.assert_allclose(bern.eval(z=grid), 3e6 * grid**0.8, rtol=1e-8)


def test_notebook_view_shows_the_correlations():
    x, y, _ = _linear()
    fit = identify(lambda x, a, b: a + b * x, x, y, [1.0, 1.0])
    html = fit._repr_html_()
    assert "Correlations" in html
    # the correlation of intercept and slope of a straight line: −x̄/√(mean x²)
    expected = -x.mean() / np.sqrt(np.mean(x**2))
    assert f"{expected:+.3f}" in html and f"{fit.corr.iloc[0, 1]:+.3f}" in html
    assert "AIC / BIC" in html


def test_plot_fit_draws_the_measured_points_under_the_curve_and_residuals_are_y_minus_f():
    import matplotlib.pyplot as plt

    campaign = load_campaign("cullinan-sand")
    fit = fit_sinkage(campaign, "bernstein", preparation="2")
    ax = fit.plot_fit()
    points = [ln for ln in ax.get_lines() if ln.get_linestyle() == "None"]
    assert sum(len(ln.get_xdata()) for ln in points) == fit.nobs == fit.y_data.size
    assert ax.get_xlabel() == "sinkage z [m]" and ax.get_ylabel() == "pressure p [Pa]"
    assert ax.collections, "the ± σ band is drawn"
    res = fit.plot_residuals()
    dots = next(ln for ln in res.get_lines() if ln.get_linestyle() == "None")
    z = np.asarray(dots.get_xdata())
    order = np.argsort(fit.x_data, kind="stable")
    np.testing.assert_allclose(np.sort(z), fit.x_data[order])
    expected = fit.y_data - 1.0 * fit.params["k"] * fit.x_data ** fit.params["n"]
    np.testing.assert_allclose(np.sort(dots.get_ydata()), np.sort(expected), rtol=1e-9, atol=1e-6)
    plt.close("all")


def test_run_study_takes_a_name_or_a_spec_and_a_campaign_name():
    by_name = run_study("preparation", "cullinan-sand")
    by_spec = run_study(load_spec("preparation"), load_campaign("cullinan-sand"))
    pd.testing.assert_frame_equal(by_name.effects, by_spec.effects)


def _draws(kphi: float) -> pd.DataFrame:
    return pd.DataFrame({"kc": [1e3, 2e3], "kphi": [kphi, kphi], "n": [1.0, 1.1]})


def test_export_simulator_refuses_what_chrono_would_change_unless_asked_to_repair():
    priors = ["c=uniform:0:2000", "phi=normal:30:3", "K=lognormal:0.02:0.5"]
    too_stiff = _draws(5e9)  # above SCM's default elastic_K: Chrono would change the sets
    with pytest.raises(SimulatorConstraintError, match=r"elastic_K > Bekker_Kphi.*--scm-repair"):
        export_simulator(too_stiff, priors=priors, seed=1)
    repaired = export_simulator(too_stiff, priors=priors, seed=1, repair=1.5)
    assert repaired.table["elastic_K"].tolist() == [7.5e9, 7.5e9]
    kept = export_simulator(too_stiff, priors=priors, seed=1, on_failure="return")
    assert not kept.check.passed
    # The CLI's --prior strings, its text forms and the tuples give the same sets.
    tuples = {"c": ("uniform", 0, 2000), "phi": ("normal", 30, 3), "K": ("lognormal", 0.02, 0.5)}
    texts = {"c": "uniform:0:2000", "phi": "normal:30:3", "K": "lognormal:0.02:0.5"}
    a = export_simulator(_draws(1e6), priors=priors, seed=3).table
    pd.testing.assert_frame_equal(a, export_simulator(_draws(1e6), priors=tuples, seed=3).table)
    pd.testing.assert_frame_equal(a, export_simulator(_draws(1e6), priors=texts, seed=3).table)
    with pytest.raises(InputError, match="NAME=FORM"):
        export_simulator(_draws(1e6), priors=["uniform:0:2000"], seed=3)


def test_export_simulator_is_found_beside_the_samplers():
    """``from soilstats.bayes import export_simulator`` works where ``sample_posterior`` and
    ``joint_draws`` are imported from (it raised ImportError: only ``bayes.export`` had it)."""
    import soilstats.bayes as bayes

    assert bayes.export_simulator is export_simulator
    assert bayes.SimulatorConstraintError is SimulatorConstraintError
    assert {"export_simulator", "SimulatorConstraintError"} <= set(bayes.__all__)


def test_identifys_figure_shows_the_measured_points_under_the_fit():
    """Issue #47 item 5: the identify report's figure draws the samples the fit was made on."""
    import matplotlib.pyplot as plt

    from soilstats.report.identify_pdf import _MAX_POINTS, _soil_figure

    fit = fit_sinkage(load_campaign("cullinan-sand"), "bernstein", preparation="2")
    fig = _soil_figure("cullinan", [({"kind": "sinkage", "series": None}, fit)])
    dots = [ln for ln in fig.axes[0].get_lines() if ln.get_marker() == "."]
    assert len(dots) == 1
    step = max(1, fit.nobs // _MAX_POINTS)
    np.testing.assert_allclose(dots[0].get_ydata(), fit.y_data[::step] / 1e3)  # kPa
    np.testing.assert_allclose(dots[0].get_xdata(), fit.x_data[::step] * 1e3)  # mm
    plt.close(fig)
