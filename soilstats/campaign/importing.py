"""Import a lab's own export through a small TOML mapping (``soilstats import``).

The mapping names the lab's CSV files — one table, or one file per test (a folder or a glob)
— says which lab column holds which format column, in which unit and with which sign, may
set values that are the same for every test, and may take test-log values (plate diameter,
date, operator) from each file's preamble by a pattern. The result is checked like any
campaign; a reversed sign or a unit slip is refused unless the mapping says so. Format:
``docs/importing.md``.

.. code-block:: toml

    [tests]                          # no file: one test per file of [sinkage]
    [tests.constant]                 # format column = value for every test
    kind = "sinkage"
    shape = "circle"
    soil = "loam"

    [sinkage]
    file = "records/*.csv"           # a folder or a glob: one file per test, stem = test id
    skip_rows = 3                    # a logger's preamble above the header line
    [sinkage.columns]
    z_m = { column = "Sinkage", unit = "mm" }
    force_N = { column = "Load", unit = "kN", sign = -1 }
    [sinkage.header]                 # test-log column = pattern on the preamble
    radius_m = { pattern = "Plate diameter: *([0-9.]+)", unit = "mm", diameter = true }
    operator = "Operator: *(.+)"
"""

from __future__ import annotations

import glob
import hashlib
import io
import os
import re
import tomllib
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from .._version import __version__
from ..errors import CampaignError, refuse_unknown_keys
from .campaign import Campaign
from .schema import FILES, spec
from .units import LENGTH, UNITS, check_plausible_units, implausible_units, to_si

__all__ = ["ImportRecord", "import_campaign", "import_campaign_record"]

_TABLE_KEYS = {"file", "columns", "constant", "separator", "decimal", "skip_rows", "header"}
_COLUMN_KEYS = {"column", "unit", "diameter", "sign"}
_HEADER_KEYS = {"pattern", "unit", "diameter"}
#: Lines read to guess where a preamble ends (the header line), and to check skip_rows.
_GUESS_LINES = 200


@dataclass
class ImportRecord:
    """What an import read, for ``import.json``: each source file with its SHA-256, the
    mapping as read (with any ``--skip-rows`` override) and the soilstats version."""

    mapping: str
    mapping_sha256: str
    document: dict[str, Any]
    sources: list[dict[str, str]] = field(default_factory=list)
    skip_rows_override: int | None = None

    def to_dict(self) -> dict[str, Any]:
        """The JSON document written as ``import.json`` beside the campaign."""
        return {
            "soilstats_version": __version__,
            "mapping": self.mapping,
            "mapping_sha256": self.mapping_sha256,
            "skip_rows_override": self.skip_rows_override,
            "mapping_document": self.document,
            "sources": self.sources,
        }


def _fail(path: Path, key: str, message: str) -> CampaignError:
    return CampaignError(f"mapping {str(path)!r}, key {key!r}: {message}", file=path.name)


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _files(folder: Path, mapping: Path, stem: str, name: str) -> tuple[list[Path], bool]:
    """The lab files of a table, and whether they are one file per test (a folder or a
    glob: sorted by name, so the import is the same on every machine)."""
    path = folder / name
    _refuse_outside(folder, mapping, stem, name, [path])
    if path.is_dir():
        found = sorted(p for p in path.iterdir() if p.is_file() and not p.name.startswith("."))
        if not found:
            raise _fail(mapping, f"{stem}.file", f"the folder {str(path)!r} holds no file")
        _refuse_outside(folder, mapping, stem, name, found)
        return found, True
    if glob.has_magic(name):
        found = sorted(Path(p) for p in glob.glob(str(path)) if Path(p).is_file())
        if not found:
            raise _fail(mapping, f"{stem}.file", f"the pattern {str(path)!r} matches no file")
        _refuse_outside(folder, mapping, stem, name, found)
        return found, True
    if not path.is_file():
        raise _fail(mapping, f"{stem}.file", f"{str(path)!r} is not a file")
    return [path], False


def _refuse_outside(folder: Path, mapping: Path, stem: str, name: str, paths: list[Path]) -> None:
    """Refuse lab files outside the mapping's folder, before any is read: a mapping names
    the files beside it, and one shared or downloaded must not read ``../../etc/passwd``
    (an absolute path, ``..`` or a link that leads out)."""
    base = folder.resolve()
    for p in paths:
        if (
            Path(name).is_absolute()
            or ".." in Path(name).parts
            or not p.resolve().is_relative_to(base)
        ):
            raise _fail(
                mapping,
                f"{stem}.file",
                f"{name!r} leads outside the mapping's folder {str(folder)!r} ({p.name!r}); "
                "put the lab files in that folder (or below it) and name them relative to it",
            )


