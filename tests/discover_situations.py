"""Situations of real Bevameter campaigns planted in simulated ones, for discovery (issue #13).

Each situation builds a campaign from a seed and judges a :class:`DiscoveryResult`: for a
planted effect, whether it was found as it should be (power); for an artefact or an outcome,
whether anything was named (false findings).  Used by ``tests/test_discover.py`` (the fast
single-seed checks and the slow many-seed one) and by ``benchmarks/discover_power.py``
(the table in docs/discover.md).  Truth comes from the simulator's spec, never from the
code under test.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pandas as pd

from soilstats.campaign import Campaign
from soilstats.campaign.schema import DERIVED_COLUMNS
from soilstats.simulation import simulate

SOIL = {"kc": 7.0e3, "kphi": 5.0e5, "n": 1.2, "c": 800.0, "phi": 30.0, "K": 0.01}
SCATTER = {"stiffness_cv": 0.06, "n_sd": 0.015, "c_cv": 0.04, "phi_sd_deg": 0.2, "K_cv": 0.05}
PLATES = [{"shape": "circle", "radius_m": 0.025}, {"shape": "circle", "radius_m": 0.05}]


def sink(**kw) -> dict:
    """A sinkage series of the situations: two circular plates, four repetitions."""
    s = {"name": "s", "kind": "sinkage", "soils": ["s"], "plates": PLATES, "points": 60}
    return {**s, "repetitions": 4, **kw}


def shear(**kw) -> dict:
    """A shear series: one ring, three normal pressures, two repetitions."""
    s = {"name": "r", "kind": "shear", "soils": ["s"], "points": 60, "repetitions": 2}
    ring = [{"r_inner_m": 0.1, "r_outer_m": 0.15}]
    s.update(rings=ring, grouser_height_m=[0.0], normal_pressure_Pa=[3e3, 8e3, 14e3])
    return {**s, **kw}


def spec(series, effects=(), preparations=None) -> dict:
    out = {"name": "t", "scatter": SCATTER, "soils": {"s": dict(SOIL)}}
    out.update(series=list(series), effects=list(effects))
    if preparations:
        out["preparations"] = preparations
    return out


#: Nothing planted: velocity, operator, bin (sinkage), moisture, grouser height (shear)
#: crossed — any finding is false (the null campaigns of tests/test_discover.py).
NULL = spec(
    [
        sink(
            velocity_m_s=[4.8e-4, 4.8e-3],
            operators=["A", "B"],
            covariates={"bin": ["n", "s"]},
            repetitions=2,
        ),
        shear(covariates={"moisture_pct": [1.0, 3.0]}, grouser_height_m=[0.0, 0.005]),
    ]
)
#: An operator who leaves the soil 50 % stiffer only with preparation p1 (an interaction).
INTERACTION = spec(
    [
        sink(name="p1", preparations=["p1"], operators=["A", "B"], repetitions=8),
        sink(name="p2", preparations=["p2"], operators=["A", "B"], repetitions=8),
    ],
    [
        {
            "kind": "covariate",
            "column": "operator",
            "parameters": ["kc", "kphi"],
            "levels": {"B": 1.5},
            "series": ["p1"],
        }
    ],
    preparations={"p1": {}, "p2": {}},
)
#: Two causes at once in one soil: velocity stiffening and a stiffer bin.
TWO_CAUSES = spec(
    [
        sink(
            velocity_m_s=[4.8e-4, 2.4e-3, 4.8e-3],
            covariates={"bin": ["north", "south"]},
            repetitions=4,
        )
    ],
    [
        {"kind": "velocity", "exponent": -0.12, "reference_m_s": 4.8e-3},
        {
            "kind": "covariate",
            "column": "bin",
            "parameters": ["kc", "kphi"],
            "levels": {"south": 1.2},
        },
    ],
)
#: The compaction method (designed) stiffens the soil; each method ran on its own day.
CONFOUNDED = spec(
    [
        sink(name="a", preparations=["loose"], repetitions=6, covariates={"session": ["mon"]}),
        sink(name="b", preparations=["dense"], repetitions=6, covariates={"session": ["tue"]}),
    ],
    [
        {
            "kind": "covariate",
            "column": "preparation",
            "parameters": ["kc", "kphi"],
            "levels": {"dense": 1.3},
        }
    ],
    preparations={"loose": {}, "dense": {}},
)
#: The soil stiffens 6 % per hour over the test day (logged as ISO start times).
DRIFT = spec(
    [sink(covariates={"hours": list(range(8))}, repetitions=2)],
    [{"kind": "covariate", "column": "hours", "parameters": ["kc", "kphi"], "slope": 0.06}],
)
#: Nothing planted; two operators (artefacts are planted in their tests).
PLAIN = spec([sink(operators=["A", "B"], repetitions=6, points=120)])
#: Nothing planted; large preparation scatter, so that load-terminated depths vary a lot.
SCATTERED = {**spec([sink(repetitions=8)]), "scatter": {**SCATTER, "stiffness_cv": 0.2}}


def raw_frames(campaign: Campaign) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The campaign's test log and sinkage records as a lab would hand them in."""
    tests = campaign.tests.drop(columns=list(DERIVED_COLUMNS["tests"]), errors="ignore")
    sinkage = campaign.sinkage.drop(columns=list(DERIVED_COLUMNS["sinkage"]), errors="ignore")
    return tests, sinkage.reset_index(drop=True)


