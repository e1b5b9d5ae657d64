"""Every rule of the campaign format: a malformed campaign raises a CampaignError that names
the file, the column, the test and the row (1-based data row) where they exist."""

from __future__ import annotations

import pandas as pd
import pytest

from soilstats.campaign import Campaign, load_campaign
from soilstats.errors import CampaignError, SoilstatsWarning

# Row numbers of the fixture campaign (see conftest): tests.csv c1=1, r1=2, s1=3;
# sinkage.csv rows c1=1,2,4 and r1=3,5; shear.csv s1=1,2.


def _set(frames, stem, row, column, value):
    frames[stem].loc[row - 1, column] = value


def _drop_col(frames, stem, column):
    frames[stem] = frames[stem].drop(columns=[column])


def _load(write_campaign, frames):
    return load_campaign(write_campaign(**frames))


def _check(err: CampaignError, file, column, test_id, row, *fragments):
    assert (err.file, err.column, err.test_id, err.row) == (file, column, test_id, row)
    msg = str(err)
    assert msg.startswith(f"file {file!r}")
    assert f"column {column!r}" in msg
    if test_id is not None:
        assert f"test {test_id!r}" in msg
    if row is not None:
        assert f"row {row}:" in msg
    assert " — " in msg  # every message ends with the fix
    for fragment in fragments:
        assert fragment in msg, msg


