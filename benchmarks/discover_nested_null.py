"""Selection bias of discovery's cross-validated gain, and the false-keep rate of its rule.

The review's toy (docs/discover.md, "Gain"): small sinkage campaigns (two plates, a two-level
``bin`` column with no effect, 16, 20 or 24 tests) are simulated and discovered at a
lenient ``alpha`` so that the null ``bin`` (or another candidate) is selected often
enough to study.  Every finding is false: the share of them whose extension is kept is the
false-keep rate of the keep rule (:data:`soilstats.discovery.crossval.Z_KEEP`) given a
falsely named cause.  Prints the number of selected leads, the median and quartiles of the
gain that decides (the cause fixed) and of the whole search's gain (each fold re-selecting
the lead), and the share called real or kept.  ``--effect F`` plants instead a ``bin`` F
times stiffer in bin ``s`` (kc and kφ): how often it is named, kept (real gain), and its
gain.

``--replica`` runs the review's toy in plain numbers instead: 16 normal values in two
groups of 8, selected at p < 0.01 (t-test), gain of the group means over the grand mean on
five stratified folds, without and with the test repeated in each fold (SEEDS × 1000 draws).

    python benchmarks/discover_nested_null.py [SEEDS] [--alpha 0.1] [--effect 1.1]
    python benchmarks/discover_nested_null.py 100 --replica
"""

from __future__ import annotations

import sys
import time
from multiprocessing import Pool
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from discover_situations import sink, spec

from soilstats.discovery import discover
from soilstats.simulation import simulate


def campaign(seed: int, effect: float = 1.0):
    """16, 20 or 24 sinkage tests (two plates × two bins × 4–6 repetitions); bin ``s``
    ``effect`` times stiffer (1: no effect)."""
    reps = 4 + seed % 3
    planted = [
        {
            "kind": "covariate",
            "column": "bin",
            "parameters": ["kc", "kphi"],
            "levels": {"s": effect},
        }
    ]
    series = [sink(covariates={"bin": ["n", "s"]}, repetitions=reps)]
    return simulate(spec(series, planted if effect != 1.0 else ()), seed=seed)


def _one(args) -> list[tuple]:
    seed, alpha, effect = args
    result = discover(campaign(seed, effect).campaign, seed=0, alpha=alpha)
    out = []
    for f in result.findings:
        g, s = f.gain, f.gain_search
        gain = (np.nan, False) if g is None else (g.relative, g.real)
        search = (np.nan, None) if s is None else (s.relative, s.selected_folds)
        strict = g is not None and g.relative > 0 and g.z > 2.0  # the rule at 2 SE
        out.append((seed, f.cause, f.p_value, *gain, f.extension is not None, *search, strict))
    return out


def _quartiles(values) -> tuple[str, int]:
    gains = np.array(values, float)
    ok = np.isfinite(gains)
    q = np.percentile(gains[ok], [25, 50, 75]) if ok.any() else [np.nan] * 3
    return f"median {q[1]:+.1%} (quartiles {q[0]:+.1%}, {q[2]:+.1%})", int((~ok).sum())


def _line(label: str, rows: list[tuple]) -> str:
    fixed, failed = _quartiles([r[3] for r in rows])
    search, _ = _quartiles([r[6] for r in rows])
    real = sum(r[4] for r in rows)
    kept = sum(r[5] for r in rows)
    chosen = [r[7] for r in rows if r[7] is not None]
    folds = f", the lead chosen in {np.mean(chosen):.1f} of 5 folds on average" if chosen else ""
    strict = sum(r[8] for r in rows)
    return (
        f"  {label}: {len(rows)} leads; gain with the cause fixed {fixed} ({failed} without "
        f"a gain: a fold's fit failed); real {real} ({real / max(len(rows), 1):.1%}), kept "
        f"{kept} ({kept / max(len(rows), 1):.1%}; at 2 SE instead: {strict}); whole search "
        f"{search}{folds}"
    )


def replica(draws: int, level: float = 0.01) -> None:
    """The review's toy without the soil model (module docstring)."""
    from scipy import stats

    rng = np.random.default_rng(1)
    group = np.repeat([0, 1], 8)
    plain, nested = [], []
    for _ in range(draws):
        y = rng.normal(size=16)
        if stats.ttest_ind(y[:8], y[8:]).pvalue >= level:
            continue
        folds = np.empty(16, int)
        for lv in (0, 1):
            idx = rng.permutation(np.flatnonzero(group == lv))
            folds[idx] = (np.arange(8) + 8 * lv) % 5
        e_base, e_ext, e_nest = (np.empty(16) for _ in range(3))
        for k in range(5):
            tr, te = folds != k, folds == k
            means = np.array([y[tr & (group == lv)].mean() for lv in (0, 1)])
            e_base[te] = (y[te] - y[tr].mean()) ** 2
            e_ext[te] = (y[te] - means[group[te]]) ** 2
            p = stats.ttest_ind(y[tr & (group == 0)], y[tr & (group == 1)]).pvalue
            e_nest[te] = e_ext[te] if p < level else e_base[te]
        plain.append(1 - np.sqrt(e_ext.mean() / e_base.mean()))
        nested.append(1 - np.sqrt(e_nest.mean() / e_base.mean()))
    print(
        f"replica, {draws} draws: {len(plain)} selected at p < {level}; median gain "
        f"{np.median(plain):+.1%} without nesting, {np.median(nested):+.1%} nested"
    )


def main() -> None:
    if "--replica" in sys.argv:
        args = [a for a in sys.argv[1:] if not a.startswith("--")]
        replica(1000 * (int(args[0]) if args else 100))
        return
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    alpha = 0.1
    if "--alpha" in sys.argv:
        alpha = float(sys.argv[sys.argv.index("--alpha") + 1])
        args.remove(sys.argv[sys.argv.index("--alpha") + 1])
    effect = 1.0
    if "--effect" in sys.argv:
        effect = float(sys.argv[sys.argv.index("--effect") + 1])
        args.remove(sys.argv[sys.argv.index("--effect") + 1])
    seeds = 2 if "--smoke" in sys.argv else int(args[0]) if args else 300  # smoke: it runs
    start = time.perf_counter()
    with Pool(2) as pool:
        jobs = [(s, alpha, effect) for s in range(seeds)]
        rows = [r for rs in pool.map(_one, jobs, 4) for r in rs]
    what = "null campaigns" if effect == 1.0 else f"bin s {effect:g}x stiffer"
    print(
        f"{what}, seeds 0-{seeds - 1}, alpha {alpha}: {len(rows)} selected leads in "
        f"{len({r[0] for r in rows})} campaigns; {(time.perf_counter() - start):.0f} s"
    )
    print(_line("all", rows))
    print(_line("bin", [r for r in rows if r[1] == "bin"]))
    print(_line("bin, p < 0.01", [r for r in rows if r[1] == "bin" and r[2] < 0.01]))


if __name__ == "__main__":
    main()
