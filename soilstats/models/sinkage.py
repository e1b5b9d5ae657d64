"""Pressure–sinkage models: Bekker (Eq. 7), Bernstein (Eq. 8) and Reece.

All take sinkage z in m and return pressure p in Pa.  For z ≤ 0 (plate not yet in contact, or
a sensor reading around zero) they return p = 0 and a zero Jacobian row: z^n has no real value
for z < 0 and non-integer n.  The identification excludes such samples before fitting (see
``soilstats.identification.sinkage``); the models only need to stay finite there.
"""

from __future__ import annotations

import numpy as np

from .base import Model

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


class _PowerCache:
    """z^n for fixed z, with ln z precomputed and the last z^n kept (f and J share it)."""

    def __init__(self, z) -> None:
        z = np.asarray(z, dtype=float)
        self.contact = z > 0
        self.all_contact = bool(self.contact.all())
        self.lnz = np.log(np.where(self.contact, z, 1.0))
        self._n = None
        self._zn = None

    def __call__(self, n: float) -> np.ndarray:
        if n != self._n:
            zn = np.exp(n * self.lnz)
            if not self.all_contact:
                zn[~self.contact] = 0.0
            self._n, self._zn = n, zn
        return self._zn


def _prepare_bekker(x, w):
    b, z = x
    w_over_b = w / np.asarray(b, dtype=float)
    power = _PowerCache(z)
    last = {"theta": None, "f": None}

    def f(theta):
        kc, kphi, n = theta
        value = (kc * w_over_b + kphi * w) * power(n)
        last["theta"], last["f"] = (kc, kphi, n), value
        return value

    def jac(theta):
        kc, kphi, n = theta
        zn = power(n)
        # w·f is the third column's common factor; the optimiser asks for J at the point it
        # has just evaluated, so reuse it rather than recompute.
        wf = last["f"] if last["theta"] == (kc, kphi, n) else f(theta)
        rows = np.empty((3, zn.size))
        np.multiply(zn, w_over_b, out=rows[0])
        np.multiply(zn, w, out=rows[1])
        np.multiply(wf, power.lnz, out=rows[2])
        return rows

    return f, jac


def _prepare_bernstein(z, w):
    power = _PowerCache(z)

    def f(theta):
        k, n = theta
        return (k * w) * power(n)

    def jac(theta):
        k, n = theta
        zn = power(n)
        rows = np.empty((2, zn.size))
        np.multiply(zn, w, out=rows[0])
        np.multiply(rows[0], k * power.lnz, out=rows[1])
        return rows

    return f, jac


def _separable_bekker(x, w):
    b, z = x
    w_over_b = w / np.asarray(b, dtype=float)
    power = _PowerCache(z)

    def basis(n):
        zn = power(n)
        return np.vstack([w_over_b * zn, w * zn])

    return basis, power.lnz


def _separable_bernstein(z, w):
    power = _PowerCache(z)

    def basis(n):
        return (w * power(n))[None, :]

    return basis, power.lnz


_N_RANGE = (0.0, 5.0)  # measured n of dry granular soils and clays lie well inside (paper: 0.8–3.6)

BEKKER = Model(
    name="bekker",
    equation="Eq. 7: p = (kc/b + kphi) * z^n",
    inputs=("b [m]", "z [m]"),
    output="p [Pa]",
    param_names=("kc", "kphi", "n"),
    units=("N/m^(n+1)", "N/m^(n+2)", "-"),
    bounds=((0.0, np.inf), (0.0, np.inf), _N_RANGE),
    func=bekker,
    jac=bekker_jac,
    prepare=_prepare_bekker,
    separable=_separable_bekker,
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
    prepare=_prepare_bernstein,
    separable=_separable_bernstein,
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
