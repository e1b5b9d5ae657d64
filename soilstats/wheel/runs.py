"""Measured wheel runs: the runs file (``wheel.csv``) and the wheels' geometry (``wheels.toml``).

**The runs file** is a CSV (or Parquet) with one row per run (docs/wheel.md, "Runs file"):

=====================  ======  ==========================================================
column                 unit    meaning
=====================  ======  ==========================================================
``run_id``             –       unique name of the run (required)
``wheel``              –       wheel type, a name of the geometry table (required)
``slip``               –       s = (rω − V)/max(rω, V) in [−1, 1] (required)
``W_N``                N       measured normal load, > 0 (required)
``sinkage_m``          m       measured sinkage, ≥ 0 (required)
``beta_deg``           deg     slip angle β, |β| ≤ 90 (optional; 0 when absent)
``beta_cmd_deg``       deg     commanded slip angle; when given it names the β condition
``date``               –       day of the run, ISO ``YYYY-MM-DD`` (optional)
``drawbar_pull_N``     N       measured drawbar pull, + forward (optional, may be empty)
``torque_Nm``          N·m     measured driving torque (optional, may be empty)
``sinkage_rate_m_s``   m/s     sinkage rate in the averaging window (optional): a run
                               sinking faster than 0.1 mm/s is marked not steady
=====================  ======  ==========================================================

Other columns are kept and ignored.  Every violation is a :class:`WheelDataError` naming the
file, the column, the run and the 1-based data row (the header not counted).

**Conditions.**  The slip conditions of a file are found from the slips themselves: sorted,
a new level where two consecutive slips differ by more than ``slip_gap`` (0.1), labelled by
their mean; the β condition is ``beta_cmd_deg`` (else ``beta_deg``) rounded to 1°.

**Geometry** (:func:`read_wheels`): a TOML table per wheel type,

.. code-block:: toml

    [grouser]
    radius_m = 0.058          # rim radius r (slip is defined with it)
    width_m = 0.050           # width b, also Bekker's b of the plate law
    shear_radius_m = 0.063    # grouser tips (optional, default r)
    grouser_area_ratio = 0.1  # CMU's mu (optional, default 1)

A ``wheels.toml`` beside the runs file is read when no other geometry is given (the bundled
CMU campaign carries one, from its ``wheel.md``).  Its optional top-level
``caveats = ["...", ...]`` states what a reader of the data must know (an assumed sinkage
datum, unchecked forces …); reports print them (:func:`read_caveats`).
"""

from __future__ import annotations

import csv
import os
import tomllib
import warnings
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from .._text import shown
from ..errors import SoilstatsError, SoilstatsWarning, located, refuse_unknown_keys
from .geometry import Wheel

__all__ = [
    "MISSING_MARKERS",
    "OPTIONAL_COLUMNS",
    "REQUIRED_COLUMNS",
    "STEADY_RATE_M_S",
    "UnitWarning",
    "WheelDataError",
    "read_caveats",
    "read_runs",
    "read_wheels",
    "warn_load_units",
    "warn_unit_mistakes",
    "wheel_geometry",
]

#: Required columns of a runs file and their units.
REQUIRED_COLUMNS: dict[str, str] = {
    "run_id": "-",
    "wheel": "-",
    "slip": "-",
    "W_N": "N",
    "sinkage_m": "m",
}
#: Optional columns soilstats reads (others are kept and ignored).
OPTIONAL_COLUMNS: dict[str, str] = {
    "beta_deg": "deg",
    "beta_cmd_deg": "deg",
    "date": "YYYY-MM-DD",
    "drawbar_pull_N": "N",
    "torque_Nm": "N·m",
    "sinkage_rate_m_s": "m/s",
}
#: A run still sinking faster than this [m/s] in its averaging window is not steady.
STEADY_RATE_M_S = 1e-4
#: Slips further apart than this start a new slip condition.
SLIP_GAP = 0.1
_WHEEL_KEYS = ("radius_m", "width_m", "shear_radius_m", "grouser_area_ratio")


class UnitWarning(SoilstatsWarning):
    """A runs file's or a wheel's numbers look like another unit (grams-force, kN, radians,
    mm); the message names the column and the likely unit."""


class WheelDataError(SoilstatsError, ValueError):
    """A runs file or a wheel geometry breaks a rule; the message names file, column, run, row."""

    def __init__(
        self,
        message: str,
        *,
        file: str | None = None,
        column: str | None = None,
        run_id: str | None = None,
        row: int | None = None,
    ) -> None:
        self.file, self.column, self.run_id, self.row = file, column, run_id, row
        super().__init__(located(message, file=file, column=column, run=run_id, row=row))


