"""A sinkage record's plate law: the pressure under a plate of width b at sinkage z.

The wheel (:mod:`soilstats.wheel`) asks a record one thing, ``plate_pressure(b, z, *params)
-> p`` [Pa] (``Model.plate_pressure``). A :class:`PlatePowerLaw` (p = k_eq(b)·z^n) gives it
its power-law fast path; :func:`default_plate_law` is the hook of a record that states none.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["PlatePowerLaw", "default_plate_law"]


@dataclass(frozen=True)
class PlatePowerLaw:
    """A plate law that is a power law in the sinkage: p(b, z) = k_eq(b)·z^n.

    ``modulus(b, *params) -> k_eq`` [N/m^(n+2)] at plate width b [m], with ``params`` in the
    record's order and n its ``"n"`` parameter.  As the record's ``plate_pressure`` hook it
    tells the wheel (:mod:`soilstats.wheel`) to take its fast path, σ = k_eq·R^n·(cos θ −
    cos θ1)^n, instead of evaluating the law at every node's depth.  Calling it gives the
    pressure (0 where z ≤ 0), as every ``plate_pressure`` hook does.
    """

    modulus: Callable[..., np.ndarray]
    exponent_index: int = -1  # where n stands among the parameters (last for a power law)

    def __call__(self, b: ArrayLike, z: ArrayLike, *params: ArrayLike) -> np.ndarray:
        z = np.asarray(z, dtype=float)
        n = params[self.exponent_index]
        contact = z > 0
        zn = np.where(contact, np.exp(n * np.log(np.where(contact, z, 1.0))), 0.0)
        return self.modulus(b, *params) * zn


@dataclass(frozen=True)
class _PowerLawModulus:
    """k_eq(b) = Σ aᵢ·gᵢ(b) of a record's ``power_law`` basis (θ = (a₁ … a_q, n)): the
    default plate hook of Bekker and Bernstein.  Module level, so a record pickles."""

    power_law: Callable
    columns: tuple[str, ...]

    def __call__(self, b: ArrayLike, *params: ArrayLike) -> np.ndarray:
        unit_depth = 1.0
        x = (b, unit_depth) if self.columns == ("b_m", "z_m") else unit_depth
        g, _ = self.power_law(x)
        return sum((a * g_i for a, g_i in zip(params[:-1], g, strict=True)), np.asarray(0.0))


@dataclass(frozen=True)
class _FuncPlatePressure:
    """p(b, z) from a sinkage record's own ``func`` on x = (b, z) or z (its ``columns``)."""

    func: Callable
    columns: tuple[str, ...]

    def __call__(self, b: ArrayLike, z: ArrayLike, *params: ArrayLike) -> np.ndarray:
        b, z = np.broadcast_arrays(np.asarray(b, float), np.asarray(z, float))
        x = (b, z) if self.columns == ("b_m", "z_m") else z
        return np.asarray(self.func(x, *params), dtype=float)


def default_plate_law(
    kind: str,
    columns: tuple[str, ...],
    func: Callable,
    power_law: Callable | None,
    exponent_last: bool,
) -> Callable[..., np.ndarray] | None:
    """The plate hook of a record that states no ``plate_pressure`` (its ``kind``,
    ``columns``, ``func`` and ``power_law``; ``exponent_last``: n is its last parameter): a
    :class:`PlatePowerLaw` from the ``power_law`` basis for a power law, else ``func`` on
    (b, z) or z; None for a record whose inputs are not a plate's (b, z)."""
    if kind != "sinkage" or columns not in (("b_m", "z_m"), ("z_m",)):
        return None
    if power_law is not None and exponent_last:
        return PlatePowerLaw(_PowerLawModulus(power_law, columns))
    return _FuncPlatePressure(func, columns)
