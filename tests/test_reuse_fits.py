"""A least-squares fit asked for twice inside ``reused_fits()`` is made once (issue #39:
"caching what is asked twice"), and only there."""

from __future__ import annotations

import numpy as np
import pytest
from posterior_sim import joint_campaign

from soilstats.bayes import sample_posterior
from soilstats.bayes.handout import preflight
from soilstats.identification import fit_shear, fit_sinkage
from soilstats.identification import shear as shear_module
from soilstats.identification.reuse import reused_fits


@pytest.fixture(scope="module")
def campaign():
    return joint_campaign(np.random.default_rng(3), repetitions=3, points=40)


def test_same_arguments_give_the_same_fit_inside_the_block_only(campaign):
    with reused_fits():
        a = fit_shear(campaign, "janosi", test_resamples=0)
        assert fit_shear(campaign, "janosi", test_resamples=0) is a
        # Positional and keyword spellings of the same call are the same call.
        assert fit_shear(campaign, model="janosi", test_resamples=0) is a
        assert fit_shear(campaign, "janosi", test_resamples=0, weighting="none") is not a
        assert fit_shear(campaign, "mohr-coulomb", test_resamples=0) is not a
        s = fit_sinkage(campaign, "bekker", test_resamples=0)
        assert fit_sinkage(campaign, "bekker", test_resamples=0) is s
        assert fit_sinkage(campaign, "bekker", test_resamples=0, points_per_test=20) is not s
    assert fit_shear(campaign, "janosi", test_resamples=0) is not a  # outside: afresh
    with reused_fits():  # a new block remembers nothing of the last
        assert fit_shear(campaign, "janosi", test_resamples=0) is not a


def test_a_reused_fit_equals_a_new_one(campaign):
    with reused_fits():
        fit_sinkage(campaign, "bekker", test_resamples=0)
        again = fit_sinkage(campaign, "bekker", test_resamples=0)
    fresh = fit_sinkage(campaign, "bekker", test_resamples=0)
    np.testing.assert_array_equal(again.params.to_numpy(), fresh.params.to_numpy())
    np.testing.assert_array_equal(again.cov.to_numpy(), fresh.cov.to_numpy())


def test_arguments_that_cannot_be_compared_are_never_reused(campaign):
    p0 = np.array([20.0, 30.0, 0.01])
    with reused_fits():
        a = fit_shear(campaign, "janosi", test_resamples=0, p0=p0)
        assert fit_shear(campaign, "janosi", test_resamples=0, p0=p0) is not a


# A short run: whether it converges is not the question here.
@pytest.mark.filterwarnings("ignore::soilstats.errors.ConvergenceWarning")
def test_preflight_and_sampling_fit_each_model_once(campaign, monkeypatch):
    calls = []
    real = shear_module.identify

    def counting(model, *args, **kwargs):
        calls.append(model.name)
        return real(model, *args, **kwargs)

    monkeypatch.setattr(shear_module, "identify", counting)

    def pooled_fits() -> int:
        # fit_shear's pooled Janosi fits: preflight's and the sampler's start
        calls.clear()
        preflight(campaign, ["janosi"], population=False)
        sample_posterior(campaign, "janosi", seed=0, draws=400)
        return calls.count("janosi")

    alone = pooled_fits()
    with reused_fits():
        together = pooled_fits()
    assert alone >= 2 and together == alone // 2
