"""The paper's figures for a study, drawn with seaborn/matplotlib from a StudyResult.

* ``curves`` — pressure–sinkage curves, mean ± 1 sd band per condition (Figs. 7, 8);
* ``responses`` — per-test responses by condition, one point per test (the ANOVA's data);
* ``relative`` — pooled parameters relative to a reference condition with ± σ (Figs. 15, 16);
* ``mohr-coulomb`` — steady-state τ against σ per test with the fitted lines (Figs. 11–14);
* ``epsilon`` — fit quality ε per preparation method (Fig. 6).
"""

from __future__ import annotations

import contextlib
from typing import TYPE_CHECKING

import matplotlib.pyplot as plt
import numpy as np
import seaborn as sns

from ..campaign.matching import match_values
from ..identification.conditions import condition_label
from .document import tight_layout
from .labels import column_label, natural_key, natural_sorted

if TYPE_CHECKING:
    from collections.abc import Iterator

    import pandas as pd
    from matplotlib.figure import Figure

    from ..campaign.campaign import Campaign
    from ..study.result import StudyResult

__all__ = ["FIGURES", "make_figures"]

_SIZE = (6.5, 4.2)  # the text width of an A4 page, so fonts print at their size


def _panels(n: int) -> tuple[Figure, np.ndarray]:
    fig, axes = plt.subplots(1, n, figsize=_SIZE, squeeze=False)
    return fig, axes[0]


def _curves_tests(result: StudyResult) -> tuple[pd.DataFrame, str]:
    """The tests the curves figure draws and, for its caption, what they share: the spec's
    ``[curves] where`` where this campaign has such tests (the paper's plate), else the value
    every test of the campaign has (Cullinan's plates are not the paper's 0.05 m)."""
    tests = result.per_test
    said = []
    for column, value in result.spec.curves_where.items():
        if column not in tests.columns:
            continue
        keep = match_values(tests[column], value, column)
        if keep.any():
            tests = tests[keep]
            said.append(f"{column_label(column)} = {value}")
        elif tests[column].nunique() == 1:
            only = tests[column].iloc[0]
            shown = f"{only:g}" if isinstance(only, float) else str(only)
            said.append(f"{column_label(column)} = {shown}")
    return tests, ", ".join(said)


def curves(result: StudyResult, campaign: Campaign) -> plt.Figure:
    """Pressure–sinkage curves per condition: mean and ± 1 sd band over the tests (Fig. 7/8)."""
    spec = result.spec
    tests, _ = _curves_tests(result)
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
        levels = natural_sorted(stats.index.get_level_values(0).unique())
        palette = sns.color_palette("viridis", len(levels))
        for colour, level in zip(palette, levels, strict=True):
            g = stats.xs(level, level=0, drop_level=False)
            z = g.index.get_level_values(1) * 1e3
            m, s = g["mean"] / 1e3, g["std"].fillna(0) / 1e3
            ax.plot(z, m, color=colour, label=condition_label(level))
            ax.fill_between(z, m - s, m + s, color=colour, alpha=0.2)
        ax.set(title=soil, xlabel="sinkage z (mm)", ylabel="pressure p (kPa)")
        ax.legend(title=column_label(spec.factor), fontsize=8, title_fontsize=8)
    tight_layout(fig)
    return fig


@contextlib.contextmanager
def _fixed_global_seed(seed: int) -> Iterator[None]:
    """Seed numpy's global RNG for a display-only draw, then restore the caller's state."""
    state = np.random.get_state()  # noqa: NPY002 (seaborn reads the legacy global RNG)
    np.random.seed(seed)  # noqa: NPY002
    try:
        yield
    finally:
        np.random.set_state(state)  # noqa: NPY002


