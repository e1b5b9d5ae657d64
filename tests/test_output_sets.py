"""An output set is one unit (issue #44, item 2): locked, staged, swapped in whole.

Every command with ``--out`` writes through :func:`soilstats.outputs.outset.output_set`; the
cases use ``simulate`` (fast, six files) and check the folder byte for byte against a run
that was not disturbed.
"""

from __future__ import annotations

import importlib
import json
import os
import socket
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from soilstats.cli.main import main
from soilstats.errors import SoilstatsWarning
from soilstats.outputs.outset import lock_path, output_set

SPEC = """
name = "tiny"
[soils.s1]
kc = 0.0
kphi = 1.2e6
n = 0.8
[[series]]
name = "plates"
kind = "sinkage"
soils = ["s1"]
plates = [{shape = "circle", radius_m = 0.05}]
repetitions = 2
points = 20
"""


@pytest.fixture
def spec(tmp_path) -> Path:
    path = tmp_path / "tiny.toml"
    path.write_text(SPEC)
    return path


def _files(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def _beside(out: Path) -> list[str]:
    """Hidden entries soilstats keeps beside --out (lock, stages): none once a run ended."""
    return sorted(p.name for p in out.parent.iterdir() if p.name.startswith(f".{out.name}."))


def _simulate(spec: Path, out: Path, seed: int, *extra: str) -> int:
    return main(["simulate", str(spec), "--out", str(out), "--seed", str(seed), *extra])


def test_a_run_leaves_its_set_and_nothing_beside_it(spec, tmp_path):
    out = tmp_path / "out"
    assert _simulate(spec, out, 1) == 0
    assert sorted(_files(out)) == [
        "README.md", "sinkage.csv", "tests.csv", "truth.json", "truth_tests.csv"
    ]  # fmt: skip
    assert _beside(out) == []
    mode = out.stat().st_mode & 0o777
    umask = os.umask(0)
    os.umask(umask)
    assert mode == 0o777 & ~umask  # a plain mkdir's permissions, not the stage's 0700


def test_a_crash_during_overwrite_leaves_the_whole_old_set(spec, tmp_path, monkeypatch):
    """9 of 19 injected crashes left old and new files mixed: one file is written last here
    (README.md) and fails; every file is still the first run's."""
    out = tmp_path / "out"
    (out).mkdir()
    (out / "notes.txt").write_text("mine")  # a file of the user's: kept
    assert _simulate(spec, out, 1) == 0
    before = _files(out)
    module = importlib.import_module("soilstats.simulation.simulate")

    def crash(self) -> str:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(module.SimulatedCampaign, "_readme", crash)
    assert _simulate(spec, out, 2, "--overwrite") == 2
    assert _files(out) == before
    assert _beside(out) == []
    monkeypatch.undo()
    assert _simulate(spec, out, 2, "--overwrite") == 0
    after = _files(out)
    assert after["notes.txt"] == b"mine" and after["tests.csv"] == before["tests.csv"]
    assert after["sinkage.csv"] != before["sinkage.csv"]  # seed 2: the new set, whole


def test_a_run_that_writes_nothing_makes_no_folder(spec, tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(SPEC.replace("n = 0.8", "n = -1"))
    out = tmp_path / "out"
    assert _simulate(bad, out, 1) == 2
    assert not out.exists() and _beside(out) == []


def _holder(out: Path, seconds: float) -> subprocess.Popen:
    """Another process holding ``out`` as a soilstats run would, for ``seconds``."""
    code = textwrap.dedent(
        f"""
        import sys, time
        from soilstats.outputs.outset import output_set
        with output_set({str(out)!r}, command="soilstats posterior --seed 1", overwrite=False):
            print("held", flush=True)
            time.sleep({seconds})
        """
    )
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).parents[1])}
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, env=env)
    assert proc.stdout is not None and proc.stdout.readline().strip() == b"held"
    proc.stdout.close()
    return proc


