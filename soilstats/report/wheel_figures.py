"""Figures of a wheel validation (:class:`~soilstats.wheel.validation_result.WheelValidation`).

Each function returns ``(Figure, caption)``; the figure's title states the finding with its
numbers.  Object API only (no pyplot state), fonts of 8 pt and more, sinkage in mm.

=========================  ==================================================================
:func:`predicted_figure`   β = 0: measured sinkage against slip, with each run's predicted
                           90 % band from the plates (and the held-out extended median)
:func:`beta_figure`        all runs: the error (measured − predicted) against slip angle
:func:`day_figure`         β = 0: the error by day, per wheel
:func:`extension_figure`   held-out error per slip condition, base and extended model
:func:`drawbar_figure`     β = 0 drawbar pull, measured and predicted (with shear priors)
=========================  ==================================================================
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Literal, cast

import matplotlib as mpl
import numpy as np
from matplotlib import rc_context
from matplotlib.figure import Figure

from .document import FIGURE_STYLE

if TYPE_CHECKING:
    from collections.abc import Sequence

    import pandas as pd
    from matplotlib.axes import Axes
    from matplotlib.typing import RcKeyType

    from ..discovery.crossval import Gain
    from ..wheel.validation_result import WheelDiscovery, WheelValidation

__all__ = [
    "beta_figure",
    "day_figure",
    "drawbar_figure",
    "extension_figure",
    "predicted_figure",
]

FIGSIZE = (6.3, 3.3)
# The report's, titles half a point up.
_STYLE: dict[RcKeyType, Any] = {**FIGURE_STYLE, "figure.titlesize": 9.5}
BAND, MEASURED, EXTENDED = "#4c72b0", "#111111", "#dd8452"


def _wheels(result: WheelValidation) -> list[str]:
    return sorted(result.runs["wheel"].unique())


def _panels(
    n: int, figsize: tuple[float, float] = FIGSIZE, sharey: bool = True
) -> tuple[Figure, np.ndarray]:
    fig = Figure(figsize=figsize, layout="constrained")
    axes = fig.subplots(1, n, squeeze=False, sharey=sharey)[0]
    return fig, axes


def _jitter(frame, width=0.025):
    """Small offsets so that the repeats of a condition do not hide each other."""
    rank = frame.groupby(["slip_level"]).cumcount().to_numpy()
    return frame["slip"].to_numpy() + width * (rank - rank.max() / 2 if rank.size else 0)


def _band(
    ax: Axes,
    x: np.ndarray,
    sub: pd.DataFrame,
    quantity: str,
    unit: str,
    scale: float,
    what: str = "",
) -> None:
    """A run-by-run predicted band (bar), its median (tick) and the measured value (dot)."""
    lo, hi = sub[f"{quantity}_lower_{unit}"] * scale, sub[f"{quantity}_upper_{unit}"] * scale
    ax.vlines(x, lo, hi, color=BAND, lw=2.2, alpha=0.55, label=f"{what}90 % band")
    median = sub[f"{quantity}_median_{unit}"] * scale
    ax.plot(x, median, "_", color=BAND, ms=7, mew=1.5, label=f"{what}median")
    measured = f"{quantity}_measured_{unit}"
    if measured in sub:
        ax.plot(x, sub[measured] * scale, "o", color=MEASURED, ms=3, label="measured", zorder=3)


def _finish(
    fig: Figure,
    axes: Sequence[Axes] | np.ndarray,
    ylabel: str,
    title: str,
    *,
    zero: bool = True,
    legend: str | None = "axes",
    grid: Literal["both", "x", "y"] = "both",
) -> None:
    """The common end of every figure: zero line, grid, y label, legend, the finding title."""
    for ax in axes:
        if zero:
            ax.axhline(0, color="k", lw=0.6)
        ax.grid(alpha=0.3, axis=grid)
    axes[0].set_ylabel(ylabel)
    if legend == "axes":
        axes[0].legend(frameon=False)
    elif legend == "figure":
        handles, labels = axes[0].get_legend_handles_labels()
        fig.legend(handles, labels, loc="outside lower center", ncol=4, frameon=False)
    fig.suptitle(title)


def predicted_title(result: WheelValidation) -> str:
    runs = result.runs[result.runs["in_scope"]]
    near = runs[runs["slip_level"].abs() <= 0.05]
    locked = runs[runs["slip_level"] <= -0.95]
    cov = result.coverage["beta_0"]
    parts = [
        f"The plates' 90 % band holds {cov['covered']} of {cov['runs']} β = 0 runs:"
        f" {1e3 * near['sinkage_median_m'].mean():.0f} mm predicted at s ≈ 0"
        f" ({1e3 * near['sinkage_measured_m'].mean():.0f} mm measured)"
    ]
    if len(locked):
        parts.append(
            f"locked wheels sink {1e3 * locked['sinkage_measured_m'].mean():.0f} mm,"
            f" predicted {1e3 * locked['sinkage_median_m'].mean():.0f}"
        )
    return ";\n".join(parts)


def predicted_figure(result: WheelValidation) -> tuple[Figure, str]:
    """β = 0 runs: measured sinkage and each run's predicted 90 % band, against slip."""
    runs = result.runs[result.runs["in_scope"]]
    wheels = _wheels(result)
    held = "sinkage_heldout_median_m" in runs
    with rc_context(_STYLE):
        # Printed at 94 % of the text width on page 1 (6.14 in): drawn no wider, so its
        # 8 pt ticks print at 8 pt.
        fig, axes = _panels(len(wheels), figsize=(6.1, 3.2))
        for ax, wheel in zip(axes, wheels, strict=True):
            sub = runs[runs["wheel"] == wheel].sort_values("slip")
            x = _jitter(sub)
            _band(ax, x, sub, "sinkage", "m", 1e3, "plates: ")
            if held:
                extended = sub["sinkage_heldout_median_m"] * 1e3
                ax.plot(x, extended, "d", color=EXTENDED, ms=3.5, label="slip exponent, held out")
            w = result.wheels[wheel]
            ax.set(title=f"{wheel} ({w.describe().split(': ', 1)[1]})", xlabel="slip s")
        _finish(fig, axes, "sinkage (mm)", predicted_title(result), zero=False, legend="figure")
    caption = (
        "Sinkage of every β = 0 run against its slip (repeats offset slightly): measured "
        "(black), and predicted at the run's own measured load from the plate tests alone "
        f"({result.plate.kind} draws, {len(result.plate.draws)} of them): the 90 % band "
        "(5 %–95 % of the draws, blue bar) and median (blue tick)"
        + (
            "; orange: the slip-dependent exponent's median, fitted on the other slip "
            "conditions only (held out)"
            if held
            else ""
        )
        + ". Sinkage in mm below the datum the data assume."
    )
    return fig, caption


