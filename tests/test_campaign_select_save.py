"""Selection, per-test samples, save/load round trips, repr and summary."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from soilstats.campaign import Campaign, load_campaign
from soilstats.errors import CampaignError


@pytest.fixture(scope="module")
def cullinan() -> Campaign:
    return load_campaign("cullinan-sand")


@pytest.fixture
def small(write_campaign, campaign_frames) -> Campaign:
    return load_campaign(write_campaign(**campaign_frames))


def _assert_same(a: Campaign, b: Campaign) -> None:
    for name in ("tests", "sinkage", "shear"):
        pd.testing.assert_frame_equal(getattr(a, name), getattr(b, name), check_exact=True)


def test_select_scalar_on_text_column(cullinan):
    sel = cullinan.select(preparation="1")
    assert list(sel.tests["repetition"]) == [1, 2, 3, 4, 5, 6]
    assert set(sel.sinkage["test_id"]) == set(sel.tests["test_id"])
    assert len(sel.sinkage) == 6 * 2000
    assert len(cullinan.tests) == 13  # the original is untouched


def test_select_list_callable_covariate_and_derived(cullinan):
    assert len(cullinan.select(preparation=["3", "4", "5"]).tests) == 3
    assert len(cullinan.select(session={"27Aug", "27SEPT"}).tests) == 6
    dense = cullinan.select(dry_density_kg_m3=lambda s: s > 1500)
    assert list(dense.tests["test_id"]) == ["method5-test1", "method4-test1"]
    assert len(cullinan.select(dry_density_kg_m3=None).tests) == 10  # not recorded
    assert len(cullinan.select(b_m=cullinan.tests["b_m"].iloc[0], kind="sinkage").tests) == 13


def test_select_keeps_sample_order(small):
    sel = small.select(kind="sinkage")
    assert list(sel.sinkage["test_id"]) == ["c1", "c1", "r1", "c1", "r1"]
    assert sel.shear.empty


def test_partition_equals_one_select_per_part():
    campaign = load_campaign("simulated-paper")
    ids = list(campaign.tests["test_id"].astype(str))
    rng = np.random.default_rng(3)
    shuffled = list(rng.permutation(ids))
    parts = [shuffled[:5], shuffled[5:40], [ids[-1], ids[0]], shuffled[40:41]]
    parts[1] = [t for t in parts[1] if t not in parts[2]]
    pieces = campaign.partition(parts)
    assert len(pieces) == len(parts)
    for piece, part in zip(pieces, parts, strict=True):
        selected = campaign.select(test_id=part)
        _assert_same(piece, selected)  # log order and file rows (index) as select's
        assert piece.window is selected.window and piece.source == selected.source


def test_partition_interleaved_samples_keep_file_order(small):
    first, second = small.partition([["r1"], ["c1"]])
    assert list(first.sinkage.index) == list(small.sinkage.index[small.sinkage["test_id"] == "r1"])
    assert list(second.sinkage["test_id"]) == ["c1", "c1", "c1"]


def test_partition_part_without_tests_is_an_error(cullinan):
    with pytest.raises(CampaignError, match="part 1 names no test") as info:
        cullinan.partition([["method5-test1"], ["no-such-test"]])
    assert info.value.column == "test_id"


def test_partition_parts_sharing_a_test_or_numeric_ids_are_errors(cullinan):
    a, b, c = list(cullinan.tests["test_id"][:3])
    with pytest.raises(CampaignError, match=f"test '{b}' is in part 0 and part 1"):
        cullinan.partition([[a, b], [b, c]])
    with pytest.raises(CampaignError, match="is in part 0 and part 1"):
        cullinan.partition([[a], [a]])
    with pytest.raises(CampaignError, match="not text"):
        cullinan.partition([[a], [5]])


def test_select_unknown_column(cullinan):
    with pytest.raises(CampaignError, match="unknown column") as info:
        cullinan.select(moisture=3)
    assert info.value.column == "moisture"
    assert "dry_density_kg_m3" in str(info.value)


def test_select_nothing_says_which_criterion_and_values(cullinan):
    with pytest.raises(CampaignError) as info:
        cullinan.select(kind="sinkage", preparation=5)
    msg = str(info.value)
    assert "preparation=5" in msg and "'1', '2', '3', '4', '5'" in msg and "'5', not 5" in msg
    assert info.value.column == "preparation"
    with pytest.raises(CampaignError, match="no test meets all"):
        cullinan.select(preparation="5", session="24Aug")


def test_select_predicate_must_return_bools(cullinan):
    with pytest.raises(CampaignError, match="one bool per test"):
        cullinan.select(radius_m=lambda s: s * 2)


def test_samples_unknown_test(small):
    with pytest.raises(CampaignError, match=r"no test 'c9'.*'c1', 'r1', 's1'"):
        small.samples("c9")


def test_campaign_is_frozen(small):
    with pytest.raises(AttributeError):
        small.source = "x"  # type: ignore[misc]


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_round_trip_small(tmp_path, small, fmt):
    folder = small.save(tmp_path / "out", format=fmt)
    assert sorted(p.name for p in folder.iterdir()) == [
        f"{s}.{fmt}" for s in ("shear", "sinkage", "tests")
    ]
    back = load_campaign(folder)
    _assert_same(back, small)
    assert back.covariates == small.covariates == ["moisture_pct", "bin"]


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_round_trip_cullinan_exact(tmp_path, cullinan, fmt):
    folder = cullinan.save(tmp_path / "c", format=fmt)
    assert not (folder / f"shear.{fmt}").exists()  # no rows, no file
    _assert_same(load_campaign(folder), cullinan)


def test_round_trip_awkward_values(tmp_path, campaign_frames):
    z = ["-0.0", "5e-324", "1.7976931348623157e308", "0.1", "0.30000000000000004"]
    campaign_frames["sinkage"]["z_m"] = z
    campaign_frames["tests"]["note"] = ['a "quoted", text', "", "line\nbreak"]
    # Extreme floats on purpose: no plate sinks 1.8e308 m, so the units check is off here.
    c = Campaign.from_frames(**campaign_frames, check_units=False)
    back = load_campaign(c.save(tmp_path / "a"), check_units=False)
    _assert_same(back, c)
    assert np.signbit(back.sinkage["z_m"].iloc[0])
    written = (tmp_path / "a" / "tests.csv").read_text().splitlines()[1]
    assert written.startswith("c1,sinkage,loam,1,circle,0.05,,,0.01")  # whole numbers as ints


def test_save_refuses_to_mix_with_existing_files(tmp_path, small):
    folder = small.save(tmp_path / "x")
    with pytest.raises(CampaignError, match="overwrite=True"):
        small.save(folder, format="parquet")
    small.select(kind="sinkage").save(folder, format="parquet", overwrite=True)
    assert sorted(p.name for p in folder.iterdir()) == ["sinkage.parquet", "tests.parquet"]
    with pytest.raises(ValueError, match="'csv' or 'parquet'"):
        small.save(tmp_path / "y", format="xlsx")  # type: ignore[arg-type]


def test_repr_and_summary(cullinan, small):
    assert repr(cullinan) == (
        "<Campaign 'bundled:cullinan-sand': 13 tests (13 sinkage, 0 shear); soils: cullinan-sand>"
    )
    text = cullinan.summary()
    for fragment in (
        "tests: 13 (sinkage 13, shear 0)",
        "dry_density_kg_m3 (numeric, 3 of 13 recorded)",
        "sinkage samples: 26000 rows",
        "z_m",
        "force_N",
        "rows with z ≤ 0",
        "skipped tests: none",
        "Notes:",
    ):
        assert fragment in text, fragment
    small_text = small.summary()
    assert "rings: r 0.1–0.15 m, 10 grousers (×1)" in small_text
    assert "shear samples: 2 rows" in small_text
