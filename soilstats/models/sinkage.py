"""Pressure–sinkage models: Bekker (Eq. 7), Bernstein (Eq. 8) and Reece.

All take sinkage z in m and return pressure p in Pa.  For z ≤ 0 (plate not yet in contact, or
a sensor reading around zero) they return p = 0 and a zero Jacobian row: z^n has no real value
for z < 0 and non-integer n.  The identification excludes such samples before fitting (see
``soilstats.identification.sinkage``); the models only need to stay finite there.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .base import (
    InputRows,
    Model,
    ParamLabel,
    PlatePowerLaw,
    Positive,
    PositiveModulus,
    Value,
    power_law_population,
    separable_from_power_law,
)
from .priors import FLAT, POSITIVE

__all__ = ["BEKKER", "BERNSTEIN", "REECE"]


def _power(z: ArrayLike, n: Value) -> tuple[np.ndarray, np.ndarray]:
    """(z^n, ln z) for z > 0, and (0, 0) elsewhere."""
    z = np.asarray(z, dtype=float)
    contact = z > 0
    lnz = np.log(np.where(contact, z, 1.0))
    zn = np.where(contact, np.exp(n * lnz), 0.0)
    return zn, lnz


def bekker(x: InputRows, kc: Value, kphi: Value, n: Value) -> np.ndarray:
    """Bekker p = (kc/b + kφ)·z^n (Eq. 7).

    ``x = (b [m], z [m])``; kc in N/m^(n+1), kφ in N/m^(n+2), p in Pa.
    """
    b, z = x
    zn, _ = _power(z, n)
    return (kc / b + kphi) * zn


def bekker_jac(x: InputRows, kc: Value, kphi: Value, n: Value) -> np.ndarray:
    b, z = x
    zn, lnz = _power(z, n)
    return np.column_stack([zn / b, zn, (kc / b + kphi) * zn * lnz])


def bernstein(z: ArrayLike, k: Value, n: Value) -> np.ndarray:
    """Bernstein p = k·z^n (Eq. 8).  ``x = z [m]``; k in N/m^(n+2)."""
    zn, _ = _power(z, n)
    return k * zn


def bernstein_jac(z: ArrayLike, k: Value, n: Value) -> np.ndarray:
    zn, lnz = _power(z, n)
    return np.column_stack([zn, k * zn * lnz])


def reece(x: InputRows, k1: Value, k2: Value, n: Value) -> np.ndarray:
    """Reece p = (k1 + k2·b)·(z/b)^n.  ``x = (b [m], z [m])``; k1 in Pa, k2 in Pa/m."""
    b, z = x
    zbn, _ = _power(np.asarray(z, float) / b, n)
    return (k1 + k2 * b) * zbn


def reece_jac(x: InputRows, k1: Value, k2: Value, n: Value) -> np.ndarray:
    b, z = x
    zbn, ln_zb = _power(np.asarray(z, float) / b, n)
    return np.column_stack([zbn, b * zbn, (k1 + k2 * b) * zbn * ln_zb])


def _bekker_terms(x):
    """Bekker as a power law (see :class:`~soilstats.models.base.PowerLawTerms`):
    p = kc·(1/b)·z^n + kφ·1·z^n."""
    b, z = x
    return (1.0 / np.asarray(b, dtype=float), 1.0), z


def _bernstein_terms(z):
    """Bernstein as a power law: p = k·1·z^n."""
    return (1.0,), z


# Module-level functions (not partials) so that a model pickled to a worker process compares
# equal to the original.
def _separable_bekker(x, w):
    return separable_from_power_law(_bekker_terms, x, w)


def _separable_bernstein(z, w):
    return separable_from_power_law(_bernstein_terms, z, w)


def bekker_modulus(b: Value, kc: np.ndarray, kphi: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Bekker's plate modulus kc/b + kφ [N/m^(n+2)]: the pressure at unit sinkage on width b."""
    return kc / b + kphi


