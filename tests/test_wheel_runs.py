"""The runs file of a wheel validation: columns checked with file, column, run and row named;
the wheels' geometry from TOML and options; the slip-dependent exponent of the wheel model."""

from __future__ import annotations

import re

import numpy as np
import pandas as pd
import pytest

from soilstats.data import bundled_path
from soilstats.wheel import Wheel, wheel_forces
from soilstats.wheel.runs import WheelDataError, read_runs, read_wheels, slip_levels, wheel_geometry
from soilstats.wheel.slipsinkage import exponent_shift

CMU = bundled_path("cmu-3d-terramechanics")


def _runs(**changes) -> pd.DataFrame:
    frame = pd.DataFrame(
        {
            "run_id": ["a", "b", "c", "d"],
            "wheel": ["smooth", "smooth", "grouser", "grouser"],
            "slip": [0.0, 0.5, -1.0, 0.9],
            "W_N": [22.0, 23.0, 20.0, 24.0],
            "sinkage_m": [0.015, 0.02, 0.05, 0.04],
        }
    )
    for column, (row, value) in changes.items():
        frame[column] = frame[column].astype(object)
        frame.loc[row, column] = value
    return frame


def test_the_bundled_cmu_runs_read_with_their_conditions():
    runs = read_runs(CMU / "wheel.csv")
    assert len(runs) == 378
    # nine slip conditions (the nine rim speeds), seven slip angles, per wheel
    smooth = sorted(runs.loc[runs["wheel"] == "smooth", "slip_level"].unique())
    assert smooth == [-1.0, -0.7, -0.5, -0.2, 0.0, 0.23, 0.5, 0.75, 0.9]
    assert runs.groupby("wheel")["slip_level"].nunique().tolist() == [9, 9]
    cells = runs.groupby(["wheel", "slip_level", "beta_level"]).size()
    assert len(cells) == 126 and (cells == 3).all()
    assert sorted(runs["beta_level"].unique()) == [0, 15, 30, 45, 60, 75, 90]
    # beta_90 turning runs keep digging: not steady (wheel.md caveat 4)
    unsteady = runs[~runs["steady"]]
    assert len(unsteady) > 0 and set(unsteady["beta_level"]) == {90}
    assert (runs["row"] == np.arange(1, 379)).all()


def test_slip_levels_split_at_gaps_and_never_print_minus_zero():
    levels = slip_levels(np.array([-0.002, 0.001, 0.17, 0.23, 0.5, -1.0]))
    assert list(levels) == [0.0, 0.0, 0.2, 0.2, 0.5, -1.0]
    assert not np.signbit(levels[0])


@pytest.mark.parametrize(
    ("frame", "column", "row", "words"),
    [
        (_runs().drop(columns="W_N"), "W_N", None, "missing required column"),
        (_runs(slip=(2, 1.5)), "slip", 3, "not a slip in [-1, 1]"),
        (_runs(slip=(1, "fast")), "slip", 2, "not a slip"),
        (_runs(W_N=(0, -3.0)), "W_N", 1, "positive load"),
        (_runs(sinkage_m=(3, 40.0)), "sinkage_m", 4, "is it in mm"),
        (_runs(sinkage_m=(1, np.nan)), "sinkage_m", 2, "an empty cell"),
        (_runs(run_id=(3, "a")), "run_id", 4, "repeats an earlier run"),
        (_runs(wheel=(2, " ")), "wheel", 3, "empty cell"),
        (
            _runs().assign(date=["2020-11-16", "16/11/2020", "2020-11-17", "2020-11-17"]),
            "date",
            2,
            "a date YYYY-MM-DD",
        ),
        (_runs().assign(beta_deg=[0, 15, 200, 90]), "beta_deg", 3, "slip angle"),
    ],
)
def test_every_bad_cell_names_file_column_run_and_row(frame, column, row, words, tmp_path):
    path = tmp_path / "runs.csv"
    frame.to_csv(path, index=False)
    with pytest.raises(WheelDataError, match=re.escape(words)) as err:
        read_runs(path)
    assert err.value.file == "runs.csv" and err.value.column == column
    assert err.value.row == row
    assert "runs.csv" in str(err.value) and repr(column) in str(err.value)
    if row is not None:
        assert f"row {row}" in str(err.value)


