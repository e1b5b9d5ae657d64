"""The :class:`Campaign`: a validated test log, its samples and their derived quantities."""

from __future__ import annotations

import os
import re
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal, Self

import numpy as np
import pandas as pd

from ..errors import RENAMED_GO_IN, CampaignError, InputError, SoilstatsWarning
from . import io
from ._cells import TEXT_DTYPE, without_controls
from .derived import add_sample_columns, add_test_columns
from .derived_checks import derived_issues
from .digest import campaign_sha256
from .frame_checks import check_frame
from .index import campaign_index, grouped_by_code
from .log_warnings import warn_unlikely_log_cells
from .matching import match_values, values_present
from .near_names import warn_near_names
from .schema import DERIVED_COLUMNS, FILES, KINDS, spec
from .summary import describe
from .units import check_plausible_units, convert_columns
from .validate import Frames, Issue, validate
from .window import AppliedWindow, FitWindow

__all__ = ["SKIPPED_COLUMNS", "Campaign", "load_campaign"]

OnError = Literal["raise", "skip"]
#: Columns of :attr:`Campaign.skipped`.
SKIPPED_COLUMNS: tuple[str, ...] = ("test_id", "file", "column", "row", "reason")


def _skipped_table(issues: list[Issue]) -> pd.DataFrame:
    """One row per skipped test: its first problem, and how many more it has."""
    by_key: dict[str, list[Issue]] = {}
    for issue in issues:
        by_key.setdefault(issue.key, []).append(issue)
    rows = []
    for key, found in by_key.items():
        first, more = found[0], len(found) - 1
        extra = (
            f" (and {more} more problem{'s' if more > 1 else ''} with this test)" if more else ""
        )
        rows.append((key, first.file, first.column, first.row, first.message + extra))
    cols: list = list(zip(*rows, strict=True)) if rows else [[]] * len(SKIPPED_COLUMNS)
    out = {
        c: pd.Series(list(v), dtype="Int64" if c == "row" else TEXT_DTYPE)
        for c, v in zip(SKIPPED_COLUMNS, cols, strict=True)
    }
    return pd.DataFrame(out)


def _skipped_item(r: Any) -> str:  # a row of skipped.itertuples()
    """One skipped entry for the warning: 'id' (file, column, row: reason), or for rows that
    name no test, the rows themselves."""
    reason = r.reason.split(";")[0].split(" — ")[0]
    row = "" if pd.isna(r.row) else f", row {r.row}"
    if str(r.test_id).strip():
        return f"{r.test_id!r} ({r.file}, column {r.column!r}{row}: {reason})"
    rows = re.search(r"rows ([0-9, …]+)\)$", r.reason)
    row = f", rows {rows.group(1)}" if rows else row
    return f"{r.file}, column {r.column!r}{row}: {reason}"


def _check_on_error(on_error: str) -> None:
    if on_error not in ("raise", "skip"):
        raise InputError(f"on_error={on_error!r} is not an option; use 'raise' or 'skip'")


def _check_derived(
    given: pd.Series, computed: pd.Series, name: str, col: str, ids: pd.Series
) -> None:
    """An input column named like a derived one must agree with the computed value."""
    g = pd.to_numeric(given, errors="coerce").to_numpy(dtype=np.float64, na_value=np.nan)
    c = computed.to_numpy(dtype=np.float64, na_value=np.nan)
    ok = np.isclose(g, c, rtol=1e-9, atol=0.0, equal_nan=True)
    if ok.all():
        return
    i = int(np.flatnonzero(~ok)[0])
    raise CampaignError(
        f"this column is computed by soilstats, and the value given, {_cell(given.iloc[i])}, "
        f"differs from the computed {float(c[i])!r} — drop the column (soilstats adds it; see "
        "docs/campaign-format.md for how it is computed)",
        file=name,
        column=col,
        test_id=str(ids.iloc[i]),
        row=int(given.index[i]) + 1,
    )


def _cell(value: str | float) -> str:
    """A cell as its file shows it: text quoted, a number (Parquet) as a plain float."""
    return repr(value) if isinstance(value, str) else repr(float(value))