def read_runs(
    source: pd.DataFrame | str | os.PathLike[str], *, slip_gap: float = SLIP_GAP
) -> pd.DataFrame:
    """Read and validate a runs file (a path to CSV/Parquet, or a DataFrame).

    Returns a new DataFrame: the file's columns, ``beta_deg`` filled with 0 when absent, and
    the derived ``row`` (1-based data row), ``slip_level``, ``beta_level`` and ``steady``.
    Raises :class:`WheelDataError` for a missing column, a bad value (with its row) or a
    duplicate ``run_id``; ``OSError`` for a file that cannot be read.
    """
    if isinstance(source, pd.DataFrame):
        # a table read before (the CLI reads, then validates) keeps its file's name
        frame, name = source.copy(), str(source.attrs.get("file", "<DataFrame>"))
        read_as_text = False
    else:
        path = Path(source)
        name = path.name
        read_as_text = path.suffix.lower() != ".parquet"  # Parquet keeps its own types
        frame = _read_csv(path, name) if read_as_text else pd.read_parquet(path)
    if frame.empty:
        raise WheelDataError("no runs in the file", file=name)
    frame.columns = [str(c).strip() for c in frame.columns]
    _refuse_duplicate_columns(list(frame.columns), name)
    missing = [c for c in REQUIRED_COLUMNS if c not in frame.columns]
    if missing:
        raise WheelDataError(
            f"missing required column(s) {missing}; a runs file needs "
            f"{', '.join(f'{c} [{u}]' for c, u in REQUIRED_COLUMNS.items())} "
            "(docs/wheel.md, Runs file)",
            file=name,
            column=missing[0],
        )
    frame = frame.reset_index(drop=True)
    frame["row"] = np.arange(1, len(frame) + 1)
    _text(frame, "run_id", name)
    _text(frame, "wheel", name)
    duplicated = frame["run_id"].duplicated()
    if duplicated.any():
        i = int(np.flatnonzero(duplicated)[0])
        raise WheelDataError(
            "run_id repeats an earlier run; every run needs its own name",
            file=name,
            column="run_id",
            run_id=str(frame.at[i, "run_id"]),
            row=i + 1,
        )
    _number(frame, "slip", name, lambda x: (x >= -1) & (x <= 1), "a slip in [-1, 1]")
    _number(frame, "W_N", name, lambda x: x > 0, "a positive load in N")
    _number(frame, "sinkage_m", name, lambda x: x >= 0, "a sinkage >= 0 in m")
    big = frame["sinkage_m"] > 1.0
    if big.any():
        i = int(np.flatnonzero(big)[0])
        raise WheelDataError(
            f"sinkage {frame['sinkage_m'].iloc[i]:g} m is more than a metre: is it in mm? "
            "Give sinkage_m in metres",
            file=name,
            column="sinkage_m",
            run_id=str(frame.at[i, "run_id"]),
            row=i + 1,
        )
    for column in ("beta_deg", "beta_cmd_deg"):
        if column in frame:
            _number(
                frame, column, name, lambda x: np.abs(x) <= 180, "a slip angle in [-180, 180] deg"
            )
    if "beta_deg" not in frame:
        frame["beta_deg"] = 0.0
    for column in ("drawbar_pull_N", "torque_Nm", "sinkage_rate_m_s"):
        if column in frame:
            _number(frame, column, name, lambda x: np.isfinite(x), "a finite number", empty=True)
    if "date" in frame:
        _dates(frame, name)
    warn_unit_mistakes(frame, name)
    if read_as_text:
        _other_columns_as_numbers(frame)
    frame.attrs["file"] = name  # later checks (loads against the wheels) name it too
    frame["slip_level"] = slip_levels(frame["slip"].to_numpy(float), slip_gap)
    beta = frame["beta_cmd_deg"] if "beta_cmd_deg" in frame else frame["beta_deg"]
    frame["beta_level"] = np.round(beta.to_numpy(float)).astype(int)
    rate = frame.get("sinkage_rate_m_s")
    frame["steady"] = True if rate is None else ~(rate.abs() > STEADY_RATE_M_S).to_numpy()
    return frame