def test_optional_columns_may_be_empty_but_not_text(tmp_path):
    frame = _runs().assign(drawbar_pull_N=[1.0, np.nan, -3.0, 2.0])
    assert read_runs(frame)["drawbar_pull_N"].isna().sum() == 1
    frame["drawbar_pull_N"] = frame["drawbar_pull_N"].astype(object)
    frame.loc[2, "drawbar_pull_N"] = "n/a"
    with pytest.raises(WheelDataError, match="row 3"):
        read_runs(frame)
    assert (read_runs(_runs())["beta_deg"] == 0).all()


def test_empty_file_is_refused(tmp_path):
    path = tmp_path / "wheel.csv"
    path.write_text("")
    with pytest.raises(WheelDataError, match="empty"):
        read_runs(path)


def test_geometry_from_the_bundled_toml_and_options():
    tables = read_wheels(CMU / "wheels.toml")
    wheels = wheel_geometry(["smooth", "grouser"], tables)
    # the smooth wheel's shearing radius is stated as its radius (a smooth rim shears)
    assert wheels["smooth"].contact_radius_m == wheels["smooth"].radius_m == 0.058
    assert (wheels["smooth"].width_m, wheels["smooth"].name) == (0.05, "smooth")
    assert wheels["grouser"].contact_radius_m == 0.063
    assert wheels["grouser"].grouser_area_ratio == 0.1
    wider = wheel_geometry(
        ["smooth"],
        tables,
        {"*": {"width_m": 0.06}, "smooth": {"radius_m": 0.1, "shear_radius_m": 0.1}},
    )
    assert wider["smooth"].width_m == 0.06 and wider["smooth"].radius_m == 0.1
    with pytest.raises(WheelDataError, match="--wheel-radius tracked=R"):
        wheel_geometry(["tracked"], tables)


def test_a_bad_toml_is_named(tmp_path):
    path = tmp_path / "wheels.toml"
    path.write_text("[smooth]\nradius_m = 0.058\nwidth = 0.05\n")
    with pytest.raises(WheelDataError, match="unknown keys"):
        read_wheels(path)
    path.write_text("[smooth\n")
    with pytest.raises(WheelDataError, match="not valid TOML"):
        read_wheels(path)


def test_exponent_shift_is_the_model_with_n_plus_delta_n():
    # The shift is exactly a wheel whose exponent is n + Δn(s): compare slip by slip.
    wheel = Wheel(0.058, 0.05)
    params = {"kc": np.array([-2.9e5, -2.0e5]), "kphi": np.array([1.5e7, 1.2e7]), "n": [1.4, 1.5]}
    slips = np.array([-1.0, -0.5, 0.0, 0.5, 0.9])
    shift = exponent_shift(slips, 0.3, 0.6)
    assert shift == pytest.approx([0.6, 0.3, 0.0, 0.15, 0.27])
    both = wheel_forces(params, wheel, slips, law="bekker", load_N=22.0, exponent_shift=shift)
    for j, s in enumerate(slips):
        single = wheel_forces(
            {**params, "n": np.asarray(params["n"]) + shift[j]},
            wheel,
            [s],
            law="bekker",
            load_N=22.0,
        )
        assert both.sinkage_m[:, j] == pytest.approx(single.sinkage_m[:, 0], rel=1e-12)
    # a larger exponent (z in m, z < 1) is a softer soil: deeper sinkage
    base = wheel_forces(params, wheel, slips, law="bekker", load_N=22.0)
    assert np.all(both.sinkage_m[:, [0, 1, 3, 4]] > base.sinkage_m[:, [0, 1, 3, 4]])
    assert both.sinkage_m[:, 2] == pytest.approx(base.sinkage_m[:, 2])


