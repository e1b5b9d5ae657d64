"""Import a lab's own export through a small TOML mapping (``soilstats import``).

The mapping names the lab's CSV files, says which lab column holds which format column and in
which unit, and may set values that are the same for every test. The result is checked like
any campaign (and for implausible units) before anything is written. Format:
``docs/importing.md``.

.. code-block:: toml

    [tests]
    file = "log.csv"                 # relative to this TOML file
    [tests.columns]                  # format column = lab column, or a table
    test_id = "Test"
    soil = "Soil"
    radius_m = { column = "Plate diameter", unit = "mm", diameter = true }
    [tests.constant]                 # format column = value for every test
    kind = "sinkage"
    shape = "circle"

    [sinkage]
    file = "raw.csv"
    skip_rows = 3                    # a logger's preamble above the header line
    [sinkage.columns]
    test_id = "Test"
    z_m = { column = "Sinkage", unit = "mm" }
    force_N = { column = "Load", unit = "kN" }
"""

from __future__ import annotations

import os
import tomllib
from pathlib import Path

import pandas as pd

from ..errors import CampaignError, refuse_unknown_keys
from .campaign import Campaign
from .schema import FILES
from .units import to_si

__all__ = ["import_campaign"]

_TABLE_KEYS = {"file", "columns", "constant", "separator", "decimal", "skip_rows"}
_COLUMN_KEYS = {"column", "unit", "diameter"}


def _fail(path: Path, key: str, message: str) -> CampaignError:
    return CampaignError(f"mapping {str(path)!r}, key {key!r}: {message}", file=path.name)


def _read(folder: Path, mapping: Path, stem: str, table: dict) -> pd.DataFrame:
    name = table.get("file")
    if not isinstance(name, str) or not name:
        raise _fail(mapping, f"{stem}.file", "is required: the lab's CSV file for this table")
    separator = table.get("separator", ",")
    skip = table.get("skip_rows", 0)
    if isinstance(skip, bool) or not isinstance(skip, int) or skip < 0:
        raise _fail(
            mapping,
            f"{stem}.skip_rows",
            f"must be a whole number >= 0 (the lines above the header), got {skip!r}",
        )
    path = folder / name
    if not path.is_file():
        raise _fail(mapping, f"{stem}.file", f"{str(path)!r} is not a file")
    try:
        return pd.read_csv(
            path,
            sep=separator,
            skiprows=skip,
            dtype=str,
            keep_default_na=False,
            na_filter=False,
            index_col=False,
            encoding="utf-8-sig",
        )
    except (ValueError, pd.errors.ParserError, UnicodeDecodeError) as exc:
        raise CampaignError(
            f"cannot read the lab file ({type(exc).__name__}: {exc}); it must be a UTF-8 "
            f"CSV with a header row and separator {separator!r}",
            file=name,
        ) from exc


def _map_table(raw: pd.DataFrame, mapping: Path, stem: str, table: dict) -> pd.DataFrame:
    file = str(table["file"])
    columns = table.get("columns", {})
    constant = table.get("constant", {})
    decimal = table.get("decimal", ".")
    if not isinstance(columns, dict) or not isinstance(constant, dict):
        raise _fail(mapping, stem, "'columns' and 'constant' must be tables")
    out = pd.DataFrame(index=raw.index)
    used = set()
    for target, source in columns.items():
        spec = source if isinstance(source, dict) else {"column": source}
        extra = set(spec) - _COLUMN_KEYS
        if extra or not isinstance(spec.get("column"), str):
            raise _fail(
                mapping,
                f"{stem}.columns.{target}",
                f"give a lab column name or {{column = ..., unit = ..., diameter = true}} "
                f"(unknown keys: {sorted(extra)})",
            )
        lab = spec["column"]
        if lab not in raw.columns:
            raise CampaignError(
                f"the lab file has no column {lab!r} (mapped to {target!r}); its columns: "
                f"{list(raw.columns)}",
                file=file,
                column=lab,
            )
        values = raw[lab]
        if decimal != ".":
            values = values.str.replace(decimal, ".", regex=False)
        if "unit" in spec:
            values = to_si(values, target, str(spec["unit"]), file=file)
        if spec.get("diameter"):
            numbers = pd.to_numeric(values, errors="coerce")
            values = values.astype(object).where(numbers.isna(), numbers / 2.0)
        out[target] = values
        used.add(lab)
    for target, value in constant.items():
        if target in out.columns:
            raise _fail(mapping, f"{stem}.constant.{target}", "is also mapped from a column")
        out[target] = str(value) if isinstance(value, str) else value
    for lab in raw.columns:  # unmapped lab columns are kept: covariates of the test
        if lab in used:
            continue
        if lab in out.columns:
            raise CampaignError(
                f"the unmapped lab column {lab!r} has the name of a format column that the "
                "mapping also sets; map it, rename it, or drop the mapping entry",
                file=file,
                column=lab,
            )
        out[lab] = raw[lab]
    return out


def import_campaign(mapping: str | os.PathLike[str]) -> Campaign:
    """Read a lab's export through a TOML mapping and return the validated campaign.

    Raises
    ------
    CampaignError
        For a malformed mapping (naming the key), a missing lab file or column, an unknown
        unit, any rule of the campaign format, or values whose units are implausible.
    """
    path = Path(mapping)
    if not path.is_file():
        raise CampaignError(f"{str(path)!r} is not a file; give the TOML mapping file")
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as err:
        raise CampaignError(f"not valid TOML: {err}", file=path.name) from None
    refuse_unknown_keys(
        doc,
        FILES,
        lambda unknown: _fail(path, min(unknown), f"unknown table; a mapping has {list(FILES)}"),
    )
    if "tests" not in doc:
        raise _fail(path, "tests", "is required: the lab's test log")
    frames = {}
    for stem in FILES:
        table = doc.get(stem)
        if table is None:
            continue
        refuse_unknown_keys(
            table,
            _TABLE_KEYS,
            lambda unknown, stem=stem: _fail(
                path, f"{stem}.{min(unknown)}", f"unknown key; allowed: {sorted(_TABLE_KEYS)}"
            ),
        )
        raw = _read(path.parent, path, stem, table)
        frames[stem] = _map_table(raw, path, stem, table)
    return Campaign.from_frames(**frames, source=str(path))