def _derive(tables: dict[str, pd.DataFrame]) -> tuple[dict, dict]:
    """The tables with their derived columns appended, and the derived columns the input
    held (to compare); the index of each table stays the original data row."""
    given = {s: {c: tables[s][c] for c in DERIVED_COLUMNS[s] if c in tables[s]} for s in FILES}
    base = {s: tables[s].drop(columns=list(given[s])) for s in FILES}
    ids = pd.concat([base["sinkage"]["test_id"], base["shear"]["test_id"]], ignore_index=True)
    n = ids.value_counts().reindex(base["tests"]["test_id"].to_numpy(), fill_value=0)
    # Over- and underflow are judged by derived_issues, per test, not warned of per array.
    with np.errstate(over="ignore", divide="ignore", invalid="ignore", under="ignore"):
        tests = add_test_columns(base["tests"], n.to_numpy())
        sinkage, shear = add_sample_columns(tests, base["sinkage"], base["shear"])
    return {"tests": tests, "sinkage": sinkage, "shear": shear}, given


def _without(tables: dict[str, pd.DataFrame], bad: list[str]) -> dict[str, pd.DataFrame]:
    """The tables without the tests ``bad`` (and their samples).

    A row whose id differs from a bad test's only by control characters (``'c1\x00'``) was
    counted against that test by validation, so it goes with it: left behind it would be an
    orphan row of no test (issue #44).
    """
    gone = set(bad)

    def dropped(ids: pd.Series) -> np.ndarray:
        text = ids.astype(str)
        return (text.isin(gone) | text.map(without_controls).isin(gone)).to_numpy(dtype=bool)

    return {s: f[~dropped(f["test_id"])] for s, f in tables.items()}


def _build(frames: Frames, *, source: str, on_error: OnError, check_units: bool) -> Campaign:
    _check_on_error(on_error)
    tables = validate(frames)
    if tables.issues and on_error == "raise":
        raise tables.issues[0].error()
    file_names = {s: name for s, (_, name) in frames.items()}
    kept = _without({s: getattr(tables, s) for s in FILES}, [i.key for i in tables.issues])
    out, given = _derive(kept)
    late = derived_issues(out, file_names)
    if late and on_error == "raise":
        raise late[0].error()
    issues = tables.issues + late
    out = _without(out, [i.key for i in late])
    if out["tests"].empty:
        raise CampaignError(
            f"every test was skipped ({len({i.key for i in issues})}); the first problem: "
            f"{issues[0].message} — fix the campaign (see campaign.skipped of a partial load "
            "for the reasons)",
            file=issues[0].file,
        )
    for s in FILES:
        for col, values in given[s].items():
            _check_derived(
                values.loc[out[s].index], out[s][col], file_names[s], col, out[s]["test_id"]
            )
    out = {s: f.reset_index(drop=True) for s, f in out.items()}
    skipped = _skipped_table(issues)
    if len(skipped):
        listed = "; ".join(_skipped_item(r) for r in skipped.itertuples())
        n_tests = int(sum(bool(str(t).strip()) for t in skipped["test_id"]))
        plural = "s" if n_tests != 1 else ""
        parts = [f"{n_tests} test{plural} with all their samples"] if n_tests else []
        if n_tests < len(skipped):
            parts.append("the rows without a test_id")
        what = " and ".join(parts)
        warnings.warn(
            f"skipped {what}: {listed}. The reasons are in campaign.skipped.",
            SoilstatsWarning,
            stacklevel=3,  # the caller of load_campaign or from_frames
        )
    warn_near_names(out, file_names)
    warn_unlikely_log_cells(out["tests"], file_names["tests"])
    if check_units:
        check_plausible_units(out["tests"], out["sinkage"], out["shear"], file_names)
    return Campaign(out["tests"], out["sinkage"], out["shear"], source, skipped, files=file_names)


