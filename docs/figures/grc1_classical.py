"""GRC-1: the published Bekker fits (Wong's procedure) beside the paper's weighted LM.

    python docs/figures/grc1_classical.py

Prints the markdown table of docs/classical.md and writes docs/figures/grc1-classical.png.
"""

from __future__ import annotations

import tomllib
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from soilstats import fit_sinkage
from soilstats.campaign import Campaign, load_campaign
from soilstats.campaign.window import FitWindow
from soilstats.data import bundled_path
from soilstats.identification.classical import classical_bekker

HERE = Path(__file__).resolve().parent
KILO = pd.Series({"kc": 1e-3, "kphi": 1e-3, "n": 1.0})


def ensemble_campaign(fit) -> Campaign:
    """The averaged curves as a campaign (one 'test' per plate), for the LM on the same points."""
    obs = fit.observations()
    ids = [f"ensemble-{b:g}" for b in obs["b_m"]]
    tests = pd.DataFrame(
        {
            "test_id": [f"ensemble-{c.b_m:g}" for c in fit.curves],
            "kind": "sinkage",
            "soil": fit.soil,
            "shape": "circle",
            "radius_m": [c.b_m for c in fit.curves],
        }
    )
    sinkage = pd.DataFrame(
        {
            "test_id": ids,
            "z_m": obs["z_m"],
            "force_N": obs["pressure_Pa"] * np.pi * obs["b_m"] ** 2,
        }
    )
    return Campaign.from_frames(tests, sinkage)


def main() -> None:
    published = tomllib.loads((bundled_path("grc1-oravec2009") / "published.toml").read_text())
    campaign = load_campaign("grc1-oravec2009")
    rows, panels = [], []
    for name in ("lunar", "entire"):
        table = published[name]
        limits = list(zip(table["p_min_kPa"], table["p_max_kPa"], strict=True))
        plates = list(zip(published["b_m"], limits, strict=True))
        windows = {b: (lo * 1e3, hi * 1e3) for b, (lo, hi) in plates}
        wong = classical_bekker(campaign, windows)
        common = classical_bekker(campaign, windows, exponent="common")
        uniform = classical_bekker(campaign, windows, weighting="uniform")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            on_curves = fit_sinkage(
                ensemble_campaign(wong), quality="off", points_per_test=None, on_failure="warn"
            )
            p_window = FitWindow.parse(
                p_max=[f"radius_m={b}:{hi * 1e3:g}" for b, (_, hi) in plates]
            )
            on_tests = fit_sinkage(
                campaign, window=p_window, test_resamples=1000, seed=1, on_failure="warn"
            )
        pub = pd.Series({k: table[k] for k in ("kc", "kphi", "n")})
        rows += [
            (name, "published (Oravec 2009)", pub, None, ""),
            (name, "Wong, averaged n, p^2 (reproduced)", wong.params_kilo, None, ""),
            (name, "Wong, common n, p^2", common.params_kilo, None, ""),
            (name, "Wong, averaged n, uniform", uniform.params_kilo, None, ""),
            (
                name,
                "LM Eq. 11 on the averaged curves",
                on_curves.params * KILO,
                on_curves.stderr * KILO,
                ", ".join(f.code for f in on_curves.flags),
            ),
            (
                name,
                "LM Eq. 11 on the 15 tests (soilstats)",
                on_tests.params * KILO,
                on_tests.stderr_tests * KILO,
                ", ".join(f.code for f in on_tests.flags),
            ),
        ]
        panels.append((name, wong, on_tests, limits))
        print(
            f"{name}: per-plate exponents n_b = "
            + ", ".join(f"{n:.3f} (b = {b:g} m)" for b, n in wong.plate_exponents.items())
        )

    print("\n| window | estimator | n | kc [kN/m^(n+1)] | kφ [kN/m^(n+2)] | health |")
    print("|---|---|---|---|---|---|")
    for name, label, p, se, health in rows:
        cell = {k: f"{p[k]:.4g}" + ("" if se is None else f" ± {se[k]:.2g}") for k in p.index}
        print(f"| {name} | {label} | {cell['n']} | {cell['kc']} | {cell['kphi']} | {health} |")

    fig, axes = plt.subplots(1, 2, figsize=(10, 4.6), constrained_layout=True)
    colours = ("#1f4e9c", "#d4570a", "#2a8a4a")
    for ax, (name, wong, lm, limits) in zip(axes, panels, strict=True):
        for colour, curve, (_, hi) in zip(colours, wong.curves, limits, strict=True):
            keep = curve.pressure_Pa <= hi * 1e3
            p_kpa = curve.pressure_Pa[keep] / 1e3
            ax.plot(
                p_kpa[::6],
                curve.z_m[keep][::6] * 1e3,
                "o",
                ms=3,
                mfc="none",
                color=colour,
                label=f"b = {curve.b_m * 1e3:.0f} mm, mean of 5 repeats",
            )
            z = np.linspace(1e-5, curve.z_m[keep].max(), 200)
            for params, style in ((wong.params, "-"), (lm.params, "--")):
                p_model = (params["kc"] / curve.b_m + params["kphi"]) * z ** params["n"]
                ax.plot(p_model / 1e3, z * 1e3, style, color=colour, lw=1.3)
        ax.plot([], [], "k-", label="Wong, averaged n (published)")
        ax.plot([], [], "k--", label="weighted LM, Eq. 11 (soilstats)")
        ax.set_title(f"'{name}' window (p <= {', '.join(f'{hi:g}' for _, hi in limits)} kPa)")
        ax.set_xlabel("pressure p [kPa]")
        ax.set_ylabel("sinkage z [mm]")
        ax.set_xlim(left=0)
        ax.set_ylim(bottom=0)
        ax.invert_yaxis()
        ax.legend(fontsize=7.5, loc="upper right")
    fig.suptitle("GRC-1 (Oravec 2009): one Bekker curve per plate from two estimators")
    fig.savefig(HERE / "grc1-classical.png", dpi=110)


if __name__ == "__main__":
    main()