# --- issue #44: no value changed on read, unit mistakes named, empty optional cells ----------


def _write(tmp_path, text: str, name: str = "runs.csv"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


HEADER = "run_id,wheel,slip,W_N,sinkage_m"


def test_run_ids_stay_text_as_written(tmp_path):
    path = _write(tmp_path, f"{HEADER}\n001,smooth,0.1,20,0.01\n1e3,smooth,0.2,21,0.012\n")
    runs = read_runs(path)
    assert runs["run_id"].tolist() == ["001", "1e3"]
    assert runs["W_N"].tolist() == [20.0, 21.0]


@pytest.mark.parametrize(
    ("value", "words"),
    [(True, "the boolean True"), (np.complex128(20 + 1j), "the complex number")],
)
def test_numeric_columns_refuse_booleans_and_complex_numbers(value, words):
    frame = _runs(W_N=(1, value))
    with pytest.raises(WheelDataError, match=words) as err:
        read_runs(frame)
    assert err.value.column == "W_N" and err.value.row == 2
    with pytest.raises(WheelDataError, match="boolean"):
        read_runs(_runs().assign(W_N=[True, False, True, True]))


def test_a_duplicate_or_blank_column_is_an_error_naming_the_file(tmp_path):
    path = _write(tmp_path, f"{HEADER},W_N\na,smooth,0.1,20,0.01,2000\n")
    with pytest.raises(WheelDataError, match="names this column twice") as err:
        read_runs(path)
    assert err.value.file == "runs.csv" and err.value.column == "W_N"
    path = _write(tmp_path, f"{HEADER},\na,smooth,0.1,20,0.01,x\n")
    with pytest.raises(WheelDataError, match="no name") as err:
        read_runs(path)
    assert "runs.csv" in str(err.value)


@pytest.mark.parametrize(
    ("cell", "words"),
    [
        ("NA", "'NA' (a missing-value marker)"),
        ("nan", "'nan' (a missing-value marker)"),
        ("", "an empty cell"),
    ],
)
def test_missing_markers_are_named_as_such(tmp_path, cell, words):
    path = _write(tmp_path, f"{HEADER}\na,smooth,0.1,{cell},0.01\n")
    with pytest.raises(WheelDataError, match=re.escape(words)) as err:
        read_runs(path)
    assert err.value.column == "W_N" and err.value.row == 1


def test_an_encoding_error_names_the_file(tmp_path):
    path = tmp_path / "runs.csv"
    path.write_bytes(f"{HEADER}\nr\xe9,smooth,0.1,20,0.01\n".encode("latin-1"))
    with pytest.raises(WheelDataError, match="not UTF-8") as err:
        read_runs(path)
    assert err.value.file == "runs.csv"


def test_empty_optional_cells_are_undated_or_unmeasured_runs(tmp_path):
    text = (
        f"{HEADER},date,drawbar_pull_N,torque_Nm\n"
        "a,smooth,0.1,20,0.01,2020-11-16,3.5,\n"
        "b,smooth,0.2,21,0.012,,,0.2\n"
        "c,smooth,0.3,21,0.013,NA,NA,NA\n"
    )
    runs = read_runs(_write(tmp_path, text))
    assert runs["date"].tolist()[0] == "2020-11-16" and runs["date"].isna().tolist() == [
        False,
        True,
        True,
    ]
    assert runs["drawbar_pull_N"].isna().tolist() == [False, True, True]
    assert runs["torque_Nm"].isna().tolist() == [True, False, True]
    # a schema-exact file whose optional date column is empty throughout
    text = f"{HEADER},date\na,smooth,0.1,20,0.01,\nb,smooth,0.2,21,0.012,\n"
    assert read_runs(_write(tmp_path, text))["date"].isna().all()


def test_slip_angles_in_radians_are_named_with_the_likely_unit():
    frame = _runs().assign(beta_deg=[0.0, 0.2618, 0.5236, 1.5708])
    with pytest.warns(UserWarning, match=r"'beta_deg'.*likely radians"):
        read_runs(frame)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read_runs(_runs().assign(beta_deg=[0.0, 15.0, 30.0, 90.0]))  # degrees: no warning
        read_runs(_runs().assign(beta_deg=[0.0, 1.0, 1.0, 0.0]))  # whole degrees: none


@pytest.mark.parametrize(("scale", "unit"), [(1 / 9.80665e-3, "grams-force"), (1e-3, "kN")])
def test_loads_in_grams_force_or_kn_are_named_with_the_likely_unit(scale, unit):
    from soilstats.wheel.runs import warn_load_units

    wheels = {"smooth": Wheel(0.058, 0.05), "grouser": Wheel(0.058, 0.05, 0.063)}
    runs = read_runs(_runs())
    assert warn_load_units(runs, wheels, "runs.csv") == []  # 20 N on a 58 mm wheel
    runs["W_N"] = runs["W_N"] * scale
    with pytest.warns(UserWarning, match=rf"column 'W_N' of wheel '\w+'.*likely {unit}"):
        texts = warn_load_units(runs, wheels, "runs.csv")
    assert len(texts) == 2 and all("runs.csv" in t and unit in t for t in texts)


def test_a_radius_in_mm_is_named():
    with pytest.warns(UserWarning, match=r"radius_m = 58 of wheel type 'smooth'.*likely mm"):
        wheel_geometry(["smooth"], {"smooth": {"radius_m": 58, "width_m": 0.05}})


def _cmu_runs(rows: int) -> pd.DataFrame:
    return pd.read_csv(CMU / "wheel.csv", dtype=str, keep_default_na=False).head(rows)


def test_undated_runs_are_predicted_and_left_out_of_the_day_groups_only():
    from soilstats.wheel.validation import validate_wheel

    rng = np.random.default_rng(4)
    draws = pd.DataFrame(
        {
            "kc": -2.0e5 * np.exp(0.1 * rng.standard_normal(200)),
            "kphi": 1.3e7 * np.exp(0.1 * rng.standard_normal(200)),
            "n": 1.4 + 0.03 * rng.standard_normal(200),
        }
    )
    runs = _cmu_runs(60)
    runs = runs[runs["beta_cmd_deg"] == "0"].copy() if (runs["beta_cmd_deg"] == "0").any() else runs
    runs.loc[runs.index[::3], "date"] = ""
    wheels = wheel_geometry(runs["wheel"].unique(), read_wheels(CMU / "wheels.toml"))
    res = validate_wheel(None, runs, wheels=wheels, draws=draws, extension=False, sensitivity=False)
    undated = res.runs["date"].isna()
    assert undated.sum() == len(runs.index[::3]) and res.runs["predicted"].all()
    days = res.groups[res.groups["by"] == "wheel × day"]
    assert days["runs"].sum() == 2 * (~undated).sum()  # β = 0 and all-runs scopes, dated only
    assert any("undated" in n for n in res.notes)


@pytest.mark.filterwarnings("default::soilstats.wheel.runs.UnitWarning")  # printed by the CLI
def test_no_run_carried_says_why_and_writes_nothing(tmp_path, capsys):
    from soilstats.cli.main import main

    runs = _cmu_runs(6)[["run_id", "wheel", "slip", "W_N", "sinkage_m", "date"]]
    runs["W_N"] = "5000"
    runs.to_csv(tmp_path / "wheel.csv", index=False)
    (tmp_path / "wheels.toml").write_text((CMU / "wheels.toml").read_text())
    out = tmp_path / "out"
    argv = ["wheel", "cmu-3d-terramechanics", "--runs", str(tmp_path / "wheel.csv")]
    argv += ["--out", str(out), "--n-draws", "200", "--draws", "pooled", "--no-extension"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert re.search(r"wheel\.csv: column 'W_N'.*likely grams-force", err)  # said first
    assert "no run can be predicted" in err and "5000" in err and "Traceback" not in err
    assert not out.exists() or not any(out.iterdir())