# One case per rule: (id, edit of the frames, expected file, column, test_id, row, fragments
# of the message). A table reads best unwrapped.
# fmt: off
CASES = [
    # --- missing required columns, one per file ---------------------------------------------
    ("tests-kind-missing", lambda f: _drop_col(f, "tests", "kind"),
     "tests.csv", "kind", None, None, ["required column is missing"]),
    ("sinkage-force-missing", lambda f: _drop_col(f, "sinkage", "force_N"),
     "sinkage.csv", "force_N", None, None, ["required column is missing"]),
    ("shear-torque-missing", lambda f: _drop_col(f, "shear", "torque_Nm"),
     "shear.csv", "torque_Nm", None, None, ["required column is missing"]),
    # --- conditional columns absent from the file ---------------------------------------------
    ("shape-column-missing", lambda f: _drop_col(f, "tests", "shape"),
     "tests.csv", "shape", "c1", 1, ["is a sinkage test and needs it"]),
    ("radius-column-missing", lambda f: _drop_col(f, "tests", "radius_m"),
     "tests.csv", "radius_m", "c1", 1, ["is a circle test and needs it"]),
    ("width-column-missing", lambda f: _drop_col(f, "tests", "width_m"),
     "tests.csv", "width_m", "r1", 2, ["is a rectangle test and needs it"]),
    ("length-column-missing", lambda f: _drop_col(f, "tests", "length_m"),
     "tests.csv", "length_m", "r1", 2, ["is a rectangle test and needs it"]),
    *[
        (f"{col}-column-missing", lambda f, col=col: _drop_col(f, "tests", col),
         "tests.csv", col, "s1", 3, ["is a shear test and needs it"])
        for col in ("r_inner_m", "r_outer_m", "grousers", "grouser_height_m")
    ],
    # --- conditional columns present but empty for a test that needs them -------------------
    ("shape-empty", lambda f: _set(f, "tests", 1, "shape", ""),
     "tests.csv", "shape", "c1", 1, ["value is empty", "'circle', 'rectangle'"]),
    ("radius-empty", lambda f: _set(f, "tests", 1, "radius_m", ""),
     "tests.csv", "radius_m", "c1", 1, ["value is empty", "circular plate needs radius_m"]),
    ("width-empty", lambda f: _set(f, "tests", 2, "width_m", ""),
     "tests.csv", "width_m", "r1", 2, ["value is empty"]),
    ("rectangle-without-length", lambda f: _set(f, "tests", 2, "length_m", ""),
     "tests.csv", "length_m", "r1", 2, ["rectangular plate needs length_m"]),
    ("r-outer-NA", lambda f: _set(f, "tests", 3, "r_outer_m", "NA"),
     "tests.csv", "r_outer_m", "s1", 3, ["'NA' (not recorded)", "shear test needs"]),
    ("grousers-empty", lambda f: _set(f, "tests", 3, "grousers", ""),
     "tests.csv", "grousers", "s1", 3, ["value is empty"]),
    ("grouser-height-empty", lambda f: _set(f, "tests", 3, "grouser_height_m", " "),
     "tests.csv", "grouser_height_m", "s1", 3, ["value is empty"]),
    # --- the log's keys and categories ----------------------------------------------------------
    ("duplicate-test-id", lambda f: _set(f, "tests", 2, "test_id", "c1"),
     "tests.csv", "test_id", "c1", 2, ["already used in row 1", "unique"]),
    ("empty-test-id", lambda f: _set(f, "tests", 2, "test_id", ""),
     "tests.csv", "test_id", None, 2, ["test_id is empty"]),
    ("unknown-kind", lambda f: _set(f, "tests", 2, "kind", "Sinkage"),
     "tests.csv", "kind", "r1", 2, ["'Sinkage' is not a known kind", "['sinkage', 'shear']"]),
    ("unknown-shape", lambda f: _set(f, "tests", 2, "shape", "square"),
     "tests.csv", "shape", "r1", 2, ["'square' is not a known shape", "'rectangle'"]),
    ("empty-soil", lambda f: _set(f, "tests", 3, "soil", ""),
     "tests.csv", "soil", "s1", 3, ["soil name"]),
    # --- geometry values ------------------------------------------------------------------------
    ("radius-not-number", lambda f: _set(f, "tests", 1, "radius_m", "big"),
     "tests.csv", "radius_m", "c1", 1, ["'big' is not a finite number"]),
    ("radius-decimal-comma", lambda f: _set(f, "tests", 1, "radius_m", "0,05"),
     "tests.csv", "radius_m", "c1", 1, ["'0,05'", "decimal separator"]),
    ("radius-infinite", lambda f: _set(f, "tests", 1, "radius_m", "inf"),
     "tests.csv", "radius_m", "c1", 1, ["'inf' is not a finite number"]),
    ("radius-zero", lambda f: _set(f, "tests", 1, "radius_m", "0"),
     "tests.csv", "radius_m", "c1", 1, ["0.0 is not a positive radius"]),
    ("radius-negative", lambda f: _set(f, "tests", 1, "radius_m", "-0.05"),
     "tests.csv", "radius_m", "c1", 1, ["-0.05 is not a positive radius"]),
    ("width-negative", lambda f: _set(f, "tests", 2, "width_m", "-0.1"),
     "tests.csv", "width_m", "r1", 2, ["not a positive width"]),
    ("length-shorter-than-width", lambda f: _set(f, "tests", 2, "length_m", "0.05"),
     "tests.csv", "length_m", "r1", 2, ["shorter than width_m 0.1", "swap"]),
    ("r-outer-not-larger", lambda f: _set(f, "tests", 3, "r_outer_m", "0.1"),
     "tests.csv", "r_outer_m", "s1", 3, ["not larger than r_inner_m 0.1"]),
    ("r-inner-negative", lambda f: _set(f, "tests", 3, "r_inner_m", "-0.01"),
     "tests.csv", "r_inner_m", "s1", 3, ["-0.01 is negative"]),
    ("r-outer-infinite", lambda f: _set(f, "tests", 3, "r_outer_m", "inf"),
     "tests.csv", "r_outer_m", "s1", 3, ["not a finite number"]),
    ("grousers-fraction", lambda f: _set(f, "tests", 3, "grousers", "2.5"),
     "tests.csv", "grousers", "s1", 3, ["'2.5' is not a whole number ≥ 0"]),
    ("grousers-negative", lambda f: _set(f, "tests", 3, "grousers", "-1"),
     "tests.csv", "grousers", "s1", 3, ["'-1' is not a whole number ≥ 0"]),
    ("grousers-text", lambda f: _set(f, "tests", 3, "grousers", "ten"),
     "tests.csv", "grousers", "s1", 3, ["'ten' is not a finite number"]),
    ("grouser-height-negative", lambda f: _set(f, "tests", 3, "grouser_height_m", "-0.01"),
     "tests.csv", "grouser_height_m", "s1", 3, ["is negative"]),
    # a geometry column must be numeric even where the test does not use it
    ("stray-geometry-text", lambda f: _set(f, "tests", 3, "radius_m", "n/a?"),
     "tests.csv", "radius_m", "s1", 3, ["'n/a?' is not a finite number"]),
    # --- optional numbers, checked when given ---------------------------------------------------
    ("velocity-zero", lambda f: _set(f, "tests", 1, "velocity_m_s", "0"),
     "tests.csv", "velocity_m_s", "c1", 1, ["0.0 is not positive", "leave it empty"]),
    ("velocity-text", lambda f: _set(f, "tests", 1, "velocity_m_s", "fast"),
     "tests.csv", "velocity_m_s", "c1", 1, ["'fast' is not a finite number"]),
    ("omega-negative", lambda f: _set(f, "tests", 3, "omega_rpm", "-2"),
     "tests.csv", "omega_rpm", "s1", 3, ["-2.0 is not positive"]),
    ("repetition-fraction", lambda f: _set(f, "tests", 2, "repetition", "1.5"),
     "tests.csv", "repetition", "r1", 2, ["'1.5' is not a whole number"]),
    ("repetition-text", lambda f: _set(f, "tests", 2, "repetition", "first"),
     "tests.csv", "repetition", "r1", 2, ["'first' is not a finite number"]),
    # --- samples --------------------------------------------------------------------------------
    ("sample-not-a-number", lambda f: _set(f, "sinkage", 4, "force_N", "abc"),
     "sinkage.csv", "force_N", "c1", 4,
     ["value 'abc' is not a finite number; every sample must be numeric — fix or remove the "
      'row (or load with on_error="skip" to drop the whole test with a listed reason)']),
    ("sample-infinite", lambda f: _set(f, "sinkage", 3, "z_m", "-inf"),
     "sinkage.csv", "z_m", "r1", 3, ["'-inf' is not a finite number"]),
    ("sample-empty", lambda f: _set(f, "shear", 2, "angle_rad", ""),
     "shear.csv", "angle_rad", "s1", 2, ["value is empty"]),
    ("sample-nan", lambda f: _set(f, "shear", 1, "normal_force_N", "NaN"),
     "shear.csv", "normal_force_N", "s1", 1, ["'NaN' is not a finite number"]),
    ("sample-orphan", lambda f: _set(f, "sinkage", 5, "test_id", "zz"),
     "sinkage.csv", "test_id", "zz", 5, ["'zz' is not in tests.csv", "'c1'"]),
    ("sample-empty-test-id", lambda f: _set(f, "sinkage", 2, "test_id", ""),
     "sinkage.csv", "test_id", None, 2, ["test_id is empty"]),
    ("sample-of-other-kind", lambda f: _set(f, "sinkage", 5, "test_id", "s1"),
     "sinkage.csv", "test_id", "s1", 5, ["kind 'shear' (tests.csv row 3)", "shear file"]),
    ("test-without-samples", lambda f: f.update(sinkage=f["sinkage"].iloc[[0, 1, 3]]),
     "sinkage.csv", "test_id", "r1", None, ["no samples", "tests.csv row 2"]),
    ("no-sinkage-file", lambda f: f.update(sinkage=None),
     "tests.csv", "kind", "c1", 1, ["kind 'sinkage'", "no sinkage.csv"]),
    ("no-shear-file", lambda f: f.update(shear=None),
     "tests.csv", "kind", "s1", 3, ["kind 'shear'", "no shear.csv"]),
]
# fmt: on


