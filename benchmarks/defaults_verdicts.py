"""How often a default moves a verdict (issue #47, item 3): the fire rate of the warnings.

    python benchmarks/defaults_verdicts.py study       # shipped studies on the bundled data
    python benchmarks/defaults_verdicts.py simulated   # planted cases, 40 seeds each
    python benchmarks/defaults_verdicts.py posterior   # every bundled posterior, seed 0
    python benchmarks/defaults_verdicts.py --smoke     # one seed, one posterior: that it runs

``study``: each shipped study on each bundled campaign it applies to, with the time of the
study (per-test fits warm) without and with the re-evaluation of its defaulted z_ref_m /
z_window_m (soilstats.study.defaults), and the warnings.  ``simulated``: the velocity study
of tests/test_study_defaults.py (z_ref_m and z_window_m left out) on campaigns with no
effect, a depth-independent effect (a factor 2 on kc, kφ) and curves that cross at the
default z_ref (an effect that depends on the depth): how often each warns.  ``posterior``:
``sample_posterior`` and (Bekker, Bernstein, Janosi) ``sample_population`` on every bundled
soil, with the largest power-scaling sensitivity to the default priors and whether it warns
(soilstats.bayes.prior_sensitivity).  Docs: docs/studies.md and docs/posterior.md.
"""

from __future__ import annotations

import sys
import tempfile
import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

CAMPAIGNS = ("simulated-paper", "cullinan-sand", "grc1-oravec2009", "cmu-3d-terramechanics")


def bundled_studies() -> None:
    import soilstats.study.runner as runner
    from soilstats.campaign import load_campaign
    from soilstats.study import StudyDataError, available_studies, load_spec
    from soilstats.study.responses import PerTestCache

    real = runner.moved_verdicts
    for name in CAMPAIGNS:
        camp = load_campaign(name)
        cache = PerTestCache(camp)
        for study in available_studies():
            spec = load_spec(study)
            try:
                result = runner.run_study(spec, camp, cache=cache, seed=0)  # warm the fits
            except StudyDataError:
                continue
            times: dict[bool, list[float]] = {False: [], True: []}
            for _ in range(2):  # interleaved: the machine is shared
                for on in (False, True):
                    runner.moved_verdicts = real if on else (lambda *a, **k: {})
                    start = time.perf_counter()
                    result = runner.run_study(spec, camp, cache=cache, seed=0)
                    times[on].append(time.perf_counter() - start)
            runner.moved_verdicts = real
            print(
                f"{name:22s} {study:15s} defaults {sorted(result.defaults)}  "
                f"{min(times[False]):.2f} s -> {min(times[True]):.2f} s  "
                f"warnings {list(result.default_warnings)}",
                flush=True,
            )


def simulated(seeds: int) -> None:
    from test_study_defaults import STUDY, _campaign

    from soilstats.study import load_spec, run_study

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "velocity-test.toml"
        path.write_text(STUDY, encoding="utf-8")
        spec = load_spec(path)  # read again by the study: which keys the file leaves out
        for case in ("null", "uniform", "crossing"):
            fired, verdicts = 0, {}
            for seed in range(seeds):
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    result = run_study(spec, _campaign(case, seed).campaign, seed=0)
                verdict = result.effects.set_index("response").loc["log10_p_ref", "verdict"]
                verdicts[verdict] = verdicts.get(verdict, 0) + 1
                fired += bool(result.default_warnings)
            print(f"{case:9s} warned {fired}/{seeds}; log10_p_ref at 25 mm: {verdicts}", flush=True)


def posteriors(smoke: bool) -> None:
    from soilstats.bayes import sample_population, sample_posterior
    from soilstats.campaign import load_campaign

    runs, fired = 0, 0
    for name in CAMPAIGNS[:1] if smoke else CAMPAIGNS:
        camp = load_campaign(name)
        for soil, kinds in camp.tests.groupby("soil")["kind"].unique().items():
            for kind in kinds:
                models = (
                    ("bekker", "bernstein") if kind == "sinkage" else ("mohr-coulomb", "janosi")
                )
                for model in models[:1] if smoke else models:
                    for population in (False, True):
                        if population and model == "mohr-coulomb":
                            continue
                        sample = sample_population if population else sample_posterior
                        try:
                            with warnings.catch_warnings():
                                warnings.simplefilter("ignore")
                                result = sample(camp, model, seed=0, soil=soil)
                        except Exception as err:  # a refused model: said, not counted
                            print(f"{name} {soil} {model}: refused ({type(err).__name__})")
                            continue
                        table = result.prior_sensitivity
                        worst = table.sort_values("default_prior_sensitivity").iloc[-1]
                        hit = bool(table["influential"].any())
                        runs, fired = runs + 1, fired + hit
                        print(
                            f"{name:22s} {soil:13s} {model:12s} "
                            f"{'population' if population else 'pooled':10s} largest "
                            f"{worst['default_prior_sensitivity']:.3f} ({worst['quantity']}) "
                            f"warns {hit}: {list(table[table['influential']]['quantity'])}",
                            flush=True,
                        )
                        if smoke:
                            print(f"warned {fired} of {runs}")
                            return
    print(f"warned {fired} of {runs}")


if __name__ == "__main__":
    args = sys.argv[1:]
    if "--smoke" in args:
        posteriors(smoke=True)
    elif args[:1] == ["study"]:
        bundled_studies()
    elif args[:1] == ["simulated"]:
        simulated(int(args[1]) if len(args) > 1 else 40)
    else:
        posteriors(smoke=False)
