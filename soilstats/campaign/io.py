"""Reading and writing the files of a campaign folder (CSV or Parquet), and bundled names.

CSV files are read with every cell as text (``dtype=str``, no NA parsing) so that the
validator sees exactly what was written: ``"001"`` stays ``"001"``, ``"NA"`` stays ``"NA"``,
and an empty cell is an empty string. Parquet files keep their stored types; the validator
brings both to the same typed tables.
"""

from __future__ import annotations

import csv
import os
import warnings
from pathlib import Path
from typing import Literal

import numpy as np
import pandas as pd

from ..data import bundled_names, bundled_path
from ..errors import CampaignError
from .schema import FILES

__all__ = [
    "CAMPAIGN_FILE_NAMES",
    "find_file",
    "read_folder",
    "read_table",
    "resolve",
    "write_table",
]

Format = Literal["csv", "parquet"]
#: Every file name a campaign folder may hold.
CAMPAIGN_FILE_NAMES: tuple[str, ...] = tuple(f"{s}.{e}" for s in FILES for e in ("csv", "parquet"))


def resolve(path_or_name: str | os.PathLike[str]) -> tuple[Path, str]:
    """Find the folder of a campaign given as a path or as a bundled name.

    A ``str`` equal to a bundled name means the bundled campaign (pass ``"./name"`` or a
    :class:`pathlib.Path` for a local folder of the same name); anything else is a path.

    Parameters
    ----------
    path_or_name : str or os.PathLike
        Folder path, or the name of a bundled campaign.

    Returns
    -------
    (Path, str)
        The folder, and the source label: the path as given, or ``"bundled:<name>"``.

    Raises
    ------
    CampaignError
        If it is neither a bundled name nor an existing folder.
    """
    if isinstance(path_or_name, str):
        bundled = bundled_path(path_or_name)
        if bundled is not None:
            return bundled, f"bundled:{path_or_name}"
    path = Path(path_or_name)
    if path.is_dir():
        return path, str(path_or_name)
    names = ", ".join(repr(n) for n in bundled_names()) or "none"
    if path.exists():
        problem = f"{str(path)!r} is a file, not a campaign folder"
        fix = "pass the folder that holds tests.csv, not one of its files"
    else:
        problem = f"{str(path_or_name)!r} is not a bundled campaign and the path does not exist"
        fix = "pass a folder holding tests.csv (or tests.parquet) or a bundled name"
        if str(path_or_name) in bundled_names():
            fix = f"pass the bundled name as a str, load_campaign({str(path_or_name)!r})"
    raise CampaignError(f"{problem}; bundled campaigns: {names} — {fix}")


def find_file(folder: Path, stem: str) -> Path | None:
    """Return ``folder/stem.csv`` or ``folder/stem.parquet``, None if neither exists.

    Raises
    ------
    CampaignError
        If both exist (which one is meant is ambiguous).
    """
    found = [folder / f"{stem}.{ext}" for ext in ("csv", "parquet")]
    found = [p for p in found if p.is_file()]
    if len(found) == 2:
        raise CampaignError(
            f"both {stem}.csv and {stem}.parquet are in {str(folder)!r}; a campaign holds "
            "each table once — remove one of them",
            file=f"{stem}.csv",
        )
    return found[0] if found else None


def _header(path: Path) -> list[str]:
    with path.open(newline="", encoding="utf-8-sig") as fh:
        return next(csv.reader(fh), [])


def _line_of_names(path: Path, search: int = 50) -> int | None:
    """1-based line, among the first ``search``, of the first row with a ``test_id`` cell
    (every campaign file has that column): below line 1, lines precede the header."""
    with path.open(newline="", encoding="utf-8-sig", errors="replace") as fh:
        for number, row in enumerate(csv.reader(fh), start=1):
            if "test_id" in (cell.strip() for cell in row):
                return number
            if number >= search:
                break
    return None


def _long_row(path: Path) -> int | None:
    """First 1-based data row with more fields than the header (blank lines not counted)."""
    with path.open(newline="", encoding="utf-8-sig") as fh:
        reader = csv.reader(fh)
        width = len(next(reader, []))
        rows = (r for r in reader if r)
        return next((i for i, r in enumerate(rows, start=1) if len(r) > width), None)


