"""Column specifications of the campaign format (v1), as data, in one place.

Every other module of :mod:`soilstats.campaign` reads the format from here: which columns
each file has, which are required (always, or only for some tests), their type and unit, and
the canonical column order (the order of the tables below, which is the order of the format's
documentation). The user-facing description is ``docs/campaign-format.md``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from .._version import FORMAT_VERSION  # the format these specifications describe
from ..kinds import TEST_KINDS

__all__ = [
    "DERIVED_COLUMNS",
    "FILES",
    "FORMAT_VERSION",
    "KINDS",
    "MAX_CELL_CHARS",
    "MIN_SAMPLES",
    "MISSING_TOKENS",
    "SHAPES",
    "SPECS",
    "ColumnSpec",
    "canonical_order",
    "spec",
]

#: Values of ``kind``; the samples of a test of kind K are in the sample file K (.csv/.parquet).
KINDS: tuple[str, ...] = TEST_KINDS

#: Fewest samples in contact a test's record needs to enter a fit (three: a power law has two
#: parameters, and one residual degree of freedom is the least that says anything). Pooling
#: (:mod:`soilstats.identification.pooling`) refuses a test with fewer; the unit check judges
#: a record's load only from this many on.
MIN_SAMPLES = 3

#: Values of ``shape`` (plate shape of a sinkage test).
SHAPES: tuple[str, ...] = ("circle", "rectangle")

#: The three files of a campaign, in the order a reader scans them (stems; ``.csv`` or
#: ``.parquet`` is appended).
FILES: tuple[str, ...] = ("tests", "sinkage", "shear")

#: Cell texts that mean "not recorded" in a *numeric* optional or covariate column, besides
#: the empty cell (compared case-insensitively after stripping blanks). Text columns keep
#: every non-empty value literally, so a test may be called ``NA``.
MISSING_TOKENS: frozenset[str] = frozenset({"na", "n/a", "nan", "null"})

#: The longest cell (and column name) a campaign file may hold, in characters. No name,
#: number or note of a Bevameter test needs more; a longer cell is a broken file (an
#: unclosed quote that swallowed the lines after it, a binary file read as text), and the
#: reader refuses it by file, column and row instead of carrying it into every message.
MAX_CELL_CHARS = 4096

Dtype = Literal["text", "float", "int"]
#: When a column is required: ``always``; ``sinkage``/``shear`` for tests of that kind;
#: ``circle``/``rectangle`` for sinkage tests of that shape; ``optional`` never.
Need = Literal["always", "sinkage", "shear", "circle", "rectangle", "optional"]


@dataclass(frozen=True)
class ColumnSpec:
    """One column of the format.

    Attributes
    ----------
    name : str
        Exact (case-sensitive) column name.
    dtype : {"text", "float", "int"}
        ``int`` columns are held as float64 (so that "not recorded" is NaN) and checked to be
        whole numbers.
    need : str
        When the column must be present and filled; see :data:`Need`.
    unit : str
        SI unit, empty for text and counts.
    geometry : bool
        A geometry column: any non-empty cell must be a finite number, whatever the test.
    meaning : str
        One line for messages and documentation.
    """

    name: str
    dtype: Dtype
    need: Need
    unit: str = ""
    geometry: bool = False
    meaning: str = ""


_TESTS = (
    ColumnSpec("test_id", "text", "always", meaning="unique key of the test"),
    ColumnSpec("kind", "text", "always", meaning="'sinkage' or 'shear'"),
    ColumnSpec("soil", "text", "always", meaning="soil name"),
    ColumnSpec("preparation", "text", "optional", meaning="preparation method"),
    ColumnSpec("operator", "text", "optional", meaning="who prepared the soil"),
    ColumnSpec("repetition", "int", "optional", meaning="repetition number"),
    ColumnSpec("shape", "text", "sinkage", meaning="'circle' or 'rectangle'"),
    ColumnSpec("radius_m", "float", "circle", "m", True, "plate radius (b of a circle)"),
    ColumnSpec("width_m", "float", "rectangle", "m", True, "short side (b of a rectangle)"),
    ColumnSpec("length_m", "float", "rectangle", "m", True, "long side of a rectangle"),
    ColumnSpec("velocity_m_s", "float", "optional", "m/s", meaning="penetration velocity"),
    ColumnSpec("r_inner_m", "float", "shear", "m", True, "inner radius of the shear ring"),
    ColumnSpec("r_outer_m", "float", "shear", "m", True, "outer radius of the shear ring"),
    ColumnSpec("grousers", "int", "shear", "", True, "number of grousers"),
    ColumnSpec("grouser_height_m", "float", "shear", "m", True, "grouser height"),
    ColumnSpec("omega_rpm", "float", "optional", "rpm", meaning="rotational shear velocity"),
)
_SINKAGE = (
    ColumnSpec("test_id", "text", "always", meaning="a sinkage test of the log"),
    ColumnSpec("z_m", "float", "always", "m", meaning="sinkage, increasing into the soil"),
    ColumnSpec("force_N", "float", "always", "N", meaning="force normal to the plate"),
)
_SHEAR = (
    ColumnSpec("test_id", "text", "always", meaning="a shear test of the log"),
    ColumnSpec("angle_rad", "float", "always", "rad", meaning="rotation angle α of the ring"),
    ColumnSpec("torque_Nm", "float", "always", "N m", meaning="measured torque T"),
    ColumnSpec("normal_force_N", "float", "always", "N", meaning="normal force on the ring"),
)

#: Column specifications per file stem, in canonical order.
SPECS: dict[str, tuple[ColumnSpec, ...]] = {
    "tests": _TESTS,
    "sinkage": _SINKAGE,
    "shear": _SHEAR,
}

#: Columns soilstats computes (see :mod:`soilstats.campaign.derived`), per file stem, in the
#: order they are appended. An input column with one of these names must agree with the
#: computed value (it is then replaced by it).
DERIVED_COLUMNS: dict[str, tuple[str, ...]] = {
    "tests": ("b_m", "area_m2", "aspect_ratio", "ring_area_m2", "n_samples"),
    "sinkage": ("pressure_Pa",),
    "shear": ("sigma_Pa", "tau_Pa", "j_m"),
}


def spec(file: str, column: str) -> ColumnSpec | None:
    """Return the specification of ``column`` in file stem ``file``, or None if extra."""
    for s in SPECS[file]:
        if s.name == column:
            return s
    return None


def canonical_order(file: str, columns: list[str]) -> list[str]:
    """Order ``columns``: the format's columns in canonical order, then the others as given.

    Parameters
    ----------
    file : {"tests", "sinkage", "shear"}
        File stem.
    columns : list of str
        Column names present.

    Returns
    -------
    list of str
        The same names, reordered.
    """
    known = [s.name for s in SPECS[file] if s.name in columns]
    return known + [c for c in columns if c not in known]
