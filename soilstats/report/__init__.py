"""Everything that turns results into files: provenance, JSON/CSV writers, PDF pages.

Analysis packages compute results; this package writes them. Importing it is cheap: the
writers import pandas or matplotlib only when called.
"""

from __future__ import annotations

from .files import json_safe, output_path, safe_stem, write_csv, write_json
from .provenance import Provenance, campaign_sha256, source_date

__all__ = [
    "Provenance",
    "campaign_sha256",
    "json_safe",
    "output_path",
    "safe_stem",
    "source_date",
    "write_csv",
    "write_json",
]