def _fields(line: str, separator: str) -> int:
    return len(line.split(separator)) if line.strip() else 0


def _guess_skip(lines: list[str], separator: str) -> int | None:
    """The number of preamble lines above the header: the first line from which every
    following line (of the first few hundred) splits into the same number (≥ 2) of fields."""
    counts = [_fields(line, separator) for line in lines]
    for start, count in enumerate(counts):
        rest = counts[start:]
        if count >= 2 and rest.count(count) >= 2 and all(c in (0, count) for c in rest):
            return start
    return None


def _skip_hint(lines: list[str], separator: str, skip: int) -> str:
    guess = _guess_skip(lines, separator)
    if guess is None or guess == skip:
        return ""
    return (
        f"; the header line looks like line {guess + 1}: set skip_rows = {guess} in the "
        f"mapping (or --skip-rows {guess}), which now skips {skip}"
    )


def _read(
    path: Path, mapping: Path, stem: str, table: dict, skip: int
) -> tuple[pd.DataFrame, list[str]]:
    """The lab file as text cells under its own header, and the preamble lines above it."""
    separator = table.get("separator", ",")
    try:
        text = path.read_bytes().decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise CampaignError(
            f"cannot read the lab file: not UTF-8 ({exc.reason} at byte {exc.start})",
            file=path.name,
        ) from None
    lines = text.splitlines()
    # Bounded by the file: a huge skip_rows is an error here, never a huge allocation.
    if skip >= len(lines):
        raise _fail(
            mapping,
            f"{stem}.skip_rows",
            f"skip_rows = {skip}, but {path.name!r} has only {len(lines)} lines; it counts "
            "the lines above the header line",
        )
    preamble, body = lines[:skip], lines[skip:]
    hint_lines = lines[: skip + _GUESS_LINES]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            raw = pd.read_csv(
                io.StringIO("\n".join(body)),
                sep=separator,
                header=None,
                dtype=str,
                keep_default_na=False,
                na_filter=False,
                index_col=False,
                engine="c",
            )
        except (ValueError, pd.errors.ParserError) as exc:
            detail = str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__
            raise CampaignError(
                f"cannot read the lab file ({detail}) with separator {separator!r} after "
                f"skip_rows = {skip} lines{_skip_hint(hint_lines, separator, skip)}",
                file=path.name,
            ) from None
    if caught:  # no library's warning reaches the user: it is a question about this file
        raise CampaignError(
            f"reading the lab file raised {caught[0].category.__name__}: {caught[0].message}"
            f"{_skip_hint(hint_lines, separator, skip)}",
            file=path.name,
        )
    header = [str(h).strip() for h in raw.iloc[0]]
    blank = [i + 1 for i, h in enumerate(header) if not h]
    if blank:
        raise CampaignError(
            f"header line {skip + 1} has a blank column name (column {blank[0]}); name every "
            f"column{_skip_hint(hint_lines, separator, skip)}",
            file=path.name,
        )
    seen: set[str] = set()
    twice = [h for h in header if h in seen or seen.add(h)]  # type: ignore[func-returns-value]
    if twice:
        raise CampaignError(
            f"header line {skip + 1} names the column {twice[0]!r} twice; rename one",
            file=path.name,
            column=twice[0],
        )
    raw = raw.iloc[1:].reset_index(drop=True)
    raw.columns = header
    raw.attrs["hint"] = _skip_hint(hint_lines, separator, skip)
    return raw, preamble


def _numeric_target(stem: str, target: str) -> bool:
    column = spec(stem, target)
    return target in UNITS or (column is not None and column.dtype != "text")


def _decimal(values: pd.Series, decimal: str) -> pd.Series:
    return values.str.replace(decimal, ".", regex=False)


def _looks_numeric(values: pd.Series) -> bool:
    cells = values[values.str.strip() != ""]
    return len(cells) > 0 and bool(pd.to_numeric(cells, errors="coerce").notna().all())


def _strict_bool(value: object, mapping: Path, key: str) -> bool:
    if not isinstance(value, bool):
        raise _fail(mapping, key, f"must be true or false (a TOML boolean), got {value!r}")
    return value


