"""Renamed names keep working for one release (docs/conventions.md, "Renamed").

Each old Python name still answers, with a ``FutureWarning`` (a
:class:`~soilstats.errors.RenamedWarning`) that names the new one, and gives what the new one
gives; each old JSON key is still written, beside the new one, with the same value. The
posterior's renamed keys are checked in tests/test_posterior.py, on its posteriors.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from soilstats.errors import RENAMED_GO_IN, RenamedWarning, SoilstatsWarning


def test_the_renamed_warning_is_a_future_warning_of_soilstats():
    assert issubclass(RenamedWarning, FutureWarning)
    assert issubclass(RenamedWarning, SoilstatsWarning)  # one filter silences every warning


def test_study_result_runtime_s_and_its_old_name_seconds():
    from soilstats.study.result import StudyResult

    empty = pd.DataFrame()
    result = StudyResult(
        spec=None,  # not read by either name
        source="here",
        date=None,
        soils=[],
        effects=empty,
        anova=empty,
        pairs=empty,
        parameters=empty,
        lines=empty,
        per_test=empty,
        runtime_s=1.25,
    )
    assert result.runtime_s == 1.25
    with pytest.warns(FutureWarning, match=rf"runtime_s.*goes in soilstats {RENAMED_GO_IN}"):
        assert result.seconds == 1.25


def test_ensemble_run_runtime_s_and_its_old_name_seconds():
    from soilstats.bayes.sampler import run_ensemble

    def log_prob(theta):
        return -0.5 * np.sum(theta**2, axis=1)

    run = run_ensemble(log_prob, np.zeros(2), np.eye(2), draws=64, seed=0, n_walkers=8, tune=20)
    assert run.runtime_s > 0
    with pytest.warns(RenamedWarning, match=r"EnsembleRun\.seconds is renamed .*runtime_s"):
        assert run.seconds == run.runtime_s
