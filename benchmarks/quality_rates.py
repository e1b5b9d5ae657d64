"""Detection and false-flag rates of the screening rules on planted record phases and glitches.

Situations designed for this benchmark, apart from the ones the tests use (other soils,
plate sizes, record lengths, noise levels and depths, other seeds): campaigns are simulated
(``soilstats.simulation.simulate``) with one kind of ``[[artefacts]]`` planted in half of
the tests, and screened with the default rules.

* **detection**: planted events found by the rule's code, starting within one sample of the
  planted start and holding at least half of the planted samples (a step: of those still
  below the force's running maximum, as the rule defines it);
* **false flags**: tests without the planted kind that carry its code, and tests carrying a
  phase, burst or pre-contact code in the clean campaigns;
* **seating toe**: every test of a soil zeroed a given distance above the surface (the
  free travel sampled at the force's noise floor): the share of tests re-zeroed, and the
  share of soils whose tests were all treated alike (all re-zeroed or none).
* **false flags per design cell** (``--cells``): clean campaigns over the simulator's stated
  range — n 0.3-1.8 (60 kPa at 30 mm), plates r 25/50/75 mm, 15/50/300 samples, quiet
  (0.2 N) or noisy (3 N + 2 % + 1 N offset) force, depth 20/50 mm, the record starting
  0.5 mm above the surface or at it — every flag of any code counted, per cell of plate
  size x sample count x noise x n (#46: no cell above 0.5 %).

    python benchmarks/quality_rates.py            # ~1-2 minutes on 2 cores
    python benchmarks/quality_rates.py --seeds 2  # quicker
    python benchmarks/quality_rates.py --cells    # the per-cell false flags only (~1 min)

One run on this machine; the numbers are what it printed, not a unit test.
"""

from __future__ import annotations

import argparse
import itertools

import numpy as np
import pandas as pd
from tqdm import tqdm

from soilstats.campaign import Campaign
from soilstats.campaign.schema import DERIVED_COLUMNS
from soilstats.quality import screen
from soilstats.simulation import simulate

SOILS = {
    "gravel": {"kc": 6.0e3, "kphi": 4.0e5, "n": 0.5},
    "regolith": {"kc": -2.0e4, "kphi": 2.5e6, "n": 0.9},
    "silty-clay": {"kc": 5.0e4, "kphi": 8.0e6, "n": 1.25},
    "snow": {"kc": 1.0e4, "kphi": 3.0e6, "n": 1.6},
}
DESIGNS = [
    {"points": points, "noise": noise, "depth": depth}
    for points, noise, depth in itertools.product((80, 250), (0.1, 0.8), (0.025, 0.05))
]
PLANTED = {
    "release": ("release", {"drop": 0.7, "samples": 25, "backoff": 0.005}),
    "hold": ("hold", {"relaxation": 0.12, "samples": 20, "at": 0.45}),
    "unload-reload": ("unload-reload", {"to": 0.2, "samples": 12, "at": 0.55}),
    "step": ("step", {"drop": 0.2, "recovery": 20, "at": 0.5}),
    "burst (z, 3-5 samples)": ("burst", {"channel": "z_m", "length": [3, 5], "size": 0.25}),
    "burst (force, clustered)": (
        "burst",
        {"channel": "force_N", "length": [2, 3], "cluster": True, "size": 0.3},
    ),
    "glitch cluster (z, 5-60 samples, 3-15x)": ("glitch-cluster", {"channel": "z_m"}),
    "glitch cluster (force, 5-60 samples, 3-15x)": ("glitch-cluster", {"channel": "force_N"}),
}
CLEAN_CODES = (
    "release",
    "hold",
    "unload-reload",
    "step",
    "burst",
    "glitch-cluster",
    "pre-contact",
    "bearing-failure",
)


def spec(design: dict, artefacts: list[dict] | None = None, start_m: float = -5e-4) -> dict:
    out = {
        "name": "rates",
        "scatter": {"stiffness_cv": 0.12, "n_sd": 0.04},
        "noise": {"force_N": design["noise"], "force_offset_N": design["noise"]},
        "soils": SOILS,
        "series": [
            {
                "name": "plates",
                "kind": "sinkage",
                "soils": list(SOILS),
                "plates": [{"shape": "circle", "radius_m": b} for b in (0.035, 0.055, 0.09)],
                "repetitions": 4,
                "points": design["points"],
                "sinkage_m": design["depth"],
                "start_m": start_m,
            }
        ],
    }
    if artefacts:
        out["artefacts"] = artefacts
    return out


