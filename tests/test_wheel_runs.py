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
    assert wheels["smooth"] == Wheel(0.058, 0.05, name="smooth")
    assert wheels["grouser"].contact_radius_m == 0.063
    assert wheels["grouser"].grouser_area_ratio == 0.1
    wider = wheel_geometry(
        ["smooth"], tables, {"*": {"width_m": 0.06}, "smooth": {"radius_m": 0.1}}
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