def _bad(frame: pd.DataFrame, column: str, name: str, mask: np.ndarray, what: str) -> None:
    if mask.any():
        i = int(np.flatnonzero(mask)[0])
        raise WheelDataError(
            f"{_cell(frame.at[i, column])} is not {what}"
            + (f" ({int(mask.sum())} rows)" if mask.sum() > 1 else ""),
            file=name,
            column=column,
            run_id=str(frame.at[i, "run_id"]) if column != "run_id" else None,
            row=i + 1,
        )


#: Cells that say "no value" in an optional column (a force not measured, a run undated):
#: an empty cell or one of these markers (R's and pandas' NA, NaN).
MISSING_MARKERS = ("", "NA", "NaN", "nan")


def _read_csv(path: Path, name: str) -> pd.DataFrame:
    """The CSV as text (ids stay as written: ``001`` is not 1; no cell becomes NaN unseen),
    its header checked for duplicates before pandas would rename one ``W_N.1``."""
    try:
        with path.open(encoding="utf-8-sig", newline="") as handle:
            header = next(csv.reader(handle), None)
    except UnicodeDecodeError as err:
        raise WheelDataError(
            f"not UTF-8 text (byte {err.start}: {err.reason}); save the runs file as UTF-8 CSV",
            file=name,
        ) from None
    if header is None:
        raise WheelDataError("the file is empty", file=name)
    _refuse_duplicate_columns([c.strip() for c in header], name)
    try:
        return pd.read_csv(
            path, comment=None, dtype=str, keep_default_na=False, encoding="utf-8-sig"
        )
    except pd.errors.EmptyDataError:
        raise WheelDataError("the file is empty", file=name) from None
    except UnicodeDecodeError as err:
        raise WheelDataError(
            f"not UTF-8 text (byte {err.start}: {err.reason}); save the runs file as UTF-8 CSV",
            file=name,
        ) from None


def _other_columns_as_numbers(frame: pd.DataFrame) -> None:
    """Columns soilstats does not read, read from a CSV as text: numbers where every filled
    cell is one (as pandas would have read them), else text as written."""
    known = {*REQUIRED_COLUMNS, *OPTIONAL_COLUMNS, "row"}
    for column in frame.columns:
        if column in known or frame[column].dtype != object:
            continue
        filled = ~_is_missing(frame[column])
        values = pd.to_numeric(frame[column].where(filled), errors="coerce")
        if filled.any() and values[filled].notna().all():
            frame[column] = values


def _refuse_duplicate_columns(columns: list[str], name: str) -> None:
    seen: set[str] = set()
    for column in columns:
        if column in seen:
            raise WheelDataError(
                "the header names this column twice; which one holds the values is not for "
                "soilstats to guess: keep one",
                file=name,
                column=column,
            )
        if column == "":
            raise WheelDataError("a column has no name in the header", file=name)
        seen.add(column)


def _cell(value: object) -> str:
    if value is None:
        return "an empty cell"
    if isinstance(value, bool | np.bool_):
        return f"the boolean {value}"
    if isinstance(value, complex | np.complexfloating):
        return f"the complex number {value}"
    if isinstance(value, float | np.floating):
        return "a missing value (NaN)" if np.isnan(value) else f"{float(value):g}"
    if isinstance(value, str) and value.strip() == "":
        return "an empty cell"
    if isinstance(value, str) and value.strip() in MISSING_MARKERS:
        return f"{value.strip()!r} (a missing-value marker)"
    return shown(value)


def _is_missing(values: pd.Series) -> np.ndarray:
    """Empty cells and missing-value markers (``MISSING_MARKERS``), NaN and None."""
    text = values.astype(str).str.strip()
    return values.isna().to_numpy() | text.isin(MISSING_MARKERS).to_numpy()


def _text(frame: pd.DataFrame, column: str, name: str) -> None:
    values = frame[column]
    blank = values.isna().to_numpy() | (values.astype(str).str.strip() == "").to_numpy()
    _bad(frame, column, name, blank, "a name (empty cell)")
    frame[column] = values.astype(str).str.strip()


def _not_real(raw: pd.Series) -> np.ndarray:
    """Cells that are booleans or complex numbers (a DataFrame's or Parquet's own types): no
    number a measurement is, though numpy would take True as 1.0 and drop an imaginary part."""
    if pd.api.types.is_bool_dtype(raw) or pd.api.types.is_complex_dtype(raw):
        return np.ones(len(raw), bool)
    if raw.dtype != object:
        return np.zeros(len(raw), bool)
    return np.array(
        [isinstance(v, bool | np.bool_ | complex | np.complexfloating) for v in raw], bool
    )


