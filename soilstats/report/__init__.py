"""Everything that turns results into files: provenance, JSON/CSV writers, typeset PDFs.

Analysis packages compute results; this package writes them. Importing it is cheap: the
writers import pandas or matplotlib only when called, and the PDF modules are imported only
by whoever writes a PDF.

==================  =====================================================================
``provenance``      version, campaign format and hash, command, seed, date
``files``           safe output paths, atomic writes (never through a link), JSON (no
                    NaN) and CSV with a provenance header (formula cells escaped)
``document``        the report engine: a typeset (Typst) document of prose, tables,
                    equations and figures, rendered to PDF
``front``           page 1 of every report: question, data (measured/simulated), conclusion
``methods``         the paper's equations, typeset and cited
``labels``          human names with units, parameter symbols, natural level order
``parameters``      parameter tables (Table 5 per condition, one fit) as value ± σ
``study_pdf``       a study's report; its figures in ``study_figures``
``discovery_pdf``   the discovery report
``check_pdf``       the data-quality screening report
``identify_pdf``    the identification report (parameters per soil and condition)
``posterior_pdf``   the posterior report; its figures in ``posterior_figures``
``text``            plain-text pieces every ``summary()`` shares
==================  =====================================================================
"""

from __future__ import annotations

from .files import json_safe, output_path, safe_stem, write_atomic, write_csv, write_json
from .provenance import Provenance, campaign_sha256, source_date

__all__ = [
    "Provenance",
    "campaign_sha256",
    "json_safe",
    "output_path",
    "safe_stem",
    "source_date",
    "write_atomic",
    "write_csv",
    "write_json",
]
