"""Writing output files: atomically, never through a link, JSON and CSV with provenance.

The one place that turns results into files on disk (PDF pages, netCDF posteriors and
campaign tables are rendered elsewhere, but checked through :func:`output_path` and written
through :func:`write_atomic` or :func:`replacing`), so every output follows the same rules:

* a file that exists is never replaced unless the caller passes ``overwrite=True``
  (:class:`FileExistsError` otherwise);
* an output name is a plain file name: a study spec's ``name`` can never write outside the
  output folder;
* an output is never written through a symbolic link, dangling or not (a link inside the
  output folder could point anywhere: the write would create or replace its target);
* every file is written to a temporary file beside it and renamed into place
  (:func:`os.replace`): a reader sees the old file or the new one, never half of one, and a
  write that fails leaves the old file as it was and no temporary file behind;
* JSON has no NaN or infinity (they become ``null``), numpy scalars become Python ones, and
  the document carries ``"provenance"``;
* CSV starts with ``# key: value`` comment lines of provenance (each kept on one line: a line
  break in a value is written as ``\\n``); read it back with
  ``pandas.read_csv(path, comment="#")``. Text cells that a spreadsheet would run as a
  formula (starting with ``=``, ``+``, ``-``, ``@``, a TAB or a CR) get a leading ``'``
  (OWASP's advice); numbers are never altered, so a negative number stays a number. A text
  cell holding a comma, a quote, a line break or a ``#`` is quoted, so that it reads back
  whole with ``comment="#"``.
"""

from __future__ import annotations

import errno
import io
import json
import math
import os
import re
import secrets
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from ..errors import InputError

if TYPE_CHECKING:
    import pandas as pd

    from .provenance import Provenance

__all__ = [
    "csv_text",
    "escape_formula",
    "json_safe",
    "netcdf_bytes",
    "output_path",
    "replacing",
    "safe_stem",
    "unescape_formula",
    "write_atomic",
    "write_csv",
    "write_json",
]

_STEM = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*$")


def safe_stem(name: str) -> str:
    """``name`` if it is a plain file-name stem (letters, digits, ``._-``), else ValueError.

    Rejects path separators, ``..``, leading dots and empty names, so that a name taken from
    a user's file (a study spec) cannot address anything outside the output folder.
    """
    if not _STEM.match(name) or ".." in name:
        raise InputError(
            f"output name {name!r} is not a plain file name (letters, digits, '.', '_' and "
            "'-', not starting with a dot, no '..' or '/'); rename it"
        )
    return name


def _refuse_link(path: Path) -> None:
    """Raise if ``path`` is a symbolic link: writing would create or replace its target,
    which may lie anywhere (outside the output folder)."""
    if os.path.islink(path):
        target = os.readlink(path)
        state = "" if os.path.exists(path) else ", dangling"
        raise OSError(
            errno.ELOOP,
            f"is a symbolic link (to {target!r}{state}); soilstats never writes through a "
            "link, whose target may lie outside the output folder — remove the link or "
            "choose another --out",
            str(path),
        )


def output_path(
    folder: str | Path, filename: str, *, overwrite: bool = False, create: bool = True
) -> Path:
    """The path ``folder/filename``, checked and with ``folder`` created (``create=False``:
    checked only, so that a command refused later leaves no empty folder behind).

    ``folder`` itself may be a link to a folder (the user named it); the file in it may not
    be a link at all.

    Raises
    ------
    ValueError
        If ``filename`` is not a plain file name.
    FileExistsError
        If the file exists and ``overwrite`` is false.
    NotADirectoryError
        If ``folder`` exists but is a file.
    IsADirectoryError
        If ``folder/filename`` is a folder.
    OSError
        If ``folder`` is a dangling link, or ``folder/filename`` is a link (``errno.ELOOP``).
    """
    safe_stem(filename)
    folder = Path(folder)
    if os.path.islink(folder) and not folder.exists():
        raise OSError(  # ELOOP: a plain OSError, its text shown as is (ENOENT would not be)
            errno.ELOOP,
            f"is a dangling symbolic link (to {os.readlink(folder)!r}); give a folder",
            str(folder),
        )
    if folder.exists() and not folder.is_dir():
        raise NotADirectoryError(20, "not a folder", str(folder))
    folder = staged(folder)  # an output set being written: its staging folder
    if create:
        folder.mkdir(parents=True, exist_ok=True)
    path = folder / filename
    _refuse_link(path)
    if path.is_dir():
        raise IsADirectoryError(21, "is a folder", str(path))
    if path.exists() and not overwrite:
        raise FileExistsError(17, "exists already", str(path))
    return path


