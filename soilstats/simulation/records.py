"""The records of a checked SPEC (frozen dataclasses), its constants and its error class.

Parsing and checking live in :mod:`soilstats.simulation.spec`; the format is documented in
``docs/simulator.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from ..errors import SpecError
from ..kinds import TEST_KINDS

__all__ = [
    "EFFECT_KINDS",
    "KINDS",
    "PARAMS",
    "SHEAR_PARAMS",
    "SINKAGE_PARAMS",
    "Artefact",
    "Effect",
    "Noise",
    "Preparation",
    "Resolution",
    "Scatter",
    "Series",
    "Soil",
    "Spec",
    "SpecError",
]

#: Soil parameters of the pressure–sinkage law (Bekker, Eq. 7): kc [N/m^(n+1)], kφ [N/m^(n+2)].
SINKAGE_PARAMS: tuple[str, ...] = ("kc", "kphi", "n")
#: Soil parameters of the shear law (Janosi–Hanamoto, Eq. 13): c [Pa], φ [deg], K [m].
SHEAR_PARAMS: tuple[str, ...] = ("c", "phi", "K")
PARAMS: tuple[str, ...] = SINKAGE_PARAMS + SHEAR_PARAMS
KINDS = TEST_KINDS  # the kinds of series a SPEC simulates: a campaign's test kinds
EFFECT_KINDS = ("covariate", "velocity", "softening", "size", "side-walls")


@dataclass(frozen=True)
class Scatter:
    """Per-test preparation scatter ("the soil has some random characteristic", Sect. 2.1).

    Each test draws its own parameters: kc and kφ share one log-normal factor exp(cv·N(0,1))
    (so a test is uniformly stiffer or softer), n gets an additive N(0, n_sd²), c and K
    log-normal factors, φ an additive N(0, phi_sd_deg²) in degrees.
    """

    stiffness_cv: float = 0.05
    n_sd: float = 0.01
    c_cv: float = 0.05
    phi_sd_deg: float = 0.2
    K_cv: float = 0.05


@dataclass(frozen=True)
class Preparation:
    """A preparation method: its scatter, operator dependence and metadata columns."""

    name: str
    scatter: Scatter
    operator_cv: float = 0.0  # sd of a persistent log factor on stiffness and c per operator
    columns: dict[str, str | float] = field(default_factory=dict)


@dataclass(frozen=True)
class Soil:
    """A soil: base parameters and overrides that hold where test-log columns match."""

    name: str
    params: dict[str, float]
    conditions: tuple[tuple[dict[str, str | float], dict[str, float]], ...] = ()

    def params_for(self, row: dict[str, Any]) -> dict[str, float]:
        """Base parameters updated by every condition whose ``where`` matches ``row``."""
        out = dict(self.params)
        for where, params in self.conditions:
            if all(_cell_equal(row.get(k), v) for k, v in where.items()):
                out.update(params)
        return out


def _cell_equal(a: Any, b: Any) -> bool:
    if isinstance(a, int | float) and isinstance(b, int | float):
        return math.isclose(a, b, rel_tol=1e-9, abs_tol=0.0)
    return str(a) == str(b)


@dataclass(frozen=True)
class Series:
    """One test series: the crossed design of soils × geometries × conditions × repetitions."""

    name: str
    kind: str
    soils: tuple[str, ...]
    geometries: tuple[dict[str, str | float], ...]
    preparations: tuple[str, ...]
    operators: tuple[str, ...]
    repetitions: int
    points: int
    velocity_m_s: tuple[float, ...] = ()
    sinkage_m: float = 0.03
    start_m: float = -5e-4
    grousers: tuple[int, ...] = ()
    grouser_height_m: tuple[float, ...] = ()
    omega_rpm: tuple[float, ...] = ()
    normal_pressure_Pa: tuple[float, ...] = ()
    shear_deformation_m: float = 0.1
    covariates: dict[str, tuple[str | float, ...]] = field(default_factory=dict)


@dataclass(frozen=True)
class Noise:
    """Measurement noise (all standard deviations; 0 switches a source off)."""

    force_N: float = 0.2  # white sensor noise on the plate force
    force_rel: float = 0.0  # relative white noise on the plate force
    force_offset_N: float = 0.3  # per-test zero offset of the force sensor
    torque_Nm: float = 0.02  # white sensor noise on the torque
    torque_offset_Nm: float = 0.01  # per-test zero offset of the torque sensor
    normal_force_rel: float = 0.01  # controller noise: relative wobble of the true normal force
    normal_force_N: float = 0.5  # white sensor noise on the recorded normal force


@dataclass(frozen=True)
class Resolution:
    """Quantisation step of each recorded value (a realistic sensor resolution)."""

    z_m: float = 1e-6
    force_N: float = 0.01
    angle_rad: float = 1e-5
    torque_Nm: float = 1e-4
    normal_force_N: float = 0.01


@dataclass(frozen=True)
class Effect:
    """One planted effect (see :mod:`soilstats.simulation.effects` for each kind)."""

    kind: str
    options: dict[str, Any]
    soils: tuple[str, ...] = ()  # empty: every soil
    series: tuple[str, ...] = ()  # empty: every series

    def applies(self, soil: str, series: str) -> bool:
        return (not self.soils or soil in self.soils) and (not self.series or series in self.series)


@dataclass(frozen=True)
class Artefact(Effect):
    """One planted record phase or sensor glitch (see :mod:`soilstats.simulation.artefacts`
    for each kind); ``options["share"]`` is the probability that a matching test gets it."""


@dataclass(frozen=True)
class Spec:
    """A checked SPEC; build it with :func:`load_spec` or :func:`parse_spec`."""

    name: str
    description: str
    soils: dict[str, Soil]
    preparations: dict[str, Preparation]
    series: tuple[Series, ...]
    effects: tuple[Effect, ...]
    noise: Noise
    resolution: Resolution
    scatter: Scatter
    artefacts: tuple[Artefact, ...] = ()
    raw: dict[str, Any] = field(repr=False, default_factory=dict)  # the TOML as read: any values
    source: str = "<memory>"
    sha256: str = ""
