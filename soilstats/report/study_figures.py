"""The paper's figures for a study, drawn with seaborn/matplotlib from a StudyResult.

* ``curves`` — pressure–sinkage curves, mean ± 1 sd band per condition (Figs. 7, 8);
* ``responses`` — per-test responses by condition, one point per test (the ANOVA's data);
* ``relative`` — pooled parameters relative to a reference condition with ± σ (Figs. 15, 16);
* ``mohr-coulomb`` — steady-state τ against σ per test with the fitted lines (Figs. 11–14);
* ``epsilon`` — fit quality ε per preparation method (Fig. 6).
"""

from __future__ import annotations

import contextlib

import matplotlib.pyplot as plt
import numpy as np
import seaborn as sns

from ..campaign.campaign import match_values
from ..identification.conditions import condition_label

__all__ = ["FIGURES", "make_figures"]

_SIZE = (8.27, 5.2)  # A4 width, readable when printed


def _panels(n: int):
    fig, axes = plt.subplots(1, n, figsize=_SIZE, squeeze=False)
    return fig, axes[0]


def curves(result, campaign) -> plt.Figure:
    """Pressure–sinkage curves per condition: mean and ± 1 sd band over the tests (Fig. 7/8)."""
    spec = result.spec
    tests = result.per_test
    for column, value in spec.curves_where.items():
        if column in tests.columns:
            keep = match_values(tests[column], value, column)
            if keep.any():
                tests = tests[keep]
    samples = campaign.sinkage[campaign.sinkage["test_id"].isin(set(tests["test_id"]))]
    samples = samples.merge(tests[["test_id", "soil", spec.factor]], on="test_id")
    samples = samples[samples["z_m"] > 0]
    fig, axes = _panels(len(result.soils))
    for ax, soil in zip(axes, result.soils, strict=True):
        sub = samples[samples["soil"] == soil]
        if sub.empty:
            continue
        grid = np.linspace(0, sub["z_m"].max(), 40)
        sub = sub.assign(z_bin=grid[np.clip(np.searchsorted(grid, sub["z_m"]), 0, 39)])
        stats = sub.groupby([spec.factor, "z_bin"])["pressure_Pa"].agg(["mean", "std"])
        palette = sns.color_palette("viridis", stats.index.get_level_values(0).nunique())
        for colour, (level, g) in zip(palette, stats.groupby(level=0), strict=True):
            z = g.index.get_level_values(1) * 1e3
            m, s = g["mean"] / 1e3, g["std"].fillna(0) / 1e3
            ax.plot(z, m, color=colour, label=condition_label(level))
            ax.fill_between(z, m - s, m + s, color=colour, alpha=0.2)
        ax.set(title=soil, xlabel="sinkage z [mm]", ylabel="pressure p [kPa]")
        ax.legend(title=spec.factor, fontsize=7, title_fontsize=7)
    where = ", ".join(f"{k} = {v}" for k, v in spec.curves_where.items()) or "all plates"
    fig.suptitle(f"Pressure–sinkage curves by {spec.factor} ({where}); band: ± 1 sd of tests")
    fig.tight_layout()
    return fig


@contextlib.contextmanager
def _fixed_global_seed(seed: int):
    """Seed numpy's global RNG for a display-only draw, then restore the caller's state."""
    state = np.random.get_state()  # noqa: NPY002 (seaborn reads the legacy global RNG)
    np.random.seed(seed)  # noqa: NPY002
    try:
        yield
    finally:
        np.random.set_state(state)  # noqa: NPY002


def responses(result, campaign=None) -> plt.Figure:
    """One point per test, by condition, for each soil and response (the ANOVA's data)."""
    spec = result.spec
    names = [r.name for r in spec.responses if r.name in result.per_test.columns]
    fig, axes = plt.subplots(len(names), 1, figsize=(_SIZE[0], 2.6 * len(names)), squeeze=False)
    data = result.per_test.assign(level=result.per_test[spec.factor].map(condition_label))
    order = [condition_label(v) for v in sorted(result.per_test[spec.factor].dropna().unique())]
    for ax, name in zip(axes[:, 0], names, strict=True):
        with _fixed_global_seed(0):  # seaborn jitters with numpy's global RNG
            sns.stripplot(
                data=data,
                x="level",
                y=name,
                hue="soil",
                order=order,
                dodge=True,
                size=3,
                ax=ax,
                jitter=0.2,
            )
        ax.set(xlabel=spec.factor, ylabel=name)
        ax.legend(fontsize=7)
    fig.suptitle("Per-test responses (one point per test)")
    fig.tight_layout()
    return fig


