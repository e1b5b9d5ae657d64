"""parallel_map: input order kept, the same results for any number of jobs, clear errors."""

from __future__ import annotations

import numpy as np
import pytest

from soilstats.parallel import effective_jobs, parallel_map


def _seeded_mean(seed: int) -> float:
    # Each task draws from its own seed: the promise that makes any --jobs give one answer.
    return float(np.random.default_rng(seed).normal(size=1000).mean())


def test_results_keep_input_order_and_match_serial():
    seeds = list(range(7, 0, -1))  # an order a worker pool would not finish in by accident
    serial = parallel_map(_seeded_mean, seeds, jobs=1)
    assert serial == [_seeded_mean(s) for s in seeds]
    assert parallel_map(_seeded_mean, seeds, jobs=2) == serial


def _calls_from_threads(sizes, *, jobs, wrap=lambda target: target):
    """parallel_map over range(n) from one thread per n in ``sizes``, as discovery calls it
    from its group threads, each thread's target passed through ``wrap``; returns
    {n: results}, asserting that no thread hung."""
    import threading

    results: dict[int, list] = {}

    def call(n: int) -> None:
        results[n] = parallel_map(_seeded_mean, list(range(n)), jobs=jobs, single_in_process=False)

    threads = [threading.Thread(target=wrap(call), args=(n,), daemon=True) for n in sizes]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=120)
    assert not any(thread.is_alive() for thread in threads), "parallel_map hung"
    return results


def test_overlapping_calls_from_threads_with_any_item_count_finish():
    """Discovery calls parallel_map from one thread per group, with waves of 1 to dozens of
    fits.  With more workers than some waves have items (jobs=3), calls that asked joblib for
    different worker counts made loky resize its one pool under running jobs and hang."""
    sizes = (1, 2, 3, 17, 30)
    results = _calls_from_threads(sizes, jobs=3)
    assert results == {n: [_seeded_mean(s) for s in range(n)] for n in sizes}


@pytest.mark.parametrize("configured", [False, True], ids=["default", "parallel_config"])
def test_threads_started_in_this_backend_each_get_their_own_backend(configured):
    """Threads carrying the caller's joblib configuration must not share its backend object:
    joblib configures and terminates the instance it is given, and discovery's group threads
    sharing one loky backend pulled its pool from under each other ("'NoneType' object has no
    attribute 'submit'", or CI hanging for 90 minutes)."""
    import contextlib
    import threading

    import joblib
    from joblib.parallel import get_active_backend

    from soilstats.parallel import in_this_backend

    sizes = (2, 5, 9, 2, 5, 9)
    context = joblib.parallel_config("loky", n_jobs=2) if configured else contextlib.nullcontext()
    with context:
        caller = get_active_backend()[0]
        seen = []
        probe = threading.Thread(
            target=in_this_backend(lambda: seen.append(get_active_backend()[0]))
        )
        probe.start()
        probe.join()
        assert type(seen[0]) is type(caller) and seen[0] is not caller
        for _ in range(3):  # the race showed within a few rounds
            results = _calls_from_threads(sizes, jobs=2, wrap=in_this_backend)
            assert results == {n: [_seeded_mean(s) for s in range(n)] for n in sizes}


def test_effective_jobs_follows_joblib_convention():
    import os

    cores = os.cpu_count() or 1
    assert effective_jobs(None) == effective_jobs(0) == 1
    assert effective_jobs(3) == 3
    assert effective_jobs(-1) == cores
    with pytest.raises(ValueError, match="fewer than one worker"):
        effective_jobs(-(cores + 1))


def test_condition_fits_are_the_same_for_any_number_of_jobs():
    import soilstats
    from soilstats.identification.conditions import fit_conditions

    campaign = soilstats.load_campaign("simulated-paper").select(series="velocity")
    runs = [
        fit_conditions(campaign, "sinkage", test_resamples=40, seed=3, jobs=jobs) for jobs in (1, 2)
    ]
    one, two = ([f.fit for f in run.fits] for run in runs)
    assert len(one) == len(two) > 1
    for a, b in zip(one, two, strict=True):
        assert np.array_equal(a.values, b.values)
        assert np.array_equal(a.bootstrap.draws, b.bootstrap.draws)
        assert [f.code for f in a.flags] == [f.code for f in b.flags]
    assert runs[0].summary() == runs[1].summary()


def test_planned_kinds_fitted_as_one_queue_equal_separate_calls():
    """identify plans sinkage and shear and fits them as one queue over the workers; each
    kind's result is the one fit_conditions gives for it alone, condition by condition."""
    import soilstats
    from soilstats.identification.conditions import fit_conditions, fit_planned, plan_conditions

    campaign = soilstats.load_campaign("simulated-paper").select(series=["velocity", "grousers"])
    options = {"test_resamples": 30, "seed": 2}
    plans = [plan_conditions(campaign, kind, **options) for kind in ("sinkage", "shear")]
    together = fit_planned(plans, jobs=2)
    for kind, result in zip(("sinkage", "shear"), together, strict=True):
        alone = fit_conditions(campaign, kind, **options)
        assert [f.kind for f in result.fits] == [kind] * len(alone.fits)
        assert result.summary() == alone.summary()
        for a, b in zip(result.fits, alone.fits, strict=True):
            assert (a.soil, a.condition, a.model) == (b.soil, b.condition, b.model)
            assert np.array_equal(a.fit.values, b.fit.values)
            assert np.array_equal(a.fit.bootstrap.draws, b.fit.bootstrap.draws)
