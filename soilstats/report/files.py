"""Writing output files: JSON and CSV with provenance, safe names, no silent overwrite.

The one place that turns results into files on disk (PDF pages are rendered elsewhere in
this package but opened through :func:`output_path` too), so every output follows the same
rules:

* a file that exists is never replaced unless the caller passes ``overwrite=True``
  (:class:`FileExistsError` otherwise);
* an output name is a plain file name: a study spec's ``name`` can never write outside the
  output folder;
* JSON has no NaN or infinity (they become ``null``), numpy scalars become Python ones, and
  the document carries ``"provenance"``;
* CSV starts with ``# key: value`` comment lines of provenance; read it back with
  ``pandas.read_csv(path, comment="#")``.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import pandas as pd

    from .provenance import Provenance

__all__ = ["json_safe", "output_path", "safe_stem", "write_csv", "write_json"]

_STEM = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*$")


def safe_stem(name: str) -> str:
    """``name`` if it is a plain file-name stem (letters, digits, ``._-``), else ValueError.

    Rejects path separators, ``..``, leading dots and empty names, so that a name taken from
    a user's file (a study spec) cannot address anything outside the output folder.
    """
    if not _STEM.match(name) or ".." in name:
        raise ValueError(
            f"output name {name!r} is not a plain file name (letters, digits, '.', '_' and "
            "'-', not starting with a dot, no '..' or '/'); rename it"
        )
    return name


def output_path(folder: str | Path, filename: str, *, overwrite: bool = False) -> Path:
    """The path ``folder/filename``, checked and with ``folder`` created.

    Raises
    ------
    ValueError
        If ``filename`` is not a plain file name.
    FileExistsError
        If the file exists and ``overwrite`` is false.
    NotADirectoryError
        If ``folder`` exists but is a file.
    """
    safe_stem(filename)
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise NotADirectoryError(20, "not a folder", str(folder))
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / filename
    if path.exists() and not overwrite:
        raise FileExistsError(17, "exists already", str(path))
    return path


def json_safe(value: Any) -> Any:
    """A JSON-ready copy: NaN/±inf → None, numpy and pandas scalars → Python, tuples → lists."""
    import numpy as np

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
        import pandas as pd

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
    target.write_text(json.dumps(doc, indent=2, ensure_ascii=False) + "\n", encoding="utf-8")
    return target


def write_csv(
    path: str | Path,
    frame: pd.DataFrame,
    provenance: Provenance,
    *,
    overwrite: bool = False,
    float_format: str | None = None,
) -> Path:
    """Write ``frame`` (no index) after ``# key: value`` provenance comment lines."""
    path = Path(path)
    target = output_path(path.parent, path.name, overwrite=overwrite)
    header = "".join(f"# {line}\n" for line in provenance.lines())
    body = frame.to_csv(index=False, float_format=float_format, lineterminator="\n")
    target.write_text(header + body, encoding="utf-8")
    return target
