"""Your own data in: unit conversion, TOML import, DataFrames, and implausible units caught."""

from __future__ import annotations

import math
import textwrap
import warnings

import numpy as np
import pandas as pd
import pytest

import soilstats
from soilstats.campaign import Campaign, UnitsWarning, import_campaign, load_campaign
from soilstats.campaign.units import to_si
from soilstats.cli.main import main
from soilstats.errors import CampaignError


@pytest.mark.parametrize(
    ("column", "unit", "value", "si"),
    [
        ("z_m", "mm", "12.5", 0.0125),
        ("z_m", "cm", "3", 0.03),
        ("radius_m", "in", "2", 0.0508),
        ("force_N", "kN", "0.9", 900.0),
        ("force_N", "lbf", "1", 4.4482216152605),
        ("torque_Nm", "N·mm", "2500", 2.5),
        ("torque_Nm", "N mm", "2500", 2.5),
        ("torque_Nm", "Nmm", "2500", 2.5),
        ("torque_Nm", "kN*m", "0.002", 2.0),
        ("angle_rad", "deg", "90", math.pi / 2),
        ("velocity_m_s", "mm/min", "60", 1e-3),
        ("omega_rpm", "deg/s", "360", 60.0),
    ],
)
def test_conversions_by_hand(column, unit, value, si):
    out = to_si(pd.Series([value, "abc"]), column, unit)
    assert out[0] == pytest.approx(si, rel=1e-12)
    assert out[1] == "abc"  # left for validation to report with its row


def test_unknown_unit_names_the_column_and_the_choices():
    with pytest.raises(CampaignError, match=r"z_m.*unknown unit 'furlong'.*'mm'"):
        to_si(pd.Series(["1"]), "z_m", "furlong")


def _lab_export(folder):
    """A lab's own files: its column names, mm, kN, plate diameters, a covariate."""
    (folder / "log.csv").write_text(
        "Test;Soil;Plate diameter;Moisture\nT1;loam;100;12,5\nT2;loam;150;13,0\n"
    )
    (folder / "raw.csv").write_text(
        "Test;Sinkage;Load\n"
        + "".join(f"T1;{z:.1f};{0.02 * z**1.1:.5f}\n" for z in range(1, 31))
        + "".join(f"T2;{z:.1f};{0.05 * z**1.1:.5f}\n" for z in range(1, 31))
    )
    mapping = folder / "lab.toml"
    mapping.write_text(
        textwrap.dedent(
            """
            [tests]
            file = "log.csv"
            separator = ";"
            [tests.columns]
            test_id = "Test"
            soil = "Soil"
            radius_m = { column = "Plate diameter", unit = "mm", diameter = true }
            [tests.constant]
            kind = "sinkage"
            shape = "circle"

            [sinkage]
            file = "raw.csv"
            separator = ";"
            [sinkage.columns]
            test_id = "Test"
            z_m = { column = "Sinkage", unit = "mm" }
            force_N = { column = "Load", unit = "kN" }
            """
        )
    )
    return mapping


def test_toml_import_gives_the_si_campaign(tmp_path):
    campaign = import_campaign(_lab_export(tmp_path))
    tests = campaign.tests.set_index("test_id")
    assert tests.loc["T1", "radius_m"] == pytest.approx(0.05)
    assert tests.loc["T2", "radius_m"] == pytest.approx(0.075)
    assert list(tests["Moisture"]) == ["12,5", "13,0"]  # unmapped: kept as a covariate
    t2 = campaign.samples("T2")
    assert t2["z_m"].iloc[4] == pytest.approx(0.005)
    assert t2["force_N"].iloc[4] == pytest.approx(1000 * float(f"{0.05 * 5.0**1.1:.5f}"))


def test_import_command_writes_a_campaign_that_loads_back(tmp_path, capsys):
    mapping = _lab_export(tmp_path)
    assert main(["import", str(mapping), "--out", str(tmp_path / "campaign")]) == 0
    back = load_campaign(tmp_path / "campaign")
    assert len(back.tests) == 2 and back.sinkage["z_m"].max() == pytest.approx(0.03)
    assert main(["import", str(mapping), "--out", str(tmp_path / "campaign")]) == 2
    assert "overwrite" in capsys.readouterr().err


def test_import_mapping_errors_name_the_key(tmp_path):
    mapping = _lab_export(tmp_path)
    text = mapping.read_text()
    mapping.write_text(text.replace('"Sinkage"', '"Depth"'))
    with pytest.raises(CampaignError, match=r"'raw.csv'.*'Depth'.*columns: \['Test', 'Sinkage'"):
        import_campaign(mapping)
    mapping.write_text(text.replace('unit = "kN"', 'unit = "tonnes"'))
    with pytest.raises(CampaignError, match="unknown unit 'tonnes'"):
        import_campaign(mapping)


