"""Loading: bundled campaigns, the real Cullinan data kept as measured, typing, parquet."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import soilstats
from soilstats.campaign import Campaign, bundled_campaigns, load_campaign
from soilstats.campaign._cells import _parse_decimals
from soilstats.data import DATA_DIR
from soilstats.errors import CampaignError

CULLINAN = DATA_DIR / "cullinan-sand"


@pytest.fixture(scope="module")
def cullinan() -> Campaign:
    return load_campaign("cullinan-sand")


def _raw_sinkage() -> list[list[str]]:
    # Independent reading with the csv module and Python's float(): the reference values.
    with (CULLINAN / "sinkage.csv").open(newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["test_id", "z_m", "force_N"]
    return rows[1:]


def test_bundled_names_and_source(cullinan):
    assert "cullinan-sand" in bundled_campaigns()
    assert cullinan.source == "bundled:cullinan-sand"
    assert len(cullinan.tests) == 13 and len(cullinan.sinkage) == 26000
    assert cullinan.shear.empty and list(cullinan.shear.columns[:4]) == [
        "test_id",
        "angle_rad",
        "torque_Nm",
        "normal_force_N",
    ]


def test_bundled_readme_keeps_attribution():
    text = (CULLINAN / "README.md").read_text(encoding="utf-8")
    assert text.startswith("> Bundled with soilstats under CC-BY-4.0")
    assert "doi:10.1016/j.jterra.2023.06.002" in text and "CC-BY-4.0" in text


def test_unknown_name_lists_bundled_and_says_path_missing():
    with pytest.raises(CampaignError) as info:
        load_campaign("culinan-sand")
    msg = str(info.value)
    assert "'cullinan-sand'" in msg and "path does not exist" in msg


def test_file_instead_of_folder_is_refused():
    with pytest.raises(CampaignError, match="is a file"):
        load_campaign(CULLINAN / "tests.csv")


def test_path_forms_give_the_same_campaign(cullinan):
    by_path = load_campaign(CULLINAN)
    by_str = load_campaign(str(CULLINAN))
    assert by_path.source == str(CULLINAN)
    for c in (by_path, by_str):
        pd.testing.assert_frame_equal(c.tests, cullinan.tests)
        pd.testing.assert_frame_equal(c.sinkage, cullinan.sinkage)


def test_every_sample_is_kept_as_measured_in_file_order(cullinan):
    raw = _raw_sinkage()
    assert list(cullinan.sinkage["test_id"]) == [r[0] for r in raw]
    z = np.array([float(r[1]) for r in raw])
    force = np.array([float(r[2]) for r in raw])
    np.testing.assert_array_equal(cullinan.sinkage["z_m"].to_numpy(), z)
    np.testing.assert_array_equal(cullinan.sinkage["force_N"].to_numpy(), force)


def test_readings_at_or_below_zero_are_kept(cullinan):
    s = cullinan.sinkage
    negative_z = s[s["z_m"] < 0]
    negative_f = s[s["force_N"] < 0]
    assert len(negative_z) > 0 and len(negative_f) > 0
    # several tests, not one, read below zero near their start
    assert negative_f["test_id"].nunique() > 1
    assert (negative_f["pressure_Pa"] < 0).all()  # p = F/A keeps the sign


def test_test_starting_deep_is_kept(cullinan):
    start = cullinan.samples("method2-test4")["z_m"].iloc[0]
    assert start == pytest.approx(3.4e-3, abs=0.05e-3)
    others = cullinan.select(test_id=lambda s: s != "method2-test4")
    firsts = others.sinkage.groupby("test_id")["z_m"].first()
    assert (firsts.abs() < 1e-4).all()


def test_log_typing_and_covariates(cullinan):
    t = cullinan.tests
    assert cullinan.covariates == ["session", "dry_density_kg_m3", "void_ratio"]
    assert t["preparation"].iloc[0] == "5"  # preparation is text in the format
    assert t["repetition"].dtype == np.float64
    assert t["dry_density_kg_m3"].dtype == np.float64  # every recorded value parses
    assert t["dry_density_kg_m3"].notna().sum() == 3  # empty cells are missing, not 0
    assert not pd.api.types.is_numeric_dtype(t["session"])
    assert list(t.columns[:10]) == list(pd.read_csv(CULLINAN / "tests.csv", nrows=0).columns)
    assert (t["n_samples"] == 2000).all()


def test_text_keys_stay_text(write_campaign):
    folder = write_campaign(
        tests="test_id,kind,soil,shape,radius_m,operator,velocity_m_s,note,batch\n"
        "001,sinkage,NA,circle,0.05,,,NA,1\n"
        "NA,sinkage,loam,circle,0.05,ann,0.001,wet,\n",
        sinkage="test_id,z_m,force_N\n001,0,1\nNA,0,1\n",
    )
    t = load_campaign(folder).tests
    assert list(t["test_id"]) == ["001", "NA"]
    assert t["soil"].iloc[0] == "NA"  # a text value, not a missing one
    assert pd.isna(t["operator"].iloc[0]) and t["operator"].iloc[1] == "ann"
    assert np.isnan(t["velocity_m_s"].iloc[0])  # empty optional number: NaN, never 0
    assert t["velocity_m_s"].iloc[1] == 0.001
    assert list(t["note"]) == ["NA", "wet"]  # a text covariate keeps every value
    assert t["batch"].dtype == np.float64 and t["batch"].iloc[0] == 1.0
    assert np.isnan(t["batch"].iloc[1])


def test_missing_tokens_in_numeric_covariate(write_campaign):
    folder = write_campaign(
        tests="test_id,kind,soil,shape,radius_m,moisture_pct\n"
        "a,sinkage,s,circle,0.05,NA\nb,sinkage,s,circle,0.05,3.5\nc,sinkage,s,circle,0.05,\n",
        sinkage="test_id,z_m,force_N\na,0,1\nb,0,1\nc,0,1\n",
    )
    m = load_campaign(folder).tests["moisture_pct"]
    assert m.dtype == np.float64
    np.testing.assert_array_equal(m.to_numpy(), [np.nan, 3.5, np.nan])


def test_extra_sample_columns_are_kept_and_typed(write_campaign, campaign_frames):
    campaign_frames["sinkage"]["temperature_C"] = ["20", "", "21", "22", "23"]
    campaign_frames["sinkage"]["flag"] = ["ok", "", "ok", "drift", "ok"]
    c = load_campaign(write_campaign(**campaign_frames))
    s = c.sinkage
    assert list(s.columns) == ["test_id", "z_m", "force_N", "temperature_C", "flag", "pressure_Pa"]
    assert s["temperature_C"].dtype == np.float64 and np.isnan(s["temperature_C"].iloc[1])
    assert s["flag"].iloc[3] == "drift" and pd.isna(s["flag"].iloc[1])


def test_sample_rows_need_not_be_contiguous(write_campaign, campaign_frames):
    c = load_campaign(write_campaign(**campaign_frames))
    np.testing.assert_array_equal(c.samples("c1")["z_m"].to_numpy(), [-0.0001, 0.001, 0.002])
    np.testing.assert_array_equal(c.samples("r1")["force_N"].to_numpy(), [0.0, 20.0])
    assert list(c.samples("s1")["torque_Nm"]) == [0.0, 40.0]


def test_parquet_loads_identically_to_csv(tmp_path, cullinan, write_campaign, campaign_frames):
    # Parquet files written directly with typed columns, as another tool would.
    folder = tmp_path / "pq"
    folder.mkdir()
    tests = pd.read_csv(CULLINAN / "tests.csv", dtype={"test_id": str, "preparation": str})
    tests.to_parquet(folder / "tests.parquet")
    raw = _raw_sinkage()
    sink = pd.DataFrame(
        {
            "test_id": [r[0] for r in raw],
            "z_m": [float(r[1]) for r in raw],
            "force_N": [float(r[2]) for r in raw],
        }
    )
    sink.to_parquet(folder / "sinkage.parquet")
    pq = load_campaign(folder)
    pd.testing.assert_frame_equal(pq.tests, cullinan.tests)
    pd.testing.assert_frame_equal(pq.sinkage, cullinan.sinkage, check_exact=True)
    # and text-celled parquet of the small campaign (with shear) equals its csv
    csv_campaign = load_campaign(write_campaign(**campaign_frames))
    small = tmp_path / "small"
    small.mkdir()
    for stem, frame in campaign_frames.items():
        frame.to_parquet(small / f"{stem}.parquet")
    pq_small = load_campaign(small)
    for name in ("tests", "sinkage", "shear"):
        pd.testing.assert_frame_equal(getattr(pq_small, name), getattr(csv_campaign, name))


def test_from_frames_with_typed_columns(campaign_frames, write_campaign):
    from_csv = load_campaign(write_campaign(**campaign_frames))
    typed = Campaign.from_frames(
        from_csv.tests.drop(columns=["n_samples"]), from_csv.sinkage, from_csv.shear
    )
    assert typed.source == "<memory>"
    pd.testing.assert_frame_equal(typed.tests, from_csv.tests)
    pd.testing.assert_frame_equal(typed.shear, from_csv.shear)


def test_byte_order_mark_is_ignored(write_campaign, campaign_frames):
    folder = write_campaign(**campaign_frames)
    path = Path(folder) / "tests.csv"
    path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    assert list(load_campaign(folder).tests["test_id"]) == ["c1", "r1", "s1"]


def test_numbers_read_in_bulk_are_those_of_float_bit_for_bit(write_campaign):
    """A column of plain decimal numbers is parsed in Arrow (a large campaign loads in a
    second); every value must be float()'s, to the last bit, whatever the digits."""
    rng = np.random.default_rng(0)
    values = rng.normal(size=300) * 10.0 ** rng.integers(-300, 300, 300)
    cells = [repr(float(v)) for v in values] + [f"{v:.17g}" for v in values]
    cells += ["1", "-0", "+1.5", "1.", ".5", "-.5", "1E5", "4.9e-324"]
    cells += ["0.1000000000000000055511151231257827021181583404541015625"]
    cells += ["123456789012345678901234567890e-5"]
    # A campaign holds forces whose pressure a fit can square (|p| <= 1e150 Pa, the loader's
    # rule); the bulk parser below sees the whole range.
    loadable = [c for c in cells if abs(float(c)) < 1e145]
    assert len(loadable) > 300
    rows = "".join(f"a,{i * 1e-4},{c}\n" for i, c in enumerate(loadable))
    sinkage = "test_id,z_m,force_N\n" + rows
    tests = "test_id,kind,soil,shape,radius_m\na,sinkage,s,circle,0.05\n"
    got = load_campaign(write_campaign(tests=tests, sinkage=sinkage), check_units=False)
    want = np.array([float(c) for c in loadable]).view(np.int64)
    np.testing.assert_array_equal(got.sinkage["force_N"].to_numpy().view(np.int64), want)
    # Numbers float64 cannot hold as written are refused by the rules (the loader), not
    # by the parser: the parser still reads them as float() does.
    cells += ["1e-400", "9007199254740993", "2.4703282292062328e-324"]
    want = np.array([float(c) for c in cells]).view(np.int64)
    bulk = _parse_decimals(pd.Series(cells, dtype="str"))  # the bulk path, not float()
    assert bulk is not None and np.array_equal(bulk.view(np.int64), want)
    assert _parse_decimals(pd.Series([*cells, " 1"], dtype="str")) is None


