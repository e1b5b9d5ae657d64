"""Seeded malformed campaigns (benchmarks/malformed_campaigns.py) through the library readers.

Every case is a valid campaign (or runs file, prior, import mapping, in-memory table,
simulate spec) with one thing broken; each must end in the package's own error naming the
file, column or test, or in a read whose every cell equals what was written (or that says
why not). Never a traceback, never a silent change. The fast test runs a small seeded
subset; the slow one 400 cases; the command-line run is the benchmark's ``--cli``.

Below them, one regression test per finding of the benchmark.
"""

from __future__ import annotations

import importlib.util
import re
import sys
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from soilstats.campaign import load_campaign
from soilstats.errors import SoilstatsWarning

_PATH = Path(__file__).resolve().parents[1] / "benchmarks" / "malformed_campaigns.py"
_SPEC = importlib.util.spec_from_file_location("malformed_campaigns", _PATH)
assert _SPEC is not None and _SPEC.loader is not None
bench = importlib.util.module_from_spec(_SPEC)
sys.modules["malformed_campaigns"] = bench
_SPEC.loader.exec_module(bench)


def _run(count: int, seed: int, tmp_path: Path) -> list[tuple[str, str, str]]:
    out = []
    for case in bench.generate(count, seed):
        folder = tmp_path / case.name[:4]
        bench.write_case(case, folder)
        outcome, detail = bench.run_library(case, folder)
        out.append((case.name, outcome, detail))
    return out


def _failures(results: list[tuple[str, str, str]]) -> list[tuple[str, str, str]]:
    return [r for r in results if r[1] in (*bench.FAILING, "error-unnamed")]


def test_a_seeded_subset_of_malformed_inputs_gives_clean_errors_or_faithful_reads(tmp_path):
    results = _run(66, 2026, tmp_path)  # every category and surface 3 times or more
    assert _failures(results) == []
    outcomes = {r[1] for r in results}
    assert "error" in outcomes and "ok" in outcomes  # the run judges both ways


@pytest.mark.slow
def test_four_hundred_malformed_inputs_give_clean_errors_or_faithful_reads(tmp_path):
    results = _run(400, 44, tmp_path)
    assert _failures(results) == []


def test_the_round_trip_check_sees_a_changed_cell(tmp_path):
    """The benchmark's silent-change detector, against a campaign changed behind its back."""
    case = bench.generate(1, 1)[0]
    case.files = {f"{s}.csv": bench.to_bytes(t) for s, t in bench.base_tables().items()}
    bench.write_case(case, tmp_path)
    campaign = load_campaign(tmp_path)
    assert bench.silent_changes(case, campaign) == []
    campaign.sinkage.loc[3, "force_N"] += 1.0
    assert "force_N" in bench.silent_changes(case, campaign)[0]


# --- regressions of the benchmark's findings ---------------------------------------------
def _folder(tmp_path: Path, edit) -> Path:
    tables = bench.base_tables()
    edit(tables)
    for stem, table in tables.items():
        (tmp_path / f"{stem}.csv").write_bytes(bench.to_bytes(table))
    return tmp_path


def _load_warnings(folder: Path) -> list[str]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        load_campaign(folder)
    return [str(w.message) for w in caught if issubclass(w.category, SoilstatsWarning)]


@pytest.mark.parametrize("header", [" preparation", "Operator", "VELOCITY_M_S ", "ｔest_id"])
def test_a_header_that_differs_from_a_format_column_only_in_case_or_blanks_is_named(
    tmp_path, header
):
    """Was read silently as a covariate while the format column counted as not given."""
    if header == "ｔest_id":  # a required column: the near name is a covariate beside it
        folder = _folder(tmp_path, lambda t: [r.append("x") for r in t["sinkage"]])
        text = (folder / "sinkage.csv").read_text(encoding="utf-8")
        (folder / "sinkage.csv").write_text(text.replace(",x\n", f",{header}\n", 1), "utf-8")
    else:
        column = header.strip().lower()

        def rename(t):
            t["tests"][0][t["tests"][0].index(column)] = header

        folder = _folder(tmp_path, rename)
    messages = [m for m in _load_warnings(folder) if repr(header) in m]
    assert len(messages) == 1, _load_warnings(folder)
    file = "sinkage.csv" if header == "ｔest_id" else "tests.csv"
    assert f"file '{file}'" in messages[0] and "kept as a covariate" in messages[0]
    assert header == "ｔest_id" or "counts as not given" in messages[0]


@pytest.mark.parametrize("twin", ["shape-0001 ", "SHAPE-0001", "ｓhape-0001"])
def test_test_ids_a_reader_cannot_tell_apart_are_named_and_kept_apart(tmp_path, twin):
    def rename(t):
        for stem in ("tests", "sinkage"):
            for r in t[stem][1:]:
                if r[0] == "shape-0004":
                    r[0] = twin

    campaign_folder = _folder(tmp_path, rename)
    messages = [m for m in _load_warnings(campaign_folder) if "column 'test_id'" in m]
    assert len(messages) == 1 and repr(twin) in messages[0] and "'shape-0001'" in messages[0]
    with pytest.warns(SoilstatsWarning):
        campaign = load_campaign(campaign_folder)
    assert {"shape-0001", twin} <= set(campaign.tests["test_id"])  # nothing merged
    assert len(campaign.tests) == 18


