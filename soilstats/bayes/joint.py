"""Joint (kc, kφ, n, c, φ, K) draws for rover Monte Carlo, and simulator parameter sets.

Sinkage and shear parameters come from *separate physical tests* (plate tests and shear-ring
tests on separately prepared soil), so their posteriors are independent blocks: a joint draw
pairs a sinkage draw with an independently chosen shear draw.  Correlations *within* each
block (kc–kφ–n, c–φ–K) are kept exactly; none is invented between blocks.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
import pandas as pd

from ..errors import InputError

__all__ = ["PosteriorDraws", "joint_draws"]


class PosteriorDraws(Protocol):
    """What :func:`joint_draws` reads of a posterior: its draws
    (:meth:`~.result.PosteriorResult.draws`). :mod:`.result` reaches this module through
    :mod:`.handout`, so an import of it here would close a loop (tests/test_layers.py)."""

    def draws(
        self, n: int | None = None, seed: int | None = None, *, allow_unconverged: bool = False
    ) -> pd.DataFrame: ...


def joint_draws(
    sinkage: PosteriorDraws,
    shear: PosteriorDraws,
    n: int,
    seed: int | None = None,
    *,
    allow_unconverged: bool = False,
) -> pd.DataFrame:
    """``n`` joint draws of the sinkage and shear parameters (independent blocks).

    Parameters
    ----------
    sinkage, shear : PosteriorResult
        Posteriors (pooled or population) of a sinkage model and a shear model of one soil
        (annotated by the protocol :class:`PosteriorDraws`: :mod:`.result` reaches this
        module through :mod:`.handout`, and an import back would close the circle).
    n : int
        Number of rows.
    seed : int, optional
        Seed of the (independent) subsampling of each block.
    allow_unconverged : bool, default False
        Take the draws of a posterior that failed its convergence checks; without it such a
        posterior raises ConvergenceError (:meth:`PosteriorResult.draws`).

    Returns
    -------
    DataFrame
        Sinkage columns then shear columns, SI units, φ in degrees.
    """
    rng = np.random.default_rng(seed)
    seeds = rng.integers(2**32, size=2)
    a = sinkage.draws(n, seed=int(seeds[0]), allow_unconverged=allow_unconverged)
    b = shear.draws(n, seed=int(seeds[1]), allow_unconverged=allow_unconverged)
    clash = set(a.columns) & set(b.columns)
    if clash:
        raise InputError(
            f"both posteriors have parameters {sorted(clash)}; pass a sinkage and a shear posterior"
        )
    return pd.concat([a, b], axis=1)
