"""Malformed campaigns and inputs, generated with a seed, run through the library and the CLI.

Issue #44's "Done when": every malformed input gives a clean error (the package's own error,
exit 2, naming the file and column or test) or a clean success; never a traceback, a crash
(a signal), a hang, or a silent change (a value read differently from what was written, with
no message). The filer's 230-case generator was never published: this one is ours.

Each case starts from a small valid campaign (12 plate tests, 6 shear-ring tests of the
bundled ``simulated-paper``) and breaks one thing, drawn with the seed from one category:

    columns   missing / extra / duplicate / blank / renamed headers
    types     booleans, complex, text, decimal commas, unicode digits, underscores in numbers
    values    NaN / inf / huge / tiny, negative or zero sizes, loads, unit mistakes
    ids       leading zeros, whitespace, NUL, unicode forms, duplicates, orphans, unknown kinds
    files     empty, header-only, truncated, encodings (latin-1, BOM, UTF-16), binary, missing
    metadata  conflicting geometry and log columns
    surfaces  wheel runs files, --prior strings, import mappings, Campaign.from_frames,
              simulate specs, study specs (through their library readers)

Outcomes: ``ok`` (read, and every cell equal to what was written), ``ok-warned`` (read with a
soilstats warning), ``error`` (the package's error naming a file/column/test/key),
``error-unnamed`` (the package's error naming none of them), ``silent-change`` (read, a
cell differs from what was written and nothing was said), ``traceback`` (any other
exception, or exit 1), ``crash`` (a signal), ``hang`` (over the time limit). The last four
fail the run.

Run from the repository root::

    python benchmarks/malformed_campaigns.py --smoke                 # 40 cases, library only
    python benchmarks/malformed_campaigns.py --count 320 --seed 44 --cli check,identify

``--cli`` runs each listed subcommand on each campaign case in a forked child of this process
(the package imported once; a signal or a hang in the child is seen as such); the child's
exit code and stderr are classified as above. Prints one table per category and outcome.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # forked children must not inherit a BLAS thread pool

import argparse  # noqa: E402
import csv  # noqa: E402
import io  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import re  # noqa: E402
import shutil  # noqa: E402
import signal  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import traceback  # noqa: E402
import warnings  # noqa: E402
from collections import defaultdict  # noqa: E402
from collections.abc import Callable  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from soilstats.campaign.schema import SPECS  # noqa: E402

Table = list[list[str]]  # header first
Tables = dict[str, Table]
FAILING = ("silent-change", "traceback", "crash", "hang")
NAMES = re.compile(
    r"tests\.csv|sinkage\.csv|shear\.csv|\.parquet|runs\.csv|\.toml|column|test_id|test |"
    r"run_id|key|row|'[a-z_]+'|prior|spec|field|mapping|units",
    re.IGNORECASE,
)
SINK_IDS = [f"shape-{i:04d}" for i in range(1, 13)]
SHEAR_IDS = [f"shear-ring-{i:04d}" for i in range(1, 7)]
#: The format's numeric columns per table, from the schema (a new column is broken too).
NUMERIC = {stem: [c.name for c in specs if c.dtype == "float"] for stem, specs in SPECS.items()}


def base_tables(samples_per_test: int = 40) -> Tables:
    """The valid campaign every case breaks: 12 plates (two sizes), 6 shear rings."""
    from soilstats.data import bundled_path

    folder = bundled_path("simulated-paper")
    assert folder is not None
    out: Tables = {}
    keep = set(SINK_IDS + SHEAR_IDS)
    for stem in ("tests", "sinkage", "shear"):
        with open(folder / f"{stem}.csv", newline="", encoding="utf-8") as fh:
            rows = list(csv.reader(fh))
        head, body = rows[0], [r for r in rows[1:] if r[0] in keep]
        if stem != "tests":  # thin the samples: every k-th, so each test keeps its curve
            by: dict[str, list[list[str]]] = defaultdict(list)
            for r in body:
                by[r[0]].append(r)
            body = [r for v in by.values() for r in v[:: max(1, len(v) // samples_per_test)]]
        else:  # drop columns empty for all kept tests
            used = [j for j in range(len(head)) if any(r[j] for r in body)]
            head, body = [head[j] for j in used], [[r[j] for j in used] for r in body]
        out[stem] = [head, *body]
    return out


def to_bytes(table: Table, encoding: str = "utf-8", newline: str = "\n") -> bytes:
    buf = io.StringIO()
    csv.writer(buf, lineterminator=newline).writerows(table)
    return buf.getvalue().encode(encoding)


@dataclass
class Case:
    name: str
    category: str
    files: dict[str, bytes | None] = field(default_factory=dict)  # None: delete the file
    surface: str = "campaign"  # or runs, prior, import, frames, simulate, study
    payload: object = None  # for non-campaign surfaces
    roundtrip: bool = True  # compare read values with written text on success


# --------------------------------------------------------------------- campaign mutations
def _col(table: Table, name: str) -> int:
    return table[0].index(name)


def _set_cell(t: Tables, stem: str, column: str, row: int, value: str) -> None:
    t[stem][row][_col(t[stem], column)] = value


def pick(rng: np.random.Generator, options: list[str]) -> str:
    """One of ``options``, drawn (not ``rng.choice``: numpy strings drop a trailing NUL)."""
    return options[int(rng.integers(0, len(options)))]


def _pick_row(rng: np.random.Generator, t: Tables, stem: str) -> int:
    return int(rng.integers(1, len(t[stem])))


def _pick_stem(rng: np.random.Generator) -> str:
    return pick(rng, ["tests", "sinkage", "shear"])


def _tests_row(t: Tables, test_id: str) -> int:
    return next(i for i, r in enumerate(t["tests"]) if r[0] == test_id)


def m_columns(rng: np.random.Generator, t: Tables) -> str:
    stem = _pick_stem(rng)
    table = t[stem]
    j = int(rng.integers(0, len(table[0])))
    what = pick(rng, ["missing", "extra", "duplicate", "blank", "case", "space", "reorder"])
    if what == "missing":
        for r in table:
            del r[j]
    elif what == "extra":
        extra = pick(rng, ["note", "bin", "moisture_pct", "z_m_2", "ünïcode"])
        table[0].append(extra)
        for r in table[1:]:
            r.append(pick(rng, ["1", "", "x", "0.5"]))
    elif what == "duplicate":
        for r in table:
            r.append(r[j])
    elif what == "blank":
        table[0].append("")
        for r in table[1:]:
            r.append("1")
    elif what == "case":
        table[0][j] = table[0][j].upper()
    elif what == "space":
        table[0][j] = f" {table[0][j]}"
    else:
        order = list(rng.permutation(len(table[0])))
        for i, r in enumerate(table):
            table[i] = [r[k] for k in order]
    if what == "extra":
        return f"extra column {extra!r} in {stem}"
    return f"{what} column {table[0][j] if j < len(table[0]) else j} in {stem}"


BAD_NUMBERS = [
    "True",
    "false",
    "1+2j",
    "(1+0j)",
    "abc",
    "1,5",
    "1.0.0",
    "0x10",
    "1e",
    "--1",
    "٣",
    "1_000",
    "½",
    "NaN",
    "nan",
    "inf",
    "-Infinity",
    "NA",
    "None",
    "null",
    "",
    " ",
    "1e400",
    "-1e400",
    "1e308",
    "1e-320",
    " 0.05 ",
    "0.05\t",
    "+0.05",
    "5e-2",
    "0,05",
    "1 000",
    "१",
    "0.05m",
]


def m_types(rng: np.random.Generator, t: Tables) -> str:
    stem = _pick_stem(rng)
    column = pick(rng, [c for c in NUMERIC[stem] if c in t[stem][0]])
    row = _pick_row(rng, t, stem)
    if stem == "tests":  # only a cell the test uses
        kind = t["tests"][row][_col(t["tests"], "kind")]
        if kind == "shear":
            column = pick(rng, ["r_inner_m", "r_outer_m", "grouser_height_m"])
        else:
            shape = t["tests"][row][_col(t["tests"], "shape")]
            column = "radius_m" if shape == "circle" else pick(rng, ["width_m", "length_m"])
    value = pick(rng, BAD_NUMBERS)
    _set_cell(t, stem, column, row, value)
    return f"{stem} {column} row {row} = {value!r}"


def m_values(rng: np.random.Generator, t: Tables) -> str:
    what = pick(
        rng,
        [
            "negative-size",
            "zero-size",
            "mm-radius",
            "kN-force",
            "mm-sinkage",
            "deg-angle",
            "negative-force",
            "rings",
            "grousers",
            "repetition",
            "velocity",
            "huge-force",
            "constant-z",
            "one-sample",
        ],
    )
    tests = t["tests"]
    if what in ("negative-size", "zero-size", "mm-radius"):
        row = _tests_row(t, pick(rng, SINK_IDS[:6]))
        value = {"negative-size": "-0.05", "zero-size": "0", "mm-radius": "50"}[what]
        _set_cell(t, "tests", "radius_m", row, value)
    elif what in ("kN-force", "negative-force", "huge-force"):
        c = _col(t["sinkage"], "force_N")
        scale = {"kN-force": 1e-3, "negative-force": -1.0, "huge-force": 1e300}[what]
        for r in t["sinkage"][1:]:
            r[c] = repr(float(r[c]) * scale)
    elif what == "mm-sinkage":
        c = _col(t["sinkage"], "z_m")
        for r in t["sinkage"][1:]:
            r[c] = repr(float(r[c]) * 1e3)
    elif what == "deg-angle":
        c = _col(t["shear"], "angle_rad")
        for r in t["shear"][1:]:
            r[c] = repr(math.degrees(float(r[c])))
    elif what == "rings":
        row = _tests_row(t, pick(rng, SHEAR_IDS))
        _set_cell(t, "tests", "r_inner_m", row, pick(rng, ["0.15", "0.2", "-0.01"]))
    elif what == "grousers":
        row = _tests_row(t, pick(rng, SHEAR_IDS))
        value = pick(rng, ["-1", "1.5", "x", "1e3", "True"])
        _set_cell(t, "tests", "grousers", row, value)
        return f"grousers = {value!r}"
    elif what == "repetition":
        row = _pick_row(rng, t, "tests")
        value = pick(rng, ["1.5", "x", "-1", "True", "01"])
        _set_cell(t, "tests", "repetition", row, value)
        return f"repetition = {value!r}"
    elif what == "velocity":
        row = _tests_row(t, pick(rng, SINK_IDS))
        value = pick(rng, ["0", "-1", "inf", "48"])
        _set_cell(t, "tests", "velocity_m_s", row, value)
        return f"velocity_m_s = {value!r}"
    elif what == "constant-z":
        tid = pick(rng, SINK_IDS)
        c = _col(t["sinkage"], "z_m")
        for r in t["sinkage"][1:]:
            if r[0] == tid:
                r[c] = "0.01"
    else:
        tid = pick(rng, SINK_IDS)
        seen = False
        keep = [t["sinkage"][0]]
        for r in t["sinkage"][1:]:
            if r[0] != tid or not seen:
                keep.append(r)
                seen = seen or r[0] == tid
        t["sinkage"] = keep
    del tests
    return what


ODD_IDS = [
    "001",
    "1",
    " shape-0001",
    "shape-0001 ",
    "shape-0001\x00",
    "shape-0001\x00x",
    "ｓhape-0001",
    "shape\u20130001",
    "SHAPE-0001",
    "shape-0001.0",
    "",
    "nan",
    "NA",
    "=cmd|' /C calc'!A0",
    "shape-0001\r",
    "x" * 300,
    "😀",
    "e\u0301",
    "\u00e9",
    "1e3",
]


def m_ids(rng: np.random.Generator, t: Tables) -> str:
    what = pick(
        rng,
        [
            "rename-test",
            "rename-sample",
            "duplicate-test",
            "orphan",
            "no-samples",
            "unknown-kind",
            "unknown-shape",
            "swap-kind",
            "duplicate-sample-rows",
        ],
    )
    if what in ("rename-test", "rename-sample"):
        new = pick(rng, ODD_IDS)
        old = pick(rng, SINK_IDS + SHEAR_IDS)
        stems = (
            ("tests", "sinkage", "shear")
            if rng.random() < 0.5
            else (("tests",) if what == "rename-test" else ("sinkage", "shear"))
        )
        for stem in stems:
            for r in t[stem][1:]:
                if r[0] == old:
                    r[0] = new
        return f"{what} {old!r} -> {new!r} in {stems}"
    if what == "duplicate-test":
        t["tests"].append(list(t["tests"][_pick_row(rng, t, "tests")]))
    elif what == "orphan":
        stem = pick(rng, ["sinkage", "shear"])
        row = list(t[stem][1])
        row[0] = pick(rng, ["ghost", "shape-9999", "shape-0001\x00"])
        t[stem].insert(int(rng.integers(1, len(t[stem]))), row)
        return f"orphan {row[0]!r} in {stem}"
    elif what == "no-samples":
        tid = pick(rng, SINK_IDS + SHEAR_IDS)
        for stem in ("sinkage", "shear"):
            t[stem] = [r for r in t[stem] if r[0] != tid]
    elif what == "unknown-kind":
        _set_cell(
            t,
            "tests",
            "kind",
            _pick_row(rng, t, "tests"),
            pick(rng, ["Sinkage", "plate", "", " shear", "SHEAR"]),
        )
    elif what == "unknown-shape":
        row = _tests_row(t, pick(rng, SINK_IDS))
        _set_cell(t, "tests", "shape", row, pick(rng, ["square", "Circle", "", "circle "]))
    elif what == "swap-kind":
        row = _tests_row(t, pick(rng, SINK_IDS))
        _set_cell(t, "tests", "kind", row, "shear")
    else:
        stem = pick(rng, ["sinkage", "shear"])
        row = t[stem][_pick_row(rng, t, stem)]
        t[stem].append(list(row))
    return what


def m_files(rng: np.random.Generator, t: Tables) -> tuple[str, dict[str, bytes | None]]:
    stem = _pick_stem(rng)
    name = f"{stem}.csv"
    raw = to_bytes(t[stem])
    what = pick(
        rng,
        [
            "empty",
            "header-only",
            "truncated",
            "latin-1",
            "bom",
            "utf-16",
            "crlf",
            "no-newline",
            "binary",
            "missing",
            "gzip",
            "nul-byte",
            "cr-only",
            "semicolon",
            "quote",
            "parquet-too",
            "blank-lines",
            "trailing-commas",
        ],
    )
    files: dict[str, bytes | None] = {}
    if what == "empty":
        files[name] = b""
    elif what == "header-only":
        files[name] = raw.split(b"\n", 1)[0] + b"\n"
    elif what == "truncated":
        files[name] = raw[: int(rng.integers(len(raw) // 4, len(raw) - 1))]
    elif what == "latin-1":
        t["tests"][1][_col(t["tests"], "soil")] = "soïl01"
        files["tests.csv"] = to_bytes(t["tests"], "latin-1")
    elif what == "bom":
        files[name] = b"\xef\xbb\xbf" + raw
    elif what == "utf-16":
        files[name] = raw.decode().encode("utf-16")
    elif what == "crlf":
        files[name] = raw.replace(b"\n", b"\r\n")
    elif what == "cr-only":
        files[name] = raw.replace(b"\n", b"\r")
    elif what == "no-newline":
        files[name] = raw.rstrip(b"\n")
    elif what == "binary":
        files[name] = bytes(rng.integers(0, 256, 2000, dtype=np.uint8))
    elif what == "missing":
        files[name] = None
    elif what == "gzip":
        import gzip

        files[name] = gzip.compress(raw)
    elif what == "nul-byte":
        k = int(rng.integers(len(raw) // 2, len(raw) - 1))
        files[name] = raw[:k] + b"\x00" + raw[k:]
    elif what == "semicolon":
        files[name] = raw.replace(b",", b";")
    elif what == "quote":
        k = int(rng.integers(len(raw) // 2, len(raw) - 1))
        files[name] = raw[:k] + b'"' + raw[k:]
    elif what == "parquet-too":
        files[f"{stem}.parquet"] = b"PAR1garbagePAR1"
    elif what == "blank-lines":
        files[name] = raw.replace(b"\n", b"\n\n", 3)
    else:
        files[name] = raw.replace(b"\n", b",\n")
    return f"{what} {name}", files


def m_metadata(rng: np.random.Generator, t: Tables) -> str:
    what = pick(
        rng,
        [
            "circle-with-width",
            "rect-no-length",
            "length<width",
            "shear-with-shape",
            "soil-formula",
            "soil-dollar",
            "huge-cell",
            "operator-blank",
            "sinkage-in-shear",
            "kind-case",
        ],
    )
    if what == "circle-with-width":
        _set_cell(t, "tests", "width_m", _tests_row(t, "shape-0001"), "0.1")
    elif what == "rect-no-length":
        _set_cell(t, "tests", "length_m", _tests_row(t, "shape-0007"), "")
    elif what == "length<width":
        _set_cell(t, "tests", "length_m", _tests_row(t, "shape-0007"), "0.01")
    elif what == "shear-with-shape":
        _set_cell(t, "tests", "shape", _tests_row(t, "shear-ring-0001"), "circle")
    elif what == "soil-formula":
        _set_cell(t, "tests", "soil", 1, '=HYPERLINK("x")')
    elif what == "soil-dollar":
        _set_cell(t, "tests", "soil", 1, "$x^{")
    elif what == "huge-cell":
        _set_cell(t, "tests", "operator", 1, "x" * 200_000)
    elif what == "operator-blank":
        _set_cell(t, "tests", "operator", 1, "")
    elif what == "sinkage-in-shear":
        row = list(t["shear"][1])
        row[0] = "shape-0001"
        t["shear"].append(row)
    else:
        _set_cell(t, "tests", "kind", 1, "Sinkage")
    return what


CAMPAIGN_MUTATIONS: dict[str, Callable] = {
    "columns": m_columns,
    "types": m_types,
    "values": m_values,
    "ids": m_ids,
    "files": m_files,
    "metadata": m_metadata,
}


# ----------------------------------------------------------------------- other surfaces
def runs_base() -> Table:
    from soilstats.data import bundled_path

    folder = bundled_path("cmu-3d-terramechanics")
    assert folder is not None
    with open(folder / "wheel.csv", newline="", encoding="utf-8") as fh:
        rows = list(csv.reader(fh))
    return rows[:13]


def s_runs(rng: np.random.Generator) -> tuple[str, object]:
    table = runs_base()
    head = table[0]
    column = pick(
        rng, ["run_id", "wheel", "slip", "W_N", "sinkage_m", "beta_deg", "drawbar_pull_N"]
    )
    j = head.index(column)
    row = int(rng.integers(1, len(table)))
    what = pick(rng, ["value", "duplicate-col", "missing-col", "blank-header", "dup-run"])
    if what == "value":
        value = pick(rng, [*BAD_NUMBERS, "001", "-20", "2000", "0"])
        table[row][j] = value
        what = f"{column} row {row} = {value!r}"
    elif what == "duplicate-col":
        for r in table:
            r.append(r[j])
    elif what == "missing-col":
        for r in table:
            del r[j]
    elif what == "blank-header":
        table[0][j] = ""
    else:
        table.append(list(table[row]))
    return what, to_bytes(table)


PRIORS = [
    "c=truncnormal:0:1:50:60",
    "c=normal:0:-1",
    "c=normal:0:nan",
    "phi=uniform:90:0",
    "c=lognormal:0:inf",
    "c=",
    "=normal:0:1",
    "c=normal",
    "c=normal:0:1:2",
    "c=truncnormal:0:1:8:60",
    "c=uniform:0:1e308",
    "c=beta:1:1",
    "c=normal:1e400:1",
    "phi=uniform:-100:100",
    "K=halfnormal:0",
    "n=uniform:0:0",
    "c=normal:0:1e-320",
    "kc=normal:0:1",
    "zz=normal:0:1",
    "c=normal:nan:1",
    "c=normal:0:1:60:50",
    "c=normal:0:1:5:5",
    "c=normal:-inf:1",
    "c=normal:٣:1",
    "c=normal:True:1",
    "c=normal:1_0:1",
]


def s_prior(rng: np.random.Generator) -> tuple[str, object]:
    text = pick(rng, PRIORS)
    return text, text


def s_frames(rng: np.random.Generator) -> tuple[str, object]:
    what = pick(
        rng,
        [
            "complex",
            "bool",
            "object-mixed",
            "dup-cols",
            "multiindex",
            "units-none",
            "units-str",
            "units-unknown",
            "int-ids",
            "nan-id",
            "category",
            "float32",
            "inf",
            "index-noncontiguous",
        ],
    )
    return what, what


def build_frames(what: str, t: Tables) -> tuple[dict, dict]:
    frames = {s: pd.DataFrame(v[1:], columns=v[0]) for s, v in t.items()}
    for s in ("sinkage", "shear"):
        for c in NUMERIC[s]:
            frames[s][c] = frames[s][c].astype(float)
    tests = frames["tests"]
    for c in NUMERIC["tests"]:
        if c in tests:
            tests[c] = pd.to_numeric(tests[c].replace("", np.nan))
    kwargs: dict = {}
    sink = frames["sinkage"]
    if what == "complex":
        sink["force_N"] = sink["force_N"].astype(complex) + 1j
    elif what == "bool":
        sink["force_N"] = sink["force_N"] > 5
    elif what == "object-mixed":
        sink["force_N"] = sink["force_N"].astype(object)
        sink.loc[3, "force_N"] = "x"
    elif what == "dup-cols":
        frames["sinkage"] = pd.concat([sink, sink[["force_N"]]], axis=1)
    elif what == "multiindex":
        sink.columns = pd.MultiIndex.from_tuples([(c, "") for c in sink.columns])
    elif what == "units-none":
        kwargs["units"] = {"z_m": None}
    elif what == "units-str":
        kwargs["units"] = "mm"
    elif what == "units-unknown":
        kwargs["units"] = {"z_m": "furlong"}
    elif what == "int-ids":
        tests["repetition"] = tests["repetition"].astype(int)
        ids = {tid: i + 1 for i, tid in enumerate(tests["test_id"])}
        for s in frames:
            frames[s]["test_id"] = frames[s]["test_id"].map(ids)
    elif what == "nan-id":
        sink.loc[2, "test_id"] = np.nan
    elif what == "category":
        tests["soil"] = tests["soil"].astype("category")
    elif what == "float32":
        sink["force_N"] = sink["force_N"].astype(np.float32)
    elif what == "inf":
        sink.loc[5, "z_m"] = np.inf
    else:
        frames["sinkage"] = sink.set_axis(range(100, 100 + len(sink)))
    return frames, kwargs


IMPORTS = [
    ('[tests]\nfile="log.csv"\nseparator=5\n[tests.columns]\ntest_id="Test"\n', "Test\na\n"),
    (
        '[tests]\nfile="log.csv"\nskip_rows=9223372036854775807\n[tests.columns]\ntest_id="Test"\n',
        "Test\na\n",
    ),
    (
        '[tests]\nfile="log.csv"\ndecimal=","\nseparator=";"\n[tests.columns]\ntest_id="Test"\n'
        'soil="Soil"\nradius_m={column="D",unit="mm",diameter=true}\n[tests.constant]\n'
        'kind="sinkage"\nshape="circle"\n',
        "Test;Soil;D\n1,5;s;100,0\n",
    ),
    (
        '[tests]\nfile="log.csv"\n[tests.columns]\ntest_id="Test"\nradius_m={column="D",'
        'diameter="no"}\n',
        "Test,D\na,1\n",
    ),
    ('[tests]\nfile="log.csv"\n[tests.columns]\ntest_id="Test"\n', "Test,Test\na,b\n"),
    ('[tests]\nfile="log.csv"\n[tests.columns]\ntest_id="Test"\n', "Test,\na,b\n"),
    ("[tests\nfile=", None),
    ('[tests]\nfile="nope.csv"\n[tests.columns]\ntest_id="Test"\n', None),
    ('[tests]\nfile="log.csv"\n[tests.columns]\ntest_id="Test"\n', "Test\n001\n002\n"),
    ('[tests]\nfile="log.csv"\nskip_rows=-1\n[tests.columns]\ntest_id="Test"\n', "Test\na\n"),
    ('[tests]\nfile="log.csv"\n[tests.columns]\ntest_id=5\n', "Test\na\n"),
    (
        '[tests]\nfile="log.csv"\n[tests.columns]\ntest_id="Test"\nvelocity_m_s={column="V",'
        "diameter=true}\n",
        "Test,V\na,1\n",
    ),
    ('[tests]\nfile="log.csv"\nencoding="klingon"\n[tests.columns]\ntest_id="Test"\n', "Test\na\n"),
    ('[tests]\nfile="../../../../etc/passwd"\n[tests.columns]\ntest_id="Test"\n', None),
    (
        '[tests]\nfile="log.csv"\n[tests.columns]\ntest_id="Test"\n[tests.constant]\nkind=1\n',
        "Test\na\n",
    ),
]


def s_import(rng: np.random.Generator) -> tuple[str, object]:
    k = int(rng.integers(0, len(IMPORTS)))
    return f"mapping {k}", IMPORTS[k]


SIM_EDITS = [
    ("n", "0"),
    ("n", "-1"),
    ("kphi", "0"),
    ("phi", "95"),
    ("c", "-1"),
    ("n", "nan"),
    ("n", "1e400"),
    ("kphi", "true"),
    ("n", '"x"'),
    ("phi", "90"),
    ("n", "[1, 2]"),
]


def s_simulate(rng: np.random.Generator) -> tuple[str, object]:
    k = int(rng.integers(0, len(SIM_EDITS) + 2))
    if k == len(SIM_EDITS):
        return "broken toml", "name = \n[["
    if k == len(SIM_EDITS) + 1:
        return "empty spec", ""
    return f"{SIM_EDITS[k][0]} = {SIM_EDITS[k][1]}", SIM_EDITS[k]


SURFACES: dict[str, Callable] = {
    "runs": s_runs,
    "prior": s_prior,
    "frames": s_frames,
    "import": s_import,
    "simulate": s_simulate,
}


def generate(count: int, seed: int) -> list[Case]:
    """``count`` cases drawn with ``seed``: three campaign cases for each other surface."""
    rng = np.random.default_rng(seed)
    base = base_tables()
    kinds = [*CAMPAIGN_MUTATIONS] * 3 + [*SURFACES]
    cases: list[Case] = []
    for i in range(count):
        kind = kinds[i % len(kinds)]
        t = {s: [list(r) for r in v] for s, v in base.items()}
        if kind in CAMPAIGN_MUTATIONS:
            result = CAMPAIGN_MUTATIONS[kind](rng, t)
            files: dict[str, bytes | None] = {f"{s}.csv": to_bytes(v) for s, v in t.items()}
            if isinstance(result, tuple):
                result, changed = result
                files.update(changed)
            cases.append(Case(f"{i:04d} {result}", kind, files))
        else:
            label, payload = SURFACES[kind](rng)
            case = Case(f"{i:04d} {kind}: {label}", kind, surface=kind, payload=payload)
            if kind == "frames":
                case.payload = (payload, t)
            cases.append(case)
    return cases


# ------------------------------------------------------------------------------ running
def write_case(case: Case, folder: Path) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for name, content in case.files.items():
        if content is not None:
            (folder / name).write_bytes(content)


def _cell_differs(text: str, value: object, numeric: bool) -> bool:
    if numeric:
        try:
            written = float(text) if text.strip() else math.nan
        except ValueError:
            return True
        got = float(value) if value is not None and not pd.isna(value) else math.nan
        return not (written == got or (math.isnan(written) and math.isnan(got)))
    got = "" if value is None or (isinstance(value, float) and math.isnan(value)) else str(value)
    return got != text


def silent_changes(case: Case, campaign) -> list[str]:
    """Cells of the written CSVs that the campaign holds differently (skipped tests aside)."""
    skipped = set(campaign.skipped["test_id"]) if len(campaign.skipped) else set()
    out: list[str] = []
    for stem in ("tests", "sinkage", "shear"):
        content = case.files.get(f"{stem}.csv")
        if content is not None:
            out += table_changes(stem, content, getattr(campaign, stem), skipped)
    return out


def table_changes(stem: str, content: bytes, table: pd.DataFrame, skipped: set) -> list[str]:
    """Cells of one written CSV that ``table`` (what the reader returned) holds differently."""
    try:
        rows = list(csv.reader(io.StringIO(content.decode("utf-8-sig"))))
    except (UnicodeDecodeError, csv.Error):
        return []  # the reader accepted what the stdlib cannot: judged by its own tests
    if not rows:
        return []
    head, body = rows[0], [r for r in rows[1:] if r and r[0] not in skipped]
    if len(body) != len(table):
        return [f"{stem}: {len(body)} rows written (skips aside), {len(table)} read"]
    out = []
    for j, column in enumerate(head):
        if column not in table.columns:
            out.append(f"{stem}: column {column!r} written, not in the table read")
            continue
        values = table[column].tolist()
        kind = table[column].dtype
        numeric = pd.api.types.is_numeric_dtype(kind) and not pd.api.types.is_bool_dtype(kind)
        for k, (r, v) in enumerate(zip(body, values, strict=True)):
            if j < len(r) and _cell_differs(r[j], v, numeric):
                out.append(f"{stem} row {k + 1} {column}: wrote {r[j]!r}, read {v!r}")
                break
    return out


def _classify_exception(exc: BaseException) -> tuple[str, str]:
    from soilstats.errors import SoilstatsError

    text = f"{type(exc).__name__}: {exc}"
    if isinstance(exc, SoilstatsError | OSError):
        return ("error" if NAMES.search(str(exc)) else "error-unnamed"), text
    return "traceback", text + "\n" + "".join(traceback.format_exception(exc)[-3:])


def run_library(case: Case, folder: Path) -> tuple[str, str]:
    """Read ``case`` with its library reader; (outcome, detail)."""
    from soilstats.errors import SoilstatsWarning

    with warnings.catch_warnings(record=True) as caught, np.errstate(all="ignore"):
        warnings.simplefilter("always")
        try:
            result = _read(case, folder)
        except Exception as exc:
            return _classify_exception(exc)
    ours = [w for w in caught if issubclass(w.category, SoilstatsWarning)]
    foreign = [
        w
        for w in caught
        if not issubclass(w.category, SoilstatsWarning)
        and not issubclass(w.category, DeprecationWarning | RuntimeWarning)
    ]
    if case.surface in ("campaign", "runs") and case.roundtrip:
        changes = (
            silent_changes(case, result)
            if case.surface == "campaign"
            else table_changes("runs", case.payload, result, set())  # type: ignore[arg-type]
        )
        if changes and not ours:
            return "silent-change", "; ".join(changes[:3])
    if foreign and not ours:
        return "silent-change", f"only a foreign warning: {foreign[0].message}"
    return ("ok-warned" if ours else "ok"), (str(ours[0].message)[:200] if ours else "")


def _read(case: Case, folder: Path) -> object:
    from soilstats.campaign import Campaign, import_campaign, load_campaign

    if case.surface == "campaign":
        return load_campaign(folder)
    if case.surface == "runs":
        from soilstats.wheel.runs import read_runs

        path = folder / "runs.csv"
        path.write_bytes(case.payload)  # type: ignore[arg-type]
        return read_runs(path)
    if case.surface == "prior":
        from soilstats.bayes.priors import priors_from_items
        from soilstats.bayes.stated_priors import parse_stated_prior, sample_priors

        name, _, spec = str(case.payload).partition("=")
        if ":" in spec and spec.split(":")[0].isalpha() and spec.split(":")[0] != "normal":
            prior = parse_stated_prior(spec)  # wheel --prior NAME=KIND:ARGS
            draws = sample_priors({name: prior}, 2000, 0)[name]
            if not np.all(np.isfinite(draws)):
                raise AssertionError(f"non-finite draws from {case.payload}")
            return draws
        return priors_from_items([str(case.payload)])  # posterior --prior NAME=SPEC
    if case.surface == "frames":
        what, t = case.payload  # type: ignore[misc]
        frames, kwargs = build_frames(what, t)
        return Campaign.from_frames(frames["tests"], frames["sinkage"], frames["shear"], **kwargs)
    if case.surface == "import":
        mapping, log = case.payload  # type: ignore[misc]
        (folder / "map.toml").write_text(mapping, encoding="utf-8")
        if log is not None:
            (folder / "log.csv").write_text(log, encoding="utf-8")
        return import_campaign(folder / "map.toml")
    if case.surface == "simulate":
        import tomllib

        from soilstats.data import bundled_path
        from soilstats.simulation.spec import load_spec, parse_spec

        payload = case.payload
        if isinstance(payload, str):
            (folder / "spec.toml").write_text(payload, encoding="utf-8")
            return load_spec(folder / "spec.toml")
        key, value = payload  # type: ignore[misc]
        spec_path = bundled_path("simulated-paper") / "spec.toml"  # type: ignore[operator]
        text = spec_path.read_text(encoding="utf-8")
        text, n = re.subn(rf"(?m)^{key} = [^\n#]+", f"{key} = {value}", text, count=1)
        if not n:
            raise AssertionError(f"no {key} in the spec")
        data = tomllib.loads(text)
        return parse_spec(data, source="spec.toml")
    raise ValueError(case.surface)


def run_cli(case_dir: Path, argv: list[str], timeout: float) -> tuple[str, str]:
    """Run ``soilstats ARGV`` in a forked child in ``case_dir``; (outcome, stderr tail)."""
    err_path = case_dir / ".stderr"
    pid = os.fork()
    if pid == 0:  # child
        code = 1
        try:
            os.chdir(case_dir)
            fd = os.open(err_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
            null = os.open(os.devnull, os.O_WRONLY)
            os.dup2(null, 1)
            os.dup2(fd, 2)
            sys.stdout = open(1, "w", closefd=False)
            sys.stderr = open(2, "w", closefd=False)
            signal.alarm(int(timeout))
            signal.signal(signal.SIGALRM, signal.SIG_DFL)
            from soilstats.cli.main import main

            code = main(argv)
            sys.stderr.flush()
        finally:
            os._exit(code)
    _, status = os.waitpid(pid, 0)
    err = err_path.read_text(encoding="utf-8", errors="replace") if err_path.exists() else ""
    if os.WIFSIGNALED(status):
        sig = os.WTERMSIG(status)
        return ("hang" if sig == signal.SIGALRM else "crash"), f"signal {sig}; {err[-300:]}"
    code = os.WEXITSTATUS(status)
    if "Traceback" in err or "internal error" in err:
        return "traceback", err[-600:]
    if code == 1 and "FORCED" in err:  # posterior --force: written although a check failed
        return "ok-warned", err[-300:]
    if code == 1:
        return "traceback", err[-600:]
    if code == 2:
        message = next((line for line in err.splitlines() if line.startswith("error:")), err)
        return ("error" if NAMES.search(message) else "error-unnamed"), message[:300]
    if code == 0:
        return ("ok-warned" if "warning:" in err else "ok"), ""
    return "traceback", f"exit {code}: {err[-300:]}"


COMMANDS = {
    "check": ["check", "."],
    "identify": ["identify", "."],
    "study": ["study", "tool-shape", ".", "--out", "out-study", "--no-pdf"],
    "posterior": [
        "posterior",
        ".",
        "--model",
        "bekker",
        "--draws",
        "400",
        "--force",
        "--out",
        "out-post",
    ],
    "discover": ["discover", "."],
}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seed", type=int, default=44)
    parser.add_argument("--count", type=int, default=320)
    parser.add_argument("--smoke", action="store_true", help="40 cases, library only")
    parser.add_argument(
        "--cli", default="", help="comma-separated subcommands: " + ",".join(COMMANDS)
    )
    parser.add_argument(
        "--cli-every", type=int, default=1, help="run the CLI on every k-th campaign case only"
    )
    parser.add_argument("--timeout", type=float, default=120)
    parser.add_argument("--keep", type=Path, help="write the cases here and keep them")
    parser.add_argument("--json", type=Path, help="write every outcome to this file")
    args = parser.parse_args(argv)
    count = 40 if args.smoke else args.count
    commands = [c for c in args.cli.split(",") if c] if not args.smoke else []
    for c in commands:
        if c not in COMMANDS:
            parser.error(f"unknown subcommand {c!r}")
    cases = generate(count, args.seed)
    root = args.keep or Path(tempfile.mkdtemp(prefix="malformed-"))
    rows: list[dict] = []
    started = time.perf_counter()
    for k, case in enumerate(cases):
        folder = root / re.sub(r"[^A-Za-z0-9_.-]+", "_", case.name)[:80]
        write_case(case, folder)
        outcome, detail = run_library(case, folder)
        rows.append(
            {
                "case": case.name,
                "category": case.category,
                "surface": "library",
                "outcome": outcome,
                "detail": detail,
            }
        )
        if case.surface == "campaign" and k % args.cli_every == 0:
            for c in commands:
                out, det = run_cli(folder, COMMANDS[c], args.timeout)
                rows.append(
                    {
                        "case": case.name,
                        "category": case.category,
                        "surface": c,
                        "outcome": out,
                        "detail": det,
                    }
                )
    elapsed = time.perf_counter() - started
    if not args.keep:
        shutil.rmtree(root, ignore_errors=True)
    report(rows, count, args, elapsed)
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1), encoding="utf-8")
    return 1 if any(r["outcome"] in FAILING for r in rows) else 0


def report(rows: list[dict], count: int, args: argparse.Namespace, elapsed: float) -> None:
    outcomes = ["ok", "ok-warned", "error", "error-unnamed", *FAILING]
    table = pd.DataFrame(rows)
    print(f"{count} cases, seed {args.seed}, {len(rows)} runs, {elapsed:.0f} s")
    for surface, part in table.groupby("surface", sort=False):
        counts = pd.crosstab(part["category"], part["outcome"]).reindex(
            columns=outcomes, fill_value=0
        )
        counts.loc["total"] = counts.sum()
        print(f"\n{surface}:\n{counts.to_string()}")
    bad = table[table["outcome"].isin([*FAILING, "error-unnamed"])]
    for r in bad.itertuples():
        print(f"\n[{r.outcome}] {r.surface} {r.case!r}\n  {r.detail[:500]}")


if __name__ == "__main__":
    sys.exit(main())
