"""``soilstats.outputs.output_set`` from Python: library writes made one set, as a command's.

Each test writes a whole old set, then a new one inside the block, and checks the folder
against what was written byte for byte: all new after a clean block, all old (and no stage
or lock left beside it) after an exception, and a second writer on the same folder refused.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from soilstats.campaign import Campaign
from soilstats.errors import CampaignError, InputError
from soilstats.outputs import output_set, write_atomic
from soilstats.outputs.outset import lock_path


def _write_set(out: Path, tag: str, campaign: Campaign) -> None:
    out.mkdir(exist_ok=True)  # the writers write into a folder; they do not make it
    write_atomic(out / "a.txt", f"{tag} a\n")
    write_atomic(out / "b.csv", f"tag\nset {tag}\n")
    campaign.save(out / "data", overwrite=True)


def _contents(out: Path) -> dict[str, bytes]:
    return {str(p.relative_to(out)): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}


@pytest.fixture
def campaign(campaign_frames) -> Campaign:
    return Campaign.from_frames(**campaign_frames)


def test_a_clean_block_replaces_the_whole_set(tmp_path, campaign):
    out = tmp_path / "out"
    _write_set(out, "old", campaign)
    with output_set(out, overwrite=True) as folder:
        assert folder == out
        _write_set(out, "new", campaign)
        assert (out / "a.txt").read_text() == "old a\n"  # nothing visible before the end
    assert (out / "a.txt").read_text() == "new a\n"
    assert "set new" in (out / "b.csv").read_text()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # no stage, no lock


def test_an_exception_in_the_block_leaves_the_whole_old_set(tmp_path, campaign):
    out = tmp_path / "out"
    _write_set(out, "old", campaign)
    before = _contents(out)
    with pytest.raises(RuntimeError, match="between two files"), output_set(out, overwrite=True):
        write_atomic(out / "a.txt", "new a\n")
        raise RuntimeError("a crash between two files")
    assert _contents(out) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_without_overwrite_an_existing_file_is_refused_and_nothing_changes(tmp_path, campaign):
    out = tmp_path / "out"
    _write_set(out, "old", campaign)
    before = _contents(out)
    with pytest.raises(CampaignError, match="already holds"), output_set(out):
        write_atomic(out / "new.txt", "x")
        campaign.save(out / "data")  # refuses: the folder holds a campaign
    assert _contents(out) == before


def test_a_second_writer_on_the_same_folder_is_refused_naming_the_first(tmp_path):
    out = tmp_path / "out"
    with output_set(out, command="python make_report.py"):
        with pytest.raises(InputError, match=rf"pid {os.getpid()}.*make_report"):
            with output_set(out):
                pass
        write_atomic(out / "a.txt", "one")
    assert (out / "a.txt").read_text() == "one"
    assert not lock_path(out).exists()