def load_campaign(
    path_or_name: str | os.PathLike[str] | Mapping[str, pd.DataFrame],
    *,
    on_error: OnError = "raise",
    check_units: bool = True,
) -> Campaign:
    """Read and validate a campaign folder, or a bundled campaign by name.

    Parameters
    ----------
    path_or_name : str, os.PathLike or mapping of DataFrames
        A folder holding ``tests.csv`` (or ``.parquet``) and the sample files, or the name of
        a bundled campaign (:func:`bundled_campaigns`). A ``str`` equal to a bundled name
        means the bundled campaign; pass a :class:`pathlib.Path` for a local folder. A
        mapping ``{"tests": df, "sinkage": df, "shear": df}`` (sample tables optional) is
        checked exactly like a folder (see :meth:`Campaign.from_frames`).
    on_error : {"raise", "skip"}
        ``"raise"`` (default): raise the first broken rule, scanning tests file, sinkage file,
        shear file. ``"skip"``: drop every test that breaks a per-test rule with all its
        samples, list them in :attr:`Campaign.skipped` and emit one
        :class:`~soilstats.errors.SoilstatsWarning`. File-level problems always raise.
    check_units : bool
        Check that values are plausible in the format's SI units
        (:func:`soilstats.campaign.units.check_plausible_units`: sinkage or tool sizes that
        only make sense in mm stop the load; forces, torques, angles that look like kN,
        N·mm or degrees warn). Turn off only for data you know to be unusual.

    Returns
    -------
    Campaign

    Raises
    ------
    CampaignError
        For an unknown name or path, an unreadable or ambiguous file, or a broken rule.
    """
    _check_on_error(on_error)
    if isinstance(path_or_name, Mapping):
        unknown = sorted(set(path_or_name) - set(FILES))
        if unknown or "tests" not in path_or_name:
            raise CampaignError(
                f"a campaign given as tables needs the keys 'tests' and optionally 'sinkage', "
                f"'shear'; got {sorted(path_or_name)}",
                file="tests.csv",
            )
        return Campaign.from_frames(**path_or_name, on_error=on_error, check_units=check_units)  # type: ignore[arg-type]  # mypy matches **frames against every keyword; the tables are DataFrames
    if not isinstance(path_or_name, str | os.PathLike):
        raise CampaignError(
            f"load_campaign takes a folder, a bundled name or a dict of DataFrames, not "
            f"{type(path_or_name).__name__}",
        )
    folder, source = io.resolve(path_or_name)
    return _build(io.read_folder(folder), source=source, on_error=on_error, check_units=check_units)


