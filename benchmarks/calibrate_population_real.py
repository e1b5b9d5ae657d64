"""Population bands on real data: leave-one-test-out coverage and width (issue #36, item 3).

    python benchmarks/calibrate_population_real.py [--draws 4000] [--seed 0] [--json FILE]

The check (docs/posterior.md, "Population bands on real data"), for each group of repeat
tests of one soil on one plate:

1. leave test t out; sample the population model (Bernstein, Eq. 8, one plate size) on the
   others (``sample_population(..., test_id=rest)``, ``--draws`` kept draws, seed
   ``seed·1000 + fold``);
2. draw a NEW test's curve ln p(z) = ln k + n ln z from every new-preparation draw;
3. at 5 sinkages of the held-out test — the 10, 30, 50, 70 and 90 % quantiles of the z of
   the samples its fit uses (``pool_sinkage``: 100 equidistant in z) — ask whether its
   measured ln p (linear interpolation of those samples, sorted by z) lies inside the
   pointwise equal-tailed 90 % band; also whether its own Bernstein curve does ("curve":
   what a power-law draw can reach at all), and the coverage at each of the 5 sinkages.

Coverage = the share of (held-out test, sinkage) points inside (target 80–97 %).  Width =
the band's width in ln p divided by 3.29 × the tests' own scatter: the sd of the measured
ln p over all the group's tests at the same sinkages (tests whose record reaches that
sinkage; at least 3), so that 1 is the 90 % interval of a normal with the tests' own sd
(target ≤ 3).  Both are averaged over the group's points (width: mean band width over mean
3.29·sd).  A band that knew the scatter exactly would have width ratio 1; one learned from
T − 1 tests is wider by about the t quantile √(1 + 1/(T−1))·t_{T−2}/z (1.4× from 5, 2.0×
from 3 tests).

Groups: Cullinan sand preparations 1 (6 tests) and 2 (4); GRC-1 each plate (5 each); CMU
each plate size pooled over its two boxes (6), and each plate × box (3 tests: leaving one
out leaves 2, below the population model's minimum of 3, so those rows are the in-sample
band of all 3 tests — width only, no held-out coverage).  Data are screened as the CLI
screens them (``soilstats.quality.screen``, mode ``clean``).  A few minutes on 2 cores.

Beside each group: what ``sample_population`` on all of its tests says about its own band
(``soilstats.bayes.population.BandCalibration``: Pareto-smoothed importance-weighted
leave-one-out coverage, in-sample width, which criterion fails and why).
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from dataclasses import asdict, dataclass

import numpy as np
from tqdm.auto import tqdm

import soilstats
from soilstats.bayes import sample_population
from soilstats.bayes.population import band_calibration
from soilstats.identification import fit_sinkage, pool_sinkage
from soilstats.quality import screen

#: 90 % of a normal: 2 × 1.645.
NORMAL_90 = 3.29
QUANTILES = (0.1, 0.3, 0.5, 0.7, 0.9)


@dataclass(frozen=True)
class Group:
    campaign: str
    label: str
    selection: dict


GROUPS = (
    Group("cullinan-sand", "Cullinan preparation 1", {"preparation": "1"}),
    Group("cullinan-sand", "Cullinan preparation 2", {"preparation": "2"}),
    Group("grc1-oravec2009", "GRC-1 38 mm plate", {"radius_m": 0.038}),
    Group("grc1-oravec2009", "GRC-1 51 mm plate", {"radius_m": 0.051}),
    Group("grc1-oravec2009", "GRC-1 95 mm plate", {"radius_m": 0.095}),
    *(
        Group("cmu-3d-terramechanics", f"CMU {2000 * r:.0f} mm plate, both boxes", {"radius_m": r})
        for r in (0.03, 0.04, 0.05)
    ),
    *(
        Group(
            "cmu-3d-terramechanics",
            f"CMU {2000 * r:.0f} mm plate, {box} box",
            {"radius_m": r, "box": box},
        )
        for r in (0.03, 0.04, 0.05)
        for box in ("small", "large")
    ),
)


@dataclass
class Row:
    group: str
    tests: int
    folds: int  # held-out tests whose fold ran (0: in-sample width only)
    points: int
    coverage: float  # share of held-out measured points inside the 90 % band (nan: no folds)
    coverage_power_law: float  # the same for the held-out test's own Bernstein curve
    by_depth: list  # coverage at each of QUANTILES (the shallowest first)
    width: float  # band width / (3.29 × the tests' own sd of ln p), mean over points
    sd_ratio: float  # sd of ln p over new-preparation draws / the tests' own sd
    not_converged: int
    failed_folds: list
    seconds: float
    # What sample_population on all the group's tests says itself (BandCalibration):
    own_coverage: float = float("nan")
    own_width: float = float("nan")
    own_failures: tuple = ()
    sentence: str = ""


def _curves(campaign, test_ids) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Each test's screened record (z sorted, ln p), samples with z > 0 and p > 0."""
    out = {}
    for tid in test_ids:
        data = pool_sinkage(campaign, test_id=[tid])  # the samples the fits use
        z, p = data.x["z_m"], data.y
        keep = (z > 0) & (p > 0)
        order = np.argsort(z[keep], kind="stable")
        out[tid] = (z[keep][order], np.log(p[keep][order]))
    return out