#: (output folder, its staging folder) of the output set being written (outputs.outset).
_STAGES: list[tuple[Path, Path]] = []


@contextmanager
def staging(real: Path, stage: Path) -> Iterator[None]:
    """Within the block, every writer of this module writes what belongs in ``real`` (a
    resolved folder) into ``stage`` instead (:func:`soilstats.outputs.outset.output_set`)."""
    _STAGES.append((real, stage))
    try:
        yield
    finally:
        _STAGES.remove((real, stage))


def staged(path: str | Path) -> Path:
    """Where ``path`` is written: in the staging folder when it lies in an output set being
    written (its folder resolved, its own name kept), else ``path`` itself."""
    path = Path(path)
    if not _STAGES:
        return path
    where = Path(os.path.realpath(path.parent)) / path.name
    for real, stage in reversed(_STAGES):
        if where == real:
            return stage
        if real in where.parents:
            return stage / where.relative_to(real)
    return path


def _temporary(path: Path) -> Path:
    """A new, empty file beside ``path`` (same folder, so the rename cannot cross file
    systems), created exclusively and with the permissions a plain write would give."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0)
    while True:
        tmp = path.with_name(f".{path.name}.{secrets.token_hex(6)}.tmp{path.suffix}")
        try:
            os.close(os.open(tmp, flags | getattr(os, "O_CLOEXEC", 0), 0o666))
        except FileExistsError:
            continue
        return tmp


@contextmanager
def replacing(*paths: str | Path) -> Iterator[list[Path]]:
    """Temporary files standing in for ``paths``, renamed into place when the block ends.

    Write each temporary file inside the ``with`` block. If the block raises, every
    temporary file is removed and no destination is touched; otherwise each one replaces its
    destination (:func:`os.replace`, atomic on POSIX), so a set of files (a campaign's
    tables) is replaced only once all of them are written.

    Raises
    ------
    OSError
        If a destination is a symbolic link (before anything is written).
    """
    targets = [staged(p) for p in paths]
    for target in targets:
        _refuse_link(target)
    temporaries: list[Path] = []
    try:
        temporaries.extend(_temporary(t) for t in targets)
        yield list(temporaries)
        for tmp, target in zip(temporaries, targets, strict=True):
            _refuse_link(target)  # still no link, just before the rename
            os.replace(tmp, target)
    except BaseException:
        for tmp in temporaries:
            try:
                os.unlink(tmp)
            except OSError:  # renamed already, or never written
                pass
        raise


def write_atomic(path: str | Path, content: str | bytes | Callable[..., object]) -> Path:
    """Write ``content`` to ``path`` through a temporary file renamed into place.

    Parameters
    ----------
    path : str or Path
        The destination (checked with :func:`output_path` beforehand for the no-overwrite
        rule); refused if it is a symbolic link.
    content : str, bytes or callable
        Text (written as UTF-8), bytes, or a function that writes the file whose path it is
        given (a serialiser that wants a path: netCDF, Parquet).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    OSError
        If ``path`` is a symbolic link, or the write fails (then ``path`` is unchanged and no
        temporary file is left).
    """
    try:
        with replacing(path) as (tmp,):
            if callable(content):
                content(tmp)
            else:
                _write_bytes(tmp, content.encode("utf-8") if isinstance(content, str) else content)
    except OSError as err:
        if err.errno in _NO_SPACE:
            raise OSError(
                err.errno,
                f"no space left to write {Path(path).name} into {str(Path(path).parent)!r} "
                f"({os.strerror(err.errno or 0)}); nothing of it was written — free space "
                "and run again",
            ) from None
        raise
    return Path(path)


#: errno values of a full disk or an exhausted quota.
_NO_SPACE = {errno.ENOSPC, getattr(errno, "EDQUOT", errno.ENOSPC)}


def _write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to the (temporary) file ``path`` (a full disk raises here: on write, or
    when the file is closed)."""
    with open(path, "wb") as fh:
        fh.write(data)