def test_a_concurrent_run_on_the_same_out_refuses_naming_the_other(spec, tmp_path, capsys):
    """Two posterior runs on one fresh folder both exited 0 and mixed their sets."""
    out = tmp_path / "out"
    holder = _holder(out, 30)
    try:
        assert _simulate(spec, out, 2) == 2
        err = capsys.readouterr().err
        assert f"is being written by another soilstats run (pid {holder.pid} on " in err
        assert "soilstats posterior --seed 1" in err and "Traceback" not in err
        assert not out.exists()  # the holder wrote nothing yet; the refused run nothing
    finally:
        holder.kill()
        holder.wait()


@pytest.mark.filterwarnings("default::soilstats.errors.SoilstatsWarning")
def test_a_killed_runs_lock_stage_and_temporaries_are_removed_and_named(spec, tmp_path, capsys):
    out = tmp_path / "out"
    holder = _holder(out, 30)
    holder.kill()  # SIGKILL: its lock and stage stay behind
    holder.wait()
    assert (lock := lock_path(out)).exists()
    assert any("stage" in n for n in _beside(out))
    out.mkdir()
    (out / ".tests.csv.0123456789ab.tmp.csv").write_text("half")  # an older version's
    assert _simulate(spec, out, 1) == 0
    said = capsys.readouterr().err  # the CLI shows soilstats' warnings as "warning: ..."
    stale = "removed the stale lock of a soilstats run that ended without releasing --out"
    assert f"{stale} (pid {holder.pid}, soilstats posterior --seed 1" in said
    assert "the unfinished output set of an interrupted run" in said
    assert ".tests.csv.0123456789ab.tmp.csv', a temporary file an interrupted run left" in said
    assert _beside(out) == [] and not lock.exists()
    assert not (out / ".tests.csv.0123456789ab.tmp.csv").exists()


def test_existence_is_checked_again_at_commit(spec, tmp_path, monkeypatch, capsys):
    """Checked before the work and written with overwrite on, a file made meanwhile by
    someone else was replaced silently. Now the run is refused and that file kept."""
    out = tmp_path / "out"
    module = importlib.import_module("soilstats.simulation.simulate")

    real = module.SimulatedCampaign._readme

    def readme(self) -> str:  # the last file: every check of the run is behind it
        (out / "truth.json").write_text("someone else's")
        return real(self)

    out.mkdir()
    monkeypatch.setattr(module.SimulatedCampaign, "_readme", readme)
    assert _simulate(spec, out, 1) == 2
    assert "truth.json: appeared in --out while this run was writing" in capsys.readouterr().err
    assert _files(out) == {"truth.json": b"someone else's"} and _beside(out) == []


def test_a_set_moved_aside_by_an_interrupted_swap_is_restored(tmp_path):
    """Without renameat2 the swap is two renames; killed between them, DIR is missing and
    the old set whole under .DIR.soilstats-old-*: the next run puts it back."""
    out = tmp_path / "out"
    aside = tmp_path / ".out.soilstats-old-x1"
    aside.mkdir()
    (aside / "a.csv").write_text("old")
    with pytest.warns(SoilstatsWarning, match="restored .*out' from .out.soilstats-old-x1"):
        with output_set(out, command="t", overwrite=False):
            pass
    assert (out / "a.csv").read_text() == "old" and _beside(out) == []


def test_out_the_working_folder_is_written_in_place(spec, tmp_path, monkeypatch):
    """Swapping the working folder would leave the shell in a removed one."""
    out = tmp_path / "here"
    out.mkdir()
    monkeypatch.chdir(out)
    assert main(["simulate", str(spec), "--out", ".", "--seed", "1"]) == 0
    assert Path.cwd().samefile(out) and (out / "tests.csv").is_file()
    assert _beside(out) == []


def test_the_lock_records_the_run(tmp_path):
    out = tmp_path / "out"
    with output_set(out, command="soilstats x", overwrite=False):
        record = json.loads(lock_path(out).read_text())
        assert record["pid"] == os.getpid() and record["command"] == "soilstats x"
        assert record["host"] == socket.gethostname()
        assert (
            abs(
                time.time()
                - time.mktime(time.strptime(record["started"], "%Y-%m-%dT%H:%M:%SZ"))
                + time.timezone
            )
            < 120
        )
    assert not lock_path(out).exists()
