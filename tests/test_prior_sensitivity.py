"""Power-scaling prior sensitivity (soilstats/bayes/prior_sensitivity.py; issue #47 item 3),
checked against closed forms.

Conjugate normal–normal: prior N(μ0, τ²) on a mean θ, n observations of sd σ with mean ȳ.
The prior to the power α is N(μ0, τ²/α), so the power-scaled posterior is normal with
precision α/τ² + n/σ² and mean (αμ0/τ² + nȳ/σ²)/precision — known exactly.  The sensitivity
is then the cumulative Jensen–Shannon distance between *exact* normal CDFs at α = 0.99 and
1.01 (integrated on a fine grid over the draws' range, as the estimator's ECDF covers it),
divided by 2·log2(1.01): the estimator, which only reweights draws from the base posterior,
must reproduce it.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.stats import norm

from soilstats.bayes.prior_sensitivity import (
    DELTA,
    THRESHOLD,
    cjs_distance,
    influential_warning,
    pooled_sensitivity,
    power_scaling_sensitivity,
)
from soilstats.campaign import load_campaign
from soilstats.errors import DefaultWarning
from soilstats.models.priors import FLAT, POSITIVE, Normal


def _posterior(mu0, tau, ybar, sigma, n, alpha=1.0):
    precision = alpha / tau**2 + n / sigma**2
    return (alpha * mu0 / tau**2 + n * ybar / sigma**2) / precision, precision**-0.5


def _exact_cjs(base, scaled, lo, hi):
    """CJS distance of two normal CDFs on [lo, hi], normalised by its bound (as priorsense)."""
    x = np.linspace(lo, hi, 200_001)
    dx = x[1] - x[0]
    p, q = norm.cdf(x, *base), norm.cdf(x, *scaled)
    with np.errstate(divide="ignore", invalid="ignore"):
        pq = np.nansum(p * (np.log2(p) - np.log2(0.5 * (p + q)))) * dx
        qp = np.nansum(q * (np.log2(q) - np.log2(0.5 * (p + q)))) * dx
    pq += 0.5 / np.log(2) * (q.sum() - p.sum()) * dx
    qp += 0.5 / np.log(2) * (p.sum() - q.sum()) * dx
    return np.sqrt((pq + qp) / ((p.sum() + q.sum()) * dx))


def _closed_form(case, draws):
    base = _posterior(*case)
    total = 0.0
    for alpha in (1 - DELTA, 1 + DELTA):
        m, s = _posterior(*case, alpha=alpha)
        up = _exact_cjs(base, (m, s), draws.min(), draws.max())
        down = _exact_cjs((-base[0], base[1]), (-m, s), -draws.max(), -draws.min())
        total += max(up, down)
    return total / (2 * np.log2(1 + DELTA))


STRONG = (0.0, 0.5, 2.0, 1.0, 3)  # prior sd 0.5 against 3 points of sd 1: the prior dominates
WEAK = (0.0, 10.0, 2.0, 1.0, 200)  # prior sd 10 against 200 points: the data dominate


@pytest.mark.parametrize(("case", "influential"), [(STRONG, True), (WEAK, False)])
def test_conjugate_normal_sensitivity_matches_its_closed_form(case, influential):
    rng = np.random.default_rng(1)
    m, s = _posterior(*case)
    draws = rng.normal(m, s, 20_000)
    log_prior = norm.logpdf(draws, case[0], case[1])
    found, k = power_scaling_sensitivity({"theta": draws}, log_prior)
    exact = _closed_form(case, draws)
    assert found["theta"] == pytest.approx(exact, rel=0.05)
    assert bool(found["theta"] > THRESHOLD) is influential
    assert k < 0.5  # a 1 % change of the prior's power: weights close to one


def test_a_flat_prior_has_no_sensitivity():
    draws = np.random.default_rng(2).normal(size=1000)
    found, k = power_scaling_sensitivity({"a": draws, "b": draws**2}, np.zeros(1000))
    assert found == {"a": 0.0, "b": 0.0} and np.isnan(k)


def test_cjs_distance_is_zero_for_equal_weights_and_grows_with_the_shift():
    x = np.random.default_rng(3).normal(size=4000)
    assert cjs_distance(x, np.ones_like(x)) == pytest.approx(0.0, abs=1e-6)  # float sums
    small = cjs_distance(x, np.exp(0.05 * x))  # tilting a normal shifts its mean by 0.05
    large = cjs_distance(x, np.exp(0.2 * x))
    assert 0 < small < large
    assert cjs_distance(x, np.exp(0.2 * x)) == pytest.approx(cjs_distance(-x, np.exp(-0.2 * -x)))


def test_a_given_prior_is_reported_but_not_a_default_warning():
    """A strong user prior on θ (the conjugate case) makes θ sensitive to *it*; the default
    priors (flat, and 1/σ_w on the noise scale) stay uninfluential: no warning."""
    rng = np.random.default_rng(4)
    m, s = _posterior(*STRONG)
    posterior = {
        "a": rng.normal(m, s, 20_000),
        "b": rng.lognormal(0.0, 0.01, 20_000),
        "sigma_w": rng.lognormal(0.0, 0.01, 20_000),
    }
    user = Normal(mu=STRONG[0], sd=STRONG[1])
    table = pooled_sensitivity(posterior, ("a", "b"), (user, POSITIVE), given=["a"]).set_index(
        "quantity"
    )
    assert table.loc["a", "given_prior_sensitivity"] > THRESHOLD
    assert table["default_prior_sensitivity"].max() < THRESHOLD
    assert not table["influential"].any()
    assert influential_warning("bernstein", table.reset_index()) is None
    # the same prior left as the model's default is influential and named in the warning
    default = pooled_sensitivity(posterior, ("a", "b"), (user, FLAT), given=[])
    text = influential_warning("bernstein", default)
    assert text is not None and "a (0.2" in text and "--prior" in text


def test_grc1_population_rests_on_its_default_priors_and_warns():
    """GRC-1's 15 Bernstein tests leave ln k wide (posterior sd ≈ 0.5): the default 1/k
    prior moves it (measured sensitivity 0.14, docs/posterior.md)."""
    from soilstats.bayes import sample_population

    with pytest.warns(DefaultWarning, match="default priors of the bernstein posterior"):
        result = sample_population(load_campaign("grc1-oravec2009"), "bernstein", seed=0)
    table = result.prior_sensitivity.set_index("quantity")
    assert table.loc["mu_k", "influential"]
    assert "Prior sensitivity: WARNING" in result.summary()


def test_the_paper_campaign_pooled_posterior_is_silent():
    from soilstats.bayes import sample_posterior

    with warnings.catch_warnings():
        warnings.simplefilter("error", DefaultWarning)
        result = sample_posterior(
            load_campaign("simulated-paper"), "bernstein", seed=0, soil="soil01"
        )
    assert result.prior_sensitivity is not None
    assert not result.prior_sensitivity["influential"].any()
    assert "default priors are not influential" in result.summary()


def test_a_strong_user_prior_is_reported_and_not_warned_on_a_real_posterior():
    """GRC-1's pooled Bernstein with n ~ N(1, 0.05²) stated: the posterior rests on that prior
    (its sensitivity is reported), but the user chose it — no warning."""
    from soilstats.bayes import sample_posterior

    with warnings.catch_warnings():
        warnings.simplefilter("error", DefaultWarning)
        result = sample_posterior(
            load_campaign("grc1-oravec2009"),
            "bernstein",
            seed=0,
            priors={"n": Normal(mu=1.0, sd=0.05, lower=0.0)},
        )
    table = result.prior_sensitivity.set_index("quantity")
    assert table.loc["n", "given_prior_sensitivity"] > THRESHOLD
    assert not table["influential"].any()