def test_group_names_in_another_unicode_form_are_named(tmp_path):
    def rename(t):
        soil = t["tests"][0].index("soil")
        t["tests"][1][soil] = "so\u0069\u0308l01"  # 'soïl01' decomposed
        for r in t["tests"][2:]:
            r[soil] = "so\u00efl01"  # composed

    messages = [m for m in _load_warnings(_folder(tmp_path, rename)) if "column 'soil'" in m]
    assert len(messages) == 1 and "Unicode form" in messages[0]


def test_a_peak_pressure_beyond_any_soil_warns_naming_the_column(tmp_path):
    """Forces times 1e300 loaded with no word: no check bounded the pressure from above."""

    def scale(t):
        c = t["sinkage"][0].index("force_N")
        for r in t["sinkage"][1:]:
            r[c] = repr(float(r[c]) * 1e6)  # MN read as N: peaks near 1e11 Pa

    messages = _load_warnings(_folder(tmp_path, scale))
    hits = [m for m in messages if "above 1e+08 Pa" in m]
    assert len(hits) == 1 and "'force_N'" in hits[0] and "shape-0001" in hits[0]


def test_the_valid_base_campaign_loads_without_a_word(tmp_path):
    """The benchmark's base is clean: every warning in a case comes from its one change."""
    assert _load_warnings(_folder(tmp_path, lambda t: None)) == []
    campaign = load_campaign(tmp_path)
    assert len(campaign.tests) == 18 and np.isfinite(campaign.sinkage["pressure_Pa"]).all()
    assert isinstance(campaign.tests, pd.DataFrame)


@pytest.mark.parametrize(
    "text", ["normal:1e400:1", "normal:nan:1", "normal:0:1:5:5", "normal:0:1:60:50"]
)
def test_a_normal_prior_with_no_finite_centre_or_an_empty_window_is_refused(text):
    """``--prior kc=normal:1e400:1`` was taken as normal(inf, 1): no draw could ever hold."""
    from soilstats.bayes.priors import parse_prior
    from soilstats.errors import InputError

    with pytest.raises(InputError, match=re.escape(repr(text))):
        parse_prior(text)
    assert str(parse_prior("normal:1:0.3:0:inf")) == "normal(1, 0.3) on (0, inf)"


def test_a_force_whose_pressure_a_fit_cannot_square_is_refused_naming_the_test(tmp_path):
    """Forces of 1e303 N loaded (finite), then ``identify`` ended in numpy's "Eigenvalues did
    not converge": a pressure beyond 1e150 Pa overflows in every squared residual."""
    from soilstats.errors import CampaignError

    def scale(t):
        c = t["sinkage"][0].index("force_N")
        row = next(r for r in t["sinkage"][1:] if r[0] == "shape-0002" and float(r[c]) > 1)
        row[c] = "1e303"

    folder = _folder(tmp_path, scale)
    with pytest.raises(CampaignError, match=r"beyond ±1e\+150") as err:
        load_campaign(folder)
    assert (err.value.file, err.value.column, err.value.test_id) == (
        "sinkage.csv",
        "pressure_Pa",
        "shape-0002",
    )
    with pytest.warns(SoilstatsWarning, match="shape-0002"):
        kept = load_campaign(folder, on_error="skip")
    assert "shape-0002" not in set(kept.tests["test_id"]) and len(kept.tests) == 17


@pytest.mark.parametrize(
    ("test", "column", "value", "says"),
    [
        ("shape-0001", "width_m", "0.1", "a circular plate is sized by radius_m"),
        ("shear-ring-0001", "shape", "circle", "a shear-ring test has no plate shape"),
        ("shear-ring-0002", "grousers", "1e3", "1000 grousers on a shear ring"),
        ("shape-0003", "repetition", "-1", "repetition -1 is negative"),
    ],
)
def test_log_cells_the_format_allows_but_are_likely_slips_warn_and_are_kept(
    tmp_path, test, column, value, says
):
    """Each was read without a word (the format allows it: docs/campaign-format.md); now one
    warning names the file, column and test, and the value is kept exactly as written."""

    def edit(t):
        bench._set_cell(t, "tests", column, bench._tests_row(t, test), value)

    folder = _folder(tmp_path, edit)
    messages = _load_warnings(folder)
    assert len(messages) == 1, messages
    assert messages[0].startswith(f"file 'tests.csv', column {column!r}, test(s) {test!r}: ")
    assert says in messages[0]
    with pytest.warns(SoilstatsWarning):
        tests = load_campaign(folder).tests.set_index("test_id")
    kept = tests.loc[test, column]
    assert kept == (value if column == "shape" else float(value))  # nothing changed


def test_grouser_counts_and_repetitions_within_reason_say_nothing(tmp_path):
    from soilstats.campaign.log_warnings import MAX_GROUSERS

    def edit(t):
        bench._set_cell(t, "tests", "grousers", bench._tests_row(t, "shear-ring-0001"), "100")
        bench._set_cell(t, "tests", "repetition", bench._tests_row(t, "shape-0001"), "0")

    assert MAX_GROUSERS == 100
    assert _load_warnings(_folder(tmp_path, edit)) == []
