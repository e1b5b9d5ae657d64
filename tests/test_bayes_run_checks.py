"""The posterior run's requests checked in the library before sampling
(soilstats.bayes.run_checks, moved out of cli/posterior.py, issue #45), and how the warnings
of sampling are reported (soilstats.bayes.run_sampling)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from soilstats.bayes.result import ESS_MIN
from soilstats.bayes.run_checks import (
    CONTACT_WIDTH_MAX_M,
    check_draws,
    check_models,
    check_simulator_request,
    contact_widths,
    only_soil,
    prior_seed,
)
from soilstats.bayes.run_checks import (
    tested_widths as plate_widths,
)
from soilstats.bayes.run_sampling import CaughtWarning, in_workers, sampling_warnings
from soilstats.errors import ConvergenceWarning, InputError, ModelError


class _Campaign:
    """The one attribute the checks read: the test log."""

    def __init__(self, tests: pd.DataFrame) -> None:
        self.tests = tests


@pytest.fixture
def two_soils() -> _Campaign:
    return _Campaign(
        pd.DataFrame(
            {
                "soil": ["a", "a", "a", "b", "a"],
                "kind": ["sinkage", "sinkage", "shear", "sinkage", "sinkage"],
                "b_m": [0.05, 0.1, 0.3, 0.9, np.nan],
            }
        )
    )


def test_one_model_or_a_sinkage_and_a_shear_model():
    check_models(["bekker"])
    check_models(["bekker", "janosi"])
    for models in (["bekker", "bernstein"], ["bekker", "janosi", "mohr-coulomb"]):
        with pytest.raises(ModelError, match="one sinkage and one shear model"):
            check_models(models)


def test_draws_below_the_ess_floor_are_refused_unless_forced():
    with pytest.raises(InputError, match=f"below {ESS_MIN}"):
        check_draws(ESS_MIN - 1, ["bekker"])
    check_draws(ESS_MIN - 1, ["bekker"], force=True)  # the user accepted FORCED draws
    check_draws(ESS_MIN, ["bekker"])
    check_draws(None, ["bekker"])
    with pytest.raises(InputError, match=">= 1"):
        check_draws(0, ["bekker"], force=True)
    with pytest.raises(InputError, match="memory"):  # 1e15 draws: no machine holds them
        check_draws(10**15, ["bekker"], force=True)


def test_contact_widths_parsed_or_the_tested_plates(two_soils):
    # The soil's own sinkage plates, its shear ring and the other soil's plate left out.
    assert plate_widths(two_soils, "a") == (0.05, 0.1)
    assert plate_widths(two_soils, "c") is None
    assert contact_widths(None, two_soils, "a") == (0.05, 0.1)
    assert contact_widths(None, two_soils, "c") == (1.0, 1.0)
    assert contact_widths("0.2", two_soils, "a") == (0.2, 0.2)
    assert contact_widths("0.2:0.4", two_soils, "a") == (0.2, 0.4)
    for bad in ("wide", "0.4:0.2", "0:0.1", f"0.1:{CONTACT_WIDTH_MAX_M * 2}", "nan"):
        with pytest.raises(InputError, match="--contact-width"):
            contact_widths(bad, two_soils, "a")


def test_the_soil_is_needed_only_when_there_are_several(two_soils):
    assert only_soil(two_soils, "b") == "b"
    with pytest.raises(InputError, match=r"2 soils \(a, b\)"):
        only_soil(two_soils, None)
    one = _Campaign(two_soils.tests[two_soils.tests["soil"] == "a"])
    assert only_soil(one, None) == "a"


def test_simulator_options_need_a_simulator_and_a_repair_in_range():
    plain = dict(elastic_K=None, damping_R=None, contact=None, seed=0)
    with pytest.raises(InputError, match="--scm-repair repairs"):
        check_simulator_request(None, ["bekker"], {}, **plain | {"repair": 2.0})
    with pytest.raises(InputError, match="--scm-contact checks"):
        check_simulator_request(None, ["bekker"], {}, **plain | {"repair": None, "contact": "1:1"})
    check_simulator_request(None, ["bekker"], {}, **plain | {"repair": None})
    with pytest.raises(InputError, match="c=uniform"):  # no shear model, no user priors
        check_simulator_request("chrono-scm", ["bekker"], {}, **plain | {"repair": None})
    with pytest.raises(ModelError, match="Bekker's law"):
        check_simulator_request("chrono-scm", ["reece", "janosi"], {}, **plain | {"repair": None})
    with pytest.raises(InputError, match=r"multiple in \(1, 1000\]"):
        check_simulator_request("chrono-scm", ["bekker", "janosi"], {}, **plain | {"repair": 1.0})
    check_simulator_request("chrono-scm", ["bekker", "janosi"], {}, **plain | {"repair": 2.0})


def test_the_priors_seed_is_a_stream_after_the_models():
    expected = np.random.SeedSequence([3, 2]).generate_state(1, np.uint32)[0]
    assert prior_seed(3, ["bekker", "janosi"]) == expected


def test_numerical_warnings_are_summed_up_and_ours_kept_in_their_words():
    caught = [
        CaughtWarning(RuntimeWarning, "overflow in exp"),
        CaughtWarning(ConvergenceWarning, "R-hat 1.2 for n"),
        CaughtWarning(RuntimeWarning, "invalid value"),
    ]
    said = sampling_warnings(caught)
    assert said[0] == "R-hat 1.2 for n"
    assert len(said) == 2 and said[1].startswith("2 numerical warnings")
    assert sampling_warnings([]) == []


def test_only_the_second_of_two_models_goes_to_a_worker():
    assert in_workers(["bekker", "janosi"], 2)
    assert not in_workers(["bekker", "janosi"], 1)
    assert not in_workers(["bekker"], 4)
