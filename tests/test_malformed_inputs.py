"""Hostile and malformed campaigns: one clear error each, through the API and the command line.

Every case builds a broken campaign from the valid one of conftest, then checks that

* ``load_campaign`` raises one :class:`CampaignError` whose attributes name the file, the
  column, the test and the row (where they exist), in a message of one line;
* ``soilstats check DIR`` exits 2 with that message as its only line on stderr, and no
  traceback;
* nothing blocks (a FIFO where a table belongs), and nothing is rounded or dropped silently
  (the skip-mode cases at the end).

The table grows with each malformed input found: add a row, never a special test.
"""

from __future__ import annotations

import os
import re
import signal
import stat
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pandas as pd
import pytest

from soilstats.campaign import load_campaign
from soilstats.cli.main import main
from soilstats.errors import CampaignError, SoilstatsWarning

# Row numbers of the conftest campaign: tests.csv c1=1, r1=2, s1=3; sinkage.csv rows
# c1=1,2,4 and r1=3,5; shear.csv s1=1,2.
BIG = "x" * (140 * 1024)  # 140 KiB: beyond the csv module's field limit (128 KiB)
Build = Callable[[Path], None]
SERIALS = [1, 2**60 + 1, 3]  # an int64 covariate: the second beyond what float64 holds


def edit(name: str, old: str, new: str) -> Build:
    """Replace the first ``old`` by ``new`` in the campaign file ``name``."""

    def build(folder: Path) -> None:
        path = folder / name
        text = path.read_text(encoding="utf-8")
        assert old in text, (name, old)
        path.write_text(text.replace(old, new, 1), encoding="utf-8")

    return build


def write(name: str, content: bytes) -> Build:
    def build(folder: Path) -> None:
        (folder / name).write_bytes(content)

    return build


def re_encode(name: str, encoding: str, old: str = "", new: str = "") -> Build:
    def build(folder: Path) -> None:
        path = folder / name
        path.write_bytes(path.read_text(encoding="utf-8").replace(old, new, 1).encode(encoding))

    return build


def instead(name: str, make: Callable[[Path], object]) -> Build:
    """Put ``make(path)`` (a folder, a FIFO, a link) where the file ``name`` belongs."""

    def build(folder: Path) -> None:
        path = folder / name
        if path.exists():
            path.unlink()
        make(path)

    return build


def as_parquet(stem: str, change: Callable[[pd.DataFrame], pd.DataFrame]) -> Build:
    """Store table ``stem`` as typed Parquet (numbers as numbers), changed by ``change``."""

    def build(folder: Path) -> None:
        csv = folder / f"{stem}.csv"
        frame = pd.read_csv(csv, keep_default_na=False, dtype={"test_id": str})
        csv.unlink()
        change(frame).to_parquet(folder / f"{stem}.parquet")

    return build


def setting(column: str, row: int, value) -> Callable[[pd.DataFrame], pd.DataFrame]:
    """Set one cell, keeping the column's type (an int64 column stays int64)."""

    def change(frame: pd.DataFrame) -> pd.DataFrame:
        frame = frame.copy()
        if isinstance(value, str):
            frame[column] = frame[column].astype(object)
        frame.loc[row - 1, column] = value
        return frame

    return change


def repetition(value: str) -> Build:
    """Set c1's repetition (tests.csv row 1)."""
    return edit("tests.csv", "loam,1,circle", f"loam,{value},circle")


def beside(suffix: str, make: Callable[[Path], object]) -> Callable[[Path], object]:
    """``make`` the same stem with another suffix (shear.parquet instead of shear.csv)."""
    return lambda path: make(path.with_suffix(suffix))


def _link_loop(path: Path) -> None:
    os.symlink(path.name, path)


@dataclass(frozen=True)
class Case:
    id: str
    build: Build
    file: str | None
    column: str | None
    test: str | None
    row: int | None
    says: str


