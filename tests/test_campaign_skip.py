"""on_error="skip": bad tests are dropped with their samples, listed, and warned about once."""

from __future__ import annotations

import pandas as pd
import pytest

from soilstats.campaign import load_campaign
from soilstats.errors import CampaignError, SoilstatsWarning


def test_skip_lists_every_dropped_test(write_campaign, campaign_frames):
    campaign_frames["tests"].loc[1, "length_m"] = "0.05"  # r1: length < width
    campaign_frames["shear"].loc[1, "torque_Nm"] = "abc"  # s1: bad sample
    sink = campaign_frames["sinkage"]
    campaign_frames["sinkage"] = pd.concat(
        [sink, pd.DataFrame([{"test_id": "ghost", "z_m": "0", "force_N": "1"}])],
        ignore_index=True,
    )
    with pytest.warns(SoilstatsWarning, match=r"skipped 3 tests") as record:
        c = load_campaign(write_campaign(**campaign_frames), on_error="skip")
    assert len(record) == 1
    msg = str(record[0].message)
    assert "'r1'" in msg and "'s1'" in msg and "'ghost'" in msg and "campaign.skipped" in msg
    assert list(c.tests["test_id"]) == ["c1"]
    assert set(c.sinkage["test_id"]) == {"c1"} and c.shear.empty
    assert list(c.skipped.columns) == ["test_id", "file", "column", "row", "reason"]
    rows = {r.test_id: r for r in c.skipped.itertuples()}
    assert (rows["r1"].file, rows["r1"].column, rows["r1"].row) == ("tests.csv", "length_m", 2)
    assert (rows["s1"].file, rows["s1"].column, rows["s1"].row) == ("shear.csv", "torque_Nm", 2)
    assert (rows["ghost"].file, rows["ghost"].row) == ("sinkage.csv", 6)
    assert "shorter than width_m" in rows["r1"].reason
    assert "skipped tests: 3" in c.summary()


def test_skip_counts_further_problems_of_a_test(write_campaign, campaign_frames):
    campaign_frames["tests"].loc[0, "radius_m"] = "-1"
    campaign_frames["tests"].loc[0, "velocity_m_s"] = "0"
    with pytest.warns(SoilstatsWarning, match="skipped 1 test with"):
        c = load_campaign(write_campaign(**campaign_frames), on_error="skip")
    assert list(c.skipped["test_id"]) == ["c1"]
    assert c.skipped["reason"].iloc[0].endswith("(and 1 more problem with this test)")
    assert c.skipped["row"].dtype == "Int64" and c.skipped["row"].iloc[0] == 1


def test_skip_duplicate_drops_both_rows(write_campaign, campaign_frames):
    campaign_frames["tests"].loc[1, "test_id"] = "c1"
    with pytest.warns(SoilstatsWarning):
        c = load_campaign(write_campaign(**campaign_frames), on_error="skip")
    assert list(c.tests["test_id"]) == ["s1"]
    assert c.sinkage.empty


def test_skip_nothing_wrong_means_no_warning(write_campaign, campaign_frames):
    c = load_campaign(write_campaign(**campaign_frames), on_error="skip")
    assert c.skipped.empty
    assert list(c.skipped.columns) == ["test_id", "file", "column", "row", "reason"]


def test_skipping_every_test_raises(write_campaign, campaign_frames):
    campaign_frames["sinkage"]["force_N"] = "x"
    campaign_frames["shear"]["torque_Nm"] = ""
    with pytest.raises(CampaignError, match=r"every test was skipped \(3\)"):
        load_campaign(write_campaign(**campaign_frames), on_error="skip")


def test_rows_without_a_test_id_are_listed_as_rows_not_as_a_test(write_campaign, campaign_frames):
    # Three blank test_id cells were reported as "skipped 1 test ... ''" and "(3 rows of this
    # test have this problem)".
    sink = campaign_frames["sinkage"].copy()
    blank = pd.DataFrame([{"test_id": "", "z_m": "0.01", "force_N": "1"}] * 3)
    campaign_frames["sinkage"] = pd.concat([sink, blank], ignore_index=True)
    first = len(sink) + 1  # 1-based data rows of the blank ones
    with pytest.warns(SoilstatsWarning) as record:
        c = load_campaign(write_campaign(**campaign_frames), on_error="skip")
    msg = str(record[0].message)
    assert msg.startswith("skipped the rows without a test_id:")
    assert f"rows {first}, {first + 1}, {first + 2}" in msg and "''" not in msg
    assert set(c.sinkage["test_id"]) == set(sink["test_id"])  # every test kept
    assert "3 rows have no test_id" in c.skipped.loc[0, "reason"]
