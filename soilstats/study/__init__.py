"""Studies of test-setup effects (the paper's Sections 3-4) with verdicts and PDF reports.

A study is a TOML specification (``studies/*.toml`` in the repository, shipped in the
package; format in ``docs/studies.md``): which tests, which factor, which responses, which
criteria, which figures.  Run one from Python or with ``python -m soilstats.study NAME``.

>>> import soilstats
>>> from soilstats.study import load_spec, run_study
>>> campaign = soilstats.load_campaign("simulated-paper")
>>> result = run_study(load_spec("grousers"), campaign)          # doctest: +SKIP
>>> print(result.summary())                                       # doctest: +SKIP
"""

from __future__ import annotations

from .data import StudyDataError
from .outputs import to_json_dict, write_outputs
from .result import StudyResult
from .runner import run_study
from .spec import SpecError, StudySpec, available_studies, load_spec

__all__ = [
    "SpecError",
    "StudyDataError",
    "StudyResult",
    "StudySpec",
    "available_studies",
    "load_spec",
    "run_study",
    "to_json_dict",
    "write_outputs",
]