def iso_times(hours, start: str, rng, minutes: int) -> list[str]:
    """ISO times ``start`` + each of ``hours`` + up to ``minutes`` minutes at random."""
    at = pd.Timestamp(start)
    late = rng.integers(0, minutes, len(hours))
    return [
        (at + pd.Timedelta(hours=float(h), minutes=int(m))).isoformat()
        for h, m in zip(hours, late, strict=True)
    ]


def drift_campaign(seed: int) -> Campaign:
    """:data:`DRIFT` with the hour replaced by an ISO start time (minutes at random)."""
    tests, sinkage = raw_frames(simulate(DRIFT, seed=seed).campaign)
    rng = np.random.default_rng(seed)
    tests["start_time"] = iso_times(tests["hours"], "2026-05-04T08:00", rng, minutes=50)
    return Campaign.from_frames(tests.drop(columns=["hours"]), sinkage)


def seated_late(tid: str, record: pd.DataFrame, offset: float, rng) -> pd.DataFrame:
    """A sinkage record whose plate touched the soil ``offset`` m late: twelve samples of
    free travel at zero force (noise 0.2 N), then the record shifted by the offset."""
    free = pd.DataFrame(
        {
            "test_id": tid,
            "z_m": np.linspace(0.0, offset, 12, endpoint=False),
            "force_N": rng.normal(0.0, 0.2, 12),
        }
    )
    moved = record.assign(z_m=record["z_m"].clip(lower=0.0) + offset)
    return pd.concat([free, moved[moved["z_m"] > offset]])


def artefact_campaign(seed: int) -> Campaign:
    """:data:`PLAIN` with a one-sample spike (10× the sinkage) in every test of operator A and
    a 1.5 mm seating offset in every test of operator B: fitted raw, the artefacts would line
    up with the operator column."""
    tests, sinkage = raw_frames(simulate(PLAIN, seed=seed).campaign)
    rng = np.random.default_rng(seed)
    offset, parts = 1.5e-3, []
    spiky = set(tests.loc[tests["operator"] == "A", "test_id"])
    for tid, group in sinkage.groupby("test_id", sort=False):
        group = group.copy()
        if tid in spiky:
            row = int(rng.integers(20, len(group) - 20))
            group.iloc[row, group.columns.get_loc("z_m")] *= 10.0
        else:
            group = seated_late(tid, group, offset, rng)
        parts.append(group)
    return Campaign.from_frames(tests, pd.concat(parts, ignore_index=True))