def _convert(
    values: pd.Series, target: str, spec_: dict, mapping: Path, key: str, file: str
) -> pd.Series:
    """Unit, diameter and sign of one mapped column (cells that are not numbers stay as they
    are, so that validation reports them with their row)."""
    if "unit" in spec_:
        values = to_si(values, target, str(spec_["unit"]), file=file)
    if "diameter" in spec_ and _strict_bool(spec_["diameter"], mapping, f"{key}.diameter"):
        if UNITS.get(target) is not LENGTH or target == "z_m":
            raise _fail(
                mapping,
                f"{key}.diameter",
                f"diameter = true halves a plate or ring diameter into a radius; {target!r} "
                "is not a tool size",
            )
        numbers = pd.to_numeric(values, errors="coerce")
        values = values.astype(object).where(numbers.isna(), numbers / 2.0)
    if "sign" in spec_:
        sign = spec_["sign"]
        if isinstance(sign, bool) or sign not in (1, -1):
            raise _fail(mapping, f"{key}.sign", f"must be 1 or -1, got {sign!r}")
        if target not in UNITS:
            raise _fail(mapping, f"{key}.sign", f"{target!r} is not a measured channel")
        if sign == -1:
            numbers = pd.to_numeric(values, errors="coerce")
            values = values.astype(object).where(numbers.isna(), -numbers)
    return values


def _map_table(raw: pd.DataFrame, mapping: Path, stem: str, table: dict, file: str) -> pd.DataFrame:
    columns = table.get("columns", {})
    constant = table.get("constant", {})
    decimal = table.get("decimal", ".")
    if not isinstance(columns, dict) or not isinstance(constant, dict):
        raise _fail(mapping, stem, "'columns' and 'constant' must be tables")
    if not isinstance(decimal, str) or len(decimal) != 1:
        raise _fail(mapping, f"{stem}.decimal", f"must be one character, got {decimal!r}")
    out = pd.DataFrame(index=raw.index)
    used: dict[str, str] = {}
    for target, source in columns.items():
        key = f"{stem}.columns.{target}"
        spec_ = source if isinstance(source, dict) else {"column": source}
        extra = set(spec_) - _COLUMN_KEYS
        if extra or not isinstance(spec_.get("column"), str):
            raise _fail(
                mapping,
                key,
                "give a lab column name or {column = ..., unit = ..., diameter = true, "
                f"sign = -1}} (unknown keys: {sorted(extra)})",
            )
        lab = spec_["column"]
        if lab in used:
            raise _fail(
                mapping, key, f"the lab column {lab!r} is mapped twice (also to {used[lab]!r})"
            )
        if lab not in raw.columns:
            raise CampaignError(
                f"the lab file has no column {lab!r} (mapped to {target!r}); its columns: "
                f"{list(raw.columns)}{raw.attrs.get('hint', '')}",
                file=file,
                column=lab,
            )
        values: pd.Series = raw[lab]  # type: ignore[assignment]  # pandas-stubs: raw[label] of a label typed Any may be a frame; the lab's columns are unique
        if decimal != "." and _numeric_target(stem, target):  # never inside ids or names
            values = _decimal(values, decimal)
        out[target] = _convert(values, target, spec_, mapping, key, file)
        used[lab] = target
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
        values = raw[lab]
        if decimal != "." and _looks_numeric(_decimal(values, decimal)):
            values = _decimal(values, decimal)  # a numeric covariate; text stays as written
        out[lab] = values
    return out


def _header_values(
    preamble: list[str], mapping: Path, stem: str, table: dict, file: str
) -> dict[str, Any]:
    """The test-log values found in one file's preamble by the ``header`` patterns."""
    patterns = table.get("header", {})
    if not isinstance(patterns, dict):
        raise _fail(mapping, f"{stem}.header", "must be a table: column = pattern")
    text = "\n".join(preamble)
    found: dict[str, Any] = {}
    for target, source in patterns.items():
        key = f"{stem}.header.{target}"
        spec_ = source if isinstance(source, dict) else {"pattern": source}
        extra = set(spec_) - _HEADER_KEYS
        if extra or not isinstance(spec_.get("pattern"), str):
            raise _fail(
                mapping,
                key,
                "give a pattern with one group, or {pattern = ..., unit = ..., diameter = "
                f"true}} (unknown keys: {sorted(extra)})",
            )
        try:
            regex = re.compile(spec_["pattern"], re.MULTILINE)
        except re.error as exc:
            raise _fail(mapping, key, f"not a valid pattern: {exc}") from None
        if regex.groups != 1:
            raise _fail(mapping, key, f"the pattern needs exactly one (group), has {regex.groups}")
        match = regex.search(text)
        if match is None:
            raise CampaignError(
                f"the pattern {spec_['pattern']!r} of key {key!r} matches nothing in the "
                f"{len(preamble)} preamble lines (skip_rows)",
                file=file,
            )
        value = pd.Series([match.group(1).strip()])
        decimal = table.get("decimal", ".")
        if decimal != "." and _numeric_target("tests", target):
            value = _decimal(value, decimal)
        found[target] = _convert(value, target, spec_, mapping, key, file).iloc[0]
    return found


