"""Bevameter campaigns: read, validate, derive, select and save (format v1).

A campaign is a folder with ``tests.csv`` (one row per test), ``sinkage.csv`` and/or
``shear.csv`` (raw samples), or the same tables as ``.parquet``; the format is documented in
``docs/campaign-format.md``.

Examples
--------
>>> from soilstats.campaign import load_campaign
>>> c = load_campaign("cullinan-sand")                 # a bundled campaign
>>> loose = c.select(preparation=["1", "2"])           # text column: compare as text
>>> loose.samples("method1-test1")[["z_m", "pressure_Pa"]].shape
(2000, 2)
"""

from __future__ import annotations

from ..data import bundled_names
from .campaign import Campaign, load_campaign
from .importing import import_campaign
from .units import UnitsWarning

__all__ = ["Campaign", "UnitsWarning", "bundled_campaigns", "import_campaign", "load_campaign"]


def bundled_campaigns() -> list[str]:
    """Return the names of the campaigns bundled with soilstats (``soilstats/data/<name>/``).

    Returns
    -------
    list of str
        Sorted names, each loadable with :func:`load_campaign`.
    """
    return bundled_names()