def read_table(path: Path) -> pd.DataFrame:
    """Read one campaign file; CSV cells as text (``""`` where empty), Parquet as stored.

    Raises
    ------
    CampaignError
        If the file cannot be read or parsed, a column name appears twice or a column has
        no name.
    """
    name = path.name
    try:
        if path.suffix == ".parquet":
            frame = pd.read_parquet(path)
        else:
            # utf-8-sig drops the byte-order mark that spreadsheet exports put before 'test_id'.
            header = _header(path)
            dup = sorted({c for c in header if header.count(c) > 1})
            if dup:
                raise CampaignError(
                    f"column(s) {dup} appear more than once in the header; every column "
                    "name must be unique — rename or remove the repeated column",
                    file=name,
                    column=dup[0],
                )
            # pandas would name a nameless column 'Unnamed: k' and keep it as a covariate:
            # a to_csv index became a cause discovery tested (the row numbers).
            blank = [k for k, c in enumerate(header, start=1) if not c.strip()]
            if blank:
                raise CampaignError(
                    f"column {blank[0]} of {len(header)} in the header has no name; every "
                    "column needs one — an index written by pandas' to_csv (pass "
                    "index=False), or a comma at the end of every line? Name or remove it",
                    file=name,
                )
            # index_col=False: a row with extra fields must not silently become an index.
            with warnings.catch_warnings():
                warnings.simplefilter("error", pd.errors.ParserWarning)
                frame = pd.read_csv(
                    path,
                    dtype=str,
                    keep_default_na=False,
                    na_filter=False,
                    index_col=False,
                    encoding="utf-8-sig",
                )
    except CampaignError:
        raise
    except (pd.errors.ParserError, pd.errors.ParserWarning) as exc:
        row = _long_row(path)
        if row is None:  # another parse error, e.g. an unclosed quote
            raise _unreadable(path, exc) from exc
        width = len(_header(path))
        line = _line_of_names(path)
        preamble = (
            f" The column names (test_id, …) are on line {line}: the first line must be "
            "the header, so remove the lines above it (a logger's preamble?)."
            if line and line > 1
            else ""
        )
        raise CampaignError(
            f"a data row has more fields than the header's {width}; every row "
            f"needs one cell per column — fix the row (a stray comma?).{preamble}",
            file=name,
            row=row,
        ) from exc
    except (OSError, ValueError, csv.Error, pd.errors.EmptyDataError) as exc:
        # csv.Error: e.g. a cell beyond the csv module's field limit (a binary file).
        raise _unreadable(path, exc) from exc
    return frame


def _unreadable(path: Path, exc: Exception) -> CampaignError:
    return CampaignError(
        f"cannot read the file ({type(exc).__name__}: {exc}); it must be a valid "
        f"{'Parquet' if path.suffix == '.parquet' else 'UTF-8 CSV'} file with a header "
        "row — fix or re-export it",
        file=path.name,
    )


def read_folder(folder: Path) -> dict[str, tuple[pd.DataFrame | None, str]]:
    """Read the tests, sinkage and shear files of a campaign folder.

    Returns
    -------
    dict
        File stem → (frame or None when the file is absent, file name for messages).

    Raises
    ------
    CampaignError
        If there is no tests file, a table is present twice, or a file is unreadable.
    """
    out: dict[str, tuple[pd.DataFrame | None, str]] = {}
    for stem in FILES:
        path = find_file(folder, stem)
        if path is None and stem == "tests":
            present = sorted(p.name for p in folder.iterdir())[:20]
            raise CampaignError(
                f"no tests.csv or tests.parquet in {str(folder)!r} (it holds {present}); "
                "a campaign folder needs its test log — add tests.csv or pass the right folder",
                file="tests.csv",
            )
        out[stem] = (None, f"{stem}.csv") if path is None else (read_table(path), path.name)
    return out


def _csv_ready(frame: pd.DataFrame) -> pd.DataFrame:
    # Whole-number float columns (repetition, grousers, counts) are written as integers for
    # readability; they read back as the same float64 values. -0.0 would lose its sign, so a
    # column holding it stays float (pandas writes floats with repr, which round-trips).
    out = frame.copy()
    for col in out.columns:
        if out[col].dtype != np.float64:
            continue
        v = out[col].to_numpy()
        fin = v[~np.isnan(v)]
        if (
            fin.size
            and np.all(np.isfinite(fin))
            and np.all(fin == np.trunc(fin))
            and np.all(np.abs(fin) < 2.0**53)
            and not np.any((fin == 0) & np.signbit(fin))
        ):
            out[col] = out[col].astype("Int64")
    return out


def write_table(frame: pd.DataFrame, path: Path, fmt: Format) -> None:
    """Write one table to ``path`` as CSV (missing → empty cell) or Parquet, without index."""
    if fmt == "parquet":
        frame.to_parquet(path, index=False)
    else:
        _csv_ready(frame).to_csv(path, index=False, na_rep="", lineterminator="\n")