def _read_table(
    path: Path, stem: str, table: dict, skip_override: int | None, record: ImportRecord
) -> tuple[pd.DataFrame, pd.DataFrame | None]:
    """One table of the mapping, and the test-log rows its per-test files' preambles give."""
    name = table.get("file")
    if not isinstance(name, str) or not name:
        raise _fail(path, f"{stem}.file", "is required: the lab's CSV file(s) for this table")
    separator = table.get("separator", ",")
    if not isinstance(separator, str) or len(separator) != 1 or separator in '\r\n"':
        raise _fail(
            path,
            f"{stem}.separator",
            f'must be one character such as ",", ";" or "\\t", got {separator!r}',
        )
    decimal = table.get("decimal", ".")
    if not isinstance(decimal, str) or len(decimal) != 1:
        raise _fail(path, f"{stem}.decimal", f"must be one character, got {decimal!r}")
    skip = table.get("skip_rows", 0)
    if isinstance(skip, bool) or not isinstance(skip, int) or skip < 0:
        raise _fail(
            path,
            f"{stem}.skip_rows",
            f"must be a whole number >= 0 (the lines above the header), got {skip!r}",
        )
    if skip_override is not None and stem != "tests":
        skip = skip_override
    files, per_test = _files(path.parent, path, stem, name)
    if "header" in table and not per_test:
        raise _fail(path, f"{stem}.header", "needs one file per test (a folder or a glob)")
    columns = table.get("columns", {})
    frames, log = [], []
    for file in files:
        raw, preamble = _read(file, path, stem, table, skip)
        record.sources.append({"table": stem, "file": str(file), "sha256": _sha256(file)})
        mapped = _map_table(raw, path, stem, table, file.name)
        header = _header_values(preamble, path, stem, table, file.name) if per_test else {}
        if per_test:
            test_id = header.pop("test_id", None)
            if "test_id" not in columns:
                test_id = file.stem if test_id is None else test_id
                if "test_id" in mapped.columns:
                    raise _fail(path, f"{stem}.constant.test_id", "is the file's stem here")
                mapped.insert(0, "test_id", str(test_id))
            elif test_id is not None:
                raise _fail(path, f"{stem}.header.test_id", "test_id is also mapped from a column")
            else:
                ids = mapped["test_id"].unique()
                test_id = ids[0] if len(ids) == 1 else None
            if header:
                if test_id is None:
                    raise CampaignError(
                        "the file holds several tests, so its header values cannot be "
                        "assigned to one; give one file per test",
                        file=file.name,
                    )
                log.append({"test_id": str(test_id), **header})
        frames.append(mapped)
    out = pd.concat(frames, ignore_index=True) if len(frames) > 1 else frames[0]
    return out, (pd.DataFrame(log) if log else None)


def _tests_from_files(
    path: Path, table: dict, ids: list[str], headers: list[pd.DataFrame]
) -> pd.DataFrame:
    """The test log when ``[tests]`` names no file: one row per test of the per-test files."""
    refuse_unknown_keys(
        table,
        {"constant"},
        lambda unknown: _fail(
            path, f"tests.{min(unknown)}", "without tests.file, [tests] takes only 'constant'"
        ),
    )
    log = pd.DataFrame({"test_id": ids})
    for target, value in table.get("constant", {}).items():
        log[target] = str(value) if isinstance(value, str) else value
    return _merge_headers(path, log, headers)


def _merge_headers(path: Path, log: pd.DataFrame, headers: list[pd.DataFrame]) -> pd.DataFrame:
    for values in headers:
        clash = sorted(set(values.columns) - {"test_id"} & set(log.columns))
        if clash:
            raise _fail(
                path,
                f"header.{clash[0]}",
                f"{clash[0]!r} is also set by the test log (file or constant); set it once",
            )
        log = log.merge(values, on="test_id", how="left")
    return log


