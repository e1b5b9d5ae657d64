"""The simulator: determinism, the CLI, planted effects at the size asked for, SPEC errors."""

from __future__ import annotations

import copy
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from soilstats import fit_shear, fit_sinkage
from soilstats.data import bundled_path
from soilstats.models import side_wall_ratio
from soilstats.simulation import SpecError, load_spec, parse_spec, simulate

TINY = """
name = "tiny"
[soils.s1]
kc = -9.8e3
kphi = 1.2e6
n = 0.8
c = 70.0
phi = 30.0
K = 0.01
[[series]]
name = "plates"
kind = "sinkage"
soils = ["s1"]
plates = [{shape = "circle", radius_m = 0.025}, {shape = "circle", radius_m = 0.075}]
repetitions = 2
points = 40
[[series]]
name = "ring"
kind = "shear"
soils = ["s1"]
rings = [{r_inner_m = 0.05, r_outer_m = 0.15, tool = "tool04"}]
normal_pressure_Pa = [5e3, 15e3]
points = 40
"""

FILES = ("tests.csv", "sinkage.csv", "shear.csv", "truth.json", "truth_tests.csv", "README.md")


@pytest.fixture
def tiny_spec(tmp_path) -> Path:
    path = tmp_path / "tiny.toml"
    path.write_text(TINY)
    return path


def test_same_seed_gives_byte_identical_files(tiny_spec, tmp_path):
    a = simulate(tiny_spec, seed=7).save(tmp_path / "a")
    b = simulate(tiny_spec, seed=7).save(tmp_path / "b")
    c = simulate(tiny_spec, seed=8).save(tmp_path / "c")
    for name in FILES:
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
    assert (a / "sinkage.csv").read_bytes() != (c / "sinkage.csv").read_bytes()
    assert (a / "shear.csv").read_bytes() != (c / "shear.csv").read_bytes()


def test_saved_campaign_reads_back_exactly_and_says_simulated(tiny_spec, tmp_path):
    from soilstats import load_campaign

    sim = simulate(tiny_spec, seed=3)
    back = load_campaign(sim.save(tmp_path / "out"))
    np.testing.assert_array_equal(back.sinkage["force_N"], sim.campaign.sinkage["force_N"])
    np.testing.assert_array_equal(back.shear["torque_Nm"], sim.campaign.shear["torque_Nm"])
    readme = (tmp_path / "out" / "README.md").read_text()
    assert "SIMULATED" in readme and "tiny.toml" in readme and "seed 3" in readme
    assert sim.truth["simulated"] is True and sim.truth["seed"] == 3
    # zero offsets: some readings near z = 0 are negative, as from a real sensor
    above = back.sinkage[back.sinkage["z_m"] <= 0]
    assert len(above) > 0 and np.all(np.abs(above["force_N"]) < 2.0)


