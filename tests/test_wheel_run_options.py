"""What ``soilstats wheel`` is given, read in the library (soilstats.wheel.run_options,
moved out of cli/wheel.py and cli/wheel_modes.py, issue #45)."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from soilstats.errors import InputError
from soilstats.wheel import StressAngles, Wheel
from soilstats.wheel.run_options import (
    file_sha256,
    geometry_defaults,
    parse_angles,
    parse_prior_item,
    parse_slips,
    runs_file,
)


def test_a_prior_item_is_a_name_a_kind_and_numbers():
    assert parse_prior_item(" phi = normal:29:4") == ("phi", ("normal", 29.0, 4.0))
    assert parse_prior_item("K=lognormal:0.01:0.8") == ("K", ("lognormal", 0.01, 0.8))
    for bad in ("phi", "phi=normal", "=normal:1:2", "phi=normal:a:2"):
        with pytest.raises(InputError, match=f"got {bad!r}"):
            parse_prior_item(bad)


def test_stress_angles_take_four_numbers():
    assert parse_angles(None) is None
    assert parse_angles("0.4,0.15,0,0") == StressAngles(0.4, 0.15, 0.0, 0.0)
    for bad in ("0.4,0.15,0", "a,b,c,d"):
        with pytest.raises(InputError, match="four numbers"):
            parse_angles(bad)


def test_slips_from_a_to_b_in_steps_both_ends_included():
    np.testing.assert_array_equal(parse_slips("-0.5:0.9:0.1"), np.round(np.arange(-5, 10) / 10, 10))
    np.testing.assert_array_equal(parse_slips("0:0:0.1"), [0.0])
    for bad in ("0:1", "0.5:0.1:0.1", "0:1:0", "-2:1:0.1", "0:nan:0.1"):
        with pytest.raises(InputError, match="--slips"):
            parse_slips(bad)
    with pytest.raises(InputError, match="201 slips; at most 200"):
        parse_slips("-1:1:0.01")


def test_geometry_nobody_gave_is_said_with_the_value_assumed():
    wheels = {"w1": Wheel(radius_m=0.1, width_m=0.05), "w2": Wheel(radius_m=0.2, width_m=0.1)}
    tables = {"w1": {"radius_m": 0.1, "width_m": 0.05, "shear_radius_m": 0.11}}
    overrides = {"*": {"grouser_area_ratio": 0.5}}
    assert geometry_defaults(wheels, tables, overrides) == {
        "w2: shear_radius_m": "0.2 (= radius_m: no grousers assumed; give --shear-radius "
        "w2=RS for a grousered wheel)"
    }
    assert set(geometry_defaults(wheels, {}, {})) == {
        f"{w}: {k}" for w in wheels for k in ("shear_radius_m", "grouser_area_ratio")
    }


def test_the_runs_file_as_given_or_in_the_campaign_folder(tmp_path):
    given = tmp_path / "runs.csv"
    given.write_text("run_id\n")
    assert runs_file(str(given), "cmu-3d-terramechanics") == given
    bundled = runs_file("wheel.csv", "cmu-3d-terramechanics")
    assert bundled.name == "wheel.csv" and bundled.is_file()
    with pytest.raises(FileNotFoundError, match="nor in the campaign folder"):
        runs_file("nowhere.csv", "cmu-3d-terramechanics")


def test_the_sha256_of_a_file(tmp_path):
    path = tmp_path / "abc"
    path.write_bytes(b"abc")
    # FIPS 180-2's example: SHA-256("abc").
    assert file_sha256(path) == ("ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad")
    assert file_sha256(path) == hashlib.sha256(b"abc").hexdigest()