def reece_modulus(b: Value, k1: np.ndarray, k2: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Reece's plate modulus k1 + k2·b [Pa]: the pressure at z = b (at sinkage ratio 1)."""
    return k1 + k2 * b


def bernstein_modulus(b: Value, k: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Bernstein's plate modulus k [N/m^(n+2)], whatever the width."""
    return np.asarray(k, dtype=float)


def reece_pressure_modulus(b: Value, k1: np.ndarray, k2: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Reece's k_eq = (k1 + k2·b)·b^(−n) [N/m^(n+2)]: p = k_eq·z^n on a plate of width b."""
    return (k1 + k2 * b) * b ** (-n)


# Starting values and Wong's method have one home each (soilstats.models.starting_values
# and .wong, below the identification that asks the record); imported when first used.
def _start_bekker(x, p):
    from .starting_values import bekker_start  # deferred: pandas (Wong's fit)

    b, z = x
    return bekker_start(b, z, p)


def _start_bernstein(z, p):
    from .starting_values import bernstein_start  # deferred: pandas (Wong's fit)

    return bernstein_start(z, p)


def _start_reece(x, p):
    from .starting_values import reece_start  # deferred: pandas (Wong's fit)

    b, z = x
    return reece_start(b, z, p)


def _wong_bekker(x, p):
    from .wong import wong_bekker  # deferred: pandas (Wong's fit)

    b, z = x
    return wong_bekker(b, z, p)


def _wong_bernstein(z, p):
    from .wong import wong_bernstein  # deferred: pandas (Wong's fit)

    return wong_bernstein(z, p)


_N_LABEL = ParamLabel("n", r"$n$", "n", "–", "dimensionless", 1.0)

# What Bekker and Reece share: inputs (b, z), and two plate sizes to tell their terms apart.
_SIZED_PLATES: dict[str, Any] = dict(
    kind="sinkage",
    columns=("b_m", "z_m"),
    min_plate_sizes=2,
    design_input="b_m",
    weighting="max-pressure",
)

_N_RANGE = (0.0, 5.0)  # measured n of dry granular soils and clays lie well inside (paper: 0.8–3.6)

BEKKER = Model(
    name="bekker",
    equation="Eq. 7: p = (kc/b + kphi) * z^n",
    inputs=("b [m]", "z [m]"),
    output="p [Pa]",
    param_names=("kc", "kphi", "n"),
    units=("N/m^(n+1)", "N/m^(n+2)", "-"),
    # kc may take either sign: a negative kc (a narrower plate sinks more at one pressure) is
    # what frictional sands give, bearing capacity growing with width — the paper's own
    # Table 5 soils 01 and 02. Bounding it at 0 flagged every such fit.
    bounds=((-np.inf, np.inf), (0.0, np.inf), _N_RANGE),
    func=bekker,
    jac=bekker_jac,
    separable=_separable_bekker,
    power_law=_bekker_terms,
    **_SIZED_PLATES,
    start=_start_bekker,
    wong=_wong_bekker,
    priors={"kc": FLAT, "kphi": POSITIVE, "n": POSITIVE},
    support=(Positive("n"), PositiveModulus("kc/b + kphi", bekker_modulus, ("kc", "kphi", "n"))),
    population=power_law_population(
        "k_t(b) = (kc/b + kphi) exp(eps_t - delta_t ln z_s), n_t = n + delta_t"
    ),
    scm={
        "kphi": ("Bekker_Kphi", "Pa/m^n"),
        "kc": ("Bekker_Kc", "Pa/m^(n-1)"),
        "n": ("Bekker_n", "-"),
    },
    labels={
        "kc": ParamLabel("k_c", r"$k_c$", "k_c", "kN/m$^{n+1}$", "kN/m^(n+1)", 1e-3),
        "kphi": ParamLabel("k_phi", r"$k_\varphi$", "k_φ", "kN/m$^{n+2}$", "kN/m^(n+2)", 1e-3),
        "n": _N_LABEL,
    },
    signed=("kc", "kphi"),
    plate_pressure=PlatePowerLaw(bekker_modulus),
)

BERNSTEIN = Model(
    name="bernstein",
    equation="Eq. 8: p = k * z^n",
    inputs=("z [m]",),
    output="p [Pa]",
    param_names=("k", "n"),
    units=("N/m^(n+2)", "-"),
    bounds=((0.0, np.inf), _N_RANGE),
    func=bernstein,
    jac=bernstein_jac,
    separable=_separable_bernstein,
    power_law=_bernstein_terms,
    kind="sinkage",
    columns=("z_m",),
    start=_start_bernstein,
    wong=_wong_bernstein,
    priors={"k": POSITIVE, "n": POSITIVE},
    support=(Positive("n"), Positive("k")),
    weighting="max-pressure",
    population=power_law_population("k_t = k exp(eps_t - delta_t ln z_s), n_t = n + delta_t"),
    labels={
        "k": ParamLabel("k", r"$k$", "k", "kN/m$^{n+2}$", "kN/m^(n+2)", 1e-3),
        "n": _N_LABEL,
    },
    plate_pressure=PlatePowerLaw(bernstein_modulus),
)

REECE = Model(
    name="reece",
    equation="Reece: p = (k1 + k2*b) * (z/b)^n",
    inputs=("b [m]", "z [m]"),
    output="p [Pa]",
    param_names=("k1", "k2", "n"),
    units=("Pa", "Pa/m", "-"),
    bounds=((-np.inf, np.inf), (0.0, np.inf), _N_RANGE),
    func=reece,
    jac=reece_jac,
    **_SIZED_PLATES,
    start=_start_reece,
    priors={"k1": FLAT, "k2": POSITIVE, "n": POSITIVE},
    support=(Positive("n"), PositiveModulus("k1 + k2 b", reece_modulus, ("k1", "k2", "n"))),
    labels={
        "k1": ParamLabel("k_1", r"$k_1$", "k_1", "kPa", "kPa", 1e-3),
        "k2": ParamLabel("k_2", r"$k_2$", "k_2", "kPa/m", "kPa/m", 1e-3),
        "n": _N_LABEL,
    },
    signed=("k1", "k2"),
    plate_pressure=PlatePowerLaw(reece_pressure_modulus),
)
