"""Write a study's JSON and CSV outputs (the PDF is :mod:`.report`)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd

from ..statistics import VERDICT_COLUMNS

__all__ = ["to_json_dict", "write_outputs"]

_EFFECT_KEYS = [
    *VERDICT_COLUMNS,
    "blocks",
    "n_tests",
    "largest_difference",
    "difference_bound",
    "margin",
    "verdict",
    "matters",
]


def _clean(value):
    """JSON-safe scalars: NaN → None, numpy → Python."""
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_clean(v) for v in value]
    if isinstance(value, np.bool_ | bool):
        return bool(value)
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, float | np.floating):
        return None if not math.isfinite(value) else float(value)
    return value


def _records(frame: pd.DataFrame | None, keys=None) -> list[dict]:
    if frame is None or frame.empty:
        return []
    cols = [k for k in (keys or frame.columns) if k in frame.columns]
    return [_clean(r) for r in frame[cols].to_dict("records")]


def to_json_dict(result) -> dict:
    """The JSON document of a study: ``{"study", "effects": [...], "parameters": [...], …}``."""
    spec = result.spec
    doc = {
        "study": result.name,
        "title": spec.title,
        "paper": spec.paper,
        "data": result.source,
        "date": result.date,
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
        "seconds": result.seconds,
    }
    if result.criteria is not None:
        doc["criteria"] = _records(result.criteria)
        doc["best_method"] = _clean(result.best)
    return _clean(doc)


def write_outputs(result, out_dir: Path) -> list[Path]:
    """Write ``NAME.json`` and the CSV tables into ``out_dir``; return the paths written."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    name = result.name
    paths = [out_dir / f"{name}.json"]
    paths[0].write_text(json.dumps(to_json_dict(result), indent=2) + "\n", encoding="utf-8")
    tables = {
        "effects": result.effects,
        "anova": result.anova,
        "parameters": result.parameters,
        "pairs": result.pairs,
        "lines": result.lines,
        "per_test": result.per_test,
        "criteria": result.criteria,
    }
    for label, frame in tables.items():
        if frame is None or frame.empty:
            continue
        path = out_dir / f"{name}_{label}.csv"
        frame.to_csv(path, index=False)
        paths.append(path)
    return paths
