"""The active joblib backend reaches every parallel piece (issue #39): ``discover`` run
inside ``parallel_config(backend="dask")`` sends its work to the Dask cluster — the fits
of its group threads included, which once went to local loky workers while the cluster idled
(joblib's backend setting is per thread) — and returns what ``jobs=1`` returns."""

from __future__ import annotations

import pytest

distributed = pytest.importorskip("distributed")  # the test extra installs it

pytestmark = pytest.mark.slow  # a local cluster of two processes and three discoveries


def test_discover_on_a_dask_cluster_runs_there_and_equals_one_job(monkeypatch):
    import joblib
    from joblib.parallel import get_active_backend

    import soilstats.discovery.work as work
    from soilstats import load_campaign
    from soilstats.discovery import discover

    campaign = load_campaign("grc1-oravec2009")
    alone = discover(campaign, jobs=1).to_dict()

    seen = []  # the backend each parallel piece of discovery met, in whatever thread it ran
    original = work.parallel_map

    def recording(*args, **kwargs):
        seen.append(type(get_active_backend()[0]).__name__)
        return original(*args, **kwargs)

    monkeypatch.setattr(work, "parallel_map", recording)
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    )
    with cluster, distributed.Client(cluster) as client:
        with distributed.get_task_stream(client) as stream, joblib.parallel_config("dask"):
            on_dask = discover(campaign, jobs=2).to_dict()
    assert seen and set(seen) == {"DaskDistributedBackend"}, seen
    assert len(stream.data) >= len(seen)  # the tasks ran on the cluster's workers
    for record in (alone, on_dask):
        record.pop("runtime_s", None)
        record.get("provenance", {}).pop("command", None)
    assert on_dask == alone
