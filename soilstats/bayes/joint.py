"""Joint (kc, kφ, n, c, φ, K) draws for rover Monte Carlo, and simulator parameter sets.

Sinkage and shear parameters come from *separate physical tests* (plate tests and shear-ring
tests on separately prepared soil), so their posteriors are independent blocks: a joint draw
pairs a sinkage draw with an independently chosen shear draw.  Correlations *within* each
block (kc–kφ–n, c–φ–K) are kept exactly; none is invented between blocks.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .result import PosteriorResult

__all__ = ["SIMULATOR_FORMATS", "joint_draws", "simulator_parameters"]

#: Column names and units of the parameter sets wheel–soil simulators consume.
#: ``chrono-scm``: Project Chrono's SCM terrain, ``SCMTerrain::SetSoilParameters(Bekker_Kphi,
#: Bekker_Kc, Bekker_n, Mohr_cohesion, Mohr_friction, Janosi_shear, …)`` — Kphi [Pa/m^n] =
#: N/m^(n+2), Kc [Pa/m^(n−1)] = N/m^(n+1), cohesion [Pa], friction [deg], Janosi shear [m].
#: The elastic stiffness and damping of SCM are not Bevameter parameters and are not written.
SIMULATOR_FORMATS = {
    "chrono-scm": {
        "kphi": ("Bekker_Kphi", "Pa/m^n"),
        "kc": ("Bekker_Kc", "Pa/m^(n-1)"),
        "n": ("Bekker_n", "-"),
        "c": ("Mohr_cohesion", "Pa"),
        "phi": ("Mohr_friction", "deg"),
        "K": ("Janosi_shear", "m"),
    },
}


def joint_draws(
    sinkage: PosteriorResult, shear: PosteriorResult, n: int, seed: int | None = None
) -> pd.DataFrame:
    """``n`` joint draws of the sinkage and shear parameters (independent blocks).

    Parameters
    ----------
    sinkage, shear : PosteriorResult
        Posteriors (pooled or population) of a sinkage model and a shear model of one soil.
    n : int
        Number of rows.
    seed : int, optional
        Seed of the (independent) subsampling of each block.

    Returns
    -------
    DataFrame
        Sinkage columns then shear columns, SI units, φ in degrees.
    """
    rng = np.random.default_rng(seed)
    seeds = rng.integers(2**32, size=2)
    a = sinkage.draws(n, seed=int(seeds[0]))
    b = shear.draws(n, seed=int(seeds[1]))
    clash = set(a.columns) & set(b.columns)
    if clash:
        raise ValueError(
            f"both posteriors have parameters {sorted(clash)}; pass a sinkage and a shear posterior"
        )
    return pd.concat([a, b], axis=1)


def simulator_parameters(draws: pd.DataFrame, simulator: str = "chrono-scm") -> pd.DataFrame:
    """Rename joint draws to a simulator's parameter names (see :data:`SIMULATOR_FORMATS`)."""
    try:
        spec = SIMULATOR_FORMATS[simulator]
    except KeyError:
        raise ValueError(
            f"unknown simulator {simulator!r}; choose one of {sorted(SIMULATOR_FORMATS)}"
        ) from None
    missing = [k for k in spec if k not in draws.columns]
    if missing:
        raise ValueError(
            f"{simulator} needs {list(spec)}; the draws lack {missing} — use a "
            "Bekker sinkage posterior and a Janosi shear posterior (bekker+janosi)"
        )
    return pd.DataFrame({name: draws[key].to_numpy() for key, (name, _) in spec.items()})
