"""The versions every output records: soilstats's own and the campaign format's.

Imports nothing, so :class:`soilstats.outputs.Provenance`, the command line's ``--version``
and the campaign reader (:mod:`soilstats.campaign.schema`) take them from one place.
"""

from __future__ import annotations

__all__ = ["FORMAT_VERSION", "__version__"]

__version__ = "0.1.0"

#: Version of the campaign format (``docs/campaign-format.md``) that this soilstats reads.
FORMAT_VERSION = "1"
