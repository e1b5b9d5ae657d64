"""The `soilstats` command: subcommands, shared options, exit codes, outputs and provenance."""

from __future__ import annotations

import importlib
import json
import os
import pkgutil
import re
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

import soilstats
from soilstats.campaign.selection import SelectCriterion, apply_selection, parse_selection
from soilstats.cli.common import guarded
from soilstats.cli.main import SUBCOMMANDS, build_parser, main
from soilstats.errors import CampaignError

ROOT = Path(__file__).resolve().parents[1]


def _run(*argv: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", *argv], capture_output=True, text=True, check=False, cwd=cwd
    )


# ------------------------------------------------------------------------ front door, help


def test_help_lists_every_subcommand(capsys):
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    for name in SUBCOMMANDS:
        assert re.search(rf"^\s+{name}\s", out, flags=re.M), name
    assert "Apfelbeck" in out  # the method's paper, cited by its authors


@pytest.mark.parametrize("name", list(SUBCOMMANDS))
def test_every_subcommand_has_help_with_the_shared_options(name, capsys):
    assert main([name, "--help"]) == 0
    out = capsys.readouterr().out
    for option in ("--seed", "--progress", "--json"):
        assert option in out, (name, option)
    assert not re.search(r"issue #?\d|#\d\d?\b", out), "help mentions internal issue numbers"


def test_python_dash_m_runs_the_same_front_door():
    top = _run("soilstats", "--help")
    study = _run("soilstats.study", "--help")
    assert top.returncode == 0 and "posterior" in top.stdout
    assert study.returncode == 0 and "NAME" in study.stdout and "--data" in study.stdout
    version = _run("soilstats", "--version")
    assert version.stdout.strip() == f"soilstats {soilstats.__version__}"


def test_console_script_is_declared():
    text = (ROOT / "pyproject.toml").read_text()
    assert 'soilstats = "soilstats.cli.main:main"' in text


def test_the_campaign_is_given_the_same_way_everywhere():
    parser = build_parser()
    for name in ("study", "discover", "identify", "posterior"):
        sub = parser._subparsers._group_actions[0].choices[name]
        options = {s for a in sub._actions for s in a.option_strings}
        assert {"--data", "--select", "--seed", "--progress", "--json", "--out"} <= options


def test_check_reads_a_bundled_name_given_as_its_folder_as_data_does(capsys):
    # `soilstats check cullinan-sand` used to say the bundled campaign was not bundled.
    assert main(["check", "cullinan-sand"]) == 0
    assert "bundled:cullinan-sand" in capsys.readouterr().out
    assert main(["check", "--data", "cullinan-sand"]) == 0


@pytest.mark.parametrize("name", ["identify", "discover", "posterior", "check"])
def test_every_command_takes_the_campaign_as_its_positional_or_data(name, capsys):
    # `soilstats identify DIR` was a usage error ("unrecognized arguments") while check took it.
    from soilstats.cli.common import resolve_campaign

    parser = build_parser()
    more = ["--soil", "GRC-1", "--model", "bernstein", "--out", "x"] if name == "posterior" else []
    args = parser.parse_args([name, "grc1-oravec2009", *more])
    resolve_campaign(args, args._parser)
    assert args.data == "grc1-oravec2009"
    args = parser.parse_args([name, *more])
    resolve_campaign(args, args._parser)
    assert args.data == "simulated-paper"  # the documented default
    assert main([name, "grc1-oravec2009", "--data", "cullinan-sand", *more]) == 2
    assert "campaign given twice" in capsys.readouterr().err


@pytest.mark.parametrize("name", ["identify", "discover", "check"])
def test_the_wrote_line_names_the_output_folder_not_its_staging_copy(name, tmp_path, capsys):
    # discover printed ".out.soilstats-stage-XXXX/discover.json": a folder that no longer exists
    out = tmp_path / "out"
    assert main([name, "grc1-oravec2009", "--out", str(out), "--progress", "off"]) == 0
    wrote = [line for line in capsys.readouterr().err.splitlines() if line.startswith("wrote ")]
    assert wrote and str(out) in wrote[0] and "stage" not in wrote[0], wrote
    assert (out / f"{name}.json").is_file()


