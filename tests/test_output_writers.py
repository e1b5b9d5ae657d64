"""Writers under hostile output folders and cells: links, formulas, line breaks, failures.

Every file soilstats writes into ``--out`` goes through ``soilstats.outputs.files``: never
through a symbolic link (dangling or not), always through a temporary file renamed into
place, and CSV cells made safe for spreadsheets and for ``pandas.read_csv(comment="#")``.
"""

from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import soilstats
from soilstats.campaign import Campaign, load_campaign
from soilstats.cli.main import main
from soilstats.outputs import Provenance, write_atomic, write_csv, write_json
from soilstats.outputs import files as output_files


@pytest.fixture
def outside(tmp_path: Path) -> Path:
    """A folder beside ``--out``, which nothing may write into."""
    folder = tmp_path / "outside"
    folder.mkdir()
    return folder


def _provenance(*argv: str) -> Provenance:
    return Provenance.of(None, argv=list(argv) or None)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


# --- links inside --out -------------------------------------------------------------------


@pytest.mark.parametrize("name", ["identify.json", "identify.csv", "identify.pdf"])
def test_a_dangling_link_in_out_is_refused_and_its_target_never_made(
    name, tmp_path, outside, capsys
):
    out = tmp_path / "out"
    out.mkdir()
    (out / name).symlink_to(outside / "made")
    argv = ["identify", "cullinan-sand", "--out", str(out), "--progress", "off"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"{out / name}: is a symbolic link (to '{outside / 'made'}', dangling)" in err
    assert "Traceback" not in err
    assert not list(outside.iterdir())
    assert (out / name).is_symlink()


def test_a_link_to_a_file_outside_is_never_overwritten(tmp_path, outside, capsys):
    victim = outside / "victim.json"
    victim.write_text("keep")
    out = tmp_path / "out"
    out.mkdir()
    (out / "check.json").symlink_to(victim)
    assert main(["check", "cullinan-sand", "--out", str(out), "--overwrite"]) == 2
    assert "is a symbolic link" in capsys.readouterr().err
    assert victim.read_text() == "keep" and (out / "check.json").is_symlink()


def test_out_itself_may_be_a_link_to_a_folder_but_not_a_dangling_one(tmp_path, outside, capsys):
    link = tmp_path / "out"
    link.symlink_to(outside)
    assert main(["check", "cullinan-sand", "--out", str(link)]) == 0
    assert (outside / "check.json").is_file()
    dangling = tmp_path / "gone"
    dangling.symlink_to(tmp_path / "nowhere")
    assert main(["check", "cullinan-sand", "--out", str(dangling)]) == 2
    assert "is a dangling symbolic link" in capsys.readouterr().err
    assert not (tmp_path / "nowhere").exists()


def test_saving_a_campaign_never_writes_through_a_link(tmp_path, outside):
    campaign = load_campaign("cullinan-sand")
    folder = tmp_path / "c"
    folder.mkdir()
    (folder / "sinkage.csv").symlink_to(outside / "sinkage.csv")
    with pytest.raises(OSError, match="is a symbolic link"):
        campaign.save(folder, overwrite=True)
    assert not list(outside.iterdir())
    assert sorted(p.name for p in folder.iterdir()) == ["sinkage.csv"]  # nothing written


def test_a_simulation_refuses_a_link_before_writing_anything(tmp_path, outside):
    from soilstats.simulation import simulate

    folder = tmp_path / "sim"
    folder.mkdir()
    (folder / "truth.json").symlink_to(outside / "truth.json")
    spec = Path(soilstats.__file__).parent / "data" / "simulated-paper" / "spec.toml"
    with pytest.raises(OSError, match="is a symbolic link"):
        simulate(spec, seed=1).save(folder, overwrite=True)
    assert not list(outside.iterdir())
    assert [p.name for p in folder.iterdir()] == ["truth.json"]


# --- CSV cells ------------------------------------------------------------------------------


def test_formula_cells_are_escaped_and_numbers_never_altered(tmp_path):
    texts = ['=HYPERLINK("x")', "+1", "-2", "@SUM(A1)", "\tx", "\rx", "plain", "a-b"]
    frame = pd.DataFrame(
        {"name": texts, "value": np.linspace(-3.5, 3.5, len(texts)), "n": range(-4, 4)}
    )
    frame["mixed"] = pd.Series([-1.5, "-x", 2, None, "=1", 0.0, "ok", -7], dtype=object)
    path = write_csv(tmp_path / "t.csv", frame.rename(columns={"n": "=n"}), _provenance())
    back = pd.read_csv(path, comment="#", keep_default_na=False)
    assert list(back["name"]) == ["'" + t if t[0] in "=+-@\t\r" else t for t in texts]
    assert back["value"].tolist() == frame["value"].tolist()  # negative numbers stay numbers
    assert back["'=n"].tolist() == list(range(-4, 4))  # a column name is text too
    assert list(back["mixed"]) == ["-1.5", "'-x", "2", "", "'=1", "0.0", "ok", "-7"]


def test_formula_escaping_is_reversible():
    cells = ["=1", "'=1", "''@x", "-x", "'plain", "it's", "", "a=b"]
    escaped = [output_files.escape_formula(c) for c in cells]
    assert escaped == ["'=1", "''=1", "'''@x", "'-x", "'plain", "it's", "", "a=b"]
    assert [output_files.unescape_formula(c) for c in escaped] == cells


HOSTILE_CELLS = ['=HYPERLINK("http://x")', "@SUM(A1)", "+cmd", "-x", "'=kept"]


def test_campaign_files_of_import_and_simulate_escape_formulas_and_read_back_exactly(
    tmp_path, campaign_frames
):
    """Campaign CSVs (what import and simulate write, through Campaign.save) were written raw:
    a soil named =HYPERLINK(...) ran as a formula in a spreadsheet. Escaped now, and
    load_campaign reads the very cells back."""
    tests = campaign_frames["tests"]
    tests["bin"] = HOSTILE_CELLS[:3]
    tests["soil"] = [*HOSTILE_CELLS[3:], "loam"]
    campaign = Campaign.from_frames(**campaign_frames)
    assert campaign.tests["soil"].iloc[1] == "'=kept"
    saved = campaign.save(tmp_path / "saved")
    raw = pd.read_csv(saved / "tests.csv", dtype=str, keep_default_na=False)
    assert list(raw["bin"]) == ["'" + c for c in HOSTILE_CELLS[:3]]
    assert list(raw["soil"]) == ["'-x", "''=kept", "loam"]
    back = load_campaign(saved)
    assert list(back.tests["bin"]) == HOSTILE_CELLS[:3]
    assert list(back.tests["soil"]) == [*HOSTILE_CELLS[3:], "loam"]
    assert back.sinkage.equals(campaign.sinkage)  # numbers (negative ones too) untouched


def test_simulation_truth_tables_escape_formulas(tmp_path):
    from soilstats.simulation import parse_spec, simulate

    spec = {
        "soils": {"=s1": {"kc": 0.0, "kphi": 1e6, "n": 1.0}},
        "series": [{"name": "@p", "kind": "sinkage", "soils": ["=s1"], "points": 10,
                    "plates": [{"shape": "circle", "radius_m": 0.05}]}],
    }  # fmt: skip
    folder = simulate(parse_spec(spec), seed=1).save(tmp_path / "sim")
    truth = pd.read_csv(folder / "truth_tests.csv", dtype=str)
    assert set(truth["soil"]) == {"'=s1"} and set(truth["series"]) == {"'@p"}
    assert set(load_campaign(folder).tests["soil"]) == {"=s1"}


def test_line_breaks_hashes_commas_and_quotes_in_cells_read_back_whole(tmp_path):
    cells = ["two\nlines", "cr\rinside", "bin #3", 'say "hi", twice', "", "#start"]
    frame = pd.DataFrame({"note": cells, "x": [1.0, 2.0, np.nan, 4.0, 5.0, 6.0]})
    path = write_csv(tmp_path / "t.csv", frame, _provenance())
    back = pd.read_csv(path, comment="#")
    assert back.shape == frame.shape
    assert back["note"].fillna("").tolist() == cells
    pd.testing.assert_series_equal(back["x"], frame["x"])
    one = write_csv(tmp_path / "one.csv", frame[["note"]], _provenance())
    assert len(pd.read_csv(one, comment="#")) == len(cells)  # the empty cell is a row too


def test_a_command_line_with_a_line_break_stays_in_its_comment_line(tmp_path):
    provenance = _provenance("identify", "--select", "soil=a\nb", "--out", "x\ry")
    frame = pd.DataFrame({"a": [1, 2]})
    path = write_csv(tmp_path / "t.csv", frame, provenance)
    lines = path.read_text(encoding="utf-8").split("\n")
    comments = [ln for ln in lines if ln.startswith("#")]
    assert len(comments) == len(provenance.lines())
    assert lines[len(comments)] == "a"  # the header follows the comments directly
    assert "soil=a\\nb" in path.read_text() and "x\\ry" in path.read_text()
    pd.testing.assert_frame_equal(pd.read_csv(path, comment="#"), frame)


# --- atomic writes ------------------------------------------------------------------------


def test_a_failing_serialiser_leaves_the_old_file_and_no_temporary(tmp_path, monkeypatch):
    path = write_csv(tmp_path / "t.csv", pd.DataFrame({"a": [1]}), _provenance())
    before = path.read_bytes()

    def broken(*args, **kwargs):
        raise RuntimeError("serialiser failed")

    monkeypatch.setattr(output_files, "csv_text", broken)
    with pytest.raises(RuntimeError, match="serialiser failed"):
        write_csv(path, pd.DataFrame({"a": [2]}), _provenance(), overwrite=True)
    monkeypatch.setattr(output_files.json, "dumps", broken)
    with pytest.raises(RuntimeError, match="serialiser failed"):
        write_json(tmp_path / "t.json", {"a": 1}, _provenance())
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["t.csv"]


def test_a_write_that_fails_midway_leaves_no_partial_file(tmp_path):
    path = tmp_path / "posterior.nc"
    path.write_bytes(b"old")

    def half(tmp: Path) -> None:
        tmp.write_bytes(b"half of a ")
        raise OSError(28, "No space left on device")

    with pytest.raises(OSError, match="No space left"):
        write_atomic(path, half)
    assert path.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["posterior.nc"]


def test_a_campaign_save_that_fails_leaves_the_folder_as_it_was(tmp_path, monkeypatch):
    from soilstats.campaign import io as campaign_io

    campaign = load_campaign("cullinan-sand")
    folder = campaign.save(tmp_path / "c")
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    real = campaign_io.write_table

    def fails_on_sinkage(frame, path, fmt):
        real(frame, path, fmt)
        if "sinkage" in path.name:
            raise OSError(28, "No space left on device")

    monkeypatch.setattr(campaign_io, "write_table", fails_on_sinkage)
    with pytest.raises(OSError, match="No space left"):
        campaign.select(preparation="1").save(folder, format="parquet", overwrite=True)
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before


def test_outputs_get_the_permissions_of_a_plain_write(tmp_path):
    path = write_json(tmp_path / "t.json", {"a": 1}, _provenance())
    assert path.stat().st_mode & 0o777 == 0o666 & ~_umask()


def test_the_no_silent_overwrite_rule_holds(tmp_path):
    path = write_json(tmp_path / "t.json", {"a": 1}, _provenance())
    with pytest.raises(FileExistsError):
        write_json(path, {"a": 2}, _provenance())
    write_json(path, {"a": 3}, _provenance(), overwrite=True)
    assert '"a": 3' in path.read_text()


def test_report_csv_reads_back_as_documented():
    """The README's recipe: pandas.read_csv(path, comment="#")."""
    text = output_files.csv_text(pd.DataFrame({"a": ["x#y"], "b": [-1.0]}))
    assert pd.read_csv(io.StringIO(text), comment="#").to_dict("list") == {
        "a": ["x#y"],
        "b": [-1.0],
    }


# --- a full disk, a table too large ------------------------------------------------------------


def _full_disk_after(monkeypatch, n_bytes: int) -> None:
    """Every write stops with ENOSPC after ``n_bytes`` bytes reached the file."""
    import errno

    def write(path, data):
        Path(path).write_bytes(data[:n_bytes])
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(output_files, "_write_bytes", write)


def test_a_full_disk_is_a_clear_error_and_leaves_the_old_file(tmp_path, monkeypatch):
    path = write_atomic(tmp_path / "t.json", '{"old": 1}\n')
    _full_disk_after(monkeypatch, 3)
    with pytest.raises(OSError, match=r"no space left to write t\.json into .*nothing of it"):
        write_atomic(path, '{"new": 2}\n' * 1000)
    assert path.read_text() == '{"old": 1}\n'
    assert [p.name for p in tmp_path.iterdir()] == ["t.json"]  # no temporary left


def test_netcdf_is_built_in_memory_and_reads_back(tmp_path):
    """No HDF5 handle on a file: a full disk cannot leave one half-closed (h5py segfaulted
    freeing it at exit). The bytes are deterministic and ArviZ reads them back exactly."""
    from soilstats.bayes._arviz import az

    rng = np.random.default_rng(3)
    idata = az.from_dict(
        posterior={"kc": rng.normal(size=(4, 50)), "n": rng.uniform(size=(4, 50))},
        observed_data={"y": rng.normal(size=7)},
    )
    idata.posterior.attrs["note"] = "x"
    blob = output_files.netcdf_bytes(idata)
    assert blob == output_files.netcdf_bytes(idata)
    back = az.from_netcdf(write_atomic(tmp_path / "p.nc", blob))
    assert set(back.groups()) == {"posterior", "observed_data"}
    np.testing.assert_array_equal(back.posterior["kc"], idata.posterior["kc"])
    assert back.posterior.attrs["note"] == "x"


def test_a_parquet_table_beyond_the_memory_budget_is_refused_from_its_footer(
    tmp_path, monkeypatch, write_campaign, campaign_frames
):
    """A compression bomb: 2 M zero rows are a few kB of gzip pages and ~150 MB in memory. The
    footer's sizes are checked before a page is read (Arrow ran out of memory)."""
    pytest.importorskip("pyarrow")
    from soilstats.errors import CampaignError

    folder = write_campaign(**campaign_frames)
    zeros = pd.DataFrame({"test_id": ["c1"] * 2_000_000, "z_m": 0.0, "force_N": 0.0})
    (folder / "sinkage.csv").unlink()
    zeros.to_parquet(folder / "sinkage.parquet", compression="gzip", index=False)
    assert (folder / "sinkage.parquet").stat().st_size < 200_000
    monkeypatch.setenv("SOILSTATS_MEMORY_BUDGET_GB", "0.05")  # 51 MiB
    monkeypatch.setattr(pd, "read_parquet", lambda *a, **k: pytest.fail("read the pages"))
    says = r"reading sinkage\.parquet \(2000000 rows of 3 columns\)"
    with pytest.raises(CampaignError, match=says) as err:
        load_campaign(folder)
    assert err.value.file == "sinkage.parquet" and "beyond the budget of 0.05 GiB" in str(err.value)