def load_terminated_campaign(seed: int) -> Campaign:
    """:data:`SCATTERED` with every test stopped at 60 N, as real rigs stop: softer
    preparations run deeper, so the depth reached is the test's own stiffness."""
    tests, sinkage = raw_frames(simulate(SCATTERED, seed=seed).campaign)
    return Campaign.from_frames(tests, sinkage[sinkage["force_N"] <= 60.0])


# ------------------------------------------------------------------------------ issue #35
#: Three plates (25, 37.5, 50 mm) of the issue's campaigns.
PLATES3 = [{"shape": "circle", "radius_m": r} for r in (0.025, 0.0375, 0.05)]


def _stiffer(column: str, level: str, factor: float) -> dict:
    return {
        "kind": "covariate",
        "column": column,
        "parameters": ["kc", "kphi"],
        "levels": {level: factor},
    }


#: One level effect: bin b 14 % stiffer, 30 tests (3 plates × 2 bins × 5).
SINGLE_LEVEL = spec(
    [sink(plates=PLATES3, covariates={"bin": ["a", "b"]}, repetitions=5)],
    [_stiffer("bin", "b", 1.14)],
)
#: Two causes of +12 % (operator B) and +15 % (bin s), 64 tests (2 plates × 2 × 2 × 8).
TWO_LEVELS = {
    **spec(
        [sink(operators=["A", "B"], covariates={"bin": ["n", "s"]}, repetitions=16)],
        [_stiffer("operator", "B", 1.12), _stiffer("bin", "s", 1.15)],
    ),
    "scatter": {**SCATTER, "stiffness_cv": 0.08},
}
#: The soil stiffens 3 % per hour over a day of 30 tests (3 plates × 10 hours).
DRIFT_DAY = spec(
    [sink(plates=PLATES3, covariates={"hours": list(range(10))}, repetitions=1)],
    [{"kind": "covariate", "column": "hours", "parameters": ["kc", "kphi"], "slope": 0.03}],
)
#: Operator C with preparation p2 leaves the soil 18 % stiffer: one cell of six, 54 tests
#: (3 operators × 2 preparations × 3 plates × 3 repetitions).
ONE_CELL = spec(
    [
        sink(
            name=p,
            plates=PLATES3,
            preparations=[p],
            operators=["A", "B", "C"],
            repetitions=9,
        )
        for p in ("p1", "p2")
    ],
    [{**_stiffer("operator", "C", 1.18), "series": ["p2"]}],
    preparations={"p1": {}, "p2": {}},
)


#: Three plates, each its own series of eight tests in run order; the soil under the
#: middle plate stiffens 5 % per test (a drift inside one plate block), the others do not.
BLOCK_DRIFT = spec(
    [
        sink(name=name, plates=[plate], repetitions=8)
        for name, plate in zip(("small", "mid", "large"), PLATES3, strict=True)
    ],
    [
        {
            "kind": "covariate",
            "column": "repetition",
            "parameters": ["kc", "kphi"],
            "slope": 0.05,
            "reference": 4.5,
            "series": ["mid"],
        }
    ],
)


def flagged_drift_campaign(seed: int, flagged: int = 2) -> Campaign:
    """:data:`DRIFT_DAY` with ISO start times (``started_at``, minutes at random) and a
    1.5 mm seating offset in ``flagged`` tests at random: screening flags them pre-contact
    and re-zeroes them, so the flags are on tests that carry no trend of their own."""
    tests, sinkage = raw_frames(simulate(DRIFT_DAY, seed=seed).campaign)
    rng = np.random.default_rng(seed)
    tests["started_at"] = iso_times(tests["hours"], "2026-06-01T08:00", rng, minutes=55)
    bad = set(rng.choice(tests["test_id"].to_numpy(), flagged, replace=False))
    parts = [
        seated_late(tid, g, 1.5e-3, rng) if tid in bad else g
        for tid, g in sinkage.groupby("test_id", sort=False)
    ]
    return Campaign.from_frames(tests.drop(columns=["hours"]), pd.concat(parts, ignore_index=True))


