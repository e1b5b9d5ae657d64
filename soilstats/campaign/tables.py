"""Types of what the analyses read of a campaign: its tables, and a selection criterion.

:mod:`~soilstats.campaign.campaign` imports :mod:`.digest`, :mod:`.index` and
:mod:`.summary`, so these cannot import :class:`~soilstats.campaign.Campaign` to annotate their
``campaign`` parameter, not even under ``TYPE_CHECKING`` (that would close an import loop:
tests/test_layers.py). They name the protocol :class:`CampaignTables` instead; a ``Campaign``
satisfies it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol, TypeAlias

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["CampaignTables", "Criterion"]

#: One criterion of :meth:`Campaign.select <soilstats.campaign.Campaign.select>` (and of every
#: ``**selection`` handed on to it): a value, a collection of values, or a function of the
#: column returning a boolean mask. ``Any``: a value may be of any type a column holds, and
#: the callers' ``**selection`` is passed on beside keywords of other types.
Criterion: TypeAlias = Any


class CampaignTables(Protocol):
    """A campaign's tables and the facts :func:`~soilstats.campaign.summary.describe` shows
    (read-only, as on the frozen :class:`~soilstats.campaign.Campaign`)."""

    @property
    def tests(self) -> pd.DataFrame: ...

    @property
    def sinkage(self) -> pd.DataFrame: ...

    @property
    def shear(self) -> pd.DataFrame: ...

    @property
    def source(self) -> str: ...

    @property
    def skipped(self) -> pd.DataFrame: ...

    @property
    def covariates(self) -> list[str]: ...
