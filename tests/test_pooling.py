"""Section 2.1's sample rule, in its one home (soilstats.identification.pooling)."""

from __future__ import annotations

import numpy as np
import pytest

import soilstats
from soilstats.errors import CampaignError
from soilstats.identification.pooling import (
    MIN_SAMPLES,
    kept_samples,
    pool_shear,
    pool_sinkage,
)


def test_contact_thinning_and_weight_by_hand():
    z = np.array([-0.001, 0.0, 0.001, 0.002, 0.003, 0.004, 0.005])
    p = np.array([-5.0, 0.0, 10.0, 20.0, 40.0, 30.0, 80.0])
    kept = kept_samples(z, p, "sinkage", points_per_test=3)
    assert kept.excluded == 2  # z <= 0
    assert list(kept.index) == [2, 4, 6]  # nearest to 1, 3, 5 mm
    assert kept.weight == pytest.approx(1 / 80.0) and kept.problem is None
    shear = kept_samples(z, p, "shear", points_per_test=None, weighting="none")
    assert shear.excluded == 1 and shear.weight == 1.0  # j >= 0 keeps j = 0


def test_unusable_tests_say_why():
    few = kept_samples(
        np.array([0.001, 0.002]), np.array([1.0, 2.0]), "sinkage", points_per_test=None
    )
    assert few.index.size < MIN_SAMPLES and "at least 3" in few.problem and np.isnan(few.weight)
    negative = kept_samples(np.arange(1, 6) * 1e-3, -np.ones(5), "sinkage", points_per_test=None)
    assert "<= 0" in negative.problem


def test_pooled_samples_map_back_to_their_tests():
    campaign = soilstats.load_campaign("simulated-paper")
    pooled = pool_shear(campaign, steady_only=False, weighting="max-stress", soil="soil01")
    counts = np.bincount(pooled.test_index, minlength=len(pooled.tests))
    assert np.array_equal(counts, pooled.tests["used"].to_numpy())
    taus = pooled.y
    for pos in (0, len(pooled.tests) - 1):
        mine = pooled.test_index == pos
        assert pooled.weights[mine] == pytest.approx(1 / taus[mine].max())


def test_skip_keeps_the_row_of_an_unusable_test(tmp_path):
    campaign = soilstats.load_campaign("cullinan-sand")
    sinkage = campaign.sinkage.drop(columns="pressure_Pa")
    first = campaign.tests["test_id"].iloc[0]
    sinkage.loc[sinkage["test_id"] == first, "z_m"] = -1e-3  # never in contact
    broken = soilstats.Campaign.from_frames(campaign.tests, sinkage)
    with pytest.raises(CampaignError, match=str(first)):
        pool_sinkage(broken)
    pooled = pool_sinkage(broken, on_unusable="skip")
    row = pooled.tests.iloc[0]
    assert row["used"] == 0 and "at least 3" in row["problem"]
    assert 0 not in set(pooled.test_index)