def one_cell_campaign(seed: int) -> Campaign:
    """:data:`ONE_CELL`, with the operators assigned in turn by repetition."""
    return simulate(ONE_CELL, seed=seed).campaign


def kept(result, cause: str) -> bool:
    """Whether ``cause`` is named with a kept extension and a positive held-out gain."""
    return any(
        f.cause == cause and f.extension is not None and f.gain.relative > 0
        for f in result.findings
    )


def combined_beats_each(result, causes) -> bool:
    """Whether one combined model carries an extension of every cause in ``causes`` and its
    held-out gain exceeds that of each cause's extension alone."""
    for m in result.models:
        if set(causes) <= set(m.causes) and m.gain is not None:
            alone = [f.gain.relative for f in result.findings if f.gain is not None]
            return m.gain.kept and all(m.gain.relative > g for g in alone)
    return False


@dataclass(frozen=True)
class Situation:
    """A campaign builder and the judgement of a discovery on it."""

    name: str
    build: Callable[[int], Campaign]
    judge: Callable  # DiscoveryResult -> bool
    planted: bool  # True: judge() is a success (power); False: any finding is false


def _names(result) -> set[str]:
    return {f.cause for f in result.findings}


SITUATIONS = {
    s.name: s
    for s in (
        Situation(
            "interaction (operator x preparation)",
            lambda seed: simulate(INTERACTION, seed=seed).campaign,
            lambda r: (
                "preparation × operator" in _names(r)
                and "preparation × operator" in " ".join(r.model()["causes"])
            ),
            True,
        ),
        Situation(
            "two causes (velocity, bin)",
            lambda seed: simulate(TWO_CAUSES, seed=seed).campaign,
            lambda r: (
                {"velocity_m_s", "bin"} <= _names(r)
                and len(r.model()["extensions"]) == 2
                and r.model()["gain"]["kept"]
            ),
            True,
        ),
        Situation(
            "confounded (method with its day)",
            lambda seed: simulate(CONFOUNDED, seed=seed).campaign,
            lambda r: (
                bool(r.findings)
                and r.findings[0].cause == "preparation"
                and "session" in r.findings[0].confounded_with
            ),
            True,
        ),
        Situation(
            "drift over logged time",
            drift_campaign,
            lambda r: (
                "start_time" in _names(r)
                and any(f.extension == "start_time (linear)" for f in r.findings)
            ),
            True,
        ),
        Situation("spikes and seating offsets", artefact_campaign, lambda r: not r.findings, False),
        Situation(
            "load-terminated tests",
            load_terminated_campaign,
            lambda r: not r.findings and "z_max_m" not in set(r.tests["candidate"]),
            False,
        ),
    )
}

#: Issue #35's criteria, each over 20 seeds (the slow test_issue35_criteria): a success
#: count of at least ``minimum`` is required.
CRITERIA = {
    "+14 % level effect in 30 tests, kept with a positive gain": (
        lambda seed: simulate(SINGLE_LEVEL, seed=seed).campaign,
        lambda r: kept(r, "bin"),
        16,
    ),
    "two causes, combined model better than either": (
        lambda seed: simulate(TWO_LEVELS, seed=seed).campaign,
        lambda r: combined_beats_each(r, ("operator", "bin")),
        16,
    ),
    "drift with ISO times, 2 of 30 tests flagged, named": (
        flagged_drift_campaign,
        lambda r: "started_at" in _names(r) and not r.artefacts,
        18,
    ),
    "null campaign, no extension kept": (
        lambda seed: simulate(NULL, seed=seed).campaign,
        lambda r: (
            not any(f.extension for f in r.findings) and not any(m.extensions for m in r.models)
        ),
        19,
    ),
}