def import_campaign_record(
    mapping: str | os.PathLike[str], *, skip_rows: int | None = None
) -> tuple[Campaign, ImportRecord]:
    """:func:`import_campaign`, with the :class:`ImportRecord` of what it read."""
    path = Path(mapping)
    if not path.is_file():
        raise CampaignError(f"{str(path)!r} is not a file; give the TOML mapping file")
    if skip_rows is not None and (isinstance(skip_rows, bool) or skip_rows < 0):
        raise CampaignError(f"--skip-rows must be a whole number >= 0, got {skip_rows!r}")
    content = path.read_bytes()
    try:
        doc = tomllib.loads(content.decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as err:
        raise CampaignError(f"not valid TOML: {err}", file=path.name) from None
    record = ImportRecord(
        str(path), hashlib.sha256(content).hexdigest(), doc, skip_rows_override=skip_rows
    )
    refuse_unknown_keys(
        doc,
        FILES,
        lambda unknown: _fail(path, min(unknown), f"unknown table; a mapping has {list(FILES)}"),
    )
    if "tests" not in doc:
        raise _fail(path, "tests", "is required: the lab's test log")
    for stem in FILES:
        if stem in doc and not isinstance(doc[stem], dict):
            raise _fail(path, stem, "must be a table")
        refuse_unknown_keys(
            doc.get(stem, {}),
            _TABLE_KEYS,
            lambda unknown, stem=stem: _fail(
                path, f"{stem}.{min(unknown)}", f"unknown key; allowed: {sorted(_TABLE_KEYS)}"
            ),
        )
    frames: dict[str, pd.DataFrame] = {}
    headers: list[pd.DataFrame] = []
    for stem in ("sinkage", "shear"):
        if stem in doc:
            frames[stem], found = _read_table(path, stem, doc[stem], skip_rows, record)
            if found is not None:
                headers.append(found)
    if "file" in doc["tests"]:
        log, _ = _read_table(path, "tests", doc["tests"], skip_rows, record)
        frames["tests"] = _merge_headers(path, log, headers)
    else:
        ids = list(dict.fromkeys(str(t) for f in frames.values() for t in f["test_id"]))
        if not ids:
            raise _fail(path, "tests.file", "is required unless [sinkage] or [shear] has tests")
        frames["tests"] = _tests_from_files(path, doc["tests"], ids, headers)
    campaign = Campaign.from_frames(**frames, source=str(path), check_units=False)  # type: ignore[arg-type]  # mypy matches **frames against every keyword; the tables are DataFrames
    _refuse_slips(campaign, path, doc)
    check_plausible_units(campaign.tests, campaign.sinkage, campaign.shear)
    return campaign, record


def _refuse_slips(campaign: Campaign, path: Path, doc: dict) -> None:
    """A reversed sign or a unit slip is an error at import, unless the mapping states the
    column's sign or unit (then it is the loud warning every load gives)."""
    for finding in implausible_units(campaign.tests, campaign.sinkage, campaign.shear):
        stem = finding.file.removesuffix(".csv")
        source = doc.get(stem, {}).get("columns", {}).get(finding.column)
        spec_ = source if isinstance(source, dict) else {"column": source}
        key = f"{stem}.columns.{finding.column}"
        lab = spec_.get("column") or finding.column
        shown = ", ".join(repr(t) for t in finding.test_ids[:5])
        if finding.fatal:
            fix = 'give its unit in the mapping, e.g. unit = "mm"'
        elif finding.kind == "sign" and "sign" not in spec_:
            fix = f"if the lab logs it negative, add sign = -1 to {key}"
        elif finding.kind == "unit" and "unit" not in spec_:
            fix = f"give its unit in the mapping ({key} = {{ column = {lab!r}, unit = ... }})"
        else:
            continue  # the mapping states it: a warning, as on every load
        raise CampaignError(
            f"lab column {lab!r} (mapped to {finding.column!r}): {finding.what} in "
            f"{len(finding.test_ids)} test(s) ({shown}); {fix}",
            file=path.name,
            column=lab,
            test_id=finding.test_ids[0],
        )


def import_campaign(mapping: str | os.PathLike[str], *, skip_rows: int | None = None) -> Campaign:
    """Read a lab's export through a TOML mapping and return the validated campaign.

    ``skip_rows`` (the command line's ``--skip-rows``) overrides the mapping's ``skip_rows``
    of the record tables (``[sinkage]``, ``[shear]``), for a one-off file.

    Raises
    ------
    CampaignError
        For a malformed mapping (naming the key), a missing lab file or column, an unknown
        unit, any rule of the campaign format, a reversed sign or a unit slip the mapping
        does not state, or lengths whose units are implausible.
    """
    return import_campaign_record(mapping, skip_rows=skip_rows)[0]
