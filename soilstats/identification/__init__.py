"""The paper's identification procedures on campaigns (Sections 2.1 and 2.2)."""

from __future__ import annotations

from .per_test import fit_per_test
from .pooling import pool_shear, pool_sinkage
from .shear import fit_shear
from .sinkage import fit_sinkage
from .steady_state import steady_state
from .table import parameter_table

__all__ = [
    "fit_per_test",
    "fit_shear",
    "fit_sinkage",
    "parameter_table",
    "pool_shear",
    "pool_sinkage",
    "steady_state",
]