# One row per malformed input: what is built, and what the one-line error must name.
# fmt: off
CASES = [
    # --- cells of hostile size: an error by file, column and row, never a csv traceback ----
    Case("huge-test-id", edit("tests.csv", "c1,sinkage", f"{BIG},sinkage"),
         "tests.csv", "test_id", None, 1, "characters long"),
    Case("huge-number", edit("sinkage.csv", "c1,0.001,10", f"c1,0.001,0.{BIG.replace('x', '1')}"),
         "sinkage.csv", "force_N", "c1", 2, "characters long"),
    Case("huge-cell-in-a-long-row", edit("sinkage.csv", "c1,0.001,10", f"c1,0.001,10,{BIG}"),
         "sinkage.csv", None, None, 2, "longer than 4096 characters"),
    Case("huge-cell-behind-an-open-quote", edit("sinkage.csv", "c1,0.001,10", f'c1,0.001,"{BIG}'),
         "sinkage.csv", None, None, 2, "is never closed"),
    Case("huge-column-name", edit("tests.csv", ",bin\n", f",{BIG}\n"),
         "tests.csv", BIG, None, None, "characters long"),
    # --- files that are not CSV ---------------------------------------------------------------
    Case("open-quote", edit("sinkage.csv", "r1,0.0,0.0", 'r1,"0.0,0.0'),
         "sinkage.csv", None, None, 3, "is never closed"),
    Case("empty-file", write("shear.csv", b""), "shear.csv", None, None, None, "the file is empty"),
    Case("utf-16", re_encode("tests.csv", "utf-16"), "tests.csv", None, None, None, "UTF-16"),
    Case("latin-1", re_encode("tests.csv", "latin-1", "loam", "lém"),
         "tests.csv", None, None, None, "byte 0xe9 on line 2 is not UTF-8"),
    # --- control characters in ids and names: refused, never matched or dropped quietly ------
    Case("nul-in-log-id", edit("tests.csv", "c1,sinkage", "c1\x00,sinkage"),
         "tests.csv", "test_id", "c1\x00", 1, "control character (U+0000)"),
    Case("nul-in-sample-id", edit("sinkage.csv", "c1,0.001,10", "c1\x00,0.001,10"),
         "sinkage.csv", "test_id", "c1", 2, "control character (U+0000)"),
    Case("line-break-in-soil", edit("tests.csv", "c1,sinkage,loam", 'c1,sinkage,"lo\nam"'),
         "tests.csv", "soil", "c1", 1, "control character (U+000A)"),
    Case("tab-in-sample-id", edit("shear.csv", "s1,0.1", "s1\t,0.1"),
         "shear.csv", "test_id", "s1", 2, "control character (U+0009)"),
    # --- numbers float64 would change: refused, never rounded ---------------------------------
    Case("repetition-beyond-2^53", repetition("9007199254740993"),
         "tests.csv", "repetition", "c1", 1, "would be read as 9007199254740992"),
    Case("repetition-at-2^53", repetition("9007199254740992"),
         "tests.csv", "repetition", "c1", 1, "is not below 2^53"),
    Case("repetition-1e300", repetition("1e300"),
         "tests.csv", "repetition", "c1", 1, "is not below 2^53"),
    Case("repetition-not-whole", repetition("1.0000000000000001"),
         "tests.csv", "repetition", "c1", 1, "not a whole number (float64 would read it as 1.0)"),
    Case("grousers-beyond-2^53", edit("tests.csv", "0.15,10,", "0.15,9007199254740993,"),
         "tests.csv", "grousers", "s1", 3, "beyond 2^53"),
    Case("covariate-beyond-2^53", edit("tests.csv", ",12.5,", ",12345678901234567,"),
         "tests.csv", "moisture_pct", "c1", 1, "would be read as 12345678901234568"),
    Case("sample-beyond-2^53", edit("sinkage.csv", "r1,0.001,20", "r1,0.001,9007199254740993"),
         "sinkage.csv", "force_N", "r1", 5, "beyond 2^53"),
    Case("sample-underflow", edit("sinkage.csv", "c1,0.002,30.5", "c1,0.002,1e-400"),
         "sinkage.csv", "force_N", "c1", 4, "too small for float64 and would be read as 0"),
    # --- finite inputs whose derived quantity is not finite ----------------------------------
    Case("radius-1e-200", edit("tests.csv", "circle,0.05", "circle,1e-200"),
         "tests.csv", "area_m2", "c1", 1, "plate area is 0.0 in float64 for radius_m 1e-200"),
    Case("rectangle-underflow", edit("tests.csv", "rectangle,,0.1,0.3", "rectangle,,1e-200,1e-200"),
         "tests.csv", "area_m2", "r1", 2, "plate area is 0.0"),
    Case("aspect-ratio-overflow", edit("tests.csv", "rectangle,,0.1,0.3", "rectangle,,1e-300,1e10"),
         "tests.csv", "aspect_ratio", "r1", 2, "is inf"),
    Case("ring-area-underflow", edit("tests.csv", "0.1,0.15,10", "0,1e-200,10"),
         "tests.csv", "ring_area_m2", "s1", 3, "ring area"),
    Case("force-1e308", edit("sinkage.csv", "c1,0.001,10", "c1,0.001,1e308"),
         "sinkage.csv", "pressure_Pa", "c1", 2, "p = force_N / area_m2 (Eq. 6) is inf"),
    Case("torque-1e308", edit("shear.csv", "s1,0.1,40", "s1,0.1,1e308"),
         "shear.csv", "tau_Pa", "s1", 2, "is inf in float64 for torque_Nm 1e+308"),
    Case("normal-force-1e308", edit("shear.csv", "s1,0.0,0.0,500", "s1,0.0,0.0,1e308"),
         "shear.csv", "sigma_Pa", "s1", 1, "is inf"),
    # --- something other than a file where a table belongs --------------------------------
    Case("sinkage-is-a-directory", instead("sinkage.csv", Path.mkdir),
         "sinkage.csv", None, None, None, "sinkage.csv in '{folder}' is a directory"),
    Case("sinkage-is-a-fifo", instead("sinkage.csv", os.mkfifo),
         "sinkage.csv", None, None, None, "is a FIFO (named pipe), not a regular file"),
    Case("sinkage-is-a-symlink-loop", instead("sinkage.csv", _link_loop),
         "sinkage.csv", None, None, None, "is a symlink loop"),
    Case("sinkage-is-a-dangling-link", instead("sinkage.csv", lambda p: os.symlink("gone.csv", p)),
         "sinkage.csv", None, None, None, "is a dangling symlink (to 'gone.csv'"),
    Case("sinkage-is-a-device", instead("sinkage.csv", lambda p: os.symlink(os.devnull, p)),
         "sinkage.csv", None, None, None, "is a symlink to a character device"),
    Case("tests-is-a-directory", instead("tests.csv", Path.mkdir),
         "tests.csv", None, None, None, "tests.csv in '{folder}' is a directory"),
    Case("tests-is-a-fifo", instead("tests.csv", os.mkfifo),
         "tests.csv", None, None, None, "is a FIFO (named pipe)"),
    Case("parquet-dataset-folder", instead("shear.csv", beside(".parquet", Path.mkdir)),
         "shear.parquet", None, None, None, "shear.parquet in '{folder}' is a directory"),
    Case("parquet-fifo", instead("shear.csv", beside(".parquet", os.mkfifo)),
         "shear.parquet", None, None, None, "is a FIFO"),
    # --- the same rules on typed Parquet tables ------------------------------------------------
    Case("parquet-repetition-beyond-2^53", as_parquet("tests", setting("repetition", 1, 2**53 + 1)),
         "tests.parquet", "repetition", "c1", 1, "value '9007199254740993' is a whole number"),
    Case("parquet-nul-in-log-id", as_parquet("tests", setting("test_id", 1, "c1\x00")),
         "tests.parquet", "test_id", "c1\x00", 1, "control character (U+0000)"),
    Case("parquet-huge-cell", as_parquet("sinkage", setting("test_id", 2, BIG)),
         "sinkage.parquet", "test_id", None, 2, "characters long"),
    Case("parquet-covariate-beyond-2^53", as_parquet("tests", lambda f: f.assign(serial=SERIALS)),
         "tests.parquet", "serial", "r1", 2, "value '1152921504606846977' is a whole number"),
    Case("parquet-force-1e308", as_parquet("sinkage", setting("force_N", 2, 1e308)),
         "sinkage.parquet", "pressure_Pa", "c1", 2, "is inf"),
]
# fmt: on


