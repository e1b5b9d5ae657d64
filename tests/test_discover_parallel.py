"""Discovery over worker processes: identical results for any number of jobs, each
(kind, soil) on its own fold stream, failed chains not fitted further."""

from __future__ import annotations

import json

import numpy as np
import pytest
from discover_situations import shear, sink, spec

from soilstats.discovery import discover
from soilstats.simulation import simulate

_TWO_KINDS = spec(
    [
        sink(velocity_m_s=[4.8e-4, 2.4e-3, 4.8e-3]),
        shear(grouser_height_m=[0.002, 0.005, 0.01]),
    ],
    [
        {"kind": "velocity", "exponent": -0.12, "reference_m_s": 4.8e-3},
        {"kind": "side-walls", "K0": 0.4},
    ],
)


def _runs(tmp_path, capsys, runs):
    from soilstats.cli.main import main

    folder = simulate(_TWO_KINDS, seed=5).campaign.save(tmp_path / "camp")
    out = {}
    for jobs, fmt in runs:
        args = ["discover", "--data", str(folder), "--progress", "off", "--jobs", str(jobs)]
        assert main(args + ([fmt] if fmt else [])) == 0
        out[jobs, fmt] = capsys.readouterr().out
    return out


def test_jobs_give_identical_results(tmp_path, capsys):
    """The fits of cross-validation and forward selection spread over workers, each group's
    folds drawn in one place: ``--jobs 2`` prints exactly what ``--jobs 1`` prints."""
    out = _runs(tmp_path, capsys, ((1, "--json"), (2, "--json")))
    one, two = (json.loads(out[j, "--json"]) for j in (1, 2))
    assert one["provenance"].pop("command") != two["provenance"].pop("command")
    assert one == two
    assert {f["cause"] for f in one["findings"]} >= {"velocity_m_s", "grouser_height_m"}


@pytest.mark.slow  # three more runs of discover
def test_more_workers_than_cores_and_the_summary_give_identical_results(tmp_path, capsys):
    """More workers than cores (``--jobs 3`` on two: every group's thread sends its waves to
    one pool of three) print the JSON of one job, and the summary is the same too."""
    out = _runs(tmp_path, capsys, ((1, "--json"), (1, None), (2, None), (3, "--json")))
    one, three = (json.loads(out[j, "--json"]) for j in (1, 3))
    one["provenance"].pop("command"), three["provenance"].pop("command")
    assert one == three
    strip = [line for line in out[1, None].splitlines() if "runtime" not in line]
    assert strip == [line for line in out[2, None].splitlines() if "runtime" not in line]


def test_discover_needs_a_seed():
    """The folds are random: an unseeded discovery would not be reproducible."""
    campaign = simulate(_TWO_KINDS, seed=5).campaign
    for seed in (None, -1, 1.5):
        with pytest.raises(ValueError, match="seed"):
            discover(campaign, seed=seed)


def test_a_groups_folds_do_not_depend_on_the_other_groups():
    """Each (kind, soil) draws its folds from its own stream (seed and name): the shear
    finding's cross-validated gain is the same number whether the campaign holds the sinkage
    tests (whose group runs first) or not."""
    campaign = simulate(_TWO_KINDS, seed=5).campaign
    both = discover(campaign, seed=3)
    alone = discover(campaign.select(kind="shear"), seed=3)

    def shear_gain(result):
        (finding,) = [f for f in result.findings if f.kind == "shear"]
        return finding.cause, finding.gain.base, finding.gain.extended, finding.gain.relative

    assert shear_gain(both) == shear_gain(alone)
    other_seed = discover(campaign.select(kind="shear"), seed=4)
    assert shear_gain(other_seed)[1:] != shear_gain(alone)[1:]  # the seed does draw the folds


def test_failed_chain_is_not_fitted_further():
    """A model whose first fit fails is not fitted further in its chain (as the one-at-a-time
    loop stopped at the first failed fold), in this process and over workers (where the
    first task of each chain runs first); the other chains' outcomes are the same."""
    from soilstats.discovery.data import build_groups
    from soilstats.discovery.extensions import SinkageExtension
    from soilstats.discovery.library import base_model
    from soilstats.discovery.work import FitTask, Pool
    from soilstats.errors import IdentifiabilityError

    campaign = simulate(_TWO_KINDS, seed=5).campaign
    (group,) = [g for g in build_groups(campaign)[0] if g.kind == "sinkage"]
    rows = np.unique(group.owner)
    # Round plates only: softening of narrow plates cannot be fitted (IdentifiabilityError).
    soften = SinkageExtension("softening", True, "Fig. 9", soften=True)
    base = base_model(group, rows)
    tasks = [
        FitTask(soften, rows[1:], held_out=rows[:1], chain="soft"),
        FitTask(soften, rows, chain="soft"),
        FitTask(base, rows[1:], held_out=rows[:1], chain="base"),
        FitTask(base, rows, chain="base"),
    ]
    items = [(group, task, True) for task in tasks]  # one probed wave
    serial = Pool(1).execute(items)
    parallel = Pool(2).execute(items)
    for outcomes in (serial, parallel):
        assert isinstance(outcomes[0].error, IdentifiabilityError)
        assert outcomes[1].skipped and outcomes[1].fitted is None
        assert outcomes[2].error is None and outcomes[3].error is None
    assert np.array_equal(serial[2].errors, parallel[2].errors)
    assert np.array_equal(serial[3].fitted.result.values, parallel[3].fitted.result.values)