def test_study_takes_its_name_then_the_campaign():
    args = build_parser().parse_args(["study", "velocity", "grc1-oravec2009"])
    assert (args.name, args.folder) == ("velocity", "grc1-oravec2009")


def test_public_functions_and_modules_never_share_a_name():
    modules = {m.name for m in pkgutil.iter_modules(soilstats.__path__)}
    assert not modules & set(soilstats.__all__), modules & set(soilstats.__all__)
    importlib.import_module("soilstats.discovery")  # a subpackage import shadows nothing
    assert callable(soilstats.discover) and callable(soilstats.identify)


# ------------------------------------------------------------------------------ exit codes


def test_unknown_subcommand_and_bad_option_are_usage_errors(capsys):
    assert main(["no-such-command"]) == 2
    assert main(["identify", "--no-such-option"]) == 2
    assert "usage:" in capsys.readouterr().err


@pytest.mark.parametrize(
    "make",
    [
        pytest.param(lambda p: p / "missing", id="missing-folder"),
        pytest.param(lambda p: (p / "tests.csv").mkdir() or p, id="directory-where-file-belongs"),
        pytest.param(
            lambda p: (p / "tests.csv").write_text("test_id," + "x" * 200_000 + "\nA,1\n") or p,
            id="huge-header-cell",
        ),
        pytest.param(
            lambda p: (p / "tests.csv").write_bytes(b"\x00\xff\xfe binary \x00\n") or p,
            id="binary-file",
        ),
    ],
)
def test_bad_paths_exit_2_without_traceback(make, tmp_path, capsys):
    folder = make(tmp_path)
    assert main(["identify", "--data", str(folder)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "Traceback" not in err


def test_out_that_is_a_file_is_refused_before_any_work(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert main(["study", "velocity", "--out", str(blocker)]) == 2
    assert "is not a folder" in capsys.readouterr().err


def test_permission_denied_is_bad_input_not_a_crash(tmp_path, capsys):
    def denied(args):
        raise PermissionError(13, "Permission denied", str(tmp_path / "tests.csv"))

    assert guarded(denied, build_parser().parse_args(["identify"])) == 2
    err = capsys.readouterr().err
    assert err == f"error: {tmp_path / 'tests.csv'}: permission denied\n"


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads files whatever their mode")
def test_unreadable_campaign_file_exits_2(tmp_path, capsys):
    soilstats.load_campaign("cullinan-sand").save(tmp_path / "c")
    (tmp_path / "c" / "tests.csv").chmod(0)
    assert main(["identify", "--data", str(tmp_path / "c")]) == 2


def test_internal_error_exits_1_and_asks_for_a_report(capsys):
    def bug(args):
        raise ZeroDivisionError("a bug")

    assert guarded(bug, build_parser().parse_args(["identify"])) == 1
    assert "internal error" in capsys.readouterr().err


# ------------------------------------------------------------------- known defects (item 8)


def test_select_on_a_text_column(capsys):
    assert main(["identify", "--data", "cullinan-sand", "--select", "preparation=1"]) == 0
    out = capsys.readouterr().out
    assert "tests            6" in out  # method 1 has six tests


def test_series_and_by_the_same_column_tabulates_each_model_apart(capsys):
    code = main(["identify", "--series", "shape", "--by", "shape", "--progress", "off"])
    assert code == 0
    out = capsys.readouterr().out
    assert "series shape · soil01 · bernstein" in out and "series shape · soil08 · bekker" in out
    assert "no tests of series 'shape'" in out


def test_unknown_soil_is_an_error_not_an_empty_table(capsys):
    assert main(["identify", "--data", "cullinan-sand", "--soil", "NOSUCH"]) == 2
    captured = capsys.readouterr()
    assert "NOSUCH" in captured.err and "cullinan-sand" in captured.err
    assert "parameter" not in captured.out


def test_no_pdf_writes_and_announces_no_pdf(tmp_path, capsys):
    out = tmp_path / "r"
    args = ["study", "preparation", "--data", "cullinan-sand", "--out", str(out), "--no-pdf"]
    assert main([*args, "--progress", "off"]) == 0
    assert not list(out.glob("*.pdf"))
    assert "PDF" not in capsys.readouterr().out


def test_posterior_simulator_choices_follow_the_bayes_package():
    from soilstats.bayes import SIMULATOR_FORMATS
    from soilstats.cli.posterior import SIMULATORS

    assert set(SIMULATORS) == set(SIMULATOR_FORMATS)


# ---------------------------------------------------------------------------------- select


def test_selection_grammar():
    assert parse_selection(["soil=soil01", "shear:tool=tool04"]) == [
        SelectCriterion("soil", "soil01"),
        SelectCriterion("tool", "tool04", "shear"),
    ]
    with pytest.raises(ValueError, match="COLUMN=VALUE"):
        parse_selection(["soil"])


def test_selection_compares_as_the_columns_type_and_respects_kind():
    campaign = soilstats.load_campaign("simulated-paper")
    fast = apply_selection(campaign, ["sinkage:velocity_m_s=0.0048"])
    kinds = fast.tests.groupby("kind")["velocity_m_s"]
    assert set(fast.tests.loc[fast.tests["kind"] == "sinkage", "velocity_m_s"]) == {0.0048}
    assert (fast.tests["kind"] == "shear").sum() == (campaign.tests["kind"] == "shear").sum()
    assert kinds.ngroups == 2
    with pytest.raises(CampaignError, match="numeric column"):
        apply_selection(campaign, ["velocity_m_s=fast"])
    with pytest.raises(CampaignError, match="kept no test"):
        apply_selection(campaign, ["soil=soil99"])


def test_a_selection_that_keeps_nothing_says_what_the_test_log_has(capsys):
    """A value no test has: the values present in its column (as Campaign.select says); a
    combination no test meets: every criterion, with its column's values among the tests
    meeting the others; a kind's criterion: the values of that kind's tests."""
    argv = ["identify", "cullinan-sand", "--select", "preparation=7", "--progress", "off"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "column 'preparation'" in err
    assert "preparation=7 matched none (values present: ['1', '2', '3', '4', '5'])" in err
    campaign = soilstats.load_campaign("cullinan-sand")
    with pytest.raises(CampaignError) as both:
        apply_selection(campaign, ["preparation=3", "session=24Aug"])
    message = str(both.value)
    assert "each of preparation=3, session=24Aug matches some tests, but no test meets" in message
    assert "preparation has ['1']; session has ['27SEPT']" in message
    paper = soilstats.load_campaign("simulated-paper")
    with pytest.raises(CampaignError, match=r"sinkage:series=none matched none \(values pre"):
        apply_selection(paper, ["sinkage:series=none", "shear:series=none"])


def test_counts_of_one_are_singular(capsys):
    """cullinan-sand has one failed test and three methods with one test each: no '1 tests'
    in the screening line, the pooled-fit notes or the bootstrap note."""
    assert main(["identify", "cullinan-sand", "--progress", "off", "--json"]) == 0
    captured = capsys.readouterr()
    text = captured.err + captured.out
    assert "bearing-failure in 1 test," in captured.err
    assert "unload-reload in 1 test," in captured.err
    assert "1 test pooled (method3-test1)" in text and "1 test is too few to resample" in text
    assert "1 tests" not in text
    from soilstats._text import plural

    assert [plural(n, "test") for n in (0, 1, 3)] == ["0 tests", "1 test", "3 tests"]
    assert plural(2, "criterion", "criteria") == "2 criteria"


def test_the_screening_line_counts_the_selected_tests_only(capsys):
    """cullinan-sand's one failed test is method5-test1: a selection without it reports only
    the findings of the tests it keeps (method3-test1's hold and step) and says how many it
    keeps; without --select the line counts every test."""
    from soilstats.quality import screen

    campaign = soilstats.load_campaign("cullinan-sand")
    failed = {f.test_id for f in screen(campaign, "clean").flags if f.code == "bearing-failure"}
    kept = campaign.select(preparation="3").tests["test_id"]
    assert failed and not failed & set(kept)  # the premise: the failed test is left out
    argv = ["identify", "cullinan-sand", "--progress", "off"]
    assert main([*argv, "--select", "preparation=3"]) == 0
    line = capsys.readouterr().err.splitlines()[0]
    assert line.startswith(f"Data quality (clean, selection: {len(kept)} of {len(campaign.tests)} ")
    assert "bearing-failure" not in line and "hold in 1 test, step in 1 test;" in line
    assert main(argv) == 0
    assert "bearing-failure in 1 test, hold in 5 tests" in capsys.readouterr().err


# ----------------------------------------------------------------- outputs and provenance


def test_existing_outputs_are_never_replaced_silently(tmp_path, capsys):
    args = ["identify", "--data", "cullinan-sand", "--out", str(tmp_path), "--json"]
    assert main(args) == 0
    before = (tmp_path / "identify.json").read_bytes()
    assert main(args) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert (tmp_path / "identify.json").read_bytes() == before
    assert main([*args, "--overwrite"]) == 0


def test_outputs_are_byte_identical_for_the_same_command(tmp_path, monkeypatch):
    monkeypatch.delenv("SOURCE_DATE_EPOCH", raising=False)
    runs = []
    for name in ("a", "b"):
        (tmp_path / name).mkdir()
        monkeypatch.chdir(tmp_path / name)
        code = main(["study", "preparation", "--data", "cullinan-sand", "--progress", "off"])
        assert code == 0
        runs.append(tmp_path / name / "reports")
    files = sorted(p.name for p in runs[0].iterdir())
    assert "preparation.pdf" in files and "preparation.json" in files
    for name in files:
        assert (runs[0] / name).read_bytes() == (runs[1] / name).read_bytes(), name


def test_every_output_records_its_provenance(tmp_path, monkeypatch):
    from pypdf import PdfReader

    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    out = tmp_path / "r"
    argv = ["study", "preparation", "--data", "cullinan-sand", "--out", str(out), "--seed", "7"]
    assert main([*argv, "--progress", "off"]) == 0
    campaign = soilstats.load_campaign("cullinan-sand")
    from soilstats.campaign.digest import campaign_sha256

    digest = campaign_sha256(campaign)
    doc = json.loads((out / "preparation.json").read_text())
    prov = doc["provenance"]
    assert prov["soilstats_version"] == soilstats.__version__ and prov["campaign_format"] == "1"
    assert prov["campaign_sha256"] == digest and prov["seed"] == 7
    assert prov["command"].startswith("soilstats study preparation --data cullinan-sand")
    assert prov["created"] == "2023-11-14T22:13:20+00:00" and doc["date"] == prov["created"]
    assert "Apfelbeck" in prov["method"]
    for csv in out.glob("*.csv"):
        head = csv.read_text().splitlines()[:8]
        assert f"# campaign_sha256: {digest}" in head, csv.name
        assert not pd.read_csv(csv, comment="#").empty
    reader = PdfReader(out / "preparation.pdf")
    assert digest in reader.metadata["/Subject"]
    assert "soilstats study preparation" in reader.pages[-1].extract_text()


def test_campaign_hash_is_of_the_content_not_the_container(tmp_path):
    from soilstats.campaign.digest import campaign_sha256

    campaign = soilstats.load_campaign("cullinan-sand")
    copy = soilstats.load_campaign(campaign.save(tmp_path / "c", format="parquet"))
    assert campaign_sha256(copy) == campaign_sha256(campaign)
    sinkage = campaign.sinkage.drop(columns="pressure_Pa")
    sinkage.loc[5, "force_N"] += 1e-9
    changed = soilstats.Campaign.from_frames(campaign.tests, sinkage)
    assert campaign_sha256(changed) != campaign_sha256(campaign)


def test_a_study_name_cannot_write_outside_out(tmp_path, capsys):
    spec = (ROOT / "studies" / "preparation.toml").read_text()
    evil = tmp_path / "evil.toml"
    evil.write_text(re.sub(r'^name = ".*"$', 'name = "../../escaped"', spec, flags=re.M))
    assert "../../escaped" in evil.read_text()
    out = tmp_path / "deep" / "out"
    assert main(["study", str(evil), "--data", "cullinan-sand", "--out", str(out)]) == 2
    assert "name" in capsys.readouterr().err
    assert not list(tmp_path.rglob("escaped*"))


def test_column_equals_value_has_one_meaning_everywhere():
    """Campaign.select, --select and a study's `where` keep the same tests."""
    from soilstats.study.data import select_tests
    from soilstats.study.spec import load_spec

    campaign = soilstats.load_campaign("simulated-paper")
    typed = campaign.select(radius_m=0.05 * (1 + 1e-12), kind="sinkage", series="velocity")
    cli = apply_selection(campaign, ["radius_m=0.05", "kind=sinkage", "series=velocity"])
    assert set(typed.tests["test_id"]) == set(cli.tests["test_id"])
    assert (
        len(typed.tests)
        == ((campaign.tests["radius_m"] == 0.05) & (campaign.tests["series"] == "velocity")).sum()
    )
    study = select_tests(campaign, load_spec("velocity"))  # where_present series = velocity
    velocity = apply_selection(campaign, ["kind=sinkage", "series=velocity"])
    assert set(study["test_id"]) == set(velocity.tests["test_id"])
    with pytest.raises(CampaignError, match="compare as text"):
        campaign.select(preparation=5)  # a text column: "5", not 5


def test_soilstats_warnings_reach_the_user_as_one_plain_line(tmp_path):
    # A warning used to print as '/path/soilstats/cli/common.py:217: SoilstatsWarning: ...'
    # followed by the library's source line.
    folder = tmp_path / "c"
    import shutil

    shutil.copytree(ROOT / "soilstats" / "data" / "cullinan-sand", folder)
    log = pd.read_csv(folder / "tests.csv", dtype=str, keep_default_na=False)
    log.loc[2, "soil"] = "Cullinan-sand"  # one soil written two ways
    log.to_csv(folder / "tests.csv", index=False)
    done = _run("soilstats", "check", str(folder))
    assert done.returncode == 0, done.stderr
    lines = [ln for ln in done.stderr.splitlines() if "differ only in case" in ln]
    assert len(lines) == 1 and lines[0].startswith("warning: file 'tests.csv', column 'soil'")
    assert "common.py" not in done.stderr and "SoilstatsWarning" not in done.stderr


def test_help_texts_are_written_for_users_not_developers(capsys):
    """Every subcommand's --help (issue #47 item 5): no Sphinx roles, no reST literals."""
    for name in SUBCOMMANDS:
        assert main([name, "--help"]) == 0
        text = capsys.readouterr().out
        leaks = re.findall(r":(?:func|mod|class|data|meth|attr):|``|~soilstats", text)
        assert not leaks, (name, leaks)


def test_defaults_the_user_did_not_give_are_in_the_json_and_on_page_one(tmp_path):
    """Issue #47 item 3: what the result rests on without the user having said so."""
    from pypdf import PdfReader

    argv = ["identify", "--data", "cullinan-sand", "--model", "bernstein", "--by=preparation"]
    assert main([*argv, "--out", str(tmp_path), "--progress", "off"]) == 0
    defaults = json.loads((tmp_path / "identify.json").read_text())["defaults"]
    # given (either spelling) -> not a default; left out -> its parser default, as text
    assert "--model" not in defaults and "--by" not in defaults
    assert defaults["--points-per-test"] == "100" and defaults["--test-resamples"] == "200"
    assert defaults["--seed"] == "0" and "--out" not in defaults and "--progress" not in defaults
    page = re.sub(r"\s+", "", PdfReader(tmp_path / "identify.pdf").pages[0].extract_text())
    assert "Settingsleftattheirdefaults" in page and "--points-per-test100" in page