@pytest.fixture
def never_blocks():
    """Fail (instead of hanging the suite) if reading blocks, e.g. on a FIFO."""

    def expired(signum, frame):
        raise TimeoutError("the reader blocked")

    previous = signal.signal(signal.SIGALRM, expired)
    signal.alarm(60)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, previous)


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_one_clear_error_from_the_api_and_the_command_line(
    case, write_campaign, campaign_frames, never_blocks, capsys
):
    folder = write_campaign(**campaign_frames)
    case.build(folder)
    with pytest.raises(CampaignError) as info:
        load_campaign(folder)
    err = info.value
    assert (err.file, err.column, err.test_id, err.row) == (
        case.file,
        case.column,
        case.test,
        case.row,
    )
    message = str(err)
    assert "\n" not in message and len(message) < 800, message
    assert case.says.format(folder=folder) in message, message
    assert main(["check", str(folder)]) == 2
    captured = capsys.readouterr()
    assert captured.err == f"error: {message}\n"
    assert "Traceback" not in captured.err + captured.out
    where = [f"file {case.file!r}"] + [f"row {case.row}:" for _ in [1] if case.row is not None]
    if case.test is not None:
        where.append(f"test {case.test!r}")
    for part in where:
        assert part in message, (part, message)


# --- the campaign folder itself ---------------------------------------------------------------