def planted_rates(seeds: int) -> pd.DataFrame:
    rows = []
    jobs = [(name, d, s) for name in PLANTED for d in DESIGNS for s in range(seeds)]
    for name, design, seed in tqdm(jobs, desc="planted", unit="campaign"):
        kind, options = PLANTED[name]
        sim = simulate(spec(design, [{"kind": kind, "share": 0.5, **options}]), seed=900 + seed)
        report = screen(sim.campaign)
        codes = ("spike", "burst") if kind == "burst" else (kind,)
        found: dict[str, set] = {}
        for f in report.flags:
            if f.code in codes:
                found.setdefault(f.test_id, set()).update(f.rows)
        force = sim.campaign.sinkage["force_N"]
        test_of = sim.campaign.sinkage["test_id"]
        hits = 0
        for event in sim.artefacts.itertuples():
            planted = {int(r) for r in event.rows.split()}
            if kind == "step":
                before = force[test_of == event.test_id].loc[: event.first_row - 2]
                planted = {r for r in planted if force[r - 1] < 0.99 * before.max()} or planted
            mine = found.get(event.test_id, set())
            hits += (
                bool(mine)
                and min(mine) - event.first_row in (-1, 0, 1)
                and (len(planted & mine) >= 0.5 * len(planted))
            )
        planted_tests = set(sim.artefacts["test_id"])
        false = len(set(found) - planted_tests)
        rows.append(
            {
                "situation": name,
                "points": design["points"],
                "noise_N": design["noise"],
                "events": len(sim.artefacts),
                "found": hits,
                "other_tests": len(report.tests) - len(planted_tests),
                "false_flags": false,
            }
        )
    return pd.DataFrame(rows)


def clean_rates(seeds: int) -> tuple[int, dict]:
    tests, counts = 0, dict.fromkeys(CLEAN_CODES, 0)
    jobs = [(d, s) for d in DESIGNS for s in range(seeds)]
    for design, seed in tqdm(jobs, desc="clean", unit="campaign"):
        report = screen(simulate(spec(design), seed=700 + seed).campaign)
        tests += len(report.tests)
        for code in CLEAN_CODES:
            counts[code] += len({f.test_id for f in report.flags if f.code == code})
    return tests, counts


def toe_rates(seeds: int) -> pd.DataFrame:
    """Every test zeroed ``toe`` above the surface: the recorded z is the true z + toe, and
    the record starts 0.5 mm above the (recorded) zero, so the toe is sampled."""
    rows = []
    jobs = [(toe, d, s) for toe in (1e-3, 2e-3) for d in DESIGNS for s in range(seeds)]
    for toe, design, seed in tqdm(jobs, desc="seating toe", unit="campaign"):
        sim = simulate(spec(design, start_m=-5e-4 - toe), seed=500 + seed)
        tests = sim.campaign.tests.drop(columns=list(DERIVED_COLUMNS["tests"]), errors="ignore")
        sink = sim.campaign.sinkage.drop(
            columns=list(DERIVED_COLUMNS["sinkage"]), errors="ignore"
        ).reset_index(drop=True)
        sink["z_m"] = sink["z_m"] + toe
        report = screen(Campaign.from_frames(tests, sink))
        seated = {f.test_id for f in report.flags if f.code == "pre-contact"}
        soil_of = dict(zip(tests["test_id"], tests["soil"], strict=True))
        alike = [len({t in seated for t, s in soil_of.items() if s == soil}) == 1 for soil in SOILS]
        travel = design["depth"]
        rows.append(
            {
                "toe_mm": toe * 1e3,
                "toe_share": toe / (travel + toe),
                "points": design["points"],
                "noise_N": design["noise"],
                "tests": len(tests),
                "rezeroed": len(seated),
                "soils_alike": int(np.sum(alike)),
                "soils": len(SOILS),
            }
        )
    return pd.DataFrame(rows)


CELL_NS = (0.3, 0.6, 1.0, 1.4, 1.8)
CELL_NOISE = {
    "quiet": {"force_N": 0.2, "force_offset_N": 0.3},
    "noisy": {"force_N": 3.0, "force_rel": 0.02, "force_offset_N": 1.0},
}


def cell_spec(points: int, noise: str, depth: float, start_m: float, repetitions: int) -> dict:
    """One clean campaign holding every n x plate cell of one sample count and noise."""
    return {
        "name": "cells",
        "scatter": {"stiffness_cv": 0.12, "n_sd": 0.04},
        "noise": CELL_NOISE[noise],
        "soils": {f"n{n}": {"kc": 0.0, "kphi": 6.0e4 / 0.03**n, "n": n} for n in CELL_NS},
        "series": [
            {
                "name": "cells",
                "kind": "sinkage",
                "soils": [f"n{n}" for n in CELL_NS],
                "plates": [{"shape": "circle", "radius_m": r} for r in (0.025, 0.05, 0.075)],
                "repetitions": repetitions,
                "points": points,
                "sinkage_m": depth,
                "start_m": start_m,
            }
        ],
    }