@dataclass(frozen=True, eq=False, repr=False)
class Campaign:
    """A validated Bevameter campaign (see ``docs/campaign-format.md``).

    Build one with :func:`load_campaign` or :meth:`from_frames`; treat the tables as
    read-only (methods return new campaigns, they never modify this one).

    Attributes
    ----------
    tests : DataFrame
        The log as read — every column, extra covariates included, in file order — plus the
        derived ``b_m`` [m], ``area_m2`` [m²], ``aspect_ratio`` [-] (sinkage tests),
        ``ring_area_m2`` [m²] (shear tests) and ``n_samples``; NaN where not applicable.
    sinkage : DataFrame
        ``test_id``, ``z_m`` [m], ``force_N`` [N], any extra columns, and ``pressure_Pa``
        (Eq. 6). Rows in file order; readings with z ≤ 0 or force ≤ 0 are kept.
    shear : DataFrame
        ``test_id``, ``angle_rad``, ``torque_Nm`` [N m], ``normal_force_N`` [N], extras, and
        ``sigma_Pa`` [Pa], ``tau_Pa`` [Pa] (Eq. 12), ``j_m`` [m] (Eq. 14).
    source : str
        Folder path, ``"bundled:<name>"`` or ``"<memory>"``.
    skipped : DataFrame
        Tests dropped by ``on_error="skip"``: test_id, file, column, row, reason.
    window : AppliedWindow or None
        Set by :meth:`windowed`: the fitting window whose samples were removed, with its
        per-test counts. None: no window applied.
    files : mapping of str to str
        File stem → the file name the table was read from (``sinkage.parquet``), for
        messages; ``<stem>.csv`` for tables given in memory. See :meth:`file_name`.

    A campaign holds the campaign format's data and nothing of the analyses built on it
    (docs/conventions.md, "Layers"): screening (:func:`soilstats.quality.screen`) returns
    its :class:`~soilstats.quality.QualityReport`, whose ``campaign`` — a
    :class:`~soilstats.quality.ScreenedCampaign`, this class with the report beside the
    tables — is what analyses take.
    """

    tests: pd.DataFrame
    sinkage: pd.DataFrame
    shear: pd.DataFrame
    source: str = "<memory>"
    skipped: pd.DataFrame = field(default_factory=lambda: _skipped_table([]))
    window: AppliedWindow | None = None
    files: Mapping[str, str] = field(default_factory=lambda: {s: f"{s}.csv" for s in FILES})

    def file_name(self, stem: str) -> str:
        """The file a table (``"tests"``, ``"sinkage"``, ``"shear"``) was read from, as
        error messages name it: ``sinkage.parquet`` for a Parquet campaign."""
        return self.files.get(stem, f"{stem}.csv")

    @classmethod
    def from_frames(
        cls,
        tests: pd.DataFrame,
        sinkage: pd.DataFrame | None = None,
        shear: pd.DataFrame | None = None,
        *,
        source: str = "<memory>",
        on_error: OnError = "raise",
        units: Mapping[str, str] | None = None,
        check_units: bool = True,
    ) -> Campaign:
        """Validate in-memory tables exactly like :func:`load_campaign`.

        Messages call the tables ``tests.csv``, ``sinkage.csv`` and ``shear.csv``; rows are
        1-based positions in the frames. Columns named like derived ones (e.g. the
        ``tests`` of another campaign) must agree with the recomputed values.

        ``units`` maps format columns to the unit their values are given in, e.g.
        ``{"z_m": "mm", "force_N": "kN", "radius_m": "mm"}``; they are converted to SI
        before validation (units per column: :data:`soilstats.campaign.units.UNITS`). The
        input frames are never modified. ``check_units`` as in :func:`load_campaign`.
        """
        frames: Frames = {}
        if units is not None and (
            not isinstance(units, Mapping)
            or not all(isinstance(k, str) and isinstance(v, str) for k, v in units.items())
        ):
            raise InputError(
                f"units must map format column names to unit texts, e.g. {{'z_m': 'mm'}}; "
                f"got {units!r}"
            )
        for stem, frame in zip(FILES, (tests, sinkage, shear), strict=True):
            if frame is not None and not isinstance(frame, pd.DataFrame):
                raise TypeError(f"{stem} must be a pandas DataFrame or None, not {type(frame)}")
            if frame is not None:
                check_frame(frame, f"{stem}.csv")
            if units:
                frame = convert_columns(frame, units, f"{stem}.csv")
            frames[stem] = (frame, f"{stem}.csv")
        if units:
            known = {c for f, _ in frames.values() if f is not None for c in f.columns}
            missing = sorted(set(units) - known)
            if missing:
                raise CampaignError(
                    f"units given for {missing}, which no table has; units name format "
                    "columns such as z_m, force_N, radius_m",
                    column=missing[0],
                )
        return _build(frames, source=source, on_error=on_error, check_units=check_units)

    @property
    def covariates(self) -> list[str]:
        """Extra (non-format, non-derived) columns of the log, in file order."""
        derived = DERIVED_COLUMNS["tests"]
        return [c for c in self.tests.columns if spec("tests", c) is None and c not in derived]

    def select(self, **criteria: Any) -> Self:
        """Keep the tests that meet every criterion, with their samples.

        Parameters
        ----------
        **criteria
            ``column=value`` on any column of :attr:`tests` (format, covariate or derived):
            a scalar keeps equal values (None/NaN keeps missing ones), a list, tuple, set or
            array keeps members, a callable gets the column (a Series) and returns a bool
            mask. Use ``select(**{"odd-name": v})`` for names that are not identifiers.

        Returns
        -------
        Campaign
            A new campaign of this one's class (same source, skipped list, window and, for a
            screened campaign, report).

        Raises
        ------
        CampaignError
            For an unknown column, or if no test meets all criteria.
        """
        mask = self.matches(**criteria)
        keep = self.tests["test_id"][mask]
        return replace(
            self,
            tests=self.tests[mask].reset_index(drop=True),
            sinkage=self._rows_of(self.sinkage, keep),
            shear=self._rows_of(self.shear, keep),
        )

    def matches(self, **criteria: Any) -> np.ndarray:
        """Boolean mask over :attr:`tests` of the tests :meth:`select` keeps (same criteria,
        same errors), for analyses that need the rows without a new campaign."""
        cols = list(self.tests.columns)
        for col in criteria:
            if col not in cols:
                raise CampaignError(
                    f"unknown column for select(); the columns of the log are {cols} — "
                    "use one of them (names are case-sensitive)",
                    column=col,
                )
        mask = np.ones(len(self.tests), dtype=bool)
        masks = {c: match_values(self.tests[c], w, c) for c, w in criteria.items()}
        for m in masks.values():
            mask &= m
        if not mask.any():
            empty = [c for c, m in masks.items() if not m.any()]
            why = "; ".join(
                f"{c}={criteria[c]!r} (values present: {values_present(self.tests[c])})"
                for c in (empty or criteria)
            )
            what = "matched no test" if empty else "each match some tests, but no test meets all"
            raise CampaignError(
                f"select() kept no test: {why} {what} — change the criteria (text columns "
                "compare as text: '5', not 5)",
                column=(empty or list(criteria))[0],
            )
        return mask

    @staticmethod
    def _rows_of(table: pd.DataFrame, ids: pd.Series) -> pd.DataFrame:
        # The index stays the 0-based data row of the file, so that every sample a
        # screening rule names (soilstats.quality) is named by its row in the file.
        return table[table["test_id"].isin(list(ids))]

    def partition(self, parts: Sequence[Sequence[str]]) -> list[Self]:
        """One campaign per entry of ``parts`` (lists of test ids), each what
        ``select(test_id=part)`` returns, built in one pass over the samples.

        ``select`` scans every sample once per call; cutting a large campaign into many
        pieces (one per condition, to send to workers) that way costs pieces × samples.
        Tests keep their log order and samples their file rows, as with ``select``.

        Raises
        ------
        CampaignError
            For a part that names no test of this campaign, a test named in two parts (the
            pieces must not share tests), or an id that is not text.
        """
        log_ids = pd.Index(self.tests["test_id"].astype(str))
        part_of = np.full(len(log_ids) + 1, -1)  # last entry: a sample of no logged test
        for k, part in enumerate(parts):
            part = list(part)
            odd = [t for t in part if not isinstance(t, str)]
            if odd:
                raise CampaignError(
                    f"partition(): part {k} names test ids that are not text ({odd[:5]}); "
                    "test_id is text: '001', not 1",
                    column="test_id",
                )
            known = log_ids.isin(part)
            if not known.any():
                raise CampaignError(
                    f"partition(): part {k} names no test of this campaign "
                    f"({part[:5]}) — use ids from campaign.tests['test_id']",
                    column="test_id",
                )
            taken = known & (part_of[:-1] >= 0)
            if taken.any():
                first = int(np.flatnonzero(taken)[0])
                raise CampaignError(
                    f"partition(): test {log_ids[first]!r} is in part {part_of[first]} and "
                    f"part {k}; the parts must not share tests",
                    column="test_id",
                )
            part_of[:-1][known] = k

        def split(table: pd.DataFrame, position: np.ndarray) -> list[pd.DataFrame]:
            # Log / file order within each part.
            return [table.iloc[rows] for rows in grouped_by_code(part_of[position], len(parts))]

        tests = split(self.tests, np.arange(len(log_ids)))
        index = campaign_index(self)  # each sample's log row (−1 → the last entry)
        sinkage = split(self.sinkage, index.test_of("sinkage"))
        shear = split(self.shear, index.test_of("shear"))
        return [
            replace(self, tests=t.reset_index(drop=True), sinkage=s, shear=h)
            for t, s, h in zip(tests, sinkage, shear, strict=True)
        ]

    def windowed(self, window: FitWindow | None) -> Self:
        """This campaign without the sinkage samples outside ``window`` (z > z_max or
        p > p_max), the window and its per-test counts recorded in :attr:`window`.

        Shear tests are not windowed; without a window (None, or one without limits) the
        campaign itself is returned. See :mod:`soilstats.campaign.window`.
        """
        if window is None or not window:
            return self
        sinkage, applied = window.apply(self.tests, self.sinkage, self.file_name("tests"))
        return replace(self, sinkage=sinkage, window=applied)

    @property
    def quality(self) -> object:
        """Deprecated (removed in soilstats 0.3.0): a campaign holds no screening state,
        and this one was not screened (None).

        :func:`soilstats.quality.screen` returns the report; the campaign it cleans
        (``report.campaign``, a :class:`~soilstats.quality.ScreenedCampaign`) carries it as
        ``.report``.
        """
        warnings.warn(
            f"Campaign.quality is deprecated and will be removed in soilstats {RENAMED_GO_IN}: a "
            "campaign holds no screening state (this one was not screened: None). "
            "soilstats.quality.screen(campaign) returns the QualityReport; the campaign it "
            "cleans, report.campaign (a ScreenedCampaign), carries it as .report",
            FutureWarning,
            stacklevel=2,
        )
        return None

    def samples(self, test_id: str) -> pd.DataFrame:
        """The samples of one test (from the sinkage or shear table), in file order."""
        hit = self.tests.loc[self.tests["test_id"] == test_id, "kind"]
        if hit.empty:
            ids = list(self.tests["test_id"])
            raise CampaignError(
                f"no test {test_id!r} in this campaign; its tests are {ids[:20]}"
                + (f" … ({len(ids)} in all)" if len(ids) > 20 else "")
                + " — use one of them (test_id is text: '001', not 1)",
                column="test_id",
            )
        table = self.sinkage if hit.iloc[0] == "sinkage" else self.shear
        return table[table["test_id"] == test_id]

    def save(
        self,
        path: str | os.PathLike[str],
        *,
        format: Literal["csv", "parquet"] = "csv",
        overwrite: bool = False,
    ) -> Path:
        """Write the campaign's raw columns (no derived ones) to a folder.

        Parameters
        ----------
        path : str or os.PathLike
            Folder; created if needed.
        format : {"csv", "parquet"}
            File format. CSV floats are written with ``repr`` precision, so
            ``load_campaign(c.save(p))`` gives back the same values exactly.
        overwrite : bool
            Replace campaign files already in the folder (those of tests/sinkage/shear in
            either format that are not rewritten are removed). Without it, existing
            campaign files raise. Each file is written atomically, and never through a
            symbolic link (:func:`soilstats.campaign.io.save_tables`).

        Returns
        -------
        Path
            The folder. A sample file is omitted when its table has no rows.
        """
        if format not in ("csv", "parquet"):
            raise InputError(f"format={format!r} is not an option; use 'csv' or 'parquet'")
        tables = {
            stem: table.drop(columns=[c for c in DERIVED_COLUMNS[stem] if c in table.columns])
            for stem, table in (
                ("tests", self.tests),
                ("sinkage", self.sinkage),
                ("shear", self.shear),
            )
            if stem == "tests" or not table.empty
        }
        return io.save_tables(Path(path), tables, format, overwrite=overwrite)

    def sha256(self) -> str:
        """:func:`~soilstats.campaign.digest.campaign_sha256` of this campaign: the digest of
        its raw content that every output's provenance records."""
        return campaign_sha256(self)

    def __repr__(self) -> str:
        kinds = self.tests["kind"].value_counts()
        by_kind = ", ".join(f"{int(kinds.get(k, 0))} {k}" for k in KINDS)
        soils = ", ".join(str(s) for s in self.tests["soil"].unique())
        return f"<Campaign {self.source!r}: {len(self.tests)} tests ({by_kind}); soils: {soils}>"

    def summary(self) -> str:
        """A readable overview: tests by kind and soil, columns, covariates, samples, skips."""
        return describe(self)
