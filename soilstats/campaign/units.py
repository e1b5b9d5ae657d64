"""Units: bringing a lab's numbers into the format's SI columns, and catching wrong units.

The campaign format is SI with the unit in each column's name (``z_m``, ``force_N``, ...).
Labs export millimetres, kilonewtons, newton-millimetres and degrees. Two things live here:

* :func:`to_si` and :data:`UNITS`: the conversion factors, by format column. They are used by
  ``Campaign.from_frames(..., units=...)`` and by ``soilstats import`` (docs/importing.md).
* :func:`check_plausible_units`: run on every campaign loaded, so that a number in the wrong
  unit is never fitted quietly. Lengths that only make sense in mm or cm stop the load with a
  :class:`~soilstats.errors.CampaignError` naming the file, column and test, and the fix;
  forces, torques and angles whose size suggests kN, N·mm or degrees give a loud
  :class:`UnitsWarning` (a real, if odd, test could look like that).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping

import numpy as np
import pandas as pd

from ..errors import CampaignError, SoilstatsWarning

#: Samples a record needs before its size is judged (the fitting minimum, pooling.MIN_SAMPLES).
MIN_SAMPLES = 3

__all__ = ["UNITS", "UnitsWarning", "check_plausible_units", "to_si"]


class UnitsWarning(SoilstatsWarning):
    """A value's size suggests a unit other than the format's SI unit (see the message)."""


_LENGTH = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "in": 0.0254}
_FORCE = {"N": 1.0, "kN": 1e3, "lbf": 4.4482216152605}
_TORQUE = {"N*m": 1.0, "N*mm": 1e-3, "kN*m": 1e3}
_ANGLE = {"rad": 1.0, "deg": math.pi / 180.0}
_VELOCITY = {"m/s": 1.0, "mm/s": 1e-3, "mm/min": 1e-3 / 60.0, "cm/s": 1e-2}
_ROTATION = {"rpm": 1.0, "deg/s": 60.0 / 360.0, "rad/s": 60.0 / (2.0 * math.pi)}

#: Format column → {unit: factor to the column's SI unit}.
UNITS: dict[str, dict[str, float]] = {
    **{
        col: _LENGTH
        for col in (
            "z_m",
            "radius_m",
            "width_m",
            "length_m",
            "r_inner_m",
            "r_outer_m",
            "grouser_height_m",
        )
    },
    "force_N": _FORCE,
    "normal_force_N": _FORCE,
    "torque_Nm": _TORQUE,
    "angle_rad": _ANGLE,
    "velocity_m_s": _VELOCITY,
    "omega_rpm": _ROTATION,
}


def _canonical(unit: str) -> str:
    """Spellings of one unit made equal: 'N·mm', 'N mm', 'Nmm', 'N.mm' → 'N*mm'."""
    text = unit.strip().replace("·", "*").replace(" ", "*").replace(".", "*")
    for compact, spaced in (("kNm", "kN*m"), ("Nmm", "N*mm"), ("Nm", "N*m")):
        if text == compact:
            return spaced
    aliases = {"degree": "deg", "degrees": "deg", "°": "deg", "radian": "rad", "radians": "rad"}
    return aliases.get(text, text)


def to_si(values: pd.Series, column: str, unit: str, *, file: str = "") -> pd.Series:
    """``values`` of format ``column`` given in ``unit``, converted to the column's SI unit.

    Cells that do not parse as numbers are left as they are, so that validation reports them
    with their row (nothing is turned into NaN here).

    Raises
    ------
    CampaignError
        If the column takes no unit or the unit is not one of its units.
    """
    table = UNITS.get(column)
    if table is None:
        raise CampaignError(
            f"no unit conversion for this column; columns with units: {sorted(UNITS)}",
            file=file or None,
            column=column,
        )
    factor = table.get(_canonical(unit))
    if factor is None:
        raise CampaignError(
            f"unknown unit {unit!r}; {column} takes one of {sorted(table)}",
            file=file or None,
            column=column,
        )
    if factor == 1.0:
        return values
    numbers = pd.to_numeric(values, errors="coerce")
    out = values.astype(object).copy()
    parsed = numbers.notna()
    out[parsed] = numbers[parsed].to_numpy(dtype=float) * factor
    return out


# --- plausibility --------------------------------------------------------------------------
#: A plate sinks centimetres, never a metre: a test whose z_m spans more is in mm or cm.
MAX_SINKAGE_RANGE_M = 1.0
#: Plates, rings and grousers of a Bevameter are centimetres to decimetres.
MAX_TOOL_SIZE_M = 1.0
#: A pressure–sinkage test loads the soil to kPa or more; a peak below this is kN read as N.
MIN_PEAK_PRESSURE_PA = 200.0
#: Soil shear strength is kPa to hundreds of kPa; a peak above this is N·mm read as N·m.
MAX_PEAK_SHEAR_PA = 5e6
#: ... and a peak below this is kN·m read as N·m.
MIN_PEAK_SHEAR_PA = 20.0
#: A shear-ring test turns less than two revolutions; more is degrees read as radians.
MAX_ROTATION_RAD = 4.0 * math.pi

_GEOMETRY = ("radius_m", "width_m", "length_m", "r_inner_m", "r_outer_m", "grouser_height_m")


def check_plausible_units(tests: pd.DataFrame, sinkage: pd.DataFrame, shear: pd.DataFrame) -> None:
    """Stop or warn where a value only makes sense in another unit (thresholds above).

    ``tests``, ``sinkage``, ``shear`` are the validated tables with derived columns.
    """
    for column in _GEOMETRY:
        if column not in tests.columns:
            continue
        values = tests[column].to_numpy(dtype=float, na_value=np.nan)
        bad = np.flatnonzero(values > MAX_TOOL_SIZE_M)
        if bad.size:
            i = int(bad[0])
            raise CampaignError(
                f"{values[i]:g} m is larger than any Bevameter tool ({MAX_TOOL_SIZE_M:g} m): "
                f"the column looks like millimetres or centimetres ({bad.size} tests) — divide "
                "by 1000 (or 100), or import with unit = 'mm' (docs/importing.md)",
                file="tests.csv",
                column=column,
                test_id=str(tests["test_id"].iloc[i]),
            )
    if len(sinkage):
        by_test = sinkage.groupby("test_id", sort=False)
        z_range = by_test["z_m"].max() - by_test["z_m"].min()
        wide = z_range[z_range > MAX_SINKAGE_RANGE_M]
        if len(wide):
            raise CampaignError(
                f"the sinkage spans {wide.iloc[0]:g} m in one test; a plate sinks centimetres, "
                f"so z_m looks like millimetres ({len(wide)} tests) — divide by 1000, or import "
                "with unit = 'mm' (docs/importing.md)",
                file="sinkage.csv",
                column="z_m",
                test_id=str(wide.index[0]),
            )
        # Judge the load only where the plate is in contact, on records long enough to fit.
        loaded = sinkage[sinkage["z_m"] > 0].groupby("test_id", sort=False)["pressure_Pa"]
        peak = loaded.max()[loaded.size() >= MIN_SAMPLES]
        _warn_where(
            peak < MIN_PEAK_PRESSURE_PA,
            peak,
            "sinkage.csv",
            "force_N",
            f"peak pressure below {MIN_PEAK_PRESSURE_PA:g} Pa: force_N looks like kilonewtons "
            "(multiply by 1000, or import with unit = 'kN')",
        )
    if len(shear):
        by_test = shear.groupby("test_id", sort=False)
        tau_peak = by_test["tau_Pa"].max()
        _warn_where(
            tau_peak > MAX_PEAK_SHEAR_PA,
            tau_peak,
            "shear.csv",
            "torque_Nm",
            f"peak shear stress above {MAX_PEAK_SHEAR_PA:g} Pa: torque_Nm looks like N·mm "
            "(divide by 1000, or import with unit = 'N*mm')",
        )
        _warn_where(
            tau_peak < MIN_PEAK_SHEAR_PA,
            tau_peak,
            "shear.csv",
            "torque_Nm",
            f"peak shear stress below {MIN_PEAK_SHEAR_PA:g} Pa: torque_Nm looks like kN·m "
            "(multiply by 1000, or import with unit = 'kN*m')",
        )
        turned = by_test["angle_rad"].max() - by_test["angle_rad"].min()
        _warn_where(
            turned > MAX_ROTATION_RAD,
            turned,
            "shear.csv",
            "angle_rad",
            "the ring turns more than two revolutions: angle_rad looks like degrees "
            "(multiply by pi/180, or import with unit = 'deg')",
        )


def _warn_where(mask: pd.Series, values: pd.Series, file: str, column: str, what: str) -> None:
    hits = mask[mask].index
    if not len(hits):
        return
    shown = ", ".join(f"{t!r} ({values[t]:.4g})" for t in list(hits)[:5])
    more = f" and {len(hits) - 5} more" if len(hits) > 5 else ""
    warnings.warn(
        f"file {file!r}, column {column!r}: {len(hits)} test(s) with {what}: {shown}{more}. "
        "Fitting data in the wrong unit gives wrong parameters; fix the data before trusting "
        "any result.",
        UnitsWarning,
        stacklevel=4,
    )


def convert_columns(
    frame: pd.DataFrame | None, units: Mapping[str, str], file: str
) -> pd.DataFrame | None:
    """A copy of ``frame`` with every column named in ``units`` converted to SI."""
    if frame is None:
        return None
    present = {c: u for c, u in units.items() if c in frame.columns}
    if not present:
        return frame
    out = frame.copy()
    for column, unit in present.items():
        out[column] = to_si(out[column], column, unit, file=file)
    return out
