"""What ``soilstats wheel`` is given, read in the library (moved out of cli/, issue #45:
commands only parse, call and print): stated priors and stress angles as text, the slips of
a prediction, the runs file, the wheel geometry nobody gave, the plates' pooling warnings.

Each reader refuses with an :class:`~soilstats.errors.InputError` naming the option and
the text it was given.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .._ascii import ascii_float, non_ascii_note
from ..bayes.pooling import pooling_warnings
from ..campaign.io import resolve
from ..errors import InputError
from .geometry import Wheel
from .runs import read_wheels, wheel_geometry
from .soil import choose_law, soil_tests
from .stress import StressAngles

if TYPE_CHECKING:
    import pandas as pd

    from ..campaign.campaign import Campaign

__all__ = [
    "file_sha256",
    "geometry_defaults",
    "parse_angles",
    "parse_geometry",
    "parse_prior_item",
    "parse_slips",
    "plate_pooling_warnings",
    "runs_file",
    "wheel_tables",
]


def parse_geometry(
    given: Mapping[str, Sequence[str]], keys: Mapping[str, str]
) -> dict[str, dict[str, float]]:
    """The --wheel-radius … items ({option dest: ["[TYPE=]VALUE", …]}, SI units) as
    {type or "*": {key: value}}, ``keys`` mapping each option to the wheels table's key; a
    value that is not a number names its option."""
    out: dict[str, dict[str, float]] = {}
    for option, items in given.items():
        key = keys[option]
        for item in items:
            wheel, sep, text = item.rpartition("=")
            try:
                value = float(text)
            except ValueError:
                raise InputError(
                    f"--{option.replace('_', '-')} takes [TYPE=]VALUE in SI units, got {item!r}"
                ) from None
            out.setdefault(wheel.strip() if sep else "*", {})[key] = value
    return out


def parse_prior_item(item: str) -> tuple[str, tuple]:
    """``phi=normal:29:4`` → ``("phi", ("normal", 29.0, 4.0))``; InputError naming the item."""
    name, sep, spec = item.partition("=")
    kind, *numbers = spec.split(":")
    try:
        values = tuple(ascii_float(x) for x in numbers)
    except ValueError:
        values = ()
    if not sep or not name.strip() or not kind or not values:
        raise InputError(
            f"--prior takes NAME=KIND:ARGS (e.g. phi=normal:29:4, c=uniform:0:1500, "
            f"K=lognormal:0.01:0.8), got {item!r}{non_ascii_note(spec)}"
        )
    return name.strip(), (kind.strip(), *values)


def parse_angles(text: str | None) -> StressAngles | None:
    """``A0,A1,B0,B1`` → the stress angles (None: the model's default)."""
    if text is None:
        return None
    try:
        values = [float(x) for x in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 4:
        raise InputError(f"--angles takes four numbers A0,A1,B0,B1, got {text!r}")
    return StressAngles(*values)


def parse_slips(text: str) -> np.ndarray:
    """``A:B:STEP`` → the slips A, A + STEP, … ≤ B (each in [−1, 1], at most 200)."""
    try:
        a, b, step = (float(x) for x in text.split(":"))
    except ValueError:
        raise InputError(f"--slips takes A:B:STEP, e.g. -0.5:0.9:0.1, got {text!r}") from None
    if (
        not all(map(math.isfinite, (a, b, step)))
        or step <= 0
        or b < a
        or not (-1 <= a <= 1 and -1 <= b <= 1)
    ):
        raise InputError(f"--slips needs -1 <= A <= B <= 1 and STEP > 0, got {text!r}")
    count = math.floor((b - a) / step + 1e-9) + 1
    if count > 200:
        raise InputError(f"--slips gives {count} slips; at most 200")
    return np.round(a + step * np.arange(count), 10)


def runs_file(runs: str, campaign: str) -> Path:
    """The runs file ``runs`` as given, else inside the folder of ``campaign`` (a folder or
    a bundled name); a FileNotFoundError names both places."""
    given = Path(runs)
    if given.is_file():
        return given
    folder, _ = resolve(campaign)
    inside = folder / runs
    if inside.is_file():
        return inside
    raise FileNotFoundError(
        2, f"no runs file here nor in the campaign folder ({inside})", str(given)
    )


def geometry_defaults(
    wheels: Mapping[str, Wheel],
    tables: Mapping[str, Mapping[str, float]],
    overrides: Mapping[str, Mapping[str, float]],
) -> dict[str, str]:
    """Every wheel geometry the user gave neither in the wheels file (``tables``) nor by
    option (``overrides``, ``"*"``: every type), with the value assumed: a missing shearing
    radius makes a wheel smooth, and a grousered wheel's slip finding depends on it."""
    out: dict[str, str] = {}
    for name, wheel in sorted(wheels.items()):
        given = {**tables.get(name, {}), **overrides.get("*", {}), **overrides.get(name, {})}
        if "shear_radius_m" not in given:
            out[f"{name}: shear_radius_m"] = (
                f"{wheel.radius_m:g} (= radius_m: no grousers assumed; give --shear-radius "
                f"{name}=RS for a grousered wheel)"
            )
        if "grouser_area_ratio" not in given:
            out[f"{name}: grouser_area_ratio"] = "1"
    return out


def plate_pooling_warnings(campaign: Campaign, soil: str | None, law: str | None) -> list[str]:
    """The posterior's warning when the plates pool conditions (preparations, velocities,
    shapes …): the draws then describe their mixture, not one sand state."""
    name, tests = soil_tests(campaign, soil)
    return pooling_warnings(campaign, name, [choose_law(tests, law)])


def file_sha256(path: Path) -> str:
    """The SHA-256 of a file's bytes (hex), as the record names the runs file."""
    return hashlib.sha256(path.read_bytes()).hexdigest()


def wheel_tables(
    wheels_file: str | None, runs_path: Path, runs: pd.DataFrame, overrides: dict
) -> tuple[Path, dict, dict[str, Wheel]]:
    """The wheels file (``wheels_file``, or wheels.toml beside the runs file), its tables, and
    each run wheel type's geometry with the --wheel-* ``overrides`` applied."""
    toml = Path(wheels_file) if wheels_file else runs_path.with_name("wheels.toml")
    tables = read_wheels(toml) if (wheels_file or toml.is_file()) else {}
    source = str(toml) if tables else "--wheel-*"
    return toml, tables, wheel_geometry(runs["wheel"].unique(), tables, overrides, source=source)