def beta_figure(result: WheelValidation) -> tuple[Figure, str]:
    """All runs: measured − predicted median sinkage against β, coloured by slip."""
    runs = result.runs[result.runs["predicted"]]
    wheels = _wheels(result)
    end = runs[runs["beta_level"] == runs["beta_level"].max()]
    start = runs.loc[runs["beta_level"] == 0, "residual_m"].mean()
    title = (
        f"The error grows with slip angle: {1e3 * start:+.0f} mm at β = 0,"
        f" {1e3 * end['residual_m'].mean():+.0f} mm at β = {end['beta_level'].max()}°"
        "\n(measured − predicted; the longitudinal model has no slip-angle term)"
    )
    levels = sorted(runs["slip_level"].unique())
    with rc_context(_STYLE):
        cmap = mpl.colormaps["coolwarm"]
        norm = mpl.colors.Normalize(min(levels), max(levels))
        fig, axes = _panels(len(wheels))
        for ax, wheel in zip(axes, wheels, strict=True):
            sub = runs[runs["wheel"] == wheel]
            x = sub["beta_deg"] + 1.2 * (sub["slip_level"] - 0) / max(1, len(levels))
            ax.scatter(x, sub["residual_m"] * 1e3, c=sub["slip_level"], cmap=cmap, norm=norm, s=9)
            ax.set(
                title=wheel, xlabel="slip angle β (°)", xticks=sorted(sub["beta_level"].unique())
            )
        fig.colorbar(mpl.cm.ScalarMappable(norm=norm, cmap=cmap), ax=axes[-1], label="slip s")
        _finish(fig, axes, "measured − predicted sinkage (mm)", title, legend=None)
    caption = (
        "Every run's sinkage error (measured minus the predicted median, mm) against its slip "
        "angle β, coloured by slip. Runs with β ≠ 0 are predicted with the longitudinal model "
        "as if β = 0; at β = 90° a turning wheel is still sinking in the averaging window "
        "(not steady)."
    )
    return fig, caption


def day_effects(result: WheelValidation) -> tuple[pd.DataFrame, pd.Series]:
    """Each run's error less the mean error of its condition (wheel × slip × β): what the
    day test sees.  Returns the runs with ``within_cell_m`` and the day means per wheel."""
    runs = result.runs[result.runs["predicted"] & result.runs["date"].notna()].copy()
    cell = runs.groupby(["wheel", "slip_level", "beta_level"])["residual_m"].transform("mean")
    runs["within_cell_m"] = runs["residual_m"] - cell
    return runs, runs.groupby(["wheel", "date"])["within_cell_m"].mean()


