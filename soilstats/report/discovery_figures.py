"""The discovery report's findings figures: per finding, the deviation against the cause
and the measured curves with the base and extended fits, two findings to a row (moved out of
:mod:`.discovery_pdf`, issue #45)."""

from __future__ import annotations

import math
import textwrap
from typing import Any

import matplotlib as mpl
import numpy as np
from matplotlib.figure import Figure

from ..discovery.candidates import candidate_values
from ..discovery.result import Finding
from .document import GRID_STYLE
from .labels import column_label, natural_sorted

#: Levels drawn in a finding's curve panel (spread over its sorted levels).
_CURVES = 4
#: Above this many distinct values a numeric cause is drawn on its own axis, with a trend.
_MAX_LEVELS = 12


def _numeric(labels: list[str]) -> list[float] | None:
    try:
        return [float(v) for v in labels]
    except ValueError:
        return None


def _response_words(f: Finding, response: str) -> str:
    if response == "level":
        return "pressure" if f.kind == "sinkage" else "shear strength"
    return {"shape": "n", "K": "K"}.get(response, response)


def _change(f: Finding, response: str, delta: float) -> str:
    """A change of the per-test response in physical words: a factor on the log responses
    (level, K), a difference in n (shape)."""
    if response == "shape":
        return f"{_response_words(f, response)} {delta:+.2g}"
    return f"{_response_words(f, response)} ×{math.exp(delta):.2g}"


def _short(text: str, n: int = 14) -> str:
    return text if len(text) <= n else text[: n - 1] + "…"


def _deviation_panel(ax: Any, f: Any) -> str:  # a Finding with its group
    """Each test's deviation against the cause (means per level, or a trend on a numeric
    cause of many values); returns the effect in words, for the title."""
    g, rows = f.group, f.scope_rows
    assert g is not None  # a finding of this run carries its group (the figures read it)
    response = f.responses[0] if f.responses else "level"
    dev = g.tests[f"_dev_{response}"].to_numpy(float)[rows]
    values = candidate_values(g.tests, f.cause).to_numpy()[rows]
    labels = natural_sorted({str(v) for v in values})
    numbers = _numeric(labels)
    if numbers is not None and len(labels) > _MAX_LEVELS:
        x = values.astype(float)
        ax.scatter(x, dev, s=4, alpha=0.6)
        ok = np.isfinite(x) & np.isfinite(dev)
        slope, icept = np.polyfit(x[ok], dev[ok], 1)
        span = np.array([x[ok].min(), x[ok].max()])
        ax.plot(span, icept + slope * span, color="k", lw=0.9)
        effect = f"{_change(f, response, slope * (span[1] - span[0]))} over its range"
    else:
        xs = np.array([labels.index(str(v)) for v in values], float)
        jitter = np.random.default_rng(0).uniform(-0.15, 0.15, xs.size)  # display only
        ax.scatter(xs + jitter, dev, s=4, alpha=0.6)
        means = np.array(
            [np.nanmean(dev[xs == k]) if (xs == k).any() else np.nan for k in range(len(labels))]
        )
        for k, m in enumerate(means):
            if np.isfinite(m):
                ax.hlines(m, k - 0.3, k + 0.3, color="k", lw=1.1)
        many = len(labels) > 4 or sum(map(len, labels)) > 24
        ax.set_xticks(
            range(len(labels)),
            [_short(lv, 10) for lv in labels],
            rotation=40 if many else 0,
            ha="right" if many else "center",
            rotation_mode="anchor",
        )
        if numbers is not None and len(labels) > 1:
            effect = (
                f"{_change(f, response, means[-1] - means[0])} from {labels[0]} to {labels[-1]}"
            )
        else:
            spread = float(np.nanmax(means) - np.nanmin(means))
            effect = f"{_change(f, response, spread)} between its {len(labels)} levels"
    ax.axhline(0, color="0.6", lw=0.6)
    ax.set_xlabel(_short(column_label(f.cause), 44))
    ax.set_ylabel(f"deviation in {response}")
    return effect


def _curve_panel(ax: Any, f: Any) -> str:  # a Finding with its group
    """One test per level (at most four, spread over the levels): measured samples, base
    model (dashed), extension (solid); returns the gain in words, for the title."""
    g, rows = f.group, f.scope_rows
    name = f.extension or "no extension kept"
    gain = (
        f"held-out error {f.gain.base:.3f} → {f.gain.extended:.3f} ({f.gain.relative:+.0%})"
        if f.gain is not None
        else "no held-out gain measured"
    )
    if f.base_fitted is None or f.fitted is None:
        ax.text(
            0.5,
            0.5,
            "no extended model\ncould be fitted",
            ha="center",
            va="center",
            transform=ax.transAxes,
        )
        ax.set_axis_off()
        return f"{name}: {gain}"
    # a finding of this run carries its group and rows (the figures read them)
    assert g is not None and rows is not None
    values = candidate_values(g.tests, f.cause).to_numpy()[rows]
    labels = natural_sorted({str(v) for v in values})
    if len(labels) > _CURVES:
        labels = [labels[k] for k in np.linspace(0, len(labels) - 1, _CURVES).round().astype(int)]
    xk = "z" if g.kind == "sinkage" else "j"
    for k, lv in enumerate(labels):
        pick = rows[[str(v) == lv for v in values]]
        if not pick.size:
            continue
        one, colour = pick[:1], f"C{k}"
        mask = g.samples_of(one)
        x = g.x[xk][mask]
        order = np.argsort(x)
        ax.plot(x[order] * 1e3, g.y[mask][order] / 1e3, ".", ms=1.5, color=colour, label=_short(lv))
        yb = f.base_fitted.extension.predict(f.base_fitted, g, one)
        ye = f.fitted.extension.predict(f.fitted, g, one)
        ax.plot(x[order] * 1e3, yb[order] / 1e3, "--", color=colour, lw=0.8)
        ax.plot(x[order] * 1e3, ye[order] / 1e3, "-", color=colour, lw=1.1)
    ax.set_xlabel("sinkage z (mm)" if g.kind == "sinkage" else "shear displacement j (mm)")
    ax.set_ylabel("p (kPa)" if g.kind == "sinkage" else "τ (kPa)")
    ax.legend(ncol=2, frameon=False, handletextpad=0.2, columnspacing=0.6, markerscale=3)
    return f"{name}: {gain}"


def findings_figure(numbered: list[tuple[int, Finding]]) -> Figure:
    """A grid of findings, one per row: each its deviation and curve panels under a title
    that states the effect and the gain."""
    per_row = 1  # two panels across the page: room for 8 pt levels and legends
    rows = math.ceil(len(numbered) / per_row)
    with mpl.rc_context(GRID_STYLE):
        fig = Figure(figsize=(6.5, 2.2 * rows + (0.4 if rows == 1 else 0)), layout="constrained")
        grid: Any = fig.subfigures(rows, per_row, wspace=0.03, hspace=0.02)  # one or an array
        subs = np.atleast_1d(grid).ravel()
        for k, sub in enumerate(subs):
            if k >= len(numbered):
                continue
            i, f = numbered[k]
            ax1, ax2 = sub.subplots(1, 2)
            effect = _deviation_panel(ax1, f)
            gain = _curve_panel(ax2, f)
            head = f"[{i}] {f.kind} / {f.soil}, {_short(f.cause, 30)}: {effect}"
            title = "\n".join(textwrap.wrap(head, 100) + textwrap.wrap(gain, 100))
            sub.suptitle(title, x=0.02, ha="left")
        fig.canvas.draw()  # lay out under the style's fonts before the rc context ends
    return fig