def test_cli_writes_the_same_files_as_the_library(tiny_spec, tmp_path):
    out = tmp_path / "cli"
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "soilstats",
            "simulate",
            str(tiny_spec),
            "--out",
            str(out),
            "--seed",
            "5",
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert run.returncode == 0, run.stderr
    lib = simulate(tiny_spec, seed=5).save(tmp_path / "lib")
    for name in FILES:
        assert (out / name).read_bytes() == (lib / name).read_bytes(), name
    again = subprocess.run(
        [
            sys.executable,
            "-m",
            "soilstats",
            "simulate",
            str(tiny_spec),
            "--out",
            str(out),
            "--seed",
            "5",
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert again.returncode == 2 and "overwrite" in again.stderr
    helped = subprocess.run(
        [sys.executable, "-m", "soilstats", "simulate", "--help"],
        capture_output=True,
        text=True,
        check=True,
    )
    assert "--seed" in helped.stdout and "docs/simulator.md" in helped.stdout


def test_bundled_campaign_is_regenerated_byte_for_byte(tmp_path):
    """The one documented command reproduces soilstats/data/simulated-paper exactly."""
    folder = bundled_path("simulated-paper")
    out = simulate(folder / "spec.toml", seed=2026).save(tmp_path / "regen")
    for name in FILES:
        assert (out / name).read_bytes() == (folder / name).read_bytes(), name
    size = sum(p.stat().st_size for p in folder.iterdir())
    assert size < 10e6


# --------------------------------------------------------------------------- planted effects
EFFECTS = (
    TINY.replace('name = "tiny"', 'name = "effects"')
    + """
[scatter]
stiffness_cv = 0.0
n_sd = 0.0
c_cv = 0.0
phi_sd_deg = 0.0
K_cv = 0.0
[[series]]
name = "cov"
kind = "sinkage"
soils = ["s1"]
plates = [{shape = "circle", radius_m = 0.05}]
covariates = { bin = ["A", "B"], moisture_pct = [0.0, 5.0] }
[[series]]
name = "vel"
kind = "sinkage"
soils = ["s1"]
plates = [{shape = "circle", radius_m = 0.05}]
velocity_m_s = [4.8e-4, 4.8e-3]
[[series]]
name = "narrow"
kind = "sinkage"
soils = ["s1"]
plates = [
  {shape = "rectangle", aspect = 3, area_m2 = 0.00785},
  {shape = "rectangle", aspect = 7, area_m2 = 0.00785},
]
[[series]]
name = "size"
kind = "sinkage"
soils = ["s1"]
plates = [{shape = "circle", radius_m = 0.025}, {shape = "circle", radius_m = 0.075}]
[[series]]
name = "walls"
kind = "shear"
soils = ["s1"]
rings = [{r_inner_m = 0.1, r_outer_m = 0.15}]
grouser_height_m = [0.0, 0.01]
normal_pressure_Pa = [3e3, 8e3, 14e3, 20e3]
points = 120
[[effects]]
kind = "covariate"
series = ["cov"]
column = "bin"
parameters = ["kc", "kphi"]
levels = { B = 1.3 }
[[effects]]
kind = "covariate"
series = ["cov"]
column = "moisture_pct"
parameters = ["kc", "kphi"]
slope = -0.04
[[effects]]
kind = "velocity"
series = ["vel"]
exponent = -0.1
reference_m_s = 4.8e-3
[[effects]]
kind = "softening"
series = ["narrow"]
critical_sinkage_m = 0.006
factor = 0.5
min_aspect_ratio = 5
[[effects]]
kind = "size"
series = ["size"]
exponent = "reece"
reference_b_m = 0.05
[[effects]]
kind = "side-walls"
series = ["walls"]
K0 = 0.5
"""
)


@pytest.fixture(scope="module")
def planted():
    spec = parse_spec(__import__("tomllib").loads(EFFECTS))
    return simulate(spec, seed=11).campaign


def _p_end(campaign, **sel) -> float:
    """Mean pressure over the last 10 samples of the selected tests."""
    c = campaign.select(**sel)
    return float(
        c.sinkage.groupby("test_id")["pressure_Pa"].apply(lambda p: p.iloc[-10:].mean()).mean()
    )


def test_covariate_categorical_effect(planted):
    ratio = _p_end(planted, series="cov", bin="B") / _p_end(planted, series="cov", bin="A")
    assert ratio == pytest.approx(1.3, rel=0.01)


def test_covariate_continuous_effect(planted):
    ratio = _p_end(planted, series="cov", moisture_pct=5.0) / _p_end(
        planted, series="cov", moisture_pct=0.0
    )
    assert ratio == pytest.approx(1 - 0.04 * 5, rel=0.01)


def test_velocity_effect(planted):
    ratio = _p_end(planted, series="vel", velocity_m_s=4.8e-4) / _p_end(
        planted, series="vel", velocity_m_s=4.8e-3
    )
    assert ratio == pytest.approx(10**0.1, rel=0.01)


def test_narrow_plate_softening_beyond_critical_sinkage(planted):
    """Above z_c the pressure increment of the 1:7 plate is halved; 1:3 is untouched."""
    from soilstats.models import BEKKER

    for aspect, factor in ((3, 1.0), (7, 0.5)):
        c = planted.select(series="narrow", aspect_ratio=lambda a, k=aspect: np.isclose(a, k))
        b = float(c.tests["b_m"].iloc[0])
        s = c.sinkage[c.sinkage["z_m"] > 0.01]
        bekker = BEKKER.func(np.vstack([np.full(len(s), b), s["z_m"]]), -9.8e3, 1.2e6, 0.8)
        at_zc = BEKKER.func(np.array([[b], [0.006]]), -9.8e3, 1.2e6, 0.8)[0]
        got = (s["pressure_Pa"] - at_zc) / (bekker - at_zc)
        assert float(np.median(got)) == pytest.approx(factor, rel=0.02)


def test_reece_size_effect(planted):
    """exponent 'reece' (1 − n = 0.2) on kc and kφ: p(0.075)/p(0.025) is Bekker's × 3^0.2."""
    big = _p_end(planted, series="size", radius_m=0.075)
    small = _p_end(planted, series="size", radius_m=0.025)
    bekker = (-9.8e3 / 0.075 + 1.2e6) / (-9.8e3 / 0.025 + 1.2e6)
    assert big / small == pytest.approx(bekker * 3**0.2, rel=0.01)


def test_grouser_side_walls_raise_apparent_c_and_phi(planted):
    flat = fit_shear(planted, series="walls", grouser_height_m=0.0)
    tall = fit_shear(planted, series="walls", grouser_height_m=0.01)
    a = side_wall_ratio(0.1, 0.15, 0.01)
    tan_ratio = math.tan(math.radians(tall.params["phi"])) / math.tan(
        math.radians(flat.params["phi"])
    )
    assert tan_ratio == pytest.approx(1 + 0.5 * a, rel=0.01)
    assert tall.params["c"] / flat.params["c"] == pytest.approx(1 + a, rel=0.25)
    assert flat.params["phi"] == pytest.approx(30.0, abs=0.3)


def test_planted_fit_recovers_velocity_factor_in_kphi(planted):
    """The velocity series has one plate size: Bernstein k ratio equals the planted factor."""
    slow = fit_sinkage(planted, "bernstein", series="vel", velocity_m_s=4.8e-4)
    fast = fit_sinkage(planted, "bernstein", series="vel", velocity_m_s=4.8e-3)
    assert slow.params["k"] / fast.params["k"] == pytest.approx(10**0.1, rel=0.02)


# --------------------------------------------------------------------------- SPEC errors
def _broken(edit):
    data = __import__("tomllib").loads(TINY)
    data = copy.deepcopy(data)
    edit(data)
    return data


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (lambda d: d.update(soil={}), r"top level\.soil.*unknown key 'soil'.*valid keys"),
        (lambda d: d["series"][0].update(kind="plate"), r"kind.*'plate'.*\['sinkage', 'shear'\]"),
        (lambda d: d["series"][0].update(soils=["s9"]), r"soils.*'s9'.*\['s1'\]"),
        (lambda d: d["series"][0].update(repetitons=3), r"repetitons.*valid keys"),
        (lambda d: d["soils"]["s1"].update(kphi="big"), r"soils\.s1\]\.kphi.*finite number"),
        (lambda d: d["soils"]["s1"].update(k_c=1.0), r"k_c.*valid keys"),
        (
            lambda d: d["series"][0]["plates"][0].update(shape="oval"),
            r"shape.*'oval'.*\['circle', 'rectangle'\]",
        ),
        (
            lambda d: d.update(
                effects=[
                    {"kind": "velocity", "parameters": "kp", "exponent": 1, "reference_m_s": 1}
                ]
            ),
            r"parameters.*'kp'.*\['kc', 'kphi', 'n', 'c', 'phi', 'K'\]",
        ),
        (
            lambda d: d.update(
                effects=[
                    {
                        "kind": "covariate",
                        "column": "bin",
                        "parameters": "c",
                        "levels": {"A": 1},
                        "slope": 1,
                    }
                ]
            ),
            r"exactly one of 'levels'.*'slope'",
        ),
        (lambda d: d.update(effects=[{"kind": "wind"}]), r"kind.*'wind'.*'side-walls'"),
        (lambda d: d.update(noise={"force": 1}), r"\[noise\]\.force.*valid keys"),
    ],
)
def test_malformed_spec_names_key_and_options(edit, match):
    with pytest.raises(ValueError, match=match):
        parse_spec(_broken(edit))


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        # The models' support (issue #44): each of these was simulated without a word.
        (lambda d: d["soils"]["s1"].update(n=0.0), r"\[soils\.s1\]\.n: .*n = 0 \(n <= 0"),
        (lambda d: d["soils"]["s1"].update(n=-0.5), r"n = -0\.5 \(n <= 0 \(bekker\)"),
        (lambda d: d["soils"]["s1"].update(kphi=0.0), r"kphi = 0 \(kphi outside \(0, inf\)"),
        (lambda d: d["soils"]["s1"].update(phi=95.0), r"phi = 95 \(phi outside \(0, 90\) deg"),
        (lambda d: d["soils"]["s1"].update(c=-1.0), r"\.c: .*c = -1 \(c < 0"),
        (
            lambda d: d["soils"]["s1"].update(conditions=[{"where": {"tool": "x"}, "phi": 90}]),
            r"conditions\[0\]\.phi: .*phi = 90",
        ),
        (
            lambda d: d.update(preparations={"rake": {"operator": "C"}}),
            r"\[preparations\.rake\]\.operator: 'C' is not an operator of series 'plates'",
        ),
        (
            lambda d: d.update(preparations={"rake": {"soil": "s2"}}),
            r"\[preparations\.rake\]\.soil: 'soil' is a column the design writes",
        ),
    ],
)
def test_impossible_spec_values_are_refused(edit, match):
    with pytest.raises(SpecError, match=match):
        parse_spec(_broken(edit))


