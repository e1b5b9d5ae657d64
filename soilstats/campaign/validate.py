"""Every rule of the campaign format, each broken rule a :class:`CampaignError`.

:func:`validate` takes the three tables as read (CSV text cells, or typed Parquet/user
frames), checks them in a fixed order — the tests file row by row, then sinkage.csv, then
shear.csv, then the tests without samples — and returns typed tables. File-level problems
(a missing required column) always raise; a per-test problem raises too, unless the caller
asked to skip bad tests, in which case the test and all its samples are dropped and listed.

Messages say what is wrong, the value seen, the valid options and the fix; rows are 1-based
data rows, the header not counted.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import cast

import numpy as np
import pandas as pd

from .._text import plural, shown
from ..errors import CampaignError
from ._cells import (
    EXACT_WHOLE,
    TEXT_DTYPE,
    Numbers,
    blank,
    control_characters,
    empty_samples,
    first_control,
    first_per_key,
    texts,
    typed,
    without_controls,
)
from .schema import KINDS, MAX_CELL_CHARS, SHAPES, SPECS, ColumnSpec, spec

__all__ = ["SKIP_HINT", "Issue", "Tables", "validate"]

SKIP_HINT = ' (or load with on_error="skip" to drop the whole test with a listed reason)'
Frames = dict[str, tuple[pd.DataFrame | None, str]]
_WHO = {"circle": "a circular plate", "rectangle": "a rectangular plate", "shear": "a shear test"}


@dataclass(frozen=True)
class Issue:
    """One broken per-test rule; ``key`` is the test_id as written (may be ``""``)."""

    key: str
    file: str
    column: str | None
    row: int | None
    message: str

    def error(self) -> CampaignError:
        """The error to raise for this issue (with the hint that skipping is possible)."""
        tid = self.key if self.key.strip() else None
        return CampaignError(
            self.message + SKIP_HINT, file=self.file, column=self.column, test_id=tid, row=self.row
        )


@dataclass(frozen=True)
class Tables:
    """Typed tables of a campaign and its per-test issues (in scan order).

    The index of each table is the 0-based data row of the file it came from.
    """

    tests: pd.DataFrame
    sinkage: pd.DataFrame
    shear: pd.DataFrame
    issues: list[Issue]


def _require(frame: pd.DataFrame, stem: str, name: str, columns: list[str]) -> None:
    """File-level checks of one table: sizes of names and cells, unique names, ``columns``."""
    _check_cell_sizes(frame, name)
    if frame.columns.duplicated().any():
        dup = str(frame.columns[frame.columns.duplicated()][0])
        raise CampaignError(
            "the column appears more than once; every column name must be unique — rename "
            "or remove the repeated column",
            file=name,
            column=dup,
        )
    for col in columns:
        if col in frame.columns:
            continue
        have = [str(c) for c in frame.columns]
        near = [c for c in have if c.strip().lower() == col.lower()]
        hint = f" (found {near[0]!r}: names are matched exactly)" if near else ""
        # A spreadsheet's European export separates with ';' (or a tab): one long name.
        for sep, what in ((";", "semicolon"), ("\t", "tab")):
            if not near and len(have) == 1 and sep in str(have[0]):
                hint = (
                    f" (the header is one name holding '{sep}': the file looks "
                    f"{what}-separated; campaign files are comma-separated, with '.' as the "
                    "decimal separator)"
                )
        raise CampaignError(
            f"required column is missing{hint}; the file has columns {have}, and every "
            f"{stem} file needs {columns} — add or rename the column",
            file=name,
            column=col,
        )


class _TestsChecker:
    """Row-by-row checks of the log; collects issues in (row, column) order."""

    def __init__(self, raw: pd.DataFrame, name: str) -> None:
        self.raw, self.name = raw, name
        self.issues: list[Issue] = []
        self.ids = texts(raw["test_id"])
        self.kind = texts(raw["kind"])
        self.soil = texts(raw["soil"])
        self.shape = texts(raw["shape"]) if "shape" in raw.columns else None
        # Names that group tests: a control character would make a second, invisible group.
        self.controls = {
            c: control_characters(texts(raw[c]))
            for c in ("test_id", "soil", "preparation", "operator")
            if c in raw.columns
        }
        self.num = {
            s.name: Numbers(raw[s.name])
            for s in SPECS["tests"]
            if s.dtype != "text" and s.name in raw.columns
        }

    def add(self, i: int, column: str, message: str) -> None:
        self.issues.append(Issue(self.ids[i], self.name, column, i + 1, message))

    def needs(self, i: int) -> set[str]:
        """What test ``i`` is: the conditional needs it triggers ("sinkage", "circle", ...)."""
        kind = self.kind[i]
        out = {kind} if kind in KINDS else set()
        if kind == "sinkage" and self.shape is not None and self.shape[i] in SHAPES:
            out.add(self.shape[i])
        return out

    def require_conditional(self) -> None:
        """A conditional column absent from the file is a file-level error."""
        for s in SPECS["tests"]:
            if s.need in ("always", "optional") or s.name in self.raw.columns:
                continue
            for i in range(len(self.raw)):
                if s.need in self.needs(i):
                    raise CampaignError(
                        f"column is missing, but this test is a {s.need} test and needs it "
                        f"({s.meaning}); the file has columns {list(self.raw.columns)} — add "
                        f"the column '{s.name}'",
                        file=self.name,
                        column=s.name,
                        test_id=self.ids[i],
                        row=i + 1,
                    )

    def number(self, i: int, col: str, *, needed: bool) -> float | None:
        """Value of a numeric cell; adds an issue and returns None when unusable."""
        if col not in self.num:
            return None
        num = self.num[col]
        if num.missing[i]:
            if needed:
                s = cast(ColumnSpec, spec("tests", col))  # a column of the schema
                text = num.cell(i).strip()
                seen = f"{shown(text)} (not recorded)" if text and text != "nan" else "is empty"
                self.add(
                    i,
                    col,
                    f"value {seen}, but {_WHO[s.need]} needs {col} ({s.meaning}) — fill it in",
                )
            return None
        if num.bad[i] or not num.finite[i]:
            text = num.cell(i)
            comma = "; use '.' as the decimal separator" if "," in text else ""
            self.add(
                i,
                col,
                f"value {shown(text)} is not a finite number{comma} — fix the value in {col}",
            )
            return None
        if num.lost[i]:
            self.add(i, col, f"value {shown(num.cell(i))} {num.lost_reason(i)} — fix the value")
            return None
        return float(num.values[i])

    def whole(self, i: int, col: str, *, needed: bool, least: float | None = None) -> None:
        """A whole-number cell (``repetition``, ``grousers``): refused, never rounded, when
        float64 would hold another number than the one written."""
        value = self.number(i, col, needed=needed)
        if value is None:
            return
        num = self.num[col]
        at_least = f" ≥ {least:g}" if least is not None else ""
        if abs(value) >= EXACT_WHOLE:
            self.add(
                i,
                col,
                f"value {shown(num.cell(i))} is not below 2^53 = {EXACT_WHOLE:.0f}, the "
                "largest whole number float64 holds exactly (a larger one would be read as a "
                "neighbour) — fix the value",
            )
        elif not num.whole(i) or (least is not None and value < least):
            rounded = "" if num.whole(i) else f" (float64 would read it as {value!r})"
            rounded = rounded if value == int(value) else ""
            self.add(
                i,
                col,
                f"value {shown(num.cell(i))} is not a whole number{at_least}{rounded} — fix "
                "the value",
            )

    def controlled(self, i: int, col: str, what: str) -> None:
        """Refuse a name holding a control character (checked for every grouping name)."""
        if col in self.controls and self.controls[col][i]:
            text = texts(self.raw[col].iloc[i : i + 1])[0]
            self.add(
                i,
                col,
                f"{what} {shown(text)} holds a control character ({first_control(text)}); "
                "names are printable text and one with a hidden NUL, TAB or line break would "
                "match nothing — remove the character",
            )

    def run(self) -> list[Issue]:
        first: dict[str, int] = {}
        for i in range(len(self.raw)):
            self.check_row(i, first)
        return self.issues

    def check_row(self, i: int, first: dict[str, int]) -> None:
        tid, kind = self.ids[i], self.kind[i]
        needs = self.needs(i)
        if not tid.strip():
            self.add(i, "test_id", "test_id is empty; every test needs a unique id — fill it in")
        elif tid in first:
            self.add(
                i,
                "test_id",
                f"test_id {shown(tid)} is already used in row {first[tid]}; every test_id must be "
                "unique — rename one of the tests (and its samples) or remove the duplicate row",
            )
        else:
            first[tid] = i + 1
        self.controlled(i, "test_id", "test_id")
        if kind not in KINDS:
            self.add(
                i,
                "kind",
                f"value {shown(kind)} is not a known kind; valid kinds are {list(KINDS)} "
                "(case-sensitive) — fix the value",
            )
        if not self.soil[i].strip():
            self.add(i, "soil", "value is empty; every test needs its soil name — fill it in")
        self.controlled(i, "soil", "value")
        self.controlled(i, "preparation", "value")
        self.controlled(i, "operator", "value")
        self.whole(i, "repetition", needed=False)
        if kind == "sinkage" and self.shape is not None and self.shape[i] not in SHAPES:
            shape = self.shape[i]
            problem = "is empty" if not shape.strip() else f"{shown(shape)} is not a known shape"
            self.add(
                i,
                "shape",
                f"value {problem}; valid shapes of a sinkage plate are {list(SHAPES)} "
                "(case-sensitive) — fix the value",
            )
        radius = self.number(i, "radius_m", needed="circle" in needs)
        if "circle" in needs and radius is not None and radius <= 0:
            self.add(i, "radius_m", f"value {radius!r} is not a positive radius — fix it")
        width = self.number(i, "width_m", needed="rectangle" in needs)
        if "rectangle" in needs and width is not None and width <= 0:
            self.add(i, "width_m", f"value {width!r} is not a positive width — fix it")
        length = self.number(i, "length_m", needed="rectangle" in needs)
        if "rectangle" in needs and length is not None and width is not None and length < width:
            self.add(
                i,
                "length_m",
                f"value {length!r} is shorter than width_m {width!r}; length_m is the long "
                "side (length ≥ width) — swap the two values",
            )
        self.positive_if_given(i, "velocity_m_s")
        self.check_ring(i, "shear" in needs)
        self.positive_if_given(i, "omega_rpm")

    def positive_if_given(self, i: int, col: str) -> None:
        v = self.number(i, col, needed=False)
        if v is not None and v <= 0:
            self.add(
                i, col, f"value {v!r} is not positive — fix it, or leave it empty if not recorded"
            )

    def check_ring(self, i: int, shear: bool) -> None:
        ri = self.number(i, "r_inner_m", needed=shear)
        if shear and ri is not None and ri < 0:
            self.add(i, "r_inner_m", f"value {ri!r} is negative; r_inner_m ≥ 0 — fix it")
        ro = self.number(i, "r_outer_m", needed=shear)
        if shear and ro is not None and ri is not None and ro <= ri:
            self.add(
                i,
                "r_outer_m",
                f"value {ro!r} is not larger than r_inner_m {ri!r}; a ring needs "
                "r_outer_m > r_inner_m — fix or swap the radii",
            )
        if shear:
            self.whole(i, "grousers", needed=True, least=0)
        else:
            self.number(i, "grousers", needed=False)
        h = self.number(i, "grouser_height_m", needed=shear)
        if shear and h is not None and h < 0:
            self.add(i, "grouser_height_m", f"value {h!r} is negative; it must be ≥ 0 — fix it")


def _check_samples(
    raw: pd.DataFrame, stem: str, name: str, log: dict[str, tuple[str, int]], tests_name: str
) -> tuple[pd.DataFrame, list[Issue]]:
    """Check one sample table (vectorised: one issue per test and problem, at its first row)."""
    specs = SPECS[stem]
    _require(raw, stem, name, [s.name for s in specs])
    # Judge each distinct test_id once (a few per test), then spread to the rows.
    codes, uniq = _distinct_ids(raw["test_id"])
    u_blank = blank(uniq)
    u_orphan = ~u_blank & np.array([u not in log for u in uniq], dtype=bool)
    # An id with a control character ('c1\x00') is refused, not taken for an unknown test:
    # it is counted against the test it names without them, so skipping drops that test
    # whole instead of keeping it short of the rows written with the stray character.
    u_control = u_orphan & control_characters(uniq)
    u_orphan &= ~u_control
    keys = _meant_ids(uniq, u_control, log)[codes]
    found: list[tuple[int, int, Issue]] = []  # (row position, column order, issue)

    def add(mask: np.ndarray, col: int, message: Callable[[int, str], str]) -> None:
        if not mask.any():
            return
        for pos, key, count in first_per_key(keys, mask):
            more = f" ({count} rows of this test have this problem)" if count > 1 else ""
            if count > 1 and not str(key).strip():  # rows of no test: say which rows
                rows = np.flatnonzero(mask & (keys == key))[:5] + 1
                listed = ", ".join(map(str, rows)) + (", …" if count > 5 else "")
                more = f" ({count} rows have no test_id: rows {listed})"
            issue = Issue(key, name, specs[col].name, pos + 1, message(pos, key) + more)
            found.append((pos, col, issue))

    def orphan_msg(pos: int, key: str) -> str:
        examples = ", ".join(shown(k) for k in list(log)[:5])
        return (
            f"test_id {shown(key)} is not in {tests_name} (which has "
            f"{plural(len(log), 'test')}, e.g. [{examples}]); every sample must belong to a "
            f"test of the log — add the test to {tests_name} or correct the test_id"
        )

    def control_msg(pos: int, key: str) -> str:
        written = uniq[codes[pos]]
        meant = f" (test {shown(key)} without it)" if key != written else ""
        return (
            f"test_id {shown(written)} holds a control character ({first_control(written)})"
            f"{meant}; ids are printable text — remove the character"
        )

    def other_msg(pos: int, key: str) -> str:
        kind, row = log[key]
        return (
            f"test {shown(key)} is of kind {kind!r} ({tests_name} row {row}), so its samples "
            f"belong in the {kind} file, not {name} — fix the test's kind or move the rows"
        )

    other_kinds = set(KINDS) - {stem}
    u_other = np.array([u in log and log[u][0] in other_kinds for u in uniq], dtype=bool)
    empty, orphan, other = u_blank[codes], u_orphan[codes], u_other[codes]
    unknown = orphan | u_control[codes]
    add(empty, 0, lambda p, k: "test_id is empty; every sample must name its test — fill it in")
    add(u_control[codes], 0, control_msg)
    add(orphan, 0, orphan_msg)
    add(other, 0, other_msg)
    nums = {}
    for j, s in enumerate(specs[1:], start=1):
        num = nums[s.name] = Numbers(raw[s.name])

        def bad_msg(pos: int, key: str, num: Numbers = num) -> str:
            text = num.cell(pos)
            if num.finite[pos]:
                what = f"{shown(text)} {num.lost_reason(pos)}"
            elif not text.strip():
                what = "is empty"
            else:
                what = f"{shown(text)} is not a finite number"
            comma = "; use '.' as the decimal separator" if "," in text else ""
            return f"value {what}{comma}; every sample must be numeric — fix or remove the row"

        add((~num.finite | num.lost) & ~empty & ~unknown, j, bad_msg)
    _check_extras(raw, stem, name, nums)
    found.sort(key=lambda t: (t[0], t[1]))
    return typed(raw, stem, nums), [f[2] for f in found]


def _meant_ids(uniq: np.ndarray, control: np.ndarray, log: dict) -> np.ndarray:
    """Each distinct test_id, or for one with a control character the logged id it names
    without them (the test whose samples those rows are)."""
    meant = uniq.copy()
    for k in np.flatnonzero(control):
        clean = without_controls(uniq[k])
        if clean in log:
            meant[k] = clean
    return meant


def _check_extras(raw: pd.DataFrame, stem: str, name: str, nums: dict[str, Numbers]) -> None:
    """Parse the covariate columns (into ``nums``, for :func:`typed`) and refuse a numeric one
    holding a number float64 would change (a 17-digit serial number, 1e-400).

    A covariate whose every cell is a number becomes float64 (the format's rule); rounding
    one of its cells would change the data without a word. File-level: the column's type,
    not one test, is at stake.
    """
    for col in raw.columns:
        if spec(stem, col) is not None:
            continue
        num = nums[col] = Numbers(raw[col])
        if num.bad.any() or pd.api.types.is_bool_dtype(raw[col].dtype):
            continue  # a text column: every cell kept as written
        lost = np.flatnonzero(num.lost)
        if lost.size:
            i = int(lost[0])
            raise CampaignError(
                f"value {shown(num.cell(i))} {num.lost_reason(i)}; a column whose cells are "
                "all numbers is read as float64 — write the value as text (e.g. with a "
                "letter: 'SN…') or fix it",
                file=name,
                column=str(col),
                test_id=_test_of(raw, i),
                row=i + 1,
            )


def _test_of(raw: pd.DataFrame, i: int) -> str | None:
    """The test_id of row ``i`` as written, for a file-level error (None if it has none)."""
    if "test_id" not in raw.columns:
        return None
    tid = texts(raw["test_id"].iloc[i : i + 1])[0]
    return tid if tid.strip() and len(tid) <= MAX_CELL_CHARS else None


def _first_too_long(series: pd.Series) -> tuple[int, int] | None:
    """(position, length) of the first text cell longer than :data:`MAX_CELL_CHARS`, or
    None. Arrow-held text (a CSV) is measured in Arrow: a million cells in milliseconds."""
    dtype = series.dtype
    if isinstance(dtype, pd.CategoricalDtype):
        return _first_too_long(series.astype(object))
    if isinstance(dtype, pd.StringDtype) and dtype.storage == "pyarrow":
        import pyarrow as pa  # deferred: pyarrow (the parquet extra)
        import pyarrow.compute as pc  # deferred: pyarrow (the parquet extra)

        lengths = pc.utf8_length(pa.array(series.array))
        longest = pc.max(lengths).as_py()
        if longest is None or longest <= MAX_CELL_CHARS:
            return None
        i = pc.index(pc.greater(lengths, MAX_CELL_CHARS), True).as_py()
        return i, int(lengths[i].as_py())
    if not (isinstance(dtype, pd.StringDtype) or pd.api.types.is_object_dtype(dtype)):
        return None  # typed numbers hold no text
    try:  # pandas' vectorised length (NaN for a cell that is not text): no Python loop
        lengths = series.str.len().to_numpy(dtype=float, na_value=np.nan)
    except AttributeError:  # an object column without text (numbers, None)
        return None
    too_long = np.flatnonzero(lengths > MAX_CELL_CHARS)
    return (int(too_long[0]), int(lengths[too_long[0]])) if too_long.size else None


def _check_cell_sizes(raw: pd.DataFrame, name: str) -> None:
    """Refuse a column name or cell beyond :data:`~.schema.MAX_CELL_CHARS` (a broken file)."""
    for k, col in enumerate(raw.columns, start=1):
        if len(str(col)) > MAX_CELL_CHARS:
            raise CampaignError(
                f"column {k} of the header is {len(str(col))} characters long; a column name "
                f"(like every cell) holds at most {MAX_CELL_CHARS} — a broken header (a quote "
                "left open?): fix or re-export the file",
                file=name,
                column=str(col),
            )
    for col in raw.columns:
        found = _first_too_long(raw[col])
        if found is None:
            continue
        i, length = found
        raise CampaignError(
            f"the cell is {length} characters long; a campaign cell holds at most "
            f"{MAX_CELL_CHARS} (no name, number or note needs more) — a quote left open "
            "swallows the lines after it, or the file is not text: fix the file here",
            file=name,
            column=str(col),
            test_id=None if col == "test_id" else _test_of(raw, i),
            row=i + 1,
        )


def _distinct_ids(series: pd.Series) -> tuple[np.ndarray, np.ndarray]:
    """(code of every row, the distinct test_id texts as an object array): the test_ids as
    written (:func:`texts`, missing → ``""``), factorized."""
    if series.dtype == TEXT_DTYPE and not series.hasnans:
        # Text with nothing missing (a CSV read as text): factorize the cells where pandas
        # holds them, not through a million Python strings.
        codes, uniq = pd.factorize(series)
        return codes, np.asarray(uniq, dtype=object)
    codes, distinct = pd.factorize(texts(series))
    return codes, np.asarray(distinct, dtype=object)


def validate(frames: Frames) -> Tables:
    """Check a campaign against every rule of the format and return its typed tables.

    Parameters
    ----------
    frames : dict
        File stem (``"tests"``, ``"sinkage"``, ``"shear"``) → (frame as read, or None when
        the file is absent; file name for messages). ``tests`` must not be None.

    Returns
    -------
    Tables
        Typed tables (including any rows with problems) and every per-test issue, in the
        order a reader meets them: tests file, sinkage file, shear file, tests without
        samples.

    Raises
    ------
    CampaignError
        For a file-level problem: a required column missing (including a conditional one
        some test needs), a repeated column name, or a log without rows.
    """
    raw, tests_name = frames["tests"]
    if raw is None:
        raise CampaignError("a campaign needs its test log — add tests.csv", file=tests_name)
    _require(raw, "tests", tests_name, [s.name for s in SPECS["tests"] if s.need == "always"])
    if len(raw) == 0:
        raise CampaignError(
            "the log has no tests; a campaign needs at least one test — add a row per test",
            file=tests_name,
        )
    checker = _TestsChecker(raw, tests_name)
    checker.require_conditional()
    issues = checker.run()
    parsed = dict(checker.num)
    _check_extras(raw, "tests", tests_name, parsed)
    tests = typed(raw, "tests", parsed)
    log: dict[str, tuple[str, int]] = {}
    for i, (tid, kind) in enumerate(zip(checker.ids, checker.kind, strict=True)):
        if tid.strip():
            log.setdefault(tid, (kind, i + 1))
    samples: dict[str, pd.DataFrame] = {}
    late: list[Issue] = []
    for stem in KINDS:  # the sample file of each kind
        frame, name = frames[stem]
        if frame is None:
            samples[stem] = empty_samples(stem)
            late += [
                Issue(
                    tid,
                    tests_name,
                    "kind",
                    row,
                    f"the test is of kind {stem!r} but the "
                    f"campaign has no {stem}.csv (or {stem}.parquet) — add the file with its "
                    "samples or remove the test",
                )
                for tid, (kind, row) in log.items()
                if kind == stem
            ]
            continue
        samples[stem], found = _check_samples(frame, stem, name, log, tests_name)
        issues += found
        counts = samples[stem]["test_id"].value_counts()
        late += [
            Issue(
                tid,
                name,
                "test_id",
                None,
                f"the test ({tests_name} row {row}, kind "
                f"{stem!r}) has no samples in {name}; every test needs at least one sample "
                f"— add its samples or remove it from {tests_name}",
            )
            for tid, (kind, row) in log.items()
            if kind == stem and tid not in counts.index
        ]
    return Tables(tests, samples["sinkage"], samples["shear"], issues + late)