def cell_rates(seeds: int, repetitions: int = 25) -> pd.DataFrame:
    """Every clean test's flags, one row per test, with its design cell."""
    rows = []
    jobs = list(itertools.product((15, 50, 300), CELL_NOISE, range(seeds)))
    for points, noise, seed in tqdm(jobs, desc="clean cells", unit="campaign"):
        depth = (0.02, 0.05)[seed % 2]
        start = (-5e-4, 0.0)[(seed // 2) % 2]
        sim = simulate(cell_spec(points, noise, depth, start, repetitions), seed=3000 + seed)
        codes: dict[str, set] = {}
        for f in screen(sim.campaign).flags:
            codes.setdefault(f.test_id, set()).add(f.code)
        for t in sim.campaign.tests.itertuples():
            rows.append(
                {
                    "points": points,
                    "noise": noise,
                    "n": t.soil,
                    "r_mm": round(t.radius_m * 1e3),
                    "codes": ",".join(sorted(codes.get(t.test_id, ()))),
                }
            )
    out = pd.DataFrame(rows)
    out["flagged"] = out["codes"] != ""
    return out


def print_cells(seeds: int) -> None:
    cells = cell_rates(seeds)
    per = cells.groupby(["r_mm", "points", "noise", "n"])["flagged"].agg(["size", "sum"])
    per["rate"] = per["sum"] / per["size"]
    print(
        f"\nClean designs: {len(cells)} tests in {len(per)} cells "
        f"({int(per['size'].min())}-{int(per['size'].max())} tests each); "
        f"flagged {int(cells['flagged'].sum())}; worst cell {per['rate'].max():.2%}"
    )
    if cells["flagged"].any():
        print(cells.loc[cells["flagged"], "codes"].value_counts().to_string())
        print(per[per["sum"] > 0].to_string())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3, help="campaigns per design (3)")
    parser.add_argument(
        "--smoke",
        action="store_true",
        help="tiny sizes, seconds: that it runs (tests/test_benchmarks.py)",
    )
    parser.add_argument("--cells", action="store_true", help="only the per-cell false flags")
    parser.add_argument("--cell-seeds", type=int, default=8, help="campaigns per cell design (8)")
    args = parser.parse_args()
    if args.smoke:
        # that every path runs, not the rates: the two extreme designs stand for the grid
        args.seeds, args.cell_seeds = 1, 1
        DESIGNS[:] = [DESIGNS[0], DESIGNS[-1]]
    if args.cells:
        print_cells(args.cell_seeds)
        return
    planted = planted_rates(args.seeds)
    table = planted.groupby("situation", sort=False)[
        ["events", "found", "other_tests", "false_flags"]
    ].sum()
    table["detection"] = (table["found"] / table["events"]).map("{:.1%}".format)
    table["false-flag rate"] = (table["false_flags"] / table["other_tests"]).map("{:.2%}".format)
    print(
        "\nPlanted phases and glitches (half the tests of each campaign; "
        f"{len(DESIGNS)} designs x {args.seeds} seeds):"
    )
    print(table.to_string())
    by_noise = planted.groupby(["situation", "noise_N"], sort=False)[["events", "found"]].sum()
    by_noise["detection"] = (by_noise["found"] / by_noise["events"]).map("{:.1%}".format)
    print("\nDetection by force noise:")
    print(by_noise["detection"].unstack().to_string())
    tests, counts = clean_rates(args.seeds)
    print(f"\nClean campaigns: {tests} tests; tests flagged per code:")
    for code, n in counts.items():
        print(f"  {code:<14} {n:>4}  ({n / tests:.3%})")
    toe = toe_rates(args.seeds)
    summary = toe.groupby("toe_mm")[["tests", "rezeroed", "soils_alike", "soils"]].sum()
    summary["re-zeroed"] = (summary["rezeroed"] / summary["tests"]).map("{:.1%}".format)
    summary["soils all alike"] = (summary["soils_alike"] / summary["soils"]).map("{:.1%}".format)
    print("\nSeating toe in every test of a soil (depth 25/50 mm):")
    print(summary[["tests", "re-zeroed", "soils all alike"]].to_string())
    print_cells(args.cell_seeds)


if __name__ == "__main__":
    main()
