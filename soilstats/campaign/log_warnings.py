"""Warnings for test-log cells the format allows but that are most likely slips (issue #44).

The format (``docs/campaign-format.md``) lets a test carry a geometry cell it does not use
(only "a finite number, even where the test does not use it"), a shear test a ``shape``, any
whole ``repetition`` and any whole ``grousers`` ≥ 0. Each is read as written — nothing is
changed or refused — but a circle with a ``width_m`` is most likely a rectangle with the wrong
``shape`` (its fit then uses b = radius), a shear test with a ``shape`` a sinkage test of the
wrong ``kind``, a negative repetition a sign slip, and a thousand grousers a wrong column;
with nothing else to show it, the reader says so, once per column, naming the tests.
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd

from ..errors import SoilstatsWarning

__all__ = ["MAX_GROUSERS", "warn_unlikely_log_cells"]

#: A shear ring carries a few to a few dozen grousers (one every centimetre or more of its
#: circumference); more than this is another column's number, not a count of grousers.
MAX_GROUSERS = 100

#: (kind, shape or None, column, why it is odd, what to do).
_UNUSED = (
    (
        "sinkage",
        "circle",
        "width_m",
        "a circular plate is sized by radius_m; its width_m is not used",
        "if the plate is a rectangle, set shape = rectangle (and length_m); else empty the cell",
    ),
    (
        "sinkage",
        "circle",
        "length_m",
        "a circular plate is sized by radius_m; its length_m is not used",
        "if the plate is a rectangle, set shape = rectangle (and width_m); else empty the cell",
    ),
    (
        "sinkage",
        "rectangle",
        "radius_m",
        "a rectangular plate is sized by width_m and length_m; its radius_m is not used",
        "if the plate is a circle, set shape = circle; else empty the cell",
    ),
    (
        "shear",
        None,
        "shape",
        "a shear-ring test has no plate shape; its shape is not used",
        "if it is a plate test, set kind = sinkage; else empty the cell",
    ),
)


def _names(ids: pd.Series) -> str:
    shown = [repr(str(t)) for t in ids[:6]]
    return ", ".join(shown) + (f", … ({len(ids)} tests)" if len(ids) > 6 else "")


def _warn(file: str, column: str, ids: pd.Series, message: str) -> None:
    warnings.warn(
        f"file {file!r}, column {column!r}, test(s) {_names(ids)}: {message}",
        SoilstatsWarning,
        stacklevel=5,  # the caller of load_campaign or from_frames
    )


def warn_unlikely_log_cells(tests: pd.DataFrame, file: str) -> None:
    """Warn (:class:`SoilstatsWarning`) of log cells the format allows but that are likely
    slips: a cell of a column the test does not use, a negative ``repetition``, more than
    :data:`MAX_GROUSERS` grousers. Nothing is changed."""
    kind = tests["kind"].astype(str)
    shape = tests["shape"].astype(str) if "shape" in tests else None
    for k, s, column, why, fix in _UNUSED:
        if column not in tests or (s is not None and shape is None):
            continue
        given = tests[column].notna()
        if column == "shape":  # text: an empty cell is not recorded
            given &= tests[column].astype(str).str.strip().ne("")
        hit = given & kind.eq(k) & (shape.eq(s) if s is not None and shape is not None else True)
        if hit.any():
            _warn(file, column, tests.loc[hit, "test_id"], f"{why} — {fix}")
    if "repetition" in tests:
        neg = np.asarray(tests["repetition"] < 0)
        if neg.any():
            values = sorted(set(tests.loc[neg, "repetition"].astype(float)))
            _warn(
                file,
                "repetition",
                tests.loc[neg, "test_id"],
                f"repetition {', '.join(f'{v:g}' for v in values)} is negative; repetitions "
                "are counted from 0 or 1 — check the sign (the value is kept as written)",
            )
    if "grousers" in tests:
        many = np.asarray(kind.eq("shear") & (tests["grousers"] > MAX_GROUSERS))
        if many.any():
            values = sorted(set(tests.loc[many, "grousers"].astype(float)))
            _warn(
                file,
                "grousers",
                tests.loc[many, "test_id"],
                f"{', '.join(f'{v:g}' for v in values)} grousers on a shear ring (more than "
                f"{MAX_GROUSERS}) is not a count of grousers but most likely another "
                "column's number — check the column (the value is kept as written)",
            )