def test_numbers_outside_the_plain_grammar_are_read_by_float(write_campaign):
    """Cells Arrow would refuse (blanks around) keep the meaning float() gives them; 'NaN'
    and 'inf' are still not finite samples, and what float() reads but no logger writes
    (an underscore: '1_5' may mean 1.5; non-ASCII digits) is not a number at all."""
    tests = "test_id,kind,soil,shape,radius_m\na,sinkage,s,circle,0.05\n"
    sinkage = "test_id,z_m,force_N\na,0.001, 1.5\na,0.002,1000\na,0.003,2.5 \n"
    got = load_campaign(write_campaign(tests=tests, sinkage=sinkage), check_units=False)
    assert list(got.sinkage["force_N"]) == [1.5, 1000.0, 2.5]
    for name, cell in (("nan", "NaN"), ("inf", "inf"), ("underscore", "1_5"), ("digit", "\u0663")):
        bad = sinkage.replace("2.5 ", cell)
        with pytest.raises(CampaignError, match=f"value '{cell}' is not a finite number"):
            load_campaign(write_campaign(name=name, tests=tests, sinkage=bad))


def test_a_semicolon_separated_file_is_named_as_such(write_campaign):
    # A European spreadsheet export: one column name holding every name.
    tests = "test_id,kind,soil,shape,radius_m\na,sinkage,s,circle,0.05\n"
    sinkage = "test_id;z_m;force_N\na;0.001;1.5\na;0.002;3.0\n"
    with pytest.raises(CampaignError, match="looks semicolon-separated") as info:
        load_campaign(write_campaign(tests=tests, sinkage=sinkage))
    assert "sinkage.csv" in str(info.value)