def _number(
    frame: pd.DataFrame,
    column: str,
    name: str,
    valid: Callable[[np.ndarray], np.ndarray],
    what: str,
    *,
    empty: bool = False,
) -> None:
    raw = frame[column]
    odd = _not_real(raw)
    _bad(frame, column, name, odd, what)
    text = raw.astype(str).str.strip() if raw.dtype == object else raw
    values = pd.to_numeric(text, errors="coerce").to_numpy(float)
    blank = _is_missing(raw)
    with np.errstate(invalid="ignore"):
        good = np.isfinite(values) & np.asarray(valid(values), bool)
    _bad(frame, column, name, ~(good | (blank & empty)), what)
    frame[column] = np.where(blank, np.nan, values)


def _dates(frame: pd.DataFrame, name: str) -> None:
    """ISO dates; an empty cell (or a missing-value marker) is an undated run (NaN)."""
    undated = _is_missing(frame["date"])
    text = frame["date"].astype(str).str.strip()
    parsed = pd.to_datetime(text.where(~undated), format="%Y-%m-%d", errors="coerce")
    _bad(frame, "date", name, parsed.isna().to_numpy() & ~undated, "a date YYYY-MM-DD")
    frame["date"] = parsed.dt.strftime("%Y-%m-%d").where(~undated, np.nan)


#: Loads per unit of wheel footprint (W / (b·r), Pa) outside which a unit mistake is likely.
#: Rover, test-rig and tractor wheels on soft soil carry about 1–100 kPa (CMU's rig 7 kPa,
#: a Mars rover wheel ~6 kPa, a loaded tractor tyre ~50–80 kPa); grams-force reads ~100×
#: too much, kN ~1000× too little.
FOOTPRINT_PA = (50.0, 4.0e5)


def warn_unit_mistakes(frame: pd.DataFrame, name: str) -> list[str]:
    """Warn (a :class:`~soilstats.errors.SoilstatsWarning` naming the column and the likely
    unit) where the slip angles look like radians; returns the warnings' texts.  Loads are
    checked against the wheels' geometry by :func:`warn_load_units`."""
    out = []
    for column in ("beta_deg", "beta_cmd_deg"):
        if column not in frame:
            continue
        beta = np.abs(frame[column].to_numpy(float))
        beta = beta[np.isfinite(beta) & (beta > 0)]
        # radians: every angle within π/2, the largest a real slip angle (≥ 0.25 rad, 14°;
        # not the noise of β = 0 runs, CMU's reach 0.18°) and some not a whole degree
        largest = beta.max() if beta.size else 0.0
        if 0.25 <= largest <= 0.5 * np.pi + 1e-3 and np.any(beta % 1 > 1e-6):
            out.append(
                f"{name}: column {column!r} holds slip angles of at most {beta.max():.4g} with "
                "fractions of a degree: likely radians; give them in degrees "
                f"(×{180 / np.pi:.4g})"
            )
    for text in out:
        warnings.warn(text, UnitWarning, stacklevel=3)
    return out


def warn_load_units(frame: pd.DataFrame, wheels: Mapping[str, Wheel], name: str) -> list[str]:
    """Warn where a wheel type's loads per footprint W/(b·r) lie outside :data:`FOOTPRINT_PA`
    (likely grams-force, or kN); returns the warnings' texts."""
    out = []
    for wheel_type, rows in frame.groupby("wheel", sort=True):
        wheel = wheels.get(str(wheel_type))
        if wheel is None:
            continue
        load = float(np.median(rows["W_N"].to_numpy(float)))
        pressure = load / (wheel.width_m * wheel.radius_m)
        if pressure > FOOTPRINT_PA[1]:
            unit = "grams-force (gf; 1 gf = 0.00981 N)"
        elif pressure < FOOTPRINT_PA[0]:
            unit = "kN (1 kN = 1000 N)"
        else:
            continue
        out.append(
            f"{name}: column 'W_N' of wheel {wheel_type!r}: a median load of {load:g} on a "
            f"{1e3 * wheel.width_m:g} mm x {1e3 * wheel.radius_m:g} mm wheel is "
            f"{pressure:.3g} Pa per footprint (b·r), outside {FOOTPRINT_PA[0]:g}–"
            f"{FOOTPRINT_PA[1]:.0e} Pa: likely {unit}; give W_N in N"
        )
    for text in out:
        warnings.warn(text, UnitWarning, stacklevel=3)
    return out


