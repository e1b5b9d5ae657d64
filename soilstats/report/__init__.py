"""The top floor: typeset reports (PDF) of the results every other package computes.

Analysis packages compute results; this package renders them. What every result is written
with (provenance, JSON/CSV writers, atomic files, notes) is the ground floor,
:mod:`soilstats.outputs`; its names are re-exported here for code that imported them from
``soilstats.report`` (nothing inside soilstats does: docs/conventions.md, "Layers"). Importing
it is cheap: the PDF modules are imported only by whoever writes a PDF.

==================  =====================================================================
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
==================  =====================================================================
"""

from __future__ import annotations

from .. import outputs as _outputs
from ..outputs import *  # noqa: F403  (the old names: soilstats.report.Provenance, ...)

__all__ = list(_outputs.__all__)