def test_dataframes_load_like_the_folder():
    folder = load_campaign("cullinan-sand")
    raw = {
        "tests": folder.tests.drop(columns=["b_m", "area_m2", "aspect_ratio", "ring_area_m2"]),
        "sinkage": folder.sinkage.drop(columns="pressure_Pa"),
    }
    frames = load_campaign(raw)
    pd.testing.assert_frame_equal(frames.tests, folder.tests)
    pd.testing.assert_frame_equal(frames.sinkage, folder.sinkage)
    with pytest.raises(CampaignError, match="'tests'"):
        load_campaign({"sinkage": raw["sinkage"]})


def test_from_frames_converts_units():
    folder = load_campaign("grc1-oravec2009")
    tests = folder.tests[["test_id", "kind", "soil", "shape", "radius_m"]].copy()
    sinkage = folder.sinkage[["test_id", "z_m", "force_N"]].copy()
    tests["radius_m"] *= 1000
    sinkage["z_m"] *= 1000
    sinkage["force_N"] /= 1000
    back = Campaign.from_frames(
        tests, sinkage, units={"radius_m": "mm", "z_m": "mm", "force_N": "kN"}
    )
    assert np.allclose(back.sinkage["pressure_Pa"], folder.sinkage["pressure_Pa"], rtol=1e-12)


# --------------------------------------------------------------------- implausible units


def _grc1_frames():
    c = load_campaign("grc1-oravec2009")
    return c.tests[["test_id", "kind", "soil", "shape", "radius_m"]].copy(), c.sinkage[
        ["test_id", "z_m", "force_N"]
    ].copy()


def test_sinkage_in_millimetres_is_an_error_naming_file_column_test():
    tests, sinkage = _grc1_frames()
    sinkage["z_m"] *= 1000
    with pytest.raises(CampaignError, match=r"'sinkage.csv', column 'z_m', test 'small-1'.*mm"):
        Campaign.from_frames(tests, sinkage)


def test_plate_radius_in_millimetres_is_an_error():
    tests, sinkage = _grc1_frames()
    tests["radius_m"] *= 1000
    with pytest.raises(CampaignError, match=r"column 'radius_m'.*millimetres"):
        Campaign.from_frames(tests, sinkage)


def test_force_in_kilonewtons_warns_with_the_fix():
    tests, sinkage = _grc1_frames()
    sinkage["force_N"] /= 1000
    with pytest.warns(UnitsWarning, match=r"'force_N'.*kilonewtons.*unit = 'kN'"):
        Campaign.from_frames(tests, sinkage)


def _cullinan_frames():
    c = load_campaign("cullinan-sand")
    tests = c.tests[["test_id", "kind", "soil", "shape", "radius_m"]].copy()
    return tests, c.sinkage[["test_id", "z_m", "force_N"]].copy()


def test_one_test_in_kilonewtons_among_newtons_warns_where_the_absolute_limit_cannot():
    # Cullinan's plate is large: one test read in kN still peaks above 200 Pa (419 Pa), so
    # only the comparison with the other tests of its soil can tell (1000x below them).
    tests, sinkage = _cullinan_frames()
    one = sinkage["test_id"] == "method2-test1"
    sinkage.loc[one, "force_N"] /= 1000
    with pytest.warns(UnitsWarning, match=r"'force_N': 1 test.*1/100 of the median.*method2-test1"):
        Campaign.from_frames(tests, sinkage)


def test_one_test_in_centimetres_among_metres_warns_though_it_spans_under_a_metre():
    tests, sinkage = _grc1_frames()
    one = sinkage["test_id"] == "medium-3"
    sinkage.loc[one, "z_m"] *= 100  # 0.62 m: below the 1 m limit
    with pytest.warns(UnitsWarning, match=r"'z_m': 1 test.*centimetres.*medium-3"):
        Campaign.from_frames(tests, sinkage)


def test_a_reversed_load_cell_is_named_as_a_sign_not_as_kilonewtons():
    tests, sinkage = _grc1_frames()
    one = sinkage["test_id"] == "medium-3"
    sinkage.loc[one, "force_N"] *= -1
    with pytest.warns(UnitsWarning, match=r"sign looks reversed.*medium-3") as caught:
        Campaign.from_frames(tests, sinkage)
    assert not any("kilonewtons" in str(w.message) for w in caught)


