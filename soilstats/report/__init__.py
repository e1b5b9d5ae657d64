"""Everything that turns results into files: provenance, JSON/CSV writers, PDF pages.

Analysis packages compute results; this package writes them. Importing it is cheap: the
writers import pandas or matplotlib only when called, and the PDF modules are imported only
by whoever writes a PDF.

==================  =====================================================================
``provenance``      version, campaign format and hash, command, seed, date
``files``           safe output paths, JSON (no NaN) and CSV with a provenance header
``pages``           the text pages every PDF shares (paginated, wrapped, provenance page)
``study_pdf``       a study's report; its figures in ``study_figures``
``discovery_pdf``   the discovery report
``posterior_pdf``   trace, pair and posterior-predictive pages of a posterior
==================  =====================================================================
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