def test_lines_above_the_header_are_named_with_the_header_line(write_campaign):
    # A logger's preamble: the first line is read as the header.
    tests = "test_id,kind,soil,shape,radius_m\na,sinkage,s,circle,0.05\n"
    sinkage = "Rig 3 export\nunits: m and N\ntest_id,z_m,force_N\na,0.001,1.5\na,0.002,3.0\n"
    with pytest.raises(CampaignError, match=r"column names .* are on line 3"):
        load_campaign(write_campaign(tests=tests, sinkage=sinkage))


def test_fit_time_errors_name_the_parquet_file_read(tmp_path, campaign_frames):
    """Errors raised when fitting (pooling, shear, per-test) name the file the table was read
    from — ``sinkage.parquet``, not ``sinkage.csv``; in-memory tables keep ``<stem>.csv``."""
    import soilstats
    from soilstats.errors import CampaignError

    folder = tmp_path / "pq"
    folder.mkdir()
    for stem, frame in campaign_frames.items():
        frame.to_parquet(folder / f"{stem}.parquet")
    campaign = load_campaign(folder)
    assert campaign.select(kind="shear").file_name("shear") == "shear.parquet"  # kept by select
    calls = [
        (lambda: soilstats.fit_sinkage(campaign), "sinkage.parquet", "c1"),
        (lambda: soilstats.fit_shear(campaign), "shear.parquet", None),
        (lambda: soilstats.fit_shear(campaign, model="janosi"), "shear.parquet", "s1"),
        (
            lambda: soilstats.fit_per_test(campaign.select(kind="shear"), "sinkage"),
            "tests.parquet",
            None,
        ),
    ]
    for call, file, test_id in calls:
        with pytest.raises(CampaignError, match=f"file '{file}'") as raised:
            call()
        assert raised.value.file == file and raised.value.test_id == test_id
    memory = Campaign.from_frames(campaign.tests, campaign.sinkage, campaign.shear)
    with pytest.raises(CampaignError, match=r"file 'sinkage\.csv'"):
        soilstats.fit_sinkage(memory)


def test_a_parquet_campaign_without_pyarrow_names_the_extra(tmp_path, monkeypatch, capsys):
    """pyarrow is the optional ``parquet`` extra (170 MB that a CSV user does not need):
    without it, reading or writing a .parquet table is one line naming the extra."""
    import sys

    from soilstats.cli.main import main

    campaign = soilstats.load_campaign("grc1-oravec2009")
    folder = campaign.save(tmp_path / "pq", format="parquet")
    monkeypatch.setitem(sys.modules, "pyarrow", None)  # as if not installed
    with pytest.raises(CampaignError, match=r"pip install 'soilstats\[parquet\]'"):
        soilstats.load_campaign(folder)
    assert main(["check", str(folder)]) == 2
    err = capsys.readouterr().err
    assert "soilstats[parquet]" in err and "Traceback" not in err and len(err.splitlines()) == 1
    with pytest.raises(CampaignError, match="needs pyarrow"):
        campaign.save(tmp_path / "pq2", format="parquet")