def relative(result, campaign=None) -> plt.Figure:
    """Pooled parameters relative to the reference condition, ± σ (Figs. 15, 16)."""
    params = result.parameters
    spec = result.spec
    fig, axes = _panels(max(1, params["parameter"].nunique()))
    ref = condition_label(spec.reference) if spec.reference is not None else None
    for ax, (name, g) in zip(axes, params.groupby("parameter", sort=False), strict=False):
        for soil, gs in g.groupby("soil"):
            base = gs[gs["condition"] == ref] if ref else gs.iloc[:1]
            if base.empty:
                base = gs.iloc[:1]
            v0 = float(base["value"].iloc[0])
            ax.errorbar(
                gs["condition"],
                gs["value"] / v0,
                yerr=gs["stderr"] / abs(v0),
                marker="o",
                capsize=3,
                label=soil,
            )
        ax.axhline(1.0, color="grey", lw=0.8)
        ax.set(title=f"{name} relative to {ref or 'first condition'}", xlabel=spec.factor)
        ax.tick_params(axis="x", rotation=45, labelsize=7)
        ax.legend(fontsize=7)
    fig.suptitle("Pooled identification per condition, relative (error bars ± σ, Eq. 3)")
    fig.tight_layout()
    return fig


def mohr_coulomb(result, campaign=None) -> plt.Figure:
    """τ_ss against σ per test with each level's line τ = c + σ tanφ (Figs. 11–14)."""
    spec = result.spec
    fig, axes = _panels(len(result.soils))
    data = result.per_test.assign(level=result.per_test[spec.factor].map(condition_label))
    for ax, soil in zip(axes, result.soils, strict=True):
        sub = data[(data["soil"] == soil) & data["tau_ss_Pa"].notna()]
        lines = result.lines[result.lines["soil"] == soil]
        palette = sns.color_palette("viridis", len(lines))
        sigma = np.linspace(0, sub["sigma_mean_Pa"].max() * 1.05, 20)
        for colour, (_, line) in zip(palette, lines.iterrows(), strict=True):
            pts = sub[sub["level"] == line["level"]]
            ax.scatter(pts["sigma_mean_Pa"] / 1e3, pts["tau_ss_Pa"] / 1e3, s=10, color=colour)
            ax.plot(
                sigma / 1e3,
                (line["intercept"] + line["slope"] * sigma) / 1e3,
                color=colour,
                label=f"{line['level']}: c={line['intercept']:.0f} Pa, φ={line['phi_deg']:.1f}°",
            )
        ax.set(title=soil, xlabel="normal pressure σ [kPa]", ylabel="shear stress τ_ss [kPa]")
        ax.legend(title=spec.factor, fontsize=6, title_fontsize=7)
    fig.suptitle("Mohr–Coulomb lines (Eq. 15) per level, one point per test")
    fig.tight_layout()
    return fig


def epsilon(result, campaign=None) -> plt.Figure:
    """Fit quality ε (Eq. 2) per preparation method and soil (Fig. 6)."""
    eps = result.parameters.groupby(["soil", "condition"], as_index=False)["epsilon"].first()
    order = sorted(
        eps["condition"].unique(), key=lambda s: (not s.isdigit(), int(s) if s.isdigit() else 0, s)
    )
    fig, ax = plt.subplots(figsize=_SIZE)
    sns.barplot(data=eps, x="condition", y="epsilon", hue="soil", order=order, ax=ax)
    ax.set(
        xlabel="preparation method",
        ylabel="ε (Eq. 2)",
        ylim=(max(0, eps["epsilon"].min() - 0.1), 1),
    )
    ax.set_title("Fit quality of the pooled identification per method (criterion 3, Fig. 6)")
    fig.tight_layout()
    return fig


FIGURES = {
    "curves": curves,
    "responses": responses,
    "relative": relative,
    "mohr-coulomb": mohr_coulomb,
    "epsilon": epsilon,
}


def make_figures(result, campaign) -> list[tuple[str, plt.Figure]]:
    """The spec's figures, in its order (``relative`` is skipped without pooled parameters)."""
    out = []
    for name in result.spec.figures:
        if name == "relative" and result.parameters.empty:
            continue
        out.append((name, FIGURES[name](result, campaign)))
    return out
