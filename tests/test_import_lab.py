"""Import of a lab's own exports (docs/importing.md): one file per test, header values into
the test log, signs and unit slips refused unless the mapping states them, and every
malformed mapping or file answered by one clear error naming the file and the key.

The records are simulated with known values (p = k z^n on plates of known diameter), so
every imported number is checked against the value written into the lab's file."""

from __future__ import annotations

import hashlib
import json
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pytest

from soilstats.campaign import import_campaign
from soilstats.cli.main import main
from soilstats.errors import CampaignError

K, N_EXP = 8.0e5, 1.1  # Pa / m^n and the exponent of the simulated soil
PLATES_MM = {"A01": 100.0, "A02": 150.0, "B07": 200.0}


def _force_kN(z_mm: np.ndarray, diameter_mm: float) -> np.ndarray:
    area = np.pi * (diameter_mm / 2000.0) ** 2
    return K * (z_mm / 1000.0) ** N_EXP * area / 1000.0


def _export(folder: Path, *, sign: int = 1, decimal: str = ".", unit: str = "kN") -> Path:
    """A logger's per-test files: a four-line preamble (operator, date, plate diameter),
    then ``Time;Sinkage;Load`` in s, mm and kN (or N)."""
    records = folder / "records"
    records.mkdir()
    z = np.arange(1.0, 41.0) * 0.5  # mm
    for i, (test, diameter) in enumerate(PLATES_MM.items()):
        force = _force_kN(z, diameter) * (1000.0 if unit == "N" else 1.0) * sign
        lines = [
            "Bevameter logger v2 export",
            f"Operator: op{i % 2}",
            f"Date: 2026-11-2{i}",
            f"Plate diameter: {diameter:.1f} mm".replace(".", decimal),
            "Time;Sinkage;Load",
        ] + [
            f"{0.1 * j:.1f};{zj:.2f};{fj:.6f}".replace(".", decimal)
            for j, (zj, fj) in enumerate(zip(z, force, strict=True))
        ]
        (records / f"{test}.csv").write_text("\n".join(lines) + "\n")
    return records


_MAPPING = """
[tests]
[tests.constant]
kind = "sinkage"
shape = "circle"
soil = "loam"

[sinkage]
file = "{file}"
separator = ";"
skip_rows = 4
{extra}
[sinkage.columns]
z_m = {{ column = "Sinkage", unit = "mm" }}
force_N = {{ column = "Load", unit = "{unit}"{force_extra} }}
[sinkage.header]
radius_m = {{ pattern = "Plate diameter: *([0-9.,]+)", unit = "mm", diameter = true }}
operator = "Operator: *(.+)"
date = "Date: *(.+)"
"""


def _mapping(folder: Path, file="records", unit="kN", extra="", force_extra="") -> Path:
    path = folder / "lab.toml"
    path.write_text(
        textwrap.dedent(_MAPPING.format(file=file, unit=unit, extra=extra, force_extra=force_extra))
    )
    return path


def _check_values(campaign) -> None:
    tests = campaign.tests.set_index("test_id")
    assert sorted(tests.index) == sorted(PLATES_MM)  # the file stems
    for test, diameter in PLATES_MM.items():
        assert tests.loc[test, "radius_m"] == pytest.approx(diameter / 2000.0, rel=1e-12)
        record = campaign.samples(test)
        assert record["z_m"].iloc[3] == pytest.approx(0.002, rel=1e-12)
        expected = 1000.0 * round(float(_force_kN(np.array([2.0]), diameter)[0]), 6)
        assert record["force_N"].iloc[3] == pytest.approx(expected, rel=1e-12)
    assert tests.loc["A02", "operator"] == "op1" and tests.loc["B07", "date"] == "2026-11-22"
    assert list(campaign.sinkage.columns).count("Time") == 1  # unmapped: kept


def test_a_folder_of_per_test_files_imports_with_one_mapping(tmp_path):
    _export(tmp_path)
    _check_values(import_campaign(_mapping(tmp_path)))


def test_a_glob_of_per_test_files_imports_too(tmp_path):
    _export(tmp_path)
    (tmp_path / "records" / "notes.txt").write_text("not a record\n")
    _check_values(import_campaign(_mapping(tmp_path, file="records/*.csv")))


def test_a_decimal_comma_converts_numbers_and_header_values(tmp_path):
    _export(tmp_path, decimal=",")
    _check_values(import_campaign(_mapping(tmp_path, extra='decimal = ","')))


def test_a_negative_load_cell_imports_with_sign_minus_one(tmp_path):
    _export(tmp_path, sign=-1)
    _check_values(import_campaign(_mapping(tmp_path, force_extra=", sign = -1")))