def responses(result: StudyResult, campaign: Campaign | None = None) -> plt.Figure:
    """One point per test, by condition, for each soil and response (the ANOVA's data)."""
    spec = result.spec
    names = [r.name for r in spec.responses if r.name in result.per_test.columns]
    fig, axes = plt.subplots(len(names), 1, figsize=(_SIZE[0], 2.6 * len(names)), squeeze=False)
    data = result.per_test.assign(level=result.per_test[spec.factor].map(condition_label))
    order = [
        condition_label(v) for v in natural_sorted(result.per_test[spec.factor].dropna().unique())
    ]
    labels = {r.name: r.label for r in spec.responses}
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
        ax.set(xlabel=column_label(spec.factor), ylabel=labels.get(name, column_label(name)))
        ax.legend(fontsize=8)
    tight_layout(fig)
    return fig


def relative(result: StudyResult, campaign: Campaign | None = None) -> plt.Figure:
    """Pooled parameters relative to the reference condition, ± σ (Figs. 15, 16).

    A ratio means something only between values of one sign: a parameter that is zero or
    changes sign across the conditions (kc often does) is drawn as its value ± σ instead.
    """
    params = result.parameters
    spec = result.spec
    fig, axes = _panels(max(1, params["parameter"].nunique()))
    ref = condition_label(spec.reference) if spec.reference is not None else None
    for ax, (name, g) in zip(axes, params.groupby("parameter", sort=False), strict=False):
        ratio = bool((g["value"] > 0).all() or (g["value"] < 0).all())
        unit = g["unit"].iloc[0]
        # Levels are categories: points at their places in natural order (1, 2, 10), one
        # small offset per soil, never joined by lines (a line between levels would claim a
        # trend between conditions that have no order in between).
        levels = natural_sorted(g["condition"].astype(str).unique())
        soils = list(g.groupby("soil").groups)
        width = 0.5 / max(len(soils), 1)
        for k, (soil, gs) in enumerate(g.groupby("soil")):
            gs = gs.iloc[sorted(range(len(gs)), key=lambda i: natural_key(gs["condition"].iloc[i]))]
            base = gs[gs["condition"] == ref] if ref else gs.iloc[:1]
            if base.empty:
                base = gs.iloc[:1]
            v0 = float(base["value"].iloc[0]) if ratio else 1.0
            x = [levels.index(str(c)) + (k - (len(soils) - 1) / 2) * width for c in gs["condition"]]
            ax.errorbar(
                x,
                gs["value"] / v0,
                yerr=gs["stderr"] / abs(v0),
                marker="o",
                linestyle="none",
                capsize=3,
                label=soil,
            )
        ax.set_xticks(range(len(levels)), levels)
        if ratio:
            ax.axhline(1.0, color="grey", lw=0.8)
            spread = _spread(g)
            ylabel = f"{name} / {name}({ref or 'first'})"
            ax.set(title=f"{name}: up to ×{spread:.2g}", ylabel=ylabel)
            if spread >= 10:  # ratios over a decade or more: equal factors, equal steps
                ax.set_yscale("log")
        else:
            ax.axhline(0.0, color="grey", lw=0.8)
            ax.set(title=f"{name} changes sign", ylabel=f"{name} ({unit})")
        ax.tick_params(axis="x", rotation=45 if len(levels) > 4 else 0, labelsize=8)
        ax.legend(fontsize=8)
    # once under all panels: repeated under each, a long factor name ran past the page edge
    fig.supxlabel(column_label(spec.factor), fontsize=plt.rcParams["axes.labelsize"])
    tight_layout(fig)
    return fig


def _spread(g: pd.DataFrame) -> float:
    """The largest ratio of one soil's pooled values across conditions (≥ 1; inf where a
    value is zero or the sign changes)."""
    out = 1.0
    for _, gs in g.groupby("soil"):
        v = gs["value"].to_numpy(dtype=float)
        if not ((v > 0).all() or (v < 0).all()):
            return float("inf")
        out = max(out, float(np.abs(v).max() / np.abs(v).min()))
    return out


