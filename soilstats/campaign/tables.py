"""What the campaign's helper modules read of a campaign, as a protocol.

:mod:`~soilstats.campaign.campaign` imports :mod:`.digest`, :mod:`.index` and
:mod:`.summary`, so these cannot import :class:`~soilstats.campaign.Campaign` to annotate their
``campaign`` parameter, not even under ``TYPE_CHECKING`` (that would close an import loop:
tests/test_layers.py). They name this protocol instead; a ``Campaign`` satisfies it.
"""

from __future__ import annotations

from typing import Protocol

import pandas as pd

__all__ = ["CampaignTables"]


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