def test_a_reversed_sign_is_refused_naming_the_column_and_the_fix(tmp_path, capsys):
    _export(tmp_path, sign=-1)
    mapping = _mapping(tmp_path)
    assert main(["import", str(mapping), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "'Load'" in err and "sign = -1" in err and "sinkage.columns.force_N" in err
    assert not (tmp_path / "out").exists()


def test_force_in_kilonewtons_mapped_as_newtons_is_refused_naming_kN(tmp_path, capsys):
    _export(tmp_path)  # the file holds kN; the mapping says nothing of the unit
    mapping = _mapping(tmp_path)
    text = mapping.read_text().replace(', unit = "kN"', "")
    mapping.write_text(text)
    assert main(["import", str(mapping), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "'Load'" in err and "kilonewtons" in err and "unit" in err


def test_import_json_records_sources_mapping_and_version(tmp_path, capsys):
    _export(tmp_path)
    mapping = _mapping(tmp_path)
    assert main(["import", str(mapping), "--out", str(tmp_path / "out")]) == 0
    record = json.loads((tmp_path / "out" / "import.json").read_text())
    assert record["soilstats_version"]
    assert record["mapping_sha256"] == hashlib.sha256(mapping.read_bytes()).hexdigest()
    assert record["mapping_document"]["sinkage"]["skip_rows"] == 4
    files = {Path(s["file"]).name: s["sha256"] for s in record["sources"]}
    assert set(files) == {f"{t}.csv" for t in PLATES_MM}
    a01 = tmp_path / "records" / "A01.csv"
    assert files["A01.csv"] == hashlib.sha256(a01.read_bytes()).hexdigest()


def test_skip_rows_on_the_command_line_overrides_the_mapping(tmp_path, capsys):
    _export(tmp_path)
    mapping = _mapping(tmp_path)
    mapping.write_text(mapping.read_text().replace("skip_rows = 4", "skip_rows = 1"))
    assert main(["import", str(mapping), "--out", str(tmp_path / "bad")]) == 2
    err = capsys.readouterr().err
    assert "skip_rows = 4" in err  # the N it found, named
    assert main(["import", str(mapping), "--skip-rows", "4", "--out", str(tmp_path / "o")]) == 0


def test_a_preamble_error_names_skip_rows_and_no_parser_warning_leaks(tmp_path):
    _export(tmp_path)
    mapping = _mapping(tmp_path)
    mapping.write_text(mapping.read_text().replace("skip_rows = 4", "skip_rows = 0"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(CampaignError, match=r"A01\.csv.*skip_rows = 4"):
            import_campaign(mapping)


def _single(tmp_path: Path, log: str, raw: str, tests_extra: str = "", columns: str = "") -> Path:
    (tmp_path / "log.csv").write_text(log)
    (tmp_path / "raw.csv").write_text(raw)
    path = tmp_path / "lab.toml"
    path.write_text(
        textwrap.dedent(
            f"""
            [tests]
            file = "log.csv"
            {tests_extra}
            [tests.columns]
            test_id = "Test"
            soil = "Soil"
            {columns or 'radius_m = { column = "D", unit = "mm", diameter = true }'}
            [tests.constant]
            kind = "sinkage"
            shape = "circle"
            [sinkage]
            file = "raw.csv"
            [sinkage.columns]
            test_id = "Test"
            z_m = {{ column = "z", unit = "mm" }}
            force_N = "F"
            """
        )
    )
    return path


_LOG = "Test,Soil,D,Moisture\nT,1,loam,100,12.5\n"
_RAW = "Test,z,F\n" + "".join(f"T,1,{z},{40 * z**1.1:.3f}\n" for z in range(1, 31))


def _ok(tmp_path, **kw) -> Path:
    log = kw.pop("log", "Test;Soil;D;Moisture;Note\nT,1;loam;100;12,5;a,b\n")
    raw = kw.pop("raw", _RAW.replace(",", ";").replace("T;1", "T,1"))
    mapping = _single(tmp_path, log, raw, **kw)
    text = mapping.read_text().replace('file = "raw.csv"', 'file = "raw.csv"\nseparator = ";"')
    mapping.write_text(text)
    return mapping


def test_decimal_touches_numeric_columns_only(tmp_path):
    mapping = _ok(tmp_path, tests_extra='separator = ";"\ndecimal = ","')
    campaign = import_campaign(mapping)
    row = campaign.tests.iloc[0]
    assert row["test_id"] == "T,1"  # an id keeps its comma
    assert float(row["Moisture"]) == 12.5  # a numeric covariate is converted
    assert row["Note"] == "a,b"  # text stays as written
    assert row["radius_m"] == pytest.approx(0.05)


@pytest.mark.parametrize(
    ("column", "says"),
    [
        ('radius_m = { column = "D", unit = "mm", diameter = "no" }', "true or false"),
        ('radius_m = { column = "D", unit = "mm", diameter = 1 }', "true or false"),
        ('radius_m = { column = "D", unit = "mm", sign = 2 }', "1 or -1"),
        (
            'radius_m = { column = "D", unit = "mm" }\nvelocity_m_s = { column = "Moisture", '
            "diameter = true }",
            "not a tool size",
        ),
        ('radius_m = { column = "D", unit = "mm" }\noperator = "D"', "mapped twice"),
    ],
)
def test_malformed_column_mappings_name_the_key(tmp_path, column, says):
    mapping = _ok(tmp_path, tests_extra='separator = ";"', columns=column)
    with pytest.raises(CampaignError, match=says) as info:
        import_campaign(mapping)
    assert "tests.columns" in str(info.value)


def test_a_diameter_flag_on_a_force_is_an_error_not_a_halving(tmp_path):
    mapping = _ok(tmp_path, tests_extra='separator = ";"')
    mapping.write_text(
        mapping.read_text().replace('force_N = "F"', 'force_N = { column = "F", diameter = true }')
    )
    with pytest.raises(CampaignError, match=r"sinkage\.columns\.force_N\.diameter.*not a tool"):
        import_campaign(mapping)


@pytest.mark.parametrize(
    ("log", "says"),
    [
        ("Test;Soil;D;D\nT,1;loam;100;5\n", "names the column 'D' twice"),
        ("Test;Soil;D;\nT,1;loam;100;5\n", "blank column name"),
    ],
)
def test_duplicate_or_blank_lab_headers_are_errors_naming_the_file(tmp_path, log, says):
    mapping = _ok(tmp_path, tests_extra='separator = ";"', log=log)
    with pytest.raises(CampaignError, match=says) as info:
        import_campaign(mapping)
    assert "log.csv" in str(info.value)


@pytest.mark.parametrize(
    ("setting", "says"),
    [
        ("skip_rows = 9223372036854775807", r"skip_rows = 9223372036854775807.*only \d+ lines"),
        ("separator = 5", "one character"),
        ('separator = ";;"', "one character"),
        ('decimal = ""', "one character"),
    ],
)
def test_malformed_table_settings_are_clear_errors(tmp_path, setting, says):
    mapping = _ok(tmp_path, tests_extra=setting)
    with pytest.raises(CampaignError, match=says):
        import_campaign(mapping)


def test_header_patterns_need_per_test_files_and_must_match(tmp_path):
    _export(tmp_path)
    mapping = _mapping(tmp_path)
    mapping.write_text(mapping.read_text().replace("Operator: *(.+)", "Operator = (.+)"))
    with pytest.raises(
        CampaignError, match=r"A01\.csv.*sinkage\.header\.operator.*matches nothing"
    ):
        import_campaign(mapping)


def test_the_test_id_can_come_from_a_header_line(tmp_path):
    records = _export(tmp_path)
    for path in records.iterdir():  # the id in the preamble, the file named otherwise
        text = path.read_text().replace("Bevameter logger v2 export", f"Test: lab-{path.stem}")
        (records / f"export_{path.stem}.csv").write_text(text)
        path.unlink()
    mapping = _mapping(tmp_path)
    mapping.write_text(
        mapping.read_text().replace(
            "[sinkage.header]\n", '[sinkage.header]\ntest_id = "Test: *(\\\\S+)"\n'
        )
    )
    campaign = import_campaign(mapping)
    assert sorted(campaign.tests["test_id"]) == sorted(f"lab-{t}" for t in PLATES_MM)
    radius = campaign.tests.set_index("test_id").loc["lab-B07", "radius_m"]
    assert radius == pytest.approx(0.1)


@pytest.mark.parametrize(
    "where", ["../records", "../records/*.csv", "../records/A01.csv", "abs", "link"]
)
def test_a_lab_file_outside_the_mappings_folder_is_refused_before_reading(
    tmp_path, monkeypatch, where
):
    # A mapping names the files beside it; `../../etc/passwd` used to be read, then refused
    # as a bad table. Now nothing outside the folder is opened, and the key is named.
    import soilstats.campaign.importing as importing

    records = _export(tmp_path)  # tmp_path/records: outside tmp_path/lab
    lab = tmp_path / "lab"
    lab.mkdir()
    if where == "abs":
        where = str(records / "A01.csv")
    elif where == "link":
        (lab / "records").symlink_to(records, target_is_directory=True)
        where = "records"
    read = []
    monkeypatch.setattr(importing, "_read", lambda *a, **k: read.append(a) or 1 / 0)
    with pytest.raises(CampaignError, match=r"sinkage\.file.*leads outside the mapping's folder"):
        import_campaign(_mapping(lab, file=where))
    assert read == []
    # The same files inside the folder import, to the values written.
    monkeypatch.undo()
    (lab / "records").unlink(missing_ok=True)
    records.rename(lab / "records")
    _check_values(import_campaign(_mapping(lab)))
