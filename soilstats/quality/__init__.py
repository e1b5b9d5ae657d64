"""Data-quality screening of real Bevameter records (codes: :data:`CODES`; docs/quality.md).

:func:`screen` runs every rule over a campaign and returns a :class:`QualityReport`
(:mod:`.report`: the findings, the windows they propose, and the cleaned campaign every
analysis uses, a :class:`ScreenedCampaign` that carries the report); :func:`screened` is the
guard the fitting functions call.  The rules on every sinkage record run in
:mod:`.sinkage_rules`; the detectors on one record are in :mod:`.records` (spikes in
:mod:`.spikes`, the noise width they read in :mod:`.noise`);
copied records (``duplicate``) are found across records by :mod:`.copies`, a force zero
drifting with test order (``zero-drift``) across the tests of a series by :mod:`.drift`.
"""

from .codes import ARTEFACT_CODES, CODES, MODES, PHASE_CODES, STOP_CODES, QualityCode
from .report import QualityFlag, QualityReport, ScreenedCampaign
from .screen import screen, screened

__all__ = [
    "ARTEFACT_CODES",
    "CODES",
    "MODES",
    "PHASE_CODES",
    "STOP_CODES",
    "QualityCode",
    "QualityFlag",
    "QualityReport",
    "ScreenedCampaign",
    "screen",
    "screened",
]
