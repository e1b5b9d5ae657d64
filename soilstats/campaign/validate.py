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

import numpy as np
import pandas as pd

from .._text import plural
from ..errors import CampaignError
from ._cells import TEXT_DTYPE, Numbers, blank, empty_samples, first_per_key, texts, typed
from .schema import KINDS, SHAPES, SPECS, spec

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
        self.raw, self.name, self.issues = raw, name, []
        self.ids = texts(raw["test_id"])
        self.kind = texts(raw["kind"])
        self.soil = texts(raw["soil"])
        self.shape = texts(raw["shape"]) if "shape" in raw.columns else None
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
                s = spec("tests", col)
                text = num.cell(i).strip()
                seen = f"{text!r} (not recorded)" if text and text != "nan" else "is empty"
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
                i, col, f"value {text!r} is not a finite number{comma} — fix the value in {col}"
            )
            return None
        return float(num.values[i])

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
                f"test_id {tid!r} is already used in row {first[tid]}; every test_id must be "
                "unique — rename one of the tests (and its samples) or remove the duplicate row",
            )
        else:
            first[tid] = i + 1
        if kind not in KINDS:
            self.add(
                i,
                "kind",
                f"value {kind!r} is not a known kind; valid kinds are {list(KINDS)} "
                "(case-sensitive) — fix the value",
            )
        if not self.soil[i].strip():
            self.add(i, "soil", "value is empty; every test needs its soil name — fill it in")
        rep = self.number(i, "repetition", needed=False)
        if rep is not None and rep != int(rep):
            self.add(i, "repetition", f"value {rep!r} is not a whole number — fix the value")
        if kind == "sinkage" and self.shape is not None and self.shape[i] not in SHAPES:
            shape = self.shape[i]
            problem = "is empty" if not shape.strip() else f"{shape!r} is not a known shape"
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
        g = self.number(i, "grousers", needed=shear)
        if shear and g is not None and (g < 0 or g != int(g)):
            self.add(i, "grousers", f"value {g!r} is not a whole number ≥ 0 — fix it")
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
    found: list[tuple[int, int, Issue]] = []  # (row position, column order, issue)

    def add(mask: np.ndarray, col: int, message: Callable[[int, str], str]) -> None:
        if not mask.any():
            return
        ids = uniq[codes]
        for pos, key, count in first_per_key(ids, mask):
            more = f" ({count} rows of this test have this problem)" if count > 1 else ""
            if count > 1 and not str(key).strip():  # rows of no test: say which rows
                rows = np.flatnonzero(mask & (ids == key))[:5] + 1
                listed = ", ".join(map(str, rows)) + (", …" if count > 5 else "")
                more = f" ({count} rows have no test_id: rows {listed})"
            issue = Issue(key, name, specs[col].name, pos + 1, message(pos, key) + more)
            found.append((pos, col, issue))

    def orphan_msg(pos: int, key: str) -> str:
        shown = list(log)[:5]
        return (
            f"test_id {key!r} is not in {tests_name} (which has {plural(len(log), 'test')}, "
            f"e.g. {shown}); every sample must belong to a test of the log — add the test to "
            f"{tests_name} or correct the test_id"
        )

    def other_msg(pos: int, key: str) -> str:
        kind, row = log[key]
        return (
            f"test {key!r} is of kind {kind!r} ({tests_name} row {row}), so its samples belong "
            f"in the {kind} file, not {name} — fix the test's kind or move the rows"
        )

    u_blank = blank(uniq)
    u_orphan = ~u_blank & np.array([u not in log for u in uniq], dtype=bool)
    other_kinds = set(KINDS) - {stem}
    u_other = np.array([u in log and log[u][0] in other_kinds for u in uniq], dtype=bool)
    empty, orphan, other = u_blank[codes], u_orphan[codes], u_other[codes]
    add(empty, 0, lambda p, k: "test_id is empty; every sample must name its test — fill it in")
    add(orphan, 0, orphan_msg)
    add(other, 0, other_msg)
    nums = {}
    for j, s in enumerate(specs[1:], start=1):
        num = nums[s.name] = Numbers(raw[s.name])

        def bad_msg(pos: int, key: str, num: Numbers = num) -> str:
            text = num.cell(pos)
            what = "is empty" if not text.strip() else f"{text!r} is not a finite number"
            comma = "; use '.' as the decimal separator" if "," in text else ""
            return f"value {what}{comma}; every sample must be numeric — fix or remove the row"

        add(~num.finite & ~empty & ~orphan, j, bad_msg)
    found.sort(key=lambda t: (t[0], t[1]))
    return typed(raw, stem, nums), [f[2] for f in found]


def _distinct_ids(series: pd.Series) -> tuple[np.ndarray, np.ndarray]:
    """(code of every row, the distinct test_id texts as an object array): the test_ids as
    written (:func:`texts`, missing → ``""``), factorized."""
    if series.dtype == TEXT_DTYPE and not series.hasnans:
        # Text with nothing missing (a CSV read as text): factorize the cells where pandas
        # holds them, not through a million Python strings.
        codes, uniq = pd.factorize(series)
        return codes, np.asarray(uniq, dtype=object)
    codes, uniq = pd.factorize(texts(series))
    return codes, np.asarray(uniq, dtype=object)


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
    tests = typed(raw, "tests", checker.num)
    log: dict[str, tuple[str, int]] = {}
    for i, (tid, kind) in enumerate(zip(checker.ids, checker.kind, strict=True)):
        if tid.strip():
            log.setdefault(tid, (kind, i + 1))
    samples: dict[str, pd.DataFrame] = {}
    late: list[Issue] = []
    for stem in ("sinkage", "shear"):
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
