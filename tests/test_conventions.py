"""docs/conventions.md, enforced: every public result has summary() and a JSON-ready to_dict()."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pandas as pd
import pytest

from soilstats.bayes.result import PosteriorResult
from soilstats.discovery.crossval import Gain
from soilstats.discovery.result import DiscoveryResult, Finding
from soilstats.discovery.selection import CombinedModel
from soilstats.fitting.linear import LinearFit, linear_least_squares
from soilstats.fitting.result import FitResult
from soilstats.identification.conditions import ConditionFits
from soilstats.identification.result import CampaignFit
from soilstats.statistics.analysis_of_covariance import AncovaResult, ancova
from soilstats.statistics.result import TestResult
from soilstats.study.result import StudyResult
from soilstats.wheel.result import WheelPrediction
from soilstats.wheel.validation_result import WheelDiscovery, WheelValidation

RESULTS = (
    AncovaResult,
    CampaignFit,
    CombinedModel,
    ConditionFits,
    DiscoveryResult,
    Finding,
    FitResult,
    Gain,
    LinearFit,
    PosteriorResult,
    StudyResult,
    TestResult,
    WheelDiscovery,
    WheelPrediction,
    WheelValidation,
)


@pytest.mark.parametrize("cls", RESULTS, ids=lambda c: c.__name__)
def test_every_result_type_has_summary_and_to_dict(cls):
    assert callable(getattr(cls, "summary", None)) and callable(getattr(cls, "to_dict", None))


#: Old names of docs/conventions.md's "Renamed" table, by new name: no result holds a field
#: of an old name (each lives on only as a property that warns, until 0.3.0).
RENAMED = {"seconds": "runtime_s", "problems": "flags"}


@pytest.mark.parametrize("cls", RESULTS, ids=lambda c: c.__name__)
def test_no_result_type_has_a_field_of_a_renamed_name(cls):
    fields = {f.name for f in dataclasses.fields(cls)} if dataclasses.is_dataclass(cls) else set()
    assert not fields & set(RENAMED), {old: RENAMED[old] for old in fields & set(RENAMED)}


def _strict_json(doc) -> dict:
    return json.loads(json.dumps(doc, allow_nan=False))


def test_linear_and_ancova_results_are_strict_json_with_raw_p_values():
    rng = np.random.default_rng(3)
    x = np.column_stack([np.ones(20), np.linspace(0, 1, 20)])
    fit = linear_least_squares(x, x @ [1.0, 2.0] + 0.01 * rng.standard_normal(20))
    doc = _strict_json(fit.to_dict())
    assert doc["params"]["b1"] == pytest.approx(2.0, abs=0.05)
    assert doc["stderr"]["b1"] == pytest.approx(float(fit.stderr["b1"]))
    sigma = np.tile(np.linspace(5.0, 20.0, 6), 3)
    data = pd.DataFrame({"ring": np.repeat(["a", "b", "c"], 6), "sigma": sigma})
    data["tau"] = 2.0 + 0.6 * data["sigma"] + 0.1 * rng.standard_normal(len(data))
    res = ancova(data, "tau", "sigma", "ring")
    doc = _strict_json(res.to_dict())
    assert doc["slope_test"]["p_value"] == pytest.approx(res.slope_test.p_value)
    assert "p_adjusted" not in doc["slope_test"]  # one test: nothing to adjust