def _ln_p_at(curve, z: np.ndarray) -> np.ndarray:
    """Measured ln p at sinkages ``z`` (nan outside the record's range)."""
    zz, lp = curve
    out = np.interp(z, zz, lp)
    return np.where((z >= zz[0]) & (z <= zz[-1]), out, np.nan)


def _own_sd(curves: dict, z: np.ndarray) -> np.ndarray:
    """The tests' own scatter: sd over tests of measured ln p at each of ``z`` (≥ 3 tests)."""
    values = np.array([_ln_p_at(c, z) for c in curves.values()])
    count = np.sum(np.isfinite(values), axis=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        sd = np.nanstd(values, axis=0, ddof=1)
    return np.where(count >= 3, sd, np.nan)


def _band(result, z: np.ndarray):
    """(lower, upper, sd) of ln p of a new test at ``z`` over the new-preparation draws."""
    new = result.draws(allow_unconverged=True)
    k, n = new["k"].to_numpy(), new["n"].to_numpy()
    ok = np.isfinite(k) & np.isfinite(n) & (k > 0)
    ln_p = np.log(k[ok])[:, None] + n[ok][:, None] * np.log(z)[None]
    lo, hi = np.quantile(ln_p, [0.05, 0.95], axis=0)
    return lo, hi, np.std(ln_p, axis=0, ddof=1)


def _sample(campaign, test_ids, draws, seed):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = sample_population(campaign, "bernstein", draws=draws, seed=seed, test_id=test_ids)
    return result, not result.converged or bool(caught and not result.converged)


def check_group(campaign, group: Group, *, draws: int, seed: int, bar) -> Row:
    t0 = time.perf_counter()
    tests = campaign.tests
    mask = tests["kind"] == "sinkage"
    for column, value in group.selection.items():
        mask &= tests[column].astype(str) == str(value)
    test_ids = list(tests.loc[mask, "test_id"].astype(str))
    curves = _curves(campaign, test_ids)
    hits = hits_pl = points = folds = not_converged = 0
    depth_hits, depth_points = np.zeros(len(QUANTILES)), np.zeros(len(QUANTILES))
    band_w, own_w, band_sd, own_sd = [], [], [], []
    failed = []

    def widths(lo, hi, sd, z):
        scatter = _own_sd(curves, z)
        use = np.isfinite(scatter)
        band_w.extend((hi - lo)[use])
        own_w.extend(NORMAL_90 * scatter[use])
        band_sd.extend(sd[use])
        own_sd.extend(scatter[use])

    if len(test_ids) - 1 >= 3:
        for fold, held in enumerate(test_ids):
            rest = [t for t in test_ids if t != held]
            try:
                result, bad = _sample(campaign, rest, draws, seed * 1000 + fold)
            except ValueError as exc:  # too few usable per-test fits left
                failed.append(f"{held}: {exc}")
                bar.update(1)
                continue
            not_converged += bad
            z = np.quantile(curves[held][0], QUANTILES)
            lo, hi, sd = _band(result, z)
            y = _ln_p_at(curves[held], z)
            try:
                k, n = fit_sinkage(campaign, "bernstein", test_id=[held]).params.to_numpy()
                own = np.log(k) + n * np.log(z)
            except Exception:  # a held-out test without its own fit
                own = np.full(z.size, np.nan)
            ok = np.isfinite(y)
            hits += int(np.sum((lo[ok] <= y[ok]) & (y[ok] <= hi[ok])))
            hits_pl += int(np.sum((lo[ok] <= own[ok]) & (own[ok] <= hi[ok])))
            points += int(np.sum(ok))
            depth_hits += ok & (lo <= y) & (y <= hi)
            depth_points += ok
            widths(lo[ok], hi[ok], sd[ok], z[ok])
            folds += 1
            bar.update(1)
    own_check = None
    try:  # every test of the group: the result's own check (and the width of 3-test groups)
        result, bad = _sample(campaign, test_ids, draws, seed * 1000 + 999)
        own_check = band_calibration(result)
        if not folds:
            not_converged += bad
            for held in test_ids:
                z = np.quantile(curves[held][0], QUANTILES)
                widths(*_band(result, z), z)
    except ValueError as exc:
        failed.append(str(exc))
    bar.update(1)

    def mean(v):
        return float(np.mean(v)) if v else float("nan")

    return Row(
        group=group.label,
        tests=len(test_ids),
        folds=folds,
        points=points,
        coverage=hits / points if points else float("nan"),
        coverage_power_law=hits_pl / points if points else float("nan"),
        by_depth=list(depth_hits / np.maximum(depth_points, 1)) if points else [],
        width=mean(band_w) / mean(own_w) if own_w else float("nan"),
        sd_ratio=mean(band_sd) / mean(own_sd) if own_sd else float("nan"),
        not_converged=not_converged,
        failed_folds=failed,
        seconds=time.perf_counter() - t0,
        own_coverage=own_check.coverage if own_check else float("nan"),
        own_width=own_check.width if own_check else float("nan"),
        own_failures=own_check.failures if own_check else (),
        sentence=own_check.sentence if own_check else "",
    )


def verdict(row: Row) -> str:
    parts = []
    if np.isfinite(row.coverage):
        parts.append("coverage ok" if 0.80 <= row.coverage <= 0.97 else "COVERAGE FAILS")
    else:
        parts.append("no held-out coverage (3 tests)")
    if np.isfinite(row.width):
        parts.append("width ok" if row.width <= 3.0 else "WIDTH FAILS")
    return ", ".join(parts)


def _pct(x: float) -> str:
    return f"{x:6.0%}" if np.isfinite(x) else f"{'-':>6}"


def table(rows: list[Row]) -> str:
    head = (
        f"{'group':<29} {'tests':>5} {'points':>6} {'cover':>6} {'curve':>6} {'width':>6} "
        f"{'sd':>5} | {'cover':>6} {'width':>6} {'s':>4}  {'by sinkage, %':<19} verdict"
    )
    lines = [
        f"{'':<29} {'':>5} {'':>6} {'--- leave-one-test-out ---':^33} | {'-- result --':^13}",
        head,
        "-" * (len(head) + 30),
    ]
    for r in rows:
        lines.append(
            f"{r.group:<29} {r.tests:>5} {r.points:>6} {_pct(r.coverage)} "
            f"{_pct(r.coverage_power_law)} {r.width:6.2f} {r.sd_ratio:5.2f} | "
            f"{_pct(r.own_coverage)} {r.own_width:6.2f} {r.seconds:4.0f}  "
            f"{'/'.join(f'{100 * x:.0f}' for x in r.by_depth) or '-':<19} {verdict(r)}"
            + (f" [{r.not_converged} fits not converged]" if r.not_converged else "")
        )
        lines.extend(f"{'':<29} failed: {f}" for f in r.failed_folds)
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> list[Row]:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--draws", type=int, default=4000, help="kept draws per fold")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--only", default="", help="groups whose label contains this text")
    p.add_argument("--json", default=None, help="also write the rows to this file")
    p.add_argument(
        "--smoke",
        action="store_true",
        help="tiny sizes, seconds: that it runs (tests/test_benchmarks.py)",
    )
    args = p.parse_args(argv)
    groups = [g for g in GROUPS if args.only.lower() in g.label.lower()]
    if args.smoke:
        groups, args.draws = groups[:1], 200
    campaigns = {}
    for name in dict.fromkeys(g.campaign for g in groups):
        campaigns[name] = screen(soilstats.load_campaign(name), "clean").campaign
    sizes = []
    for g in groups:
        t = campaigns[g.campaign].tests
        mask = t["kind"] == "sinkage"
        for column, value in g.selection.items():
            mask &= t[column].astype(str) == str(value)
        sizes.append(int(mask.sum()) + 1 if mask.sum() > 3 else 1)
    t0 = time.perf_counter()
    rows = []
    with tqdm(total=sum(sizes), desc="leave-one-test-out", unit="fit") as bar:
        for g in groups:
            camp = campaigns[g.campaign]
            rows.append(check_group(camp, g, draws=args.draws, seed=args.seed, bar=bar))
    print(
        "Population 90 % band of a NEW test (Bernstein per plate), leave-one-test-out on the "
        f"bundled real campaigns; {args.draws} draws per fold, seed {args.seed}; "
        f"{time.perf_counter() - t0:.0f} s"
    )
    print(
        "cover: held-out measured (test, sinkage) points inside the band (target 80-97 %); "
        "curve: the held-out test's own Bernstein curve inside; width: band width in ln p / "
        "(3.29 x the tests' own sd of ln p) (target <= 3); sd: sd over draws / own sd; "
        "result: what sample_population on all the group's tests reports itself "
        "(importance-weighted leave-one-out coverage, in-sample width); by sinkage: "
        "coverage at the 10/30/50/70/90 % quantiles of the held-out tests' sinkages"
    )
    print(table(rows))
    print("\nWhat sample_population says (posterior.attrs['calibration'], its last note):")
    for r in rows:
        print(f"  {r.group}: {r.sentence}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump([asdict(r) for r in rows], fh, indent=1)
    return rows


if __name__ == "__main__":
    main()