def moves_without_effect(result: StudyResult, factor_of: float = 2.0) -> list[str]:
    """Pooled parameters that move by more than ``factor_of`` (or change sign) in a soil whose
    verdicts all say no effect: ``["soil02 kphi ×95", …]``. The figure shows them beside a
    "no effect" verdict, so its caption must say why."""
    params, effects = result.parameters, result.effects
    if params.empty or effects.empty:
        return []
    out = []
    for (soil, name), g in params.groupby(["soil", "parameter"], sort=False):
        verdicts = effects.loc[effects["soil"] == soil, "verdict"]
        if verdicts.empty or (verdicts == "effect").any():
            continue
        spread = _spread(g)
        if spread > factor_of:
            out.append(
                f"{soil} {name} " + ("changes sign" if np.isinf(spread) else f"×{spread:.2g}")
            )
    return out


def mohr_coulomb(result: StudyResult, campaign: Campaign | None = None) -> plt.Figure:
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
        ax.set(title=soil, xlabel="normal pressure σ (kPa)", ylabel="shear stress τ_ss (kPa)")
        ax.legend(title=column_label(spec.factor), fontsize=8, title_fontsize=8)
    tight_layout(fig)
    return fig


def epsilon(result: StudyResult, campaign: Campaign | None = None) -> plt.Figure:
    """Fit quality ε (Eq. 2) per preparation method and soil (Fig. 6)."""
    eps = result.parameters.groupby(["soil", "condition"], as_index=False)["epsilon"].first()
    order = natural_sorted(eps["condition"].unique())
    fig, ax = plt.subplots(figsize=_SIZE)
    sns.barplot(data=eps, x="condition", y="epsilon", hue="soil", order=order, ax=ax)
    ax.set(
        xlabel="preparation method",
        ylabel="ε (Eq. 2)",
        ylim=(max(0, eps["epsilon"].min() - 0.1), 1),
    )
    tight_layout(fig)
    return fig


FIGURES = {
    "curves": curves,
    "responses": responses,
    "relative": relative,
    "mohr-coulomb": mohr_coulomb,
    "epsilon": epsilon,
}


def caption(name: str, result: StudyResult) -> str:
    """The caption of figure ``name``: what is shown, with units and the paper's figure."""
    spec = result.spec
    factor = column_label(spec.factor)
    where = _curves_tests(result)[1] if name == "curves" else ""
    return {
        "curves": f"Pressure–sinkage curves by {factor}"
        + (f" ({where})" if where else "")
        + ": mean over the tests of each level, band ± 1 standard deviation of the tests "
        "(cf. the paper's Figs. 7 and 8).",
        "responses": f"Per-test responses by {factor}, one point per test and colour per soil: "
        "the data of the ANOVA.",
        "relative": f"Pooled parameters per {factor}, relative to the "
        + (
            f"reference {condition_label(spec.reference)}"
            if spec.reference is not None
            else "first level"
        )
        + " with ± stderr error bars (the test-level σ; cf. Figs. 15 and 16). Parameters that "
        "change sign are drawn as values in their unit, since their ratios mean nothing."
        + _why_no_effect(result),
        "mohr-coulomb": f"Steady-state shear stress τ_ss (kPa) against normal pressure σ (kPa), "
        f"one point per test, with the Mohr–Coulomb line (Eq. 15) of each {factor} level "
        "(cf. Figs. 11–14).",
        "epsilon": "Fit quality ε (Eq. 2) of the pooled identification per preparation method "
        "and soil: criterion 3 of Table 1 (cf. Fig. 6).",
    }[name]


def _why_no_effect(result: StudyResult) -> str:
    moved = moves_without_effect(result)
    if not moved:
        return ""
    return (
        f" Large moves beside a 'no effect' verdict ({', '.join(moved)}): the verdicts test the "
        "per-test responses (the pressure at the reference sinkage and the exponent), which "
        "did not change beyond their margins; a pooled parameter alone can move a lot while "
        "the curve does not, because the parameters trade off against each other (kc against "
        "kφ above all: see each fit's correlation and its high-correlation flag)."
    )


def make_figures(result: StudyResult, campaign: Campaign) -> list[tuple[str, plt.Figure, str]]:
    """The spec's figures in its order, as (name, figure, caption); ``relative`` is skipped
    without pooled parameters."""
    out = []
    for name in result.spec.figures:
        if name == "relative" and result.parameters.empty:
            continue
        out.append((name, FIGURES[name](result, campaign), caption(name, result)))
    return out
