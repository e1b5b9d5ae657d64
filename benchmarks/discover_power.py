"""Power, kept extensions, combined models and false findings of ``soilstats discover``.

The situations below are designed here, apart from those of the tests
(``tests/discover_situations.py``): another soil (a loam: kc = 2e4, kφ = 1.2e6, n = 0.9), other
plates (30 and 60 mm, or 30, 45 and 60 mm), other effect sizes and designs, seeds 100 onwards.
Each is simulated with SEEDS seeds and discovered; per situation the table gives how often

* **detected** — the planted cause(s) named (Holm-controlled, α = 0.05);
* **kept** — each planted cause's extension kept (a real held-out gain with the cause fixed)
  and positive;
* **combined** — the combined model (forward selection) carries every planted cause, its
  gain is real, and, with two causes, exceeds each cause's gain alone;

and, for the null situation, how often anything was named or kept (all false).

    python benchmarks/discover_power.py [SEEDS] [--verbose]       # the table of docs/discover.md
    python benchmarks/discover_power.py --tests [SEEDS]           # the tests' situations
    python benchmarks/discover_power.py --null N [--verbose]      # null rate, seeds 0..N-1
    python benchmarks/discover_power.py --interaction [SEEDS]     # one-cell test vs omnibus F

``--tests`` runs the situations of ``tests/discover_situations.py`` (the slow
``test_situations_over_many_seeds`` and ``test_issue35_criteria``) from seed 0; ``--null``
the null campaigns of the tests (``NULL``: velocity, operator, bin, moisture and grouser
height crossed) on two processes; ``--interaction`` discovers the one-cell situation with
the interaction tested by its largest one-cell contrast (the default) and by the omnibus F
(every cell at once, as until issue #35), on the same campaigns.
"""

from __future__ import annotations

import functools
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from multiprocessing import Pool
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from discover_situations import iso_times, raw_frames, seated_late

from soilstats.campaign import Campaign
from soilstats.discovery import discover
from soilstats.simulation import simulate

#: A loam, stiffer and softer-curved than the tests' sand; its test-to-test scatter.
LOAM = {"kc": 2.0e4, "kphi": 1.2e6, "n": 0.9, "c": 1500.0, "phi": 26.0, "K": 0.015}
SCATTER = {"stiffness_cv": 0.07, "n_sd": 0.02, "c_cv": 0.05, "phi_sd_deg": 0.3, "K_cv": 0.05}
TWO = [{"shape": "circle", "radius_m": 0.03}, {"shape": "circle", "radius_m": 0.06}]
THREE = [{"shape": "circle", "radius_m": r} for r in (0.03, 0.045, 0.06)]
FIRST_SEED = 100


def _series(name="s", plates=TWO, **kw) -> dict:
    return {
        "name": name,
        "kind": "sinkage",
        "soils": ["loam"],
        "plates": plates,
        "points": 50,
        **kw,
    }


def _spec(series, effects=(), preparations=None) -> dict:
    out = {"name": "bench", "scatter": SCATTER, "soils": {"loam": dict(LOAM)}}
    out.update(series=list(series), effects=list(effects))
    if preparations:
        out["preparations"] = preparations
    return out


def _stiffer(column, level, factor, **kw) -> dict:
    out = {"kind": "covariate", "column": column, "parameters": ["kc", "kphi"]}
    return {**out, "levels": {level: factor}, **kw}


#: One tray of three 16 % stiffer; 36 tests (2 plates × 3 trays × 6).
ONE_LEVEL = _spec(
    [_series(covariates={"tray": ["t1", "t2", "t3"]}, repetitions=6)],
    [_stiffer("tray", "t3", 1.16)],
)
#: Two causes: one bin of three 16 % stiffer, operator Q 12 % stiffer; 72 tests.
TWO_CAUSES = _spec(
    [_series(operators=["P", "Q"], covariates={"bin": ["b1", "b2", "b3"]}, repetitions=12)],
    [_stiffer("bin", "b2", 1.16), _stiffer("operator", "Q", 1.12)],
)
#: Stiffening 2.5 %/h over a 12-hour day, 36 tests (3 plates × 12 hours), logged_at.
DAY = _spec(
    [_series(plates=THREE, covariates={"hour": list(range(12))})],
    [{"kind": "covariate", "column": "hour", "parameters": ["kc", "kphi"], "slope": 0.025}],
)
#: Method m3 with operator Z 25 % stiffer: one cell of nine, 54 tests (3 × 3 × 6).
CELL = _spec(
    [
        _series(name=m, preparations=[m], operators=["X", "Y", "Z"], repetitions=9)
        for m in ("m1", "m2", "m3")
    ],
    [_stiffer("operator", "Z", 1.25, series=["m3"])],
    preparations={"m1": {}, "m2": {}, "m3": {}},
)
#: The 60 mm plate's ten tests stiffen 6 % per test in run order, the others do not.
BLOCK = _spec(
    [_series(name=f"r{i}", plates=[p], repetitions=10) for i, p in enumerate(THREE)],
    [
        {
            "kind": "covariate",
            "column": "repetition",
            "parameters": ["kc", "kphi"],
            "slope": 0.06,
            "reference": 5.5,
            "series": ["r2"],
        }
    ],
)
#: Nothing planted: trays, operators and two velocities crossed, 48 tests.
NULL = _spec(
    [
        _series(
            operators=["P", "Q"],
            velocity_m_s=[1e-3, 5e-3],
            covariates={"tray": ["t1", "t2", "t3"]},
            repetitions=2,
        )
    ]
)


