"""Pressure–sinkage models: Bekker (Eq. 7), Bernstein (Eq. 8) and Reece.

All take sinkage z in m and return pressure p in Pa.  For z ≤ 0 (plate not yet in contact, or
a sensor reading around zero) they return p = 0 and a zero Jacobian row: z^n has no real value
for z < 0 and non-integer n.  The identification excludes such samples before fitting (see
``soilstats.identification.sinkage``); the models only need to stay finite there.
"""

from __future__ import annotations

import numpy as np

from .base import Model, separable_from_power_law

__all__ = ["BEKKER", "BERNSTEIN", "REECE"]


def _power(z: np.ndarray, n: float) -> tuple[np.ndarray, np.ndarray]:
    """(z^n, ln z) for z > 0, and (0, 0) elsewhere."""
    z = np.asarray(z, dtype=float)
    contact = z > 0
    lnz = np.log(np.where(contact, z, 1.0))
    zn = np.where(contact, np.exp(n * lnz), 0.0)
    return zn, lnz


def bekker(x, kc, kphi, n):
    """Bekker p = (kc/b + kφ)·z^n (Eq. 7).

    ``x = (b [m], z [m])``; kc in N/m^(n+1), kφ in N/m^(n+2), p in Pa.
    """
    b, z = x
    zn, _ = _power(z, n)
    return (kc / b + kphi) * zn


def bekker_jac(x, kc, kphi, n):
    b, z = x
    zn, lnz = _power(z, n)
    return np.column_stack([zn / b, zn, (kc / b + kphi) * zn * lnz])


def bernstein(z, k, n):
    """Bernstein p = k·z^n (Eq. 8).  ``x = z [m]``; k in N/m^(n+2)."""
    zn, _ = _power(z, n)
    return k * zn


def bernstein_jac(z, k, n):
    zn, lnz = _power(z, n)
    return np.column_stack([zn, k * zn * lnz])


def reece(x, k1, k2, n):
    """Reece p = (k1 + k2·b)·(z/b)^n.  ``x = (b [m], z [m])``; k1 in Pa, k2 in Pa/m."""
    b, z = x
    zbn, _ = _power(np.asarray(z, float) / b, n)
    return (k1 + k2 * b) * zbn


def reece_jac(x, k1, k2, n):
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
)
