"""Write a study's JSON and CSV outputs (the PDF is :mod:`.report`)."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

import pandas as pd

from ..outputs import Provenance, json_safe, output_path, write_csv, write_json
from ..statistics import VERDICT_COLUMNS

if TYPE_CHECKING:
    from .spec import StudySpec

__all__ = ["StudyRecord", "to_json_dict", "write_outputs"]


class StudyRecord(Protocol):
    """What the writers read of a :class:`~.result.StudyResult` (which imports this module
    for its ``to_json``: an import back would close a loop, tests/test_layers.py)."""

    @property
    def spec(self) -> StudySpec: ...

    @property
    def name(self) -> str: ...

    @property
    def source(self) -> str: ...

    @property
    def date(self) -> str | None: ...

    @property
    def soils(self) -> list: ...

    @property
    def effects(self) -> pd.DataFrame: ...

    @property
    def anova(self) -> pd.DataFrame: ...

    @property
    def pairs(self) -> pd.DataFrame: ...

    @property
    def parameters(self) -> pd.DataFrame: ...

    @property
    def lines(self) -> pd.DataFrame: ...

    @property
    def per_test(self) -> pd.DataFrame: ...

    @property
    def criteria(self) -> pd.DataFrame | None: ...

    @property
    def best(self) -> dict | None: ...

    @property
    def notes(self) -> tuple[str, ...]: ...

    @property
    def seed(self) -> int | None: ...

    @property
    def provenance(self) -> Provenance | None: ...

    def reference_pairs(self) -> pd.DataFrame: ...


_EFFECT_KEYS = [
    *VERDICT_COLUMNS,
    "blocks",
    "n_tests",
    "error_term",
    "df_error",
    "largest_difference",
    "difference_bound",
    "margin",
    "verdict",
    "matters",
]


def _records(frame: pd.DataFrame | None, keys: Iterable[str] | None = None) -> list[dict]:
    if frame is None or frame.empty:
        return []
    cols = [k for k in (keys or frame.columns) if k in frame.columns]
    return [json_safe(r) for r in frame[cols].to_dict("records")]


def to_json_dict(result: StudyRecord) -> dict:
    """The JSON document of a study: ``{"study", "effects": [...], "parameters": [...], …}``."""
    spec = result.spec
    doc = {
        "study": result.name,
        "title": spec.title,
        "paper": spec.paper,
        "data": result.source,
        "seed": result.seed,
        "factor": spec.factor,
        "alpha": spec.alpha,
        "multiple_comparisons": "Holm across all soils and responses of the study"
        if spec.family is None
        else f"Holm within each {spec.family}",
        "soils": result.soils,
        "effects": _records(result.effects, _EFFECT_KEYS),
        "parameters": _records(result.parameters),
        "reference_pairs": _records(result.reference_pairs()),
        "lines": _records(result.lines),
        "notes": list(result.notes),
        "defaults": dict(getattr(result, "defaults", {})),
        "default_warnings": dict(getattr(result, "default_warnings", {})),
    }
    if result.date is not None:  # only when SOURCE_DATE_EPOCH asks for one
        doc["date"] = result.date
    if result.criteria is not None:
        doc["criteria"] = _records(result.criteria)
        doc["best_method"] = json_safe(result.best)
    return json_safe(doc)


def write_outputs(
    result: StudyRecord,
    out_dir: Path,
    provenance: Provenance | None = None,
    *,
    overwrite: bool = False,
) -> list[Path]:
    """Write ``NAME.json`` and the ``NAME_*.csv`` tables into ``out_dir``; return the paths.

    Every file carries ``provenance`` (default: a library call on ``result.source`` with the
    result's seed). An existing file is an error unless ``overwrite``.
    """
    out_dir = Path(out_dir)
    name = result.name
    # A result built without one (StudyResult's default) records a library call on its
    # source: the result holds no campaign to hash.
    provenance = (
        provenance
        or result.provenance
        or replace(Provenance.of(None, seed=result.seed), campaign=result.source)
    )
    tables = {
        "effects": result.effects,
        "anova": result.anova,
        "parameters": result.parameters,
        "pairs": result.pairs,
        "lines": result.lines,
        "per_test": result.per_test,
        "criteria": result.criteria,
    }
    targets = [out_dir / f"{name}.json"] + [
        out_dir / f"{name}_{label}.csv"
        for label, frame in tables.items()
        if frame is not None and not frame.empty
    ]
    for path in targets:  # refuse before writing anything, so no half-written set is left
        output_path(out_dir, path.name, overwrite=overwrite)
    paths = [write_json(targets[0], to_json_dict(result), provenance, overwrite=overwrite)]
    for label, frame in tables.items():
        if frame is None or frame.empty:
            continue
        path = out_dir / f"{name}_{label}.csv"
        paths.append(write_csv(path, frame, provenance, overwrite=overwrite))
    return paths