@pytest.mark.parametrize(
    ("make", "says"),
    [
        (os.mkfifo, "is a FIFO (named pipe), not a campaign folder"),
        (_link_loop, "is a symlink loop (the link leads back to itself), not a campaign folder"),
    ],
    ids=["fifo", "symlink-loop"],
)
def test_a_campaign_that_is_no_folder_says_what_it_is(make, says, tmp_path, never_blocks, capsys):
    path = tmp_path / "campaign"
    make(path)
    with pytest.raises(CampaignError, match=re.escape(says)):
        load_campaign(path)
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and says in err and err.count("\n") == 1


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads files whatever their mode")
@pytest.mark.parametrize(
    ("target", "mode", "says"),
    [
        ("", stat.S_IRUSR | stat.S_IWUSR, "cannot look into the campaign folder"),  # no x
        ("", 0, "cannot look into the campaign folder"),
        ("tests.csv", 0, "cannot read the file: permission denied"),
    ],
    ids=["folder-without-execute", "folder-without-any", "file-without-read"],
)
def test_permission_denied_is_one_clear_error(
    target, mode, says, write_campaign, campaign_frames, capsys
):
    folder = write_campaign(**campaign_frames)
    path = folder / target if target else folder
    path.chmod(mode)
    try:
        with pytest.raises(CampaignError, match=re.escape(says)) as info:
            load_campaign(folder)
        assert info.value.file == "tests.csv"
        assert main(["check", str(folder)]) == 2
        err = capsys.readouterr().err
        assert err.startswith("error: ") and says in err and "Traceback" not in err
    finally:
        path.chmod(stat.S_IRWXU)


# --- skipping: nothing dropped silently ---------------------------------------------------------


def _skipping(folder: Path):
    with pytest.warns(SoilstatsWarning, match="skipped") as record:
        campaign = load_campaign(folder, on_error="skip")
    return campaign, str(record[0].message)


def test_a_nul_in_a_sample_id_skips_its_test_whole_and_says_so(write_campaign, campaign_frames):
    """A trailing NUL on one sample row of c1 used to make that row an unknown test's: c1
    stayed, short of the row. Now c1 is skipped whole, listed with the reason."""
    folder = write_campaign(**campaign_frames)
    edit("sinkage.csv", "c1,0.001,10", "c1\x00,0.001,10")(folder)
    campaign, warned = _skipping(folder)
    assert list(campaign.tests["test_id"]) == ["r1", "s1"]
    assert "c1" not in set(campaign.sinkage["test_id"])
    (row,) = campaign.skipped.itertuples()
    assert (row.test_id, row.file, row.column, row.row) == ("c1", "sinkage.csv", "test_id", 2)
    assert "control character (U+0000)" in row.reason and "'c1'" in warned