def day_campaign(seed: int) -> Campaign:
    """:data:`DAY` logged as ISO times (``logged_at``), three tests seated 2 mm late."""
    tests, sinkage = raw_frames(simulate(DAY, seed=seed).campaign)
    rng = np.random.default_rng(seed + 7)
    tests["logged_at"] = iso_times(tests["hour"], "2026-09-14T07:30", rng, minutes=50)
    late = set(rng.choice(tests["test_id"].to_numpy(), 3, replace=False))
    parts = [
        seated_late(tid, g, 2e-3, rng) if tid in late else g
        for tid, g in sinkage.groupby("test_id", sort=False)
    ]
    return Campaign.from_frames(tests.drop(columns=["hour"]), pd.concat(parts, ignore_index=True))


def _named(result, cause) -> bool:
    return any(f.cause == cause or f.cause.startswith(cause) for f in result.findings)


def _kept(result, cause) -> bool:
    return any(
        (f.cause == cause or f.cause.startswith(cause))
        and f.extension is not None
        and f.gain.relative > 0
        for f in result.findings
    )


def _combined(result, causes) -> bool:
    for m in result.models:
        carried = all(any(c == x or c.startswith(x) for c in m.causes) for x in causes)
        if carried and m.gain is not None and m.gain.real:
            alone = [f.gain.relative for f in result.findings if f.gain is not None]
            return len(causes) < 2 or all(m.gain.relative > g for g in alone)
    return False


@dataclass(frozen=True)
class Situation:
    name: str
    build: Callable[[int], Campaign]
    causes: tuple[str, ...]  # empty: nothing planted


SITUATIONS = [
    Situation(
        "one tray of three +16 %, 36 tests",
        lambda s: simulate(ONE_LEVEL, seed=s).campaign,
        ("tray",),
    ),
    Situation(
        "bin +16 % and operator +12 %, 72 tests",
        lambda s: simulate(TWO_CAUSES, seed=s).campaign,
        ("bin", "operator"),
    ),
    Situation("drift 2.5 %/h, ISO times, 3 of 36 flagged", day_campaign, ("logged_at",)),
    Situation(
        "one cell of nine +25 % (method × operator), 54 tests",
        lambda s: simulate(CELL, seed=s).campaign,
        ("preparation × operator",),
    ),
    Situation(
        "drift 6 %/test inside one plate block, 30 tests",
        lambda s: simulate(BLOCK, seed=s).campaign,
        ("repetition within",),
    ),
    Situation("nothing planted, 48 tests", lambda s: simulate(NULL, seed=s).campaign, ()),
]


def _judge(args) -> tuple:
    index, seed = args
    situation = SITUATIONS[index]
    result = discover(situation.build(seed), seed=0)
    causes = situation.causes
    if not causes:
        named = bool(result.findings)
        kept = any(f.extension for f in result.findings) or any(m.extensions for m in result.models)
        return index, seed, named, kept, kept, _what(result)
    return (
        index,
        seed,
        all(_named(result, c) for c in causes),
        all(_kept(result, c) for c in causes),
        _combined(result, causes),
        _what(result),
    )


def _what(result) -> str:
    named = [
        (f.cause, f.extension, round(f.gain.relative, 3) if f.gain else None)
        for f in result.findings
    ]
    residues = [a["candidate"] for a in result.artefacts]
    return f"named {named}; model {result.model()['extensions']}; artefacts {residues}"


def independent(seeds: int, verbose: bool) -> None:
    start = time.perf_counter()
    jobs = [(i, FIRST_SEED + s) for i in range(len(SITUATIONS)) for s in range(seeds)]
    with Pool(2) as pool:
        rows = pool.map(_judge, jobs, chunksize=2)
    print(f"seeds {FIRST_SEED}-{FIRST_SEED + seeds - 1}, {time.perf_counter() - start:.0f} s")
    print(f"{'situation':<52} {'detected':>9} {'kept':>9} {'combined':>9}")
    for i, situation in enumerate(SITUATIONS):
        mine = [r for r in rows if r[0] == i]
        counts = [sum(r[k] for r in mine) for k in (2, 3, 4)]
        if situation.causes:
            cells = [f"{c}/{len(mine)}" for c in counts]
        else:  # null: anything named or kept is false
            cells = [f"{counts[0]}/{len(mine)} false", f"{counts[1]}/{len(mine)} false", ""]
        print(f"{situation.name:<52} {cells[0]:>9} {cells[1]:>9} {cells[2]:>9}")
        if verbose:
            for r in mine:
                missed = not all(r[2:5]) if situation.causes else r[2]
                if missed:
                    print(f"    seed {r[1]}: {r[5]}")