def day_figure(result: WheelValidation) -> tuple[Figure, str]:
    """All runs: the error less its condition's mean, by day, per wheel."""
    runs, means = day_effects(result)
    wheels = _wheels(result)
    spread = (means * 1e3).groupby(level=0).agg(lambda v: v.max() - v.min())
    tests = result.tests
    row = tests[tests["candidate"] == "day"]
    p = "" if row.empty else f"; day test Holm p = {float(row['p_adjusted'].iloc[0]):.1g}"
    title = (
        "Days differ within a condition: day means span "
        + ", ".join(f"{spread[w]:.1f} mm ({w})" for w in wheels if w in spread)
        + f"\n(each run's error less the mean of its wheel × slip × β cell{p})"
    )
    with rc_context(_STYLE):
        fig, axes = _panels(len(wheels), sharey=True)
        for ax, wheel in zip(axes, wheels, strict=True):
            sub = runs[runs["wheel"] == wheel]
            days = sorted(sub["date"].unique())
            pos = {d: i for i, d in enumerate(days)}
            x = sub["date"].map(pos).to_numpy()
            ax.scatter(x, sub["within_cell_m"] * 1e3, color=BAND, s=6, alpha=0.5)
            day_mean = means.loc[wheel] * 1e3
            ax.plot([pos[d] for d in day_mean.index], day_mean.to_numpy(), "_", color=MEASURED,
                    ms=14, mew=2, label="day mean")  # fmt: skip
            ax.set_xticks(range(len(days)), [d[5:] for d in days], rotation=60)
            ax.set(title=wheel, xlabel="day (month-day)")
        _finish(fig, axes, "error − its condition's mean (mm)", title)
    caption = (
        "The sinkage error of every run less the mean error of its condition (wheel, slip, "
        "slip angle), by the day the run was made: the day-to-day structure the residual "
        "test finds, with the conditions' own effects taken out. The repeats of a condition "
        "were mostly run on different days."
    )
    return fig, caption


def extension_figure(result: WheelValidation) -> tuple[Figure, str]:
    """Held-out error per slip condition: plates only, and with the slip exponent."""
    disc = cast("WheelDiscovery", result.discovery)  # drawn where the extension was fitted
    cv = disc.heldout[disc.heldout["scheme"] == "slip"]
    gain = cast("Gain", disc.gains.get("slip"))  # its slip conditions were held out
    day = disc.gains.get("day")
    title = (
        f"Slip exponent, held out: error {1e3 * gain.base:.1f} → {1e3 * gain.extended:.1f} mm"
        f" ({gain.relative:+.0%}) leaving slip conditions out"
        + (f", {day.relative:+.0%} leaving days out (repeatability)" if day else "")
        + ";\nit still misses locked wheels and small skid"
    )
    wheels = sorted(cv["wheel"].unique())
    with rc_context(_STYLE):
        fig, axes = _panels(len(wheels))
        for ax, wheel in zip(axes, wheels, strict=True):
            sub = cv[cv["wheel"] == wheel].groupby("slip_level")[["base_error", "ext_error"]]
            table = sub.mean() * 1e3
            x = np.arange(len(table))
            ax.bar(x - 0.2, table["base_error"], 0.4, color=BAND, label="plates only")
            ax.bar(x + 0.2, table["ext_error"], 0.4, color=EXTENDED, label="slip exponent")
            ax.set_xticks(x, [f"{v:g}" for v in table.index])
            ax.set(title=wheel, xlabel="slip condition held out")
        _finish(fig, axes, "mean absolute error (mm)", title, zero=False, grid="y")
    caption = (
        "Mean absolute sinkage error of the β = 0 runs of each slip condition, predicted by "
        "the plates alone (blue) and with N = n + n1·s (s ≥ 0), n + n2·|s| (s < 0), n1 and "
        "n2 fitted on the wheel's other slip conditions only (orange). At s ≈ 0 the two are "
        "the same model."
    )
    return fig, caption


def drawbar_figure(result: WheelValidation) -> tuple[Figure, str]:
    """β = 0 drawbar pull, measured and predicted (shear from the stated priors)."""
    runs = result.runs[result.runs["in_scope"]]
    wheels = _wheels(result)
    cov = result.coverage.get("drawbar_pull_beta_0", {})
    title = "Drawbar pull from plates + stated shear priors: band holds " + ", ".join(
        f"{c['covered']}/{c['runs']} ({w})" for w, c in cov.items()
    )
    with rc_context(_STYLE):
        fig, axes = _panels(len(wheels))
        for ax, wheel in zip(axes, wheels, strict=True):
            sub = runs[runs["wheel"] == wheel].sort_values("slip")
            x = _jitter(sub)
            _band(ax, x, sub, "drawbar_pull", "N", 1.0)
            ax.set(title=wheel, xlabel="slip s")
        _finish(fig, axes, "drawbar pull (N)", title)
    caption = (
        "Drawbar pull of the β = 0 runs: measured (black) and the predicted 90 % band and "
        "median (blue), with c, φ and K drawn from the user's stated priors (not measured: "
        "no shear test) and the pressure–sinkage law from the plates."
    )
    return fig, caption