def netcdf_bytes(idata: Any) -> bytes:
    """An ArviZ InferenceData as the bytes of its netCDF-4 file (``az.from_netcdf`` reads
    them), built in memory.

    What :meth:`InferenceData.to_netcdf` writes (attributes, then each group, compressed
    like ArviZ does), but no HDF5 handle is ever open on a file: a full disk is then a plain
    OSError of :func:`write_atomic`, not an HDF5 file left half-closed (which ended in a
    segmentation fault when h5py freed it at exit).
    """
    import xarray as xr  # deferred: xarray (netCDF only)

    buffer = io.BytesIO()
    mode = "w"
    if idata._attrs:
        xr.Dataset(attrs=idata._attrs).to_netcdf(
            buffer,  # type: ignore[call-overload]  # (xarray writes file objects too)
            mode=mode,
            engine="h5netcdf",
            group="/",
        )
        mode = "a"
    for group in idata._groups_all:
        data = getattr(idata, group)
        encoding = {
            name: {"zlib": True}
            for name, values in data.variables.items()
            if values.dtype.kind in "biufcS"
        }
        data.to_netcdf(buffer, mode=mode, group=f"/{group}", engine="h5netcdf", encoding=encoding)
        mode = "a"
    return buffer.getvalue()


def json_safe(value: Any) -> Any:
    """A JSON-ready copy: NaN/±inf → None, numpy and pandas scalars → Python, tuples → lists."""
    import numpy as np  # deferred: numpy (soilstats.outputs loads nothing heavy)

    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple | set | frozenset):
        return [json_safe(v) for v in value]
    if isinstance(value, np.ndarray):
        return [json_safe(v) for v in value.tolist()]
    if isinstance(value, bool | np.bool_):
        return bool(value)
    if isinstance(value, int | np.integer):
        return int(value)
    if isinstance(value, float | np.floating):
        return float(value) if math.isfinite(value) else None
    if value is None or isinstance(value, str):
        return value
    try:  # pandas NA/NaT and other missing markers
        import pandas as pd  # deferred: pandas (soilstats.outputs loads nothing heavy)

        if pd.isna(value):
            return None
    except (TypeError, ValueError):
        pass
    return str(value)


def write_json(
    path: str | Path, document: dict, provenance: Provenance, *, overwrite: bool = False
) -> Path:
    """Write ``document`` (+ ``"provenance"``) as indented JSON; see the module rules."""
    path = Path(path)
    target = output_path(path.parent, path.name, overwrite=overwrite)
    doc = {**json_safe(document), "provenance": provenance.to_dict()}
    return write_atomic(target, json.dumps(doc, indent=2, ensure_ascii=False) + "\n")


#: Characters that make a text cell need quotes: the CSV syntax, and the comment character
#: readers are told to pass (``comment="#"`` cuts an unquoted line at its first ``#``).
_NEEDS_QUOTES = re.compile(r'[,"\r\n#]')
#: Characters that end a line for some reader (str.splitlines): escaped in comment lines.
_LINE_BREAKS: dict[str, str | int | None] = {
    c: repr(c)[1:-1] for c in "\n\r\x0b\x0c\x1c\x1d\x1e\x85\u2028\u2029"
}


#: A cell a spreadsheet would take for a formula, behind any apostrophes already there.
_FORMULA_CELL = re.compile(r"'*[=+\-@\t\r]")
#: A cell escaped by :func:`escape_formula`.
_ESCAPED_CELL = re.compile(r"'+[=+\-@\t\r]")


