"""Reading and writing the files of a campaign folder (CSV or Parquet), and bundled names.

CSV files are read with every cell as text (``dtype=str``, no NA parsing) so that the
validator sees exactly what was written: ``"001"`` stays ``"001"``, ``"NA"`` stays ``"NA"``,
and an empty cell is an empty string. Parquet files keep their stored types; the validator
brings both to the same typed tables.
"""

from __future__ import annotations

import csv
import errno
import io as io_
import os
import re
import stat
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import BinaryIO, Literal

import numpy as np
import pandas as pd

from .._text import shown
from ..data import bundled_names, bundled_path
from ..errors import CampaignError
from ..outputs.files import escape_formula, output_path, replacing, staged, unescape_formula
from .read_budget import check_csv_size, check_parquet_size
from .schema import FILES, MAX_CELL_CHARS

__all__ = [
    "CAMPAIGN_FILE_NAMES",
    "find_file",
    "read_folder",
    "read_table",
    "resolve",
    "save_tables",
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
    if path.is_dir():  # a folder, or a link to one
        return path, str(path_or_name)
    what = _entry(path, denied=_parent_denied)
    names = ", ".join(repr(n) for n in bundled_names()) or "none"
    if what is not None:
        problem = f"{str(path)!r} is {what or 'a file'}, not a campaign folder"
        fix = (
            "pass the folder that holds tests.csv, not one of its files"
            if not what
            else "pass a folder holding tests.csv (or tests.parquet) or a bundled name"
        )
    else:
        problem = f"{str(path_or_name)!r} is not a bundled campaign and the path does not exist"
        fix = "pass a folder holding tests.csv (or tests.parquet) or a bundled name"
        if str(path_or_name) in bundled_names():
            fix = f"pass the bundled name as a str, load_campaign({str(path_or_name)!r})"
    raise CampaignError(f"{problem}; bundled campaigns: {names} — {fix}")


_MODES = (
    (stat.S_ISDIR, "a directory"),
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


def _mode_name(mode: int) -> str:
    """``""`` for a regular file, else what the mode says the entry is ("a FIFO (named pipe)")."""
    if stat.S_ISREG(mode):
        return ""
    return next((name for test, name in _MODES if test(mode)), "not a regular file")


def _parent_denied(path: Path) -> CampaignError:
    return CampaignError(
        f"cannot look into {str(path.parent)!r}: permission denied; a campaign folder (and "
        "the folders above it) needs read and execute permission for you — chmod u+rx it"
    )


def _entry(path: Path, *, denied: Callable[[Path], Exception] = _parent_denied) -> str | None:
    """What is at ``path``: None if nothing, ``""`` for a regular file or a link to one, else
    what is there instead ("a directory", "a FIFO (named pipe)", "a symlink loop", ...).

    The reader used to ask ``is_file()``, which is False for a folder, a pipe or a broken
    link alike: each was reported as "no sinkage.csv" while the user could see one.
    ``denied(path)`` is the error raised when the folder holding ``path`` cannot be searched.
    """
    try:
        mode = os.stat(path).st_mode
    except PermissionError:
        raise denied(path) from None
    except FileNotFoundError:
        if not os.path.islink(path):
            return None
        return f"a dangling symlink (to {os.readlink(path)!r}, which does not exist)"
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            return "a symlink loop (the link leads back to itself)"
        raise CampaignError(
            f"cannot look at {str(path)!r} ({exc.strerror or type(exc).__name__}) — check the path"
        ) from None
    what = _mode_name(mode)
    return f"a symlink to {what}" if what and os.path.islink(path) else what


def find_file(folder: Path, stem: str) -> Path | None:
    """Return ``folder/stem.csv`` or ``folder/stem.parquet``, None if neither exists.

    Raises
    ------
    CampaignError
        If both exist (which one is meant is ambiguous), if what is there is not a regular
        file (a directory, a FIFO, a device, a symlink loop or a dangling link: said as
        such), or if the folder cannot be searched.
    """

    def denied(path: Path) -> CampaignError:
        return CampaignError(
            f"cannot look into the campaign folder {str(folder)!r}: permission denied; it "
            "needs read and execute permission for you — chmod u+rx it",
            file=path.name,
        )

    found = []
    for path in (folder / f"{stem}.{ext}" for ext in ("csv", "parquet")):
        what = _entry(path, denied=denied)
        if what:
            fix = (
                "put the test log there"
                if stem == "tests"
                else f"put the file there, or remove it if the campaign has no {stem} tests"
            )
            raise CampaignError(
                f"{path.name} in {str(folder)!r} is {what}, not a regular file; a campaign "
                f"table is a CSV or Parquet file — {fix}",
                file=path.name,
            )
        if what is not None:
            found.append(path)
    if len(found) == 2:
        raise CampaignError(
            f"both {stem}.csv and {stem}.parquet are in {str(folder)!r}; a campaign holds "
            "each table once — remove one of them",
            file=f"{stem}.csv",
        )
    return found[0] if found else None


def _open(path: Path) -> BinaryIO:
    """Open a campaign file for reading, refusing anything but a regular file.

    ``O_NONBLOCK``: a FIFO put in place after :func:`find_file` looked must not block the
    reader forever; the mode is checked on the opened descriptor, so what is read is what
    was checked.
    """
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0)
    try:
        fd = os.open(path, flags | getattr(os, "O_CLOEXEC", 0))
    except PermissionError:
        raise CampaignError(
            "cannot read the file: permission denied — give yourself read permission "
            f"(chmod u+r {str(path)!r})",
            file=path.name,
        ) from None
    except OSError as exc:
        raise _unreadable(path, exc) from None
    what = _mode_name(os.fstat(fd).st_mode)
    if what:
        os.close(fd)
        raise CampaignError(f"is {what}, not a regular file — put the file there", file=path.name)
    return os.fdopen(fd, "rb")


@contextmanager
def _records(fh: BinaryIO, name: str) -> Iterator[Iterator[list[str]]]:
    """The records of a CSV file as the csv module reads them (a blank line is ``[]``).

    Used to explain a parse error pandas reports (which row is long, where a quote opens).
    A cell beyond the csv module's field limit (128 KiB) is refused with the data row it is
    in, not left to end in a ``csv.Error`` traceback.
    """
    fh.seek(0)
    text = io_.TextIOWrapper(fh, encoding="utf-8-sig", errors="replace", newline="")

    def guarded() -> Iterator[list[str]]:
        filled = 0  # non-blank records read: the header, then data rows
        try:
            for record in csv.reader(text):
                filled += bool(record)
                yield record
        except csv.Error as exc:
            if "field limit" not in str(exc):
                raise _unreadable(Path(name), exc) from exc
            raise _too_long(name, filled or None) from exc

    try:
        yield guarded()
    finally:
        text.detach()


def _at(name: str, row: int | None, problem: str) -> CampaignError:
    """An error at a data row of a CSV file (None: its header); ``{where}`` in ``problem``
    becomes "this row" or "the header"."""
    where = "the header" if row is None else "this row"
    return CampaignError(problem.format(where=where), file=name, row=row)


def _too_long(name: str, row: int | None) -> CampaignError:
    return _at(
        name,
        row,
        f"a cell of {{where}} is longer than {MAX_CELL_CHARS} characters, the most a campaign "
        "cell holds; a quote left open swallows the lines after it — fix the file there",
    )


def _header(fh: BinaryIO) -> list[str]:
    """The cells of the first non-blank line as written (pandas, not the csv module: a
    header cell beyond the csv module's field limit must be judged, not crash the read)."""
    fh.seek(0)
    first = pd.read_csv(
        fh,
        header=None,
        nrows=1,
        dtype=str,
        keep_default_na=False,
        na_filter=False,
        index_col=False,
        encoding="utf-8-sig",
    )
    fh.seek(0)
    return [str(c) for c in first.iloc[0]] if len(first) else []


def _line_of_names(fh: BinaryIO, name: str, search: int = 50) -> int | None:
    """1-based line, among the first ``search``, of the first row with a ``test_id`` cell
    (every campaign file has that column): below line 1, lines precede the header."""
    with _records(fh, name) as records:
        for number, row in enumerate(records, start=1):
            if "test_id" in (cell.strip() for cell in row):
                return number
            if number >= search:
                break
    return None


def _long_row(fh: BinaryIO, name: str) -> int | None:
    """First 1-based data row with more fields than the header (blank lines not counted)."""
    with _records(fh, name) as records:
        rows = (r for r in records if r)
        width = len(next(rows, []))
        return next((i for i, r in enumerate(rows, start=1) if len(r) > width), None)


def _open_quote_row(fh: BinaryIO, name: str, record: int) -> int | None:
    """Data row of the 0-based ``record`` (pandas counts blank lines as records; data rows
    do not), None when it is the header."""
    with _records(fh, name) as records:
        filled = sum(bool(r) for _, r in zip(range(record), records, strict=False))
    return filled or None


def _not_utf8(fh: BinaryIO, name: str) -> CampaignError:
    """Say where the first byte that is not UTF-8 is, and what encoding it suggests."""
    fh.seek(0)
    start = fh.read(2)
    if start in (b"\xff\xfe", b"\xfe\xff"):
        problem = (
            "the file is UTF-16 (a spreadsheet's 'Unicode text' export); campaign files are "
            "UTF-8 — save it as 'CSV UTF-8'"
        )
        return CampaignError(f"cannot read the file: {problem}", file=name)
    fh.seek(0)
    for line, raw in enumerate(fh, start=1):
        try:
            raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            byte = raw[exc.start : exc.start + 1].hex()
            return CampaignError(
                f"cannot read the file: byte 0x{byte} on line {line} is not UTF-8 (a Latin-1 "
                "or Windows-1252 export?); campaign files are UTF-8 — re-export as 'CSV UTF-8'",
                file=name,
            )
    return CampaignError("cannot read the file: it is not UTF-8 — re-export it", file=name)


_OPEN_QUOTE = re.compile(r"EOF inside string starting at row (\d+)")


def _parse_error(fh: BinaryIO, name: str, exc: Exception) -> CampaignError:
    """The error of a CSV pandas could not parse: an unclosed quote, a long row, or else."""
    opened = _OPEN_QUOTE.search(str(exc))
    if opened:
        return _at(
            name,
            _open_quote_row(fh, name, int(opened.group(1))),
            'cannot read the file: a quote (") opened in {where} is never closed, so it takes '
            "in every line after it — close the quote or remove it",
        )
    row = _long_row(fh, name)
    if row is None:  # another parse error
        return _unreadable(Path(name), exc)
    with _records(fh, name) as records:
        width = len(next((r for r in records if r), []))
    line = _line_of_names(fh, name)
    preamble = (
        f" The column names (test_id, …) are on line {line}: the first line must be "
        "the header, so remove the lines above it (a logger's preamble?)."
        if line and line > 1
        else ""
    )
    return CampaignError(
        f"a data row has more fields than the header's {width}; every row "
        f"needs one cell per column — fix the row (a stray comma?).{preamble}",
        file=name,
        row=row,
    )


def require_parquet(name: str) -> None:
    """A one-line :class:`CampaignError` naming the ``parquet`` extra when pyarrow, which
    reads and writes Parquet, is not installed (it is 170 MB, and CSV needs none of it)."""
    try:
        import pyarrow  # noqa: F401  # deferred: pyarrow (the parquet extra)
    except ImportError:
        raise CampaignError(
            f"{name} is a Parquet table, and Parquet needs pyarrow, which is not installed: "
            "pip install 'soilstats[parquet]' (or save the table as CSV)",
            file=name,
        ) from None


def read_table(path: Path) -> pd.DataFrame:
    """Read one campaign file; CSV cells as text (``""`` where empty), Parquet as stored.

    Raises
    ------
    CampaignError
        If the file is not a regular file, cannot be read or parsed (not UTF-8, a quote
        never closed, a row longer than the header, a cell beyond the csv module's limit),
        is empty, a column name appears twice or a column has no name.
    """
    if path.suffix == ".parquet":
        require_parquet(path.name)
    with _open(path) as fh:
        if path.suffix == ".parquet":
            try:
                check_parquet_size(fh, path.name)
                return pd.read_parquet(fh)
            except CampaignError:
                raise
            except (OSError, ValueError) as exc:
                raise _unreadable(path, exc) from exc
        check_csv_size(fh, path.name)
        try:
            return _read_csv(fh, path.name)
        except CampaignError:
            raise
        except UnicodeDecodeError:
            raise _not_utf8(fh, path.name) from None
        except (pd.errors.ParserError, pd.errors.ParserWarning) as exc:
            raise _parse_error(fh, path.name, exc) from exc
        except pd.errors.EmptyDataError:
            raise CampaignError(
                "the file is empty; it needs a header row (test_id, …) and a row per "
                "test or sample — fill it in or remove it",
                file=path.name,
            ) from None
        except (OSError, ValueError, csv.Error) as exc:
            raise _unreadable(path, exc) from exc


def _read_csv(fh: BinaryIO, name: str) -> pd.DataFrame:
    # utf-8-sig drops the byte-order mark that spreadsheet exports put before 'test_id'.
    header = _header(fh)
    dup = sorted({c for c in header if header.count(c) > 1})
    if dup:
        raise CampaignError(
            f"column(s) [{', '.join(shown(c) for c in dup)}] appear more than once in the "
            "header; every "
            "column name must be unique — rename or remove the repeated column",
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
            fh,
            dtype=str,
            keep_default_na=False,
            na_filter=False,
            index_col=False,
            encoding="utf-8-sig",
        )
    return _formula_unescaped(frame)


def _formula_unescaped(frame: pd.DataFrame) -> pd.DataFrame:
    """Cells as given to :func:`write_table`: the apostrophe guarding a formula cell
    (``'=x``, a spreadsheet's own escape too) dropped; a frame without one is returned as is."""
    for col in frame.columns:
        values = frame[col]
        guarded = values.str.startswith("'", na=False)
        if guarded.any():
            frame[col] = values.where(~guarded, values[guarded].map(unescape_formula))
    return frame


def _unreadable(path: Path, exc: Exception) -> CampaignError:
    return CampaignError(
        f"cannot read the file ({type(exc).__name__}: {shown(str(exc), 200)}); it must be a "
        f"valid {'Parquet' if path.suffix == '.parquet' else 'UTF-8 CSV'} file with a header "
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
        If there is no tests file, a table is present twice or is not a regular file, the
        folder cannot be searched, or a file is unreadable.
    """
    out: dict[str, tuple[pd.DataFrame | None, str]] = {}
    for stem in FILES:
        path = find_file(folder, stem)
        if path is None and stem == "tests":
            try:
                held = f"it holds {sorted(p.name for p in folder.iterdir())[:20]}"
            except PermissionError:
                held = "its content cannot be listed: permission denied, chmod u+rx it"
            raise CampaignError(
                f"no tests.csv or tests.parquet in {str(folder)!r} ({held}); "
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
    """Write one table to ``path`` as CSV (missing → empty cell) or Parquet, without index.

    A CSV text cell a spreadsheet would take for a formula (``=…``, ``+…``, ``-…``, ``@…``)
    gets a leading apostrophe (:func:`~soilstats.outputs.files.escape_formula`, reversible),
    which :func:`read_table` drops again: the cells read back exactly.
    """
    if fmt == "parquet":
        require_parquet(path.name)
        frame.to_parquet(path, index=False)
    else:
        _csv_ready(_formula_escaped(frame)).to_csv(
            path, index=False, na_rep="", lineterminator="\n"
        )


def _formula_escaped(frame: pd.DataFrame) -> pd.DataFrame:
    """The text cells of ``frame`` escaped against spreadsheet formulas (numbers untouched)."""
    out = frame.copy()
    for col in out.columns:
        if out[col].dtype == np.float64 or pd.api.types.is_integer_dtype(out[col].dtype):
            continue
        out[col] = out[col].map(lambda v: escape_formula(v) if isinstance(v, str) else v)
    return out


def save_tables(
    folder: Path, tables: dict[str, pd.DataFrame], fmt: Format, *, overwrite: bool
) -> Path:
    """Write the campaign files ``tables`` (stem → table) into ``folder``.

    Every destination is checked before anything is written (no link, no folder in the
    way; campaign files already there need ``overwrite``); every table is written to a
    temporary file, and only when all are written are they renamed into place; campaign
    files of the folder that were not rewritten (the other format, a sample table now
    empty) are removed last. A failed save leaves the folder as it was.

    Raises
    ------
    CampaignError
        If the folder holds campaign files and ``overwrite`` is false.
    OSError
        If a campaign file name in the folder is a symbolic link or a folder.
    """
    existing = [folder / n for n in CAMPAIGN_FILE_NAMES if os.path.lexists(folder / n)]
    if existing and not overwrite:
        raise CampaignError(
            f"{str(folder)!r} already holds campaign files {[p.name for p in existing]} — "
            "save to a new folder or pass overwrite=True"
        )
    for name in CAMPAIGN_FILE_NAMES:
        output_path(folder, name, overwrite=True)
    written = {f"{stem}.{fmt}" for stem in tables}
    with replacing(*(folder / f"{stem}.{fmt}" for stem in tables)) as temporaries:
        for tmp, table in zip(temporaries, tables.values(), strict=True):
            write_table(table, tmp, fmt)
    for path in existing:
        if path.name not in written:
            staged(path).unlink()  # in the output set being written, if any
    return folder