def test_a_nul_in_a_log_id_is_listed_with_the_samples_it_leaves(write_campaign, campaign_frames):
    folder = write_campaign(**campaign_frames)
    edit("tests.csv", "c1,sinkage", "c1\x00,sinkage")(folder)
    campaign, _ = _skipping(folder)
    assert list(campaign.tests["test_id"]) == ["r1", "s1"]
    listed = dict(zip(campaign.skipped["test_id"], campaign.skipped["reason"], strict=True))
    assert "control character" in listed["c1\x00"] and "is not in tests.csv" in listed["c1"]


def test_an_infinite_pressure_skips_its_test_with_the_derived_column(
    write_campaign, campaign_frames
):
    folder = write_campaign(**campaign_frames)
    edit("sinkage.csv", "c1,0.001,10", "c1,0.001,1e308")(folder)
    campaign, warned = _skipping(folder)
    assert list(campaign.tests["test_id"]) == ["r1", "s1"]
    (row,) = campaign.skipped.itertuples()
    assert (row.test_id, row.column, row.row) == ("c1", "pressure_Pa", 2)
    assert "pressure_Pa" in warned
    assert campaign.sinkage["pressure_Pa"].abs().max() < float("inf")


def test_numbers_are_kept_exactly_where_float64_holds_them(write_campaign, campaign_frames):
    """The refusals above are of numbers float64 would change; the largest exact whole
    numbers and the smallest normal ones still load, unchanged."""
    folder = write_campaign(**campaign_frames)
    repetition("9007199254740991")(folder)
    edit("tests.csv", ",12.5,", ",9007199254740993.5,")(folder)  # a decimal: rounded by any reader
    edit("sinkage.csv", "c1,0.002,30.5", "c1,0.002,2.2250738585072014e-308")(folder)
    campaign = load_campaign(folder, check_units=False)
    assert campaign.tests["repetition"].iloc[0] == 2**53 - 1
    assert campaign.sinkage["force_N"].iloc[3] == 2.2250738585072014e-308


# --- Campaign.from_frames: one clear InputError, nothing dropped ------------------------------


def _frames():
    tests = pd.DataFrame(
        {
            "test_id": ["a"],
            "kind": ["sinkage"],
            "soil": ["s"],
            "shape": ["circle"],
            "radius_m": [0.05],
        }
    )
    sinkage = pd.DataFrame(
        {
            "test_id": ["a"] * 20,
            "z_m": [0.001 * i for i in range(1, 21)],
            "force_N": [50.0 * i for i in range(1, 21)],
        }
    )
    return tests, sinkage


@pytest.mark.parametrize(
    ("change", "says"),
    [
        (lambda t, s: {"units": {"z_m": None}}, r"units\['z_m'\] = None"),
        (lambda t, s: {"units": "mm"}, "units must map format columns"),
        (lambda t, s: {"sinkage": pd.concat([s, s[["z_m"]]], axis=1)}, "'z_m' twice"),
        (
            lambda t, s: {
                "sinkage": s.set_axis(pd.MultiIndex.from_product([["x"], s.columns]), axis=1)
            },
            "MultiIndex",
        ),
        (lambda t, s: {"sinkage": s.assign(force_N=s["force_N"] + 1j)}, "'force_N'.*complex"),
        (
            lambda t, s: {
                "sinkage": s.assign(force_N=s["force_N"].astype(object).where(s.index > 0, 3 + 2j))
            },
            "'force_N'.*complex",
        ),
    ],
)
def test_from_frames_refuses_what_it_cannot_read_faithfully(change, says):
    from soilstats import Campaign
    from soilstats.errors import InputError

    tests, sinkage = _frames()
    kwargs = {"sinkage": sinkage, **change(tests, sinkage)}
    with pytest.raises(InputError, match=says):
        Campaign.from_frames(tests, **kwargs)
