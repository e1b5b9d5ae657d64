"""Glitch clusters (docs/quality.md, ``glitch-cluster``): dense runs of 5-60 samples at 3-15x
the record's depth (or peak force) that come back, planted by the simulator
(``[[artefacts]]`` kind ``glitch-cluster``), are found at their rows and nowhere else, left
out of fits (the pooled n back within its test-level σ of the clean records' fit), and a
record that runs away at its end is no glitch."""

from __future__ import annotations

from functools import partial

import numpy as np
import pytest
from quality_sim import artefact_spec, flagged_rows

from soilstats import fit_sinkage
from soilstats.quality import screen
from soilstats.quality.glitches import find_glitch_clusters
from soilstats.simulation import simulate

SOILS = {
    "mare": {"kc": 2.0e3, "kphi": 9.0e5, "n": 1.35},
    "loam": {"kc": 1.5e4, "kphi": 2.0e6, "n": 0.8},
    "soft": {"kc": 1.0e3, "kphi": 3.0e5, "n": 0.3},
}


#: This file's campaign with the artefacts given planted (``points`` per record).
_spec = partial(
    artefact_spec,
    "glitches",
    SOILS,
    points=200,
    noise_N=1.0,
    radii=(0.025, 0.05),
    repetitions=5,
    sinkage_m=0.03,
)


def _flagged(report) -> dict[str, set]:
    return flagged_rows(report, "glitch-cluster")


@pytest.mark.parametrize(("channel", "seed"), [("z_m", 3), ("force_N", 4)])
def test_planted_clusters_are_found_at_their_rows_and_nowhere_else(channel, seed):
    sim = simulate(
        _spec([{"kind": "glitch-cluster", "channel": channel, "share": 0.5, "count": 2}]),
        seed=seed,
    )
    truth = sim.artefacts
    assert len(truth) >= 8
    report = screen(sim.campaign)
    found = _flagged(report)
    assert set(found) == set(truth["test_id"])
    for row in truth.itertuples():
        planted = {int(r) for r in row.rows.split()}
        assert 5 <= len(planted) <= 120
        assert planted <= found[row.test_id], row.test_id  # every planted sample
        assert len(found[row.test_id] - planted) == 0, row.test_id  # and no good one
    # the good samples behind a cluster are no longer called non-monotone
    assert not {f.test_id for f in report.flags if f.code == "non-monotone"}


def test_clusters_left_out_restore_the_fit_that_kept_ones_ruin():
    """The mare-simulant situation of #46: clusters at 3-15x depth in z. Screened, each
    soil's pooled Bernstein n lies within 2 test-level σ of the clean records' fit (0.6-1.7
    σ: the fit has 10-25 % fewer samples); with the clusters kept (``--quality flag``) it is
    30-140 σ off (n 0.03-0.04 for 0.3-1.35)."""
    artefacts = [{"kind": "glitch-cluster", "channel": "z_m", "length": [20, 50]}]
    dirty = simulate(_spec(artefacts), seed=8).campaign
    clean = simulate(_spec([]), seed=8).campaign
    assert not _flagged(screen(clean))
    moved = 0
    for soil in SOILS:
        truth = fit_sinkage(clean, "bernstein", soil=soil, test_resamples=200)
        sigma = float(truth.stderr_tests["n"])
        screened = fit_sinkage(dirty, "bernstein", soil=soil)
        kept = fit_sinkage(dirty, "bernstein", soil=soil, quality="flag")
        assert abs(screened.params["n"] - truth.params["n"]) <= 2 * sigma, soil
        moved += abs(kept.params["n"] - truth.params["n"]) > 10 * sigma
    assert moved == len(SOILS)


def test_a_run_away_at_the_end_or_a_steep_clean_record_is_no_glitch():
    z = np.linspace(0.0, 0.03, 200)
    # punch-through: z runs to 10x its depth over the last 30 samples and never comes back
    runaway = np.r_[z[:170], np.linspace(0.03, 0.3, 30)]
    assert find_glitch_clusters(runaway).size == 0
    # a very steep force (n = 3.3 on a z grid) rises far above its 70 % quantile, monotone
    force = 1e4 * (z / 0.03) ** 3.3
    assert find_glitch_clusters(force).size == 0
    # the same record with a 30-sample cluster at 5x the depth, and back
    glitched = z.copy()
    glitched[80:110] = 0.15
    assert list(find_glitch_clusters(glitched)) == list(range(80, 110))
    # a cluster longer than a quarter of the record is not read as a glitch
    glitched[80:140] = 0.15
    assert find_glitch_clusters(glitched).size == 0


def test_a_record_that_starts_under_load_and_one_with_a_gap_are_named():
    """``starts-loaded`` and ``gap`` on simulated records with known truth: the first 4 mm of
    one record cut off (it starts under load at z = 4 mm), 6 mm of samples taken out of
    another; the other records of the campaign carry neither."""
    from dataclasses import replace

    campaign = simulate(_spec([], points=150), seed=2).campaign
    sink = campaign.sinkage
    ids = list(campaign.tests.loc[campaign.tests["soil"] == "loam", "test_id"])
    first, second = ids[0], ids[1]  # n 0.8: 20 % of the peak force at 4 mm of 30
    cut = (sink["test_id"] == first) & (sink["z_m"] < 0.004)
    hole = (sink["test_id"] == second) & (sink["z_m"] > 0.012) & (sink["z_m"] < 0.018)
    report = screen(replace(campaign, sinkage=sink[~(cut | hole)]))
    starts = [f for f in report.flags if f.code == "starts-loaded"]
    gaps = [f for f in report.flags if f.code == "gap"]
    assert [f.test_id for f in starts] == [first]
    assert starts[0].value == pytest.approx(0.004, abs=0.0003)
    assert [f.test_id for f in gaps] == [second]
    assert gaps[0].value == pytest.approx(0.006, abs=0.0005)