@pytest.mark.parametrize(
    ("edit", "file", "column", "test_id", "row", "fragments"),
    [pytest.param(*case[1:], id=case[0]) for case in CASES],
)
def test_rule_raises_with_location(
    write_campaign, campaign_frames, edit, file, column, test_id, row, fragments
):
    edit(campaign_frames)
    with pytest.raises(CampaignError) as info:
        _load(write_campaign, campaign_frames)
    _check(info.value, file, column, test_id, row, *fragments)


def test_fixture_campaign_is_valid(write_campaign, campaign_frames):
    c = _load(write_campaign, campaign_frames)
    assert list(c.tests["test_id"]) == ["c1", "r1", "s1"]


def test_from_frames_applies_the_same_rules(campaign_frames):
    _set(campaign_frames, "sinkage", 4, "force_N", "abc")
    with pytest.raises(CampaignError) as info:
        Campaign.from_frames(**campaign_frames)
    _check(info.value, "sinkage.csv", "force_N", "c1", 4, "'abc'")


def test_first_error_in_scan_order_tests_file_first(write_campaign, campaign_frames):
    _set(campaign_frames, "sinkage", 1, "z_m", "bad")  # sinkage row 1
    _set(campaign_frames, "tests", 3, "grousers", "-3")  # tests row 3: reported first
    with pytest.raises(CampaignError) as info:
        _load(write_campaign, campaign_frames)
    assert (info.value.file, info.value.row) == ("tests.csv", 3)


def test_sample_problem_counts_rows_of_the_test(write_campaign, campaign_frames):
    campaign_frames["sinkage"]["force_N"] = "x"
    with pytest.raises(CampaignError, match=r"row 1: .*\(3 rows of this test have this problem\)"):
        _load(write_campaign, campaign_frames)


def test_empty_log(write_campaign, campaign_frames):
    campaign_frames["tests"] = campaign_frames["tests"].iloc[:0]
    with pytest.raises(CampaignError, match="the log has no tests") as info:
        _load(write_campaign, campaign_frames)
    assert info.value.file == "tests.csv"


def test_required_column_hint_for_case(write_campaign, campaign_frames):
    campaign_frames["sinkage"] = campaign_frames["sinkage"].rename(columns={"z_m": "Z_m"})
    with pytest.raises(CampaignError, match="found 'Z_m': names are matched exactly"):
        _load(write_campaign, campaign_frames)


def test_repeated_column_name(write_campaign):
    folder = write_campaign(tests="test_id,kind,soil,soil\na,shear,x,y\n")
    with pytest.raises(CampaignError, match="more than once") as info:
        load_campaign(folder)
    assert (info.value.file, info.value.column) == ("tests.csv", "soil")