def _tests_one(args) -> tuple:
    from discover_situations import CRITERIA
    from discover_situations import SITUATIONS as TEST_SITUATIONS

    kind, name, seed = args
    if kind == "situation":
        situation = TEST_SITUATIONS[name]
        return kind, name, bool(situation.judge(discover(situation.build(seed), seed=0)))
    build, judge, _ = CRITERIA[name]
    return kind, name, bool(judge(discover(build(seed), seed=0)))


def tests_situations(seeds: int) -> None:
    from discover_situations import CRITERIA
    from discover_situations import SITUATIONS as TEST_SITUATIONS

    jobs = [("situation", n, s) for n in TEST_SITUATIONS for s in range(seeds)]
    jobs += [("criterion", n, s) for n in CRITERIA for s in range(seeds)]
    with Pool(2) as pool:
        rows = pool.map(_tests_one, jobs, chunksize=2)
    for kind, names in (("situation", TEST_SITUATIONS), ("criterion", CRITERIA)):
        for name in names:
            good = sum(r[2] for r in rows if r[:2] == (kind, name))
            print(f"{name:<62} {good}/{seeds}")


def _null(seed: int) -> list[str]:
    from discover_situations import NULL as TEST_NULL

    result = discover(simulate(TEST_NULL, seed=seed).campaign, seed=0)
    return [
        f"{f.kind} / {f.cause} (Holm p = {f.p_adjusted:.3g}; kept: {f.extension})"
        for f in result.findings
    ]


def null_rate(seeds: int, verbose: bool) -> None:
    start = time.perf_counter()
    with Pool(2) as pool:
        named = pool.map(_null, range(seeds), chunksize=4)
    false = [(seed, n) for seed, n in enumerate(named) if n]
    kept = [(seed, n) for seed, n in false if any("kept: None" not in x for x in n)]
    print(
        f"null campaigns, seeds 0-{seeds - 1}: {len(false)} of {seeds} gave a finding "
        f"({100 * len(false) / seeds:.1f} %), {len(kept)} kept an extension "
        f"({100 * len(kept) / seeds:.1f} %), {(time.perf_counter() - start):.0f} s"
    )
    if verbose:
        for seed, n in false:
            print(f"    seed {seed}: {'; '.join(n)}")


def _interaction_one(args) -> tuple:
    from discover_situations import ONE_CELL

    import soilstats.discovery.diagnose as diagnose
    from soilstats.discovery.ftests import interaction_test

    design, test, seed = args
    diagnose.interaction_test = functools.partial(interaction_test, test=test)
    spec = CELL if design == "bench" else ONE_CELL
    result = discover(simulate(spec, seed=seed).campaign, seed=0)
    return design, test, _named(result, "preparation × operator")


def interaction_power(seeds: int) -> None:
    """The one-cell situation of this benchmark (3 × 3, +25 %, seeds 100+) and of the tests
    (2 × 3, +18 %, issue #35's, seeds 0+), each discovered with the interaction tested by
    its largest one-cell contrast and by the omnibus F, on the same campaigns."""
    designs = {
        "bench": ("one cell of nine +25 % (3 × 3 × 6)", FIRST_SEED),
        "tests": ("one cell of six +18 % (2 × 3 × 9)", 0),
    }
    jobs = [
        (d, t, first + s)
        for d, (_, first) in designs.items()
        for t in ("cell", "omnibus")
        for s in range(seeds)
    ]
    with Pool(2) as pool:
        rows = pool.map(_interaction_one, jobs, chunksize=2)
    for design, (label, first) in designs.items():
        for test in ("cell", "omnibus"):
            found = sum(r[2] for r in rows if r[:2] == (design, test))
            print(
                f"{label}, seeds {first}-{first + seeds - 1}, tested by {test:<8}: "
                f"interaction named {found}/{seeds}"
            )


def main() -> None:
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    verbose = "--verbose" in sys.argv
    if "--smoke" in sys.argv:  # one seed of each situation: that it runs (tests, CI)
        independent(1, verbose)
    elif "--null" in sys.argv:
        null_rate(int(args[0]) if args else 200, verbose)
    elif "--tests" in sys.argv:
        tests_situations(int(args[0]) if args else 20)
    elif "--interaction" in sys.argv:
        interaction_power(int(args[0]) if args else 40)
    else:
        independent(int(args[0]) if args else 20, verbose)


if __name__ == "__main__":
    main()