def _effect(**options):
    return lambda d: d.update(effects=[options])


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (
            _effect(kind="covariate", column="moisture", parameters="c", slope=0.1),
            r"\[\[effects\]\]\[0\]\.column: 'moisture' is not a test-log column.*'tool'",
        ),
        (  # a planted effect pushing phi past 90 degrees at one level
            _effect(kind="covariate", column="tool", parameters="phi", levels={"tool04": 3.1}),
            r"test ring-0001 \(soil s1, series ring\) draws phi = 9\d\.\d+ \(phi outside",
        ),
        (  # kc/b + kphi < 0 on the narrow plate only
            lambda d: d["soils"]["s1"].update(kc=-4e4),
            r"test plates-0001 .* kc/b \+ kphi = -[0-9.e+]+ at b = 0\.025 m",
        ),
    ],
)
def test_impossible_effects_are_refused_when_simulated(edit, match):
    spec = parse_spec(_broken(edit))
    with pytest.raises(SpecError, match=match):
        simulate(spec, seed=1)


def test_spec_file_errors_are_value_errors(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("name = ")
    with pytest.raises(SpecError, match="not valid TOML"):
        load_spec(bad)
    with pytest.raises(SpecError, match="cannot read"):
        load_spec(tmp_path / "missing.toml")


def test_docs_example_spec_simulates():
    """The complete example of docs/simulator.md is a valid SPEC."""
    import re
    import tomllib

    doc = (Path(__file__).parents[1] / "docs" / "simulator.md").read_text()
    block = re.search(r"## A complete example\n\n```toml\n(.*?)```", doc, re.S).group(1)
    sim = simulate(parse_spec(tomllib.loads(block)), seed=1)
    assert set(sim.campaign.covariates) >= {"series", "bin", "moisture_pct", "loosening_tool"}
