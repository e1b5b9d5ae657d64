"""The per-campaign sample index (soilstats.campaign.index) and the shortcuts of the fit path:
each must give exactly what the pandas / generic route it replaces gives."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

import soilstats
from soilstats.campaign.index import campaign_index
from soilstats.errors import CampaignError
from soilstats.identification.adequacy import _by_group_then_value, _dense_codes
from soilstats.identification.pooling import pool_shear, pool_sinkage


@pytest.fixture(scope="module")
def campaign():
    return soilstats.load_campaign("simulated-paper")


def test_matches_is_the_mask_select_keeps(campaign):
    mask = campaign.matches(soil="soil01", velocity_m_s=[0.0048, 0.00048])
    chosen = campaign.select(soil="soil01", velocity_m_s=[0.0048, 0.00048])
    assert list(campaign.tests["test_id"][mask]) == list(chosen.tests["test_id"])
    with pytest.raises(CampaignError, match="select\\(\\) kept no test"):
        campaign.matches(soil="nowhere")


def test_index_is_kept_per_campaign_object_and_read_only(campaign):
    index = campaign_index(campaign)
    assert campaign_index(campaign) is index
    assert campaign_index(dataclasses.replace(campaign)) is not index
    test_of = index.test_of("sinkage")
    assert not test_of.flags.writeable and not index.column("sinkage", "z_m").flags.writeable
    ids = campaign.sinkage["test_id"].to_numpy()
    assert np.array_equal(index.test_id[test_of], ids)


@pytest.mark.parametrize("selection", [{"soil": "soil02"}, {"soil": "soil01", "radius_m": 0.05}])
def test_pooling_a_selection_equals_pooling_the_selected_campaign(campaign, selection):
    chosen = campaign.select(**selection)
    for pool, kw in (
        (pool_sinkage, {}),
        (pool_shear, {"steady_only": False, "weighting": "max-stress"}),
    ):
        if pool is pool_shear and "radius_m" in selection:
            continue
        a, b = pool(campaign, **kw, **selection), pool(chosen, **kw)
        pd.testing.assert_frame_equal(a.tests, b.tests, check_exact=True)
        assert a.y.tobytes() == b.y.tobytes() and a.weights.tobytes() == b.weights.tobytes()
        assert np.array_equal(a.test_index, b.test_index)


def test_fit_path_shortcuts_equal_the_generic_calls():
    rng = np.random.default_rng(0)
    for _ in range(200):
        codes = np.repeat(np.arange(5), rng.integers(0, 6, 5))
        if rng.random() < 0.5:
            codes = rng.permutation(codes) * 2
        values = rng.integers(0, 4, codes.size).astype(float)
        if rng.random() < 0.5:
            values = np.sort(values)
        if codes.size:
            assert np.array_equal(_dense_codes(codes), np.unique(codes, return_inverse=True)[1])
        assert np.array_equal(_by_group_then_value(codes, values), np.lexsort((values, codes)))


def test_grouped_by_code_keeps_original_order_and_skips_minus_one():
    import numpy as np

    from soilstats.campaign.index import grouped_by_code

    rng = np.random.default_rng(1)
    for _ in range(300):
        n = int(rng.integers(1, 8))
        codes = rng.integers(-1, n, int(rng.integers(0, 40)))
        groups = grouped_by_code(codes, n)
        assert len(groups) == n
        for k, positions in enumerate(groups):
            assert np.array_equal(positions, np.flatnonzero(codes == k))
    assert grouped_by_code(np.array([], int), 0) == []
