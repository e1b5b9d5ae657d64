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
import weakref
from collections.abc import Mapping
from dataclasses import dataclass
from decimal import Decimal, InvalidOperation, localcontext
from fractions import Fraction

import numpy as np
import pandas as pd

from ..errors import CampaignError, SoilstatsWarning
from .schema import MIN_SAMPLES

__all__ = [
    "UNITS",
    "UnitsFinding",
    "UnitsWarning",
    "check_plausible_units",
    "implausible_units",
    "to_si",
]


class UnitsWarning(SoilstatsWarning):
    """A value's size suggests a unit other than the format's SI unit (see the message)."""


#: Length units a campaign may declare, with their factor to metres (the importer reads it
#: to tell a length column from the others).
#: Length units a campaign may declare, with their factor to metres (the importer reads it
#: to tell a length column from the others).
LENGTH = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "in": 0.0254}
_FORCE = {"N": 1.0, "kN": 1e3, "lbf": 4.4482216152605}
_TORQUE = {"N*m": 1.0, "N*mm": 1e-3, "kN*m": 1e3}
_ANGLE = {"rad": 1.0, "deg": math.pi / 180.0}
_VELOCITY = {"m/s": 1.0, "mm/s": 1e-3, "mm/min": 1e-3 / 60.0, "cm/s": 1e-2}
_ROTATION = {"rpm": 1.0, "deg/s": 60.0 / 360.0, "rad/s": 60.0 / (2.0 * math.pi)}

#: The factors that are rational, exactly: a conversion by one of them is done in decimal
#: arithmetic, so a round number in the lab's unit stays round in SI (to_si).
_EXACT: dict[str, Fraction] = {
    "m": Fraction(1),
    "cm": Fraction(1, 100),
    "mm": Fraction(1, 1000),
    "in": Fraction(254, 10_000),
    "N": Fraction(1),
    "kN": Fraction(1000),
    "lbf": Fraction("4.4482216152605"),
    "N*m": Fraction(1),
    "N*mm": Fraction(1, 1000),
    "kN*m": Fraction(1000),
    "m/s": Fraction(1),
    "mm/s": Fraction(1, 1000),
    "mm/min": Fraction(1, 60_000),
    "cm/s": Fraction(1, 100),
    "rpm": Fraction(1),
    "deg/s": Fraction(1, 6),
}