def slip_levels(slip: np.ndarray, gap: float = SLIP_GAP) -> np.ndarray:
    """Each run's slip condition: slips sorted, a new level after a gap > ``gap``; the label
    is the level's mean slip rounded to 2 decimals (−1 stays −1: a locked wheel)."""
    order = np.argsort(slip, kind="stable")
    s = slip[order]
    level = np.concatenate([[0], np.cumsum(np.diff(s) > gap)])
    means = np.bincount(level, weights=s) / np.bincount(level)
    out = np.empty(slip.size)
    out[order] = np.round(means[level], 2) + 0.0  # no −0
    return out


# -- geometry ----------------------------------------------------------------------------------
def read_wheels(path: str | os.PathLike[str]) -> dict[str, dict]:
    """The wheel geometry of a TOML file: wheel type → {radius_m, width_m, ...} (module doc)."""
    path = Path(path)
    try:
        table = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as err:
        raise WheelDataError(f"not valid TOML: {err}", file=path.name) from None
    out = {}
    for name, entry in table.items():
        if name == "caveats":
            continue
        if not isinstance(entry, dict):
            raise WheelDataError(
                f"{name!r} must be a table [{name}] with radius_m and width_m", file=path.name
            )
        refuse_unknown_keys(
            entry,
            _WHEEL_KEYS,
            lambda unknown, name=name: WheelDataError(
                f"[{name}] has unknown keys {sorted(unknown)}; allowed: {list(_WHEEL_KEYS)}",
                file=path.name,
                column=min(unknown),
            ),
        )
        out[str(name)] = dict(entry)
    return out


def read_caveats(path: str | os.PathLike[str]) -> list[str]:
    """The data's caveats a ``wheels.toml`` states (``caveats = ["...", ...]``), in order."""
    table = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    caveats = table.get("caveats", [])
    if not isinstance(caveats, list) or not all(isinstance(c, str) for c in caveats):
        raise WheelDataError("caveats must be a list of sentences", file=Path(path).name)
    return caveats


#: A wheel dimension above this [m] is likely given in mm.
LARGEST_WHEEL_M = 3.0


def _warn_length_units(name: str, entry: Mapping, source: str) -> None:
    for key in ("radius_m", "width_m", "shear_radius_m"):
        value = entry.get(key)
        if isinstance(value, int | float) and not isinstance(value, bool):
            if value > LARGEST_WHEEL_M:
                warnings.warn(
                    f"{source}: {key} = {value:g} of wheel type {name!r} is over "
                    f"{LARGEST_WHEEL_M:g} m: likely mm; give it in metres (/1000)",
                    UnitWarning,
                    stacklevel=3,
                )


def wheel_geometry(
    types: Iterable[str],
    tables: Mapping[str, Mapping] | None = None,
    overrides: Mapping[str, Mapping[str, float]] | None = None,
    *,
    source: str = "the wheel geometry",
) -> dict[str, Wheel]:
    """A :class:`Wheel` for every wheel type in ``types``.

    ``tables`` (from :func:`read_wheels`) gives each type's geometry; ``overrides`` maps a
    type (or ``"*"``: every type) to keys of the table that replace it (the CLI's
    ``--wheel-radius`` …).  A type without a radius and a width is an error that says how to
    give them.
    """
    tables = {k: dict(v) for k, v in (tables or {}).items()}
    overrides = overrides or {}
    out = {}
    for name in sorted(set(types)):
        entry = dict(tables.get(name, {}))
        entry.update(overrides.get("*", {}))
        entry.update(overrides.get(name, {}))
        missing = [k for k in ("radius_m", "width_m") if k not in entry]
        if missing:
            raise WheelDataError(
                f"wheel type {name!r} has no {' and no '.join(missing)} in {source}: give "
                f"--wheel-radius {name}=R --wheel-width {name}=B (m), or a [{name}] table in "
                "--wheels FILE.toml (docs/wheel.md)",
                column="wheel",
            )
        _warn_length_units(name, entry, source)
        try:
            out[name] = Wheel(
                radius_m=float(entry["radius_m"]),
                width_m=float(entry["width_m"]),
                shear_radius_m=None
                if entry.get("shear_radius_m") is None
                else float(entry["shear_radius_m"]),
                grouser_area_ratio=float(entry.get("grouser_area_ratio", 1.0)),
                name=name,
            )
        except (TypeError, ValueError) as err:
            raise WheelDataError(f"wheel type {name!r}: {err}", column="wheel") from None
    return out