def escape_formula(text: str) -> str:
    """``text`` safe from spreadsheet formulas (OWASP, CSV injection): an apostrophe before a
    cell that starts, after any apostrophes, with ``= + - @``, a tab or a carriage return.

    Reversible (:func:`unescape_formula`): ``'=1`` is written ``''=1`` and reads back as
    ``'=1``; every other text is written unchanged.
    """
    return "'" + text if _FORMULA_CELL.match(text) else text


def unescape_formula(text: str) -> str:
    """The cell :func:`escape_formula` was given: one leading apostrophe dropped where it
    guards a formula character."""
    return text[1:] if _ESCAPED_CELL.match(text) else text


def _text_cell(text: str) -> str:
    """A text cell as written: formula-escaped, quoted where its content needs it."""
    text = escape_formula(text)
    if _NEEDS_QUOTES.search(text):
        return '"' + text.replace('"', '""') + '"'
    return text


def _object_cell(value: object) -> str:
    """A cell of a text (object) column: a number stays a number, as pandas writes it."""
    import pandas as pd  # deferred: pandas (soilstats.outputs loads nothing heavy)

    if isinstance(value, str):
        return _text_cell(value)
    if value is None or (not isinstance(value, list | tuple | dict) and pd.isna(value)):  # type: ignore[call-overload]  # pandas-stubs: isna of any object is valid
        return ""
    if isinstance(value, bool | int | float) or pd.api.types.is_number(value):
        return str(value)
    return _text_cell(str(value))


def _one_line(text: str) -> str:
    """``text`` with every line break written as its escape (``\\n``)."""
    return text.translate(str.maketrans(_LINE_BREAKS))


def csv_text(frame: pd.DataFrame, float_format: str | None = None) -> str:
    """The CSV of ``frame`` (no index): numbers as pandas writes them, text made safe.

    Numeric, boolean and date columns are formatted by pandas (``float_format`` applies);
    text cells are escaped against spreadsheet formulas and quoted where needed (module
    rules). Every line ends with ``\\n``.
    """
    import pandas as pd  # deferred: pandas (soilstats.outputs loads nothing heavy)
    from pandas.api.types import is_object_dtype  # deferred: pandas

    def is_text(dtype: object) -> bool:
        return isinstance(dtype, pd.StringDtype | pd.CategoricalDtype) or is_object_dtype(dtype)  # type: ignore[arg-type]  # pandas-stubs: any dtype-like object is valid

    def numbers(part: pd.DataFrame) -> list[str]:
        text = part.to_csv(
            index=False, header=False, float_format=float_format, na_rep="", lineterminator="\n"
        )
        return text.split("\n")[:-1]

    header = ",".join(_text_cell(str(c)) for c in frame.columns)
    if frame.shape[1] and not any(is_text(d) for d in frame.dtypes):
        rows = numbers(frame)  # no text: pandas writes it all (a draws table of numbers)
    else:
        columns: list[list[str]] = []
        for j in range(frame.shape[1]):
            series = frame.iloc[:, j]
            if is_text(series.dtype):
                columns.append([_object_cell(v) for v in series.tolist()])
            else:  # numbers never need quotes; a lone empty field is written '""'
                columns.append(["" if c == '""' else c for c in numbers(series.to_frame())])
        rows = [",".join(cells) for cells in zip(*columns, strict=True)] if columns else []
        # A row of one empty cell is written '""': an empty line would be read as no row.
        rows = [r or '""' for r in rows]
    return "".join(f"{line}\n" for line in (header, *rows))


class CommentLines(Protocol):
    """What :func:`write_csv` heads a file with: a :class:`~.provenance.Provenance`, or one
    with more lines (the posterior export's)."""

    def lines(self) -> list[str]: ...


def write_csv(
    path: str | Path,
    frame: pd.DataFrame,
    provenance: Provenance | CommentLines,
    *,
    overwrite: bool = False,
    float_format: str | None = None,
) -> Path:
    """Write ``frame`` (no index) after ``# key: value`` provenance comment lines."""
    path = Path(path)
    target = output_path(path.parent, path.name, overwrite=overwrite)
    header = "".join(f"# {_one_line(line)}\n" for line in provenance.lines())
    return write_atomic(target, header + csv_text(frame, float_format))