#: Format column → {unit: factor to the column's SI unit}.
UNITS: dict[str, dict[str, float]] = {
    **{
        col: LENGTH
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
    exact = _EXACT.get(_canonical(unit))
    if exact is None:  # an irrational factor (degrees, rad/s): one rounding is the best
        out[parsed] = numbers[parsed].to_numpy(dtype=float) * factor
        return out
    # In decimal arithmetic, then rounded once: 12.3 mm is 0.0123 m, where float's 12.3 *
    # 0.001 writes 0.012300000000000002 into the saved campaign.
    with localcontext() as context:
        context.prec = 40
        out[parsed] = [_scaled(cell, exact) for cell in values[parsed].astype(str)]
    return out


def _scaled(cell: str, factor: Fraction) -> float:
    """The number written in ``cell`` times the exact ``factor``, rounded to float once."""
    try:
        value = Decimal(cell.strip())
    except InvalidOperation:  # a form pandas reads and Decimal does not
        return float(cell) * factor.numerator / factor.denominator
    if not value.is_finite():
        return float(value)
    return float(value * factor.numerator / factor.denominator)


# --- plausibility --------------------------------------------------------------------------
#: A plate sinks centimetres, never a metre: a test whose z_m spans more is in mm or cm.
MAX_SINKAGE_RANGE_M = 1.0
#: Plates, rings and grousers of a Bevameter are centimetres to decimetres.
MAX_TOOL_SIZE_M = 1.0
#: A pressure–sinkage test loads the soil to kPa or more; a peak below this is kN read as N.
MIN_PEAK_PRESSURE_PA = 200.0
#: ... and to MPa at most (a plate on dense soil; rock crushes near 100 MPa): a peak above
#: this is not a soil's answer but a force in mN read as N, or the wrong column.
MAX_PEAK_PRESSURE_PA = 1e8
#: Soil shear strength is kPa to hundreds of kPa; a peak above this is N·mm read as N·m.
MAX_PEAK_SHEAR_PA = 5e6
#: ... and a peak below this is kN·m read as N·m.
MIN_PEAK_SHEAR_PA = 20.0
#: A shear-ring test turns less than two revolutions; more is degrees read as radians.
MAX_ROTATION_RAD = 4.0 * math.pi
#: Tests of one soil differ in peak pressure by a few times, not a hundred: a test with less
#: than 1/PRESSURE_JUMP of its soil's median peak (of at least MIN_PEERS tests) is kN among
#: N (1000×) even where the absolute limit above cannot tell.
PRESSURE_JUMP = 100.0
#: ... and in sinkage span by up to ~10× (GRC-1's small plates punch through to 10× the
#: large plates' depth): a span over SPAN_JUMP times the median is cm (100×) or mm among m.
SPAN_JUMP = 30.0
MIN_PEERS = 3

_GEOMETRY = ("radius_m", "width_m", "length_m", "r_inner_m", "r_outer_m", "grouser_height_m")


@dataclass(frozen=True)
class UnitsFinding:
    """Tests whose values in one column only make sense in another unit."""

    file: str
    column: str
    test_ids: tuple[str, ...]
    values: tuple[float, ...]  # the offending size, one per test
    what: str  # the reason and the fix
    fatal: bool  # a length that cannot be right (stops a load), or a warning
    kind: str = "unit"  # "unit" (a unit slip) or "sign" (a reversed channel)


#: The findings of the last few campaigns judged, by the identity of their tables: loading
#: judges a campaign's units and screening reports them, on the same (read-only by contract)
#: tables, so the rule runs once.
_JUDGED: dict[int, tuple] = {}


def implausible_units(
    tests: pd.DataFrame, sinkage: pd.DataFrame, shear: pd.DataFrame
) -> list[UnitsFinding]:
    """Every column and test whose values' size suggests a unit other than SI (thresholds
    above). The one home of the rule: loading stops or warns on it
    (:func:`check_plausible_units`), and screening reports it as ``units``
    (:mod:`soilstats.quality`) — from the same run where the tables are the same objects."""
    tables = (tests, sinkage, shear)
    seen = _JUDGED.get(id(tests))
    if seen is not None and all(r() is t for r, t in zip(seen[0], tables, strict=True)):
        return list(seen[1])
    found = _implausible_units(tests, sinkage, shear)
    if len(_JUDGED) >= 8:
        _JUDGED.pop(next(iter(_JUDGED)))
    refs = tuple(weakref.ref(t) for t in tables)
    _JUDGED[id(tests)] = (refs, tuple(found))
    return found


class _Findings(list):
    """The findings of one judgement; :meth:`add` records the tests where ``mask`` holds."""

    def add(
        self,
        mask: pd.Series,
        values: pd.Series,
        file: str,
        column: str,
        what: str,
        fatal: bool = False,
        kind: str = "unit",
    ) -> None:
        hits = list(mask[mask].index)
        if hits:
            self.append(
                UnitsFinding(
                    file,
                    column,
                    tuple(map(str, hits)),
                    tuple(float(values[t]) for t in hits),
                    what,
                    fatal,
                    kind,
                )
            )


def _implausible_units(
    tests: pd.DataFrame, sinkage: pd.DataFrame, shear: pd.DataFrame
) -> list[UnitsFinding]:
    found = _Findings()
    _tool_sizes(found, tests)
    if len(sinkage):
        _sinkage_units(found, tests, sinkage)
    if len(shear):
        _shear_units(found, shear)
    return list(found)


def _tool_sizes(found: _Findings, tests: pd.DataFrame) -> None:
    for column in _GEOMETRY:
        if column not in tests.columns:
            continue
        values = pd.Series(
            tests[column].to_numpy(dtype=float, na_value=np.nan), index=tests["test_id"]
        )
        found.add(
            values > MAX_TOOL_SIZE_M,
            values,
            "tests.csv",
            column,
            f"a size larger than any Bevameter tool ({MAX_TOOL_SIZE_M:g} m): the column looks "
            "like millimetres or centimetres — divide by 1000 (or 100), or import with "
            "unit = 'mm' (docs/importing.md)",
            fatal=True,
        )


def _sinkage_units(found: _Findings, tests: pd.DataFrame, sinkage: pd.DataFrame) -> None:
    by_test = sinkage.groupby("test_id", sort=False)
    z_range = by_test["z_m"].max() - by_test["z_m"].min()
    found.add(
        z_range > MAX_SINKAGE_RANGE_M,
        z_range,
        "sinkage.csv",
        "z_m",
        f"a sinkage span above {MAX_SINKAGE_RANGE_M:g} m; a plate sinks centimetres, so "
        "z_m looks like millimetres or centimetres — divide by 1000 (or 100), or import "
        "with unit = 'mm' (or 'cm') (docs/importing.md)",
        fatal=True,
    )
    travel = by_test["z_m"].last() - by_test["z_m"].first()
    found.add(
        travel < -0.5 * z_range,
        travel,
        "sinkage.csv",
        "z_m",
        "a sinkage that falls through the record (the plate rises?): the displacement "
        "sign looks reversed (multiply z_m by -1)",
        kind="sign",
    )
    soil = tests.set_index("test_id")["soil"] if "soil" in tests.columns else None
    above = _times_soil_median(z_range, soil)
    found.add(
        (z_range <= MAX_SINKAGE_RANGE_M) & (above > SPAN_JUMP),
        z_range,
        "sinkage.csv",
        "z_m",
        f"a sinkage span more than {SPAN_JUMP:g} times the median of its soil's tests: "
        "z_m looks like centimetres or millimetres among metres — divide by 100 (or "
        "1000), or import with unit = 'cm' (or 'mm')",
    )
    # Judge the load only where the plate is in contact, on records long enough to fit.
    loaded = sinkage[sinkage["z_m"] > 0].groupby("test_id", sort=False)["pressure_Pa"]
    peak = loaded.max()[loaded.size() >= MIN_SAMPLES]
    found.add(
        peak <= 0,
        peak,
        "sinkage.csv",
        "force_N",
        "no positive force where the plate is in contact: the load cell's sign looks "
        "reversed (multiply force_N by -1)",
        kind="sign",
    )
    found.add(
        (peak > 0) & (peak < MIN_PEAK_PRESSURE_PA),
        peak,
        "sinkage.csv",
        "force_N",
        f"peak pressure below {MIN_PEAK_PRESSURE_PA:g} Pa: force_N looks like kilonewtons "
        "(multiply by 1000, or import with unit = 'kN')",
    )
    found.add(
        peak > MAX_PEAK_PRESSURE_PA,
        peak,
        "sinkage.csv",
        "force_N",
        f"peak pressure above {MAX_PEAK_PRESSURE_PA:g} Pa, beyond any soil: force_N looks like "
        "millinewtons or another quantity (check the column; divide mN by 1000)",
    )
    below = 1.0 / _times_soil_median(peak, soil)
    # Only a record that rises as a loaded curve does (not a flat or dead channel,
    # which screening names on its own) reads as a unit slip.
    rises = (peak - loaded.min()[peak.index]) > 0.5 * peak
    found.add(
        (peak >= MIN_PEAK_PRESSURE_PA) & (below > PRESSURE_JUMP) & rises,
        peak,
        "sinkage.csv",
        "force_N",
        f"a peak pressure less than 1/{PRESSURE_JUMP:g} of the median of its soil's tests: "
        "force_N looks like kilonewtons among newtons (multiply by 1000, or import with "
        "unit = 'kN')",
    )


def _shear_units(found: _Findings, shear: pd.DataFrame) -> None:
    by_test = shear.groupby("test_id", sort=False)
    tau_peak = by_test["tau_Pa"].max()
    found.add(
        tau_peak > MAX_PEAK_SHEAR_PA,
        tau_peak,
        "shear.csv",
        "torque_Nm",
        f"peak shear stress above {MAX_PEAK_SHEAR_PA:g} Pa: torque_Nm looks like N·mm "
        "(divide by 1000, or import with unit = 'N*mm')",
    )
    found.add(
        tau_peak < MIN_PEAK_SHEAR_PA,
        tau_peak,
        "shear.csv",
        "torque_Nm",
        f"peak shear stress below {MIN_PEAK_SHEAR_PA:g} Pa: torque_Nm looks like kN·m "
        "(multiply by 1000, or import with unit = 'kN*m')",
    )
    turned = by_test["angle_rad"].max() - by_test["angle_rad"].min()
    found.add(
        turned > MAX_ROTATION_RAD,
        turned,
        "shear.csv",
        "angle_rad",
        "the ring turns more than two revolutions: angle_rad looks like degrees "
        "(multiply by pi/180, or import with unit = 'deg')",
    )


def _times_soil_median(values: pd.Series, soil: pd.Series | None) -> pd.Series:
    """Each test's value over the median of the tests of its soil (NaN where the soil has
    fewer than MIN_PEERS tests with a value, or its median is not positive)."""
    if soil is None or values.empty:
        return pd.Series(np.nan, index=values.index)
    of = soil.reindex(values.index).astype(str)
    median = values.groupby(of).transform("median")
    peers = values.groupby(of).transform("size")
    ratio = values / median.where(median > 0)
    return ratio.where(peers >= MIN_PEERS)


def check_plausible_units(
    tests: pd.DataFrame,
    sinkage: pd.DataFrame,
    shear: pd.DataFrame,
    file_names: Mapping[str, str] | None = None,
) -> None:
    """Stop (lengths) or warn (loads, angles) where a value only makes sense in another unit.

    ``tests``, ``sinkage``, ``shear`` are the validated tables with derived columns;
    ``file_names`` maps each to the file it was read from (``sinkage.parquet``, say), for
    the messages (default ``<name>.csv``).
    """
    names = dict(file_names or {})
    for finding in implausible_units(tests, sinkage, shear):
        file = names.get(finding.file.removesuffix(".csv")) or finding.file
        if finding.fatal:
            raise CampaignError(
                f"{finding.values[0]:g} m: {finding.what} ({len(finding.test_ids)} tests)",
                file=file,
                column=finding.column,
                test_id=finding.test_ids[0],
            )
        shown = ", ".join(
            f"{t!r} ({v:.4g})" for t, v in zip(finding.test_ids[:5], finding.values, strict=False)
        )
        more = f" and {len(finding.test_ids) - 5} more" if len(finding.test_ids) > 5 else ""
        warnings.warn(
            f"file {file!r}, column {finding.column!r}: {len(finding.test_ids)} "
            f"test(s) with {finding.what}: {shown}{more}. Fitting data in the wrong unit gives "
            "wrong parameters; fix the data before trusting any result.",
            UnitsWarning,
            stacklevel=3,
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