def test_a_reversed_displacement_is_named_as_a_sign():
    # A z column with flipped sign used to be reported only as 'non-monotone'.
    tests, sinkage = _grc1_frames()
    one = sinkage["test_id"] == "medium-3"
    sinkage.loc[one, "z_m"] *= -1
    with pytest.warns(UnitsWarning, match=r"'z_m'.*displacement sign looks reversed.*medium-3"):
        Campaign.from_frames(tests, sinkage)


def test_a_flat_force_record_is_not_called_a_unit_slip():
    # A dead channel (5 N throughout, ~280 Pa) peaks far below its soil's tests, but it does not
    # rise as a loaded curve: screening names it, the unit rule does not.
    tests, sinkage = _cullinan_frames()
    sinkage.loc[sinkage["test_id"] == "method2-test1", "force_N"] = 5.0
    with warnings.catch_warnings():
        warnings.simplefilter("error", UnitsWarning)
        Campaign.from_frames(tests, sinkage)


def test_shear_angle_in_degrees_and_torque_in_newton_millimetres_warn():
    c = load_campaign("simulated-paper").select(kind="shear", soil="soil01")
    tests = c.tests.drop(columns=["b_m", "area_m2", "aspect_ratio", "ring_area_m2", "n_samples"])
    shear = c.shear[["test_id", "angle_rad", "torque_Nm", "normal_force_N"]].copy()
    degrees = shear.assign(angle_rad=np.degrees(shear["angle_rad"]) * 20)
    with pytest.warns(UnitsWarning, match="angle_rad.*degrees"):
        Campaign.from_frames(tests, shear=degrees)
    newton_mm = shear.assign(torque_Nm=shear["torque_Nm"] * 1000)
    with pytest.warns(UnitsWarning, match=r"torque_Nm.*N·mm"):
        Campaign.from_frames(tests, shear=newton_mm)


@pytest.mark.parametrize("name", soilstats.bundled_campaigns())
def test_clean_bundled_campaigns_trip_nothing(name):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_campaign(name)


def test_clean_simulated_campaigns_trip_nothing():
    from soilstats.data import bundled_path

    for seed in range(8):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            soilstats.simulate(bundled_path("simulated-paper") / "spec.toml", seed=seed)


def test_the_check_can_be_turned_off_for_data_known_to_be_unusual():
    tests, sinkage = _grc1_frames()
    sinkage["z_m"] *= 1000
    assert Campaign.from_frames(tests, sinkage, check_units=False).sinkage["z_m"].max() > 1


def test_unit_messages_name_the_file_as_it_was_read(tmp_path):
    # A Parquet campaign's messages said 'tests.csv'.
    campaign = soilstats.load_campaign("grc1-oravec2009")
    folder = tmp_path / "pq"
    folder.mkdir()
    tests = campaign.tests[["test_id", "kind", "soil", "shape", "radius_m"]].copy()
    tests["radius_m"] *= 1000.0  # millimetres
    tests.to_parquet(folder / "tests.parquet")
    campaign.sinkage[["test_id", "z_m", "force_N"]].to_parquet(folder / "sinkage.parquet")
    with pytest.raises(CampaignError, match="radius_m") as info:
        soilstats.load_campaign(folder)
    assert "tests.parquet" in str(info.value) and "tests.csv" not in str(info.value)


def test_import_skips_a_preamble_and_writes_round_numbers(tmp_path, capsys):
    """A logger's preamble above the header is skipped (``skip_rows``), and numbers in mm and
    kN come out as the round SI numbers they are: the saved sinkage.csv holds 0.0051, never
    float's 5.1 * 0.001 = 0.0050999999999999995."""
    mapping = _lab_export(tmp_path)
    raw = tmp_path / "raw.csv"
    body = raw.read_text().replace("T1;5.0;", "T1;5.1;")
    raw.write_text("Logger 7 export\nDate: 2026-11-26\nchannel map v2\n" + body)
    mapping.write_text(
        mapping.read_text().replace('file = "raw.csv"', 'file = "raw.csv"\nskip_rows = 3')
    )
    assert 5.1 * 0.001 != 0.0051  # the float noise the decimal conversion avoids
    assert main(["import", str(mapping), "--out", str(tmp_path / "campaign")]) == 0
    text = (tmp_path / "campaign" / "sinkage.csv").read_text()
    assert "T1,0.0051," in text and "0.0050999999999999995" not in text
    assert all(len(cell) < 16 for line in text.splitlines()[1:] for cell in line.split(",")[1:2])
    mapping.write_text(mapping.read_text().replace("skip_rows = 3", "skip_rows = -1"))
    with pytest.raises(CampaignError, match=r"sinkage.skip_rows.*whole number >= 0"):
        import_campaign(mapping)