@pytest.mark.parametrize(
    ("table", "position"),
    [
        ("tests", 1),  # written by DataFrame.to_csv() with its default index=True
        ("sinkage", 4),  # a comma at the end of every line
    ],
)
def test_a_column_without_a_name_is_refused(write_campaign, campaign_frames, table, position):
    # pandas named it 'Unnamed: k' and the log's row numbers became a covariate.
    frames = dict(campaign_frames)
    text = frames[table].to_csv(index=table == "tests")
    if position == 4:
        text = "".join(line + ",\n" for line in text.splitlines())
    frames[table] = text
    with pytest.raises(CampaignError, match=f"column {position} of .* has no name") as info:
        load_campaign(write_campaign(**frames))
    assert info.value.file == f"{table}.csv" and "index=False" in str(info.value)


def test_soil_names_that_differ_only_in_case_or_blanks_are_warned_of(campaign_frames):
    # Loaded silently before: 'soil01 ' and 'Soil01' became soils of one test each.
    tests = campaign_frames["tests"].copy()
    first = tests["soil"].iloc[0]
    tests.loc[tests.index[1], "soil"] = first.upper() + " "
    with pytest.warns(SoilstatsWarning, match="column 'soil': .* differ only in case") as rec:
        campaign = Campaign.from_frames(**{**campaign_frames, "tests": tests})
    assert str(tests["test_id"].iloc[1]) in str(rec[0].message)
    assert campaign.tests["soil"].nunique() == campaign_frames["tests"]["soil"].nunique() + 1
    Campaign.from_frames(**campaign_frames)  # one spelling each: no warning (errors here)


def test_missing_tests_file(write_campaign, campaign_frames):
    folder = write_campaign(sinkage=campaign_frames["sinkage"])
    with pytest.raises(CampaignError, match=r"no tests\.csv or tests\.parquet"):
        load_campaign(folder)


def test_csv_and_parquet_of_one_table_is_ambiguous(write_campaign, campaign_frames):
    folder = write_campaign(**campaign_frames)
    campaign_frames["shear"].to_parquet(folder / "shear.parquet")
    with pytest.raises(CampaignError, match=r"both shear\.csv and shear\.parquet"):
        load_campaign(folder)


@pytest.mark.parametrize(
    ("name", "content", "message", "row"),
    [
        ("sinkage.csv", "test_id,z_m,force_N\nc1,1,2,3,4\n", "more fields than the header", 1),
        # a blank line is not a data row: the long row is data row 2
        ("sinkage.csv", "test_id,z_m,force_N\nc1,1,2\n\nc1,1,2,3\n", "more fields than", 2),
        # an unclosed quote: the data row where it opens
        ("sinkage.csv", 'test_id,z_m,force_N\n"c1,1,2\n', "quote .* is never closed", 1),
        ("shear.parquet", b"not parquet", "cannot read the file", None),
        ("shear.csv", b"test_id,angle_rad\n\xff\xfe", "cannot read the file", None),
    ],
)
def test_unreadable_file(write_campaign, campaign_frames, name, content, message, row):
    campaign_frames.pop(name.split(".")[0])
    folder = write_campaign(**campaign_frames)
    path = folder / name
    path.write_bytes(content) if isinstance(content, bytes) else path.write_text(content)
    with pytest.raises(CampaignError, match=message) as info:
        load_campaign(folder)
    assert (info.value.file, info.value.row) == (name, row)


def test_derived_column_in_input_must_agree(campaign_frames):
    campaign_frames["tests"]["area_m2"] = ["1.0", "0.03", ""]
    with pytest.raises(CampaignError, match="computed by soilstats") as info:
        Campaign.from_frames(**campaign_frames)
    assert (info.value.column, info.value.test_id, info.value.row) == ("area_m2", "c1", 1)
    # Plain numbers, not numpy's reprs ('np.float64(1.0)').
    assert "the value given, 1.0, differs from the computed 0.00785398" in str(info.value)


def test_file_problems_raise_even_when_skipping(write_campaign, campaign_frames):
    _drop_col(campaign_frames, "shear", "torque_Nm")
    with pytest.raises(CampaignError, match="required column is missing"):
        load_campaign(write_campaign(**campaign_frames), on_error="skip")


def test_bad_on_error_option(campaign_frames):
    with pytest.raises(ValueError, match="'raise' or 'skip'"):
        Campaign.from_frames(**campaign_frames, on_error="ignore")


def test_frames_are_not_mutated(campaign_frames):
    before = {k: v.copy() for k, v in campaign_frames.items()}
    Campaign.from_frames(**campaign_frames)
    for k, v in campaign_frames.items():
        pd.testing.assert_frame_equal(v, before[k])
