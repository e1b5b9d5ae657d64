"""``fit_sinkage``'s test bootstrap and adequacy checks run when first needed (issue #45,
item 7): a loop reading ``params`` skips them, and whatever is read equals the eager fit's."""

from __future__ import annotations

import pickle
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from posterior_calibration import population_spec

from soilstats.identification import bootstrap, fit_sinkage, pool_sinkage, sinkage
from soilstats.identification.bootstrap import bootstrap_tests
from soilstats.models import get_model
from soilstats.quality import screened
from soilstats.simulation import simulate


@pytest.fixture(scope="module")
def campaign():
    spec = population_spec(6, stiffness_cv=0.1, n_sd=0.03, points=60)
    return simulate(spec, seed=45).campaign


def _counting(monkeypatch) -> list:
    calls: list = []
    real = bootstrap.test_bootstrap

    def counted(*args, **kwargs):
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(sinkage, "test_bootstrap", counted)
    return calls


def test_params_alone_run_no_bootstrap_and_the_first_sigma_runs_it_once(campaign, monkeypatch):
    calls = _counting(monkeypatch)
    fit = fit_sinkage(campaign, "bekker")
    assert np.isfinite(fit.params.to_numpy()).all() and fit.converged
    assert fit.stderr_eq4.notna().all()  # Eq. 4's σ is the core fit's, not deferred
    assert calls == []
    assert fit.stderr_level == "tests"
    assert calls == [1]
    fit.summary(), fit.flags, fit.to_dict()
    assert calls == [1]


def test_the_deferred_sigma_is_the_seeded_bootstrap_of_the_tests(campaign):
    """Independent of the deferral: the cluster bootstrap called directly with the fit's
    pooled data, estimate and seed gives the same σ to the bit."""
    fit = fit_sinkage(campaign, "bekker", seed=7)
    pooled = pool_sinkage(screened(campaign, "clean"), points_per_test=100)
    model = get_model("bekker")
    direct = bootstrap_tests(
        model,
        model.x_from(pooled.x),
        pooled.y,
        pooled.weights,
        pooled.test_index,
        fit.values,
        n_resamples=bootstrap.DEFAULT_RESAMPLES,
        seed=7,
        design=pooled.x["b_m"],
    )
    np.testing.assert_array_equal(fit.stderr.to_numpy(), direct.stderr.to_numpy())


def test_an_unread_fit_pickles_and_reads_as_the_one_read_here(campaign):
    fit = fit_sinkage(campaign, "bekker")
    copy = pickle.loads(pickle.dumps(fit))
    assert "_pending" not in copy.__dict__
    assert copy.summary() == fit.summary()
    assert copy.to_dict() == fit.to_dict()
    assert copy.flags == fit.flags and copy.notes == fit.notes


def test_threads_reading_one_fit_see_one_finished_result(campaign):
    fit = fit_sinkage(campaign, "bekker")
    barrier = threading.Barrier(4)

    def read(_):
        barrier.wait()
        return fit.summary()

    with ThreadPoolExecutor(4) as pool:
        texts = set(pool.map(read, range(4)))
    assert len(texts) == 1 and "test-level σ" in texts.pop()


def test_a_loop_over_one_campaign_pools_once_and_fits_as_a_fresh_campaign(campaign, monkeypatch):
    """The pooled data and Wong's start are kept per campaign object (issue #45, item 7):
    the second call pools nothing, and every fit equals the fit of a new campaign object
    with the same tables (nothing kept) to the bit."""
    import dataclasses

    calls: list = []
    real = sinkage.pool_sinkage
    monkeypatch.setattr(sinkage, "pool_sinkage", lambda *a, **k: calls.append(1) or real(*a, **k))
    kept = screened(campaign, "clean")
    for model in ("bekker", "bernstein", "bekker"):
        fit = fit_sinkage(kept, model, soil="sand")
        fresh = fit_sinkage(dataclasses.replace(kept), model, soil="sand")
        assert np.array_equal(fit.values, fresh.values)
        assert np.array_equal(fit.stderr.to_numpy(), fresh.stderr.to_numpy())
        assert fit.flags == fresh.flags
    # kept: bekker, bernstein (bekker again reused); fresh: one per call
    assert len(calls) == 2 + 3
    pooled, _, _ = sinkage._prepared(
        get_model("bekker", "sinkage"),
        kept,
        {"points_per_test": 100, "weighting": "max-pressure", "soil": "sand"},
    )
    with pytest.raises(ValueError, match="read-only"):
        pooled.y[0] = 0.0  # shared by every later fit: nobody may change it
    other = fit_sinkage(kept, "bekker", soil="sand", points_per_test=50)
    assert other.tests["used"].max() <= 50 < fit.tests["used"].max()


def test_a_fits_test_columns_are_its_own_and_their_arrays_cannot_be_written(campaign):
    """Fits of one campaign share the kept per-test arrays (read-only) but not the dict that
    holds them: a key a user adds to one fit's ``test_columns`` never reaches the next fit."""
    kept = screened(campaign, "clean")
    first = fit_sinkage(kept, "bekker", soil="sand")
    second = fit_sinkage(kept, "bekker", soil="sand")
    assert first.test_columns is not second.test_columns
    first.test_columns["note"] = np.zeros(len(first.tests))
    assert "note" not in fit_sinkage(kept, "bekker", soil="sand").test_columns
    with pytest.raises(ValueError, match="read-only"):
        first.test_columns["b_m"][0] = 99.0
