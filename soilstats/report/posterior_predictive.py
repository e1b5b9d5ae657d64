"""The posterior-predictive figure of a posterior (:func:`predictive_figure`): measured curves
against the predictive band, one line per test, one panel per plate size or normal pressure.
Moved out of :mod:`.posterior_figures` (issue #45); import it from here.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd
from matplotlib import rc_context
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import MaxNLocator

from ..bayes._arviz import az
from ..bayes.predictive import input_name
from ..campaign.index import grouped_by_code
from ..errors import InputError
from .document import FIGURE_STYLE, math_text
from .posterior_figures import FIGSIZE, FigurePosterior, figure_posterior

if TYPE_CHECKING:
    from ..bayes.result import PosteriorResult

__all__ = ["MAX_DRAWN_SAMPLES", "predictive_figure"]


#: Display of the measured quantities: (x coordinate, x label, y label, x and y factors).
_CURVES = {
    False: ("z_m", "sinkage $z$ (mm)", "pressure $p$ (kPa)", 1e3, 1e-3),
    True: ("j_m", "shear displacement $j$ (mm)", "shear stress $\\tau$ (kPa)", 1e3, 1e-3),
}
#: Test-level quantity the panels are split by: (coordinate, caption words, title format).
_PANELS = {
    False: ("b_m", "plate size b", "plate $b$ = {:.3g} mm", 1e3),
    True: ("sigma_Pa", "normal pressure σ", "$\\sigma$ = {:.3g} kPa", 1e-3),
}


def predictive_figure(
    posterior: PosteriorResult | az.InferenceData,
    *,
    prob: float = 0.9,
    max_panels: int = 6,
    max_tests: int = 4,
    draws: int = 200,
    figsize: tuple[float, float] = FIGSIZE,
) -> tuple[Figure, str]:
    """Measured curves against the posterior-predictive band, per test.

    Pressure p (kPa) against sinkage z (mm) for a sinkage model, shear stress τ (kPa) against
    shear displacement j (mm) for a shear model: every test is its own line (never
    concatenated over sample index), with its ``prob`` equal-tailed band in the same colour.
    One panel per plate size (sinkage) or normal pressure (shear).

    Pooled posterior: the band is that of the replicated data in ``posterior_predictive``
    (the weighted Gaussian likelihood, measurement noise included).  Population posterior:
    the band is that of the curve a new preparation gives at the test's plate size or
    normal pressure (``draws`` posterior draws, evenly spaced; no measurement noise), and the
    measured curves come from ``constant_data``.

    Parameters
    ----------
    posterior : PosteriorResult or arviz.InferenceData
    prob : float
        Probability of the band (equal-tailed).
    max_panels : int
        Most panels (plate sizes or normal pressures); evenly spread over the sorted levels
        when there are more.  The caption says how many are shown.
    max_tests : int
        Most tests drawn per panel (the first in test order); the caption says so.
    draws : int
        Population posterior: most posterior draws the band is computed from.
    figsize : (width, height) in inches

    Returns
    -------
    (Figure, str)
        The figure and its caption.
    """
    if not 0 < prob < 1:
        raise InputError(f"prob must be in (0, 1), got {prob!r}")
    if max_panels < 1 or max_tests < 1:
        raise InputError("max_panels and max_tests must be at least 1")
    post = figure_posterior(posterior)
    measured = _measured(post)
    xname, xlabel, ylabel, xs, ys = _CURVES[post.shear]
    gname, gwords, gtitle, gs = _PANELS[post.shear]
    samples_of = _samples_by_test(measured["test"].to_numpy().astype(str))
    order = list(samples_of)  # test order as stored
    level_of, levels, panels = _levels(measured, gname, samples_of, max_panels)
    members_of = {
        level: [t for t in order if _same(level_of[t], level)][:max_tests] for level in panels
    }
    # The band only where a line is drawn (soil01: 24 of 372 tests; the rest cost seconds).
    thinned = {t: _thinned(samples_of[t]) for tests in members_of.values() for t in tests}
    keep = np.sort(np.concatenate(list(thinned.values()))) if thinned else np.arange(0)
    lo, hi, band_words = _band(post, measured, prob, draws, keep)
    x_all = measured[xname].to_numpy() if xname in measured.coords else None
    if x_all is None:
        raise InputError(
            f"the data carry no {xname} coordinate; re-run the posterior with this soilstats "
            "version to plot curves against the physical input"
        )
    y_all = measured["y"].to_numpy()
    drawn, skipped = 0, 0
    ncols = len(panels) if len(panels) <= 3 else (2 if len(panels) == 4 else 3)
    nrows = math.ceil(len(panels) / ncols)
    with rc_context(FIGURE_STYLE):
        fig = Figure(figsize=figsize, layout="constrained")
        axes = fig.subplots(nrows, ncols, squeeze=False)
        for ax in axes.ravel()[len(panels) :]:
            ax.set_axis_off()
        for p, level in enumerate(panels):
            ax = axes.ravel()[p]
            skipped += sum(_same(level_of[t], level) for t in order) - len(members_of[level])
            for c, t in enumerate(members_of[level]):
                _test_line(ax, f"C{c % 10}", thinned[t], (x_all * xs, y_all * ys), lo * ys, hi * ys)
                drawn += 1
            if np.isfinite(level):
                math_text(ax.set_title(gtitle.format(level * gs)))
            ax.xaxis.set_major_locator(MaxNLocator(4))
            ax.yaxis.set_major_locator(MaxNLocator(5))
            row, col = divmod(p, ncols)
            if row == nrows - 1 or p + ncols >= len(panels):
                math_text(ax.set_xlabel(xlabel))
            if col == 0:
                math_text(ax.set_ylabel(ylabel))
        fig.legend(
            handles=[
                Line2D([], [], color="0.2", lw=0.9, label="measured (one line per test)"),
                Patch(color="0.2", alpha=0.25, lw=0, label=f"{prob:.0%} predictive band"),
            ],
            loc="outside upper center",
            ncols=2,
            frameon=False,
        )
    caption = _predictive_caption(
        post,
        prob,
        band_words,
        (len(order), drawn, skipped, max_tests),
        len(levels),
        len(panels),
        gwords,
    )
    return fig, caption


def _levels(
    measured: Any, gname: str, samples_of: dict[str, np.ndarray], max_panels: int
) -> tuple[dict[str, float], list[float], list[float]]:
    """Each test's level (plate size or normal pressure, rounded), the sorted levels, and
    the panels: at most ``max_panels`` levels, evenly spread."""
    if gname in measured.coords:
        values = measured[gname].to_numpy()
        level_of = {t: _round(np.mean(values[where])) for t, where in samples_of.items()}
        levels = sorted(set(level_of.values()))
    else:
        level_of, levels = dict.fromkeys(samples_of, np.nan), [np.nan]
    if len(levels) > max_panels:
        pick = np.unique(np.linspace(0, len(levels) - 1, max_panels).round().astype(int))
        return level_of, levels, [levels[i] for i in pick]
    return level_of, levels, levels


def _test_line(
    ax: Any,
    colour: str,
    where: np.ndarray,
    xy: tuple[np.ndarray, np.ndarray],
    lo: np.ndarray,
    hi: np.ndarray,
) -> None:
    """One test: its band over the samples ``where`` (sorted by x) and its measured line,
    in display units."""
    x, y = xy
    sort = where[np.argsort(x[where], kind="stable")]
    ax.fill_between(x[sort], lo[sort], hi[sort], color=colour, alpha=0.25, lw=0)
    ax.plot(x[where], y[where], color=colour, lw=0.9)


def _round(value: float) -> float:
    """A level rounded to 4 significant digits, so repeated tests share a panel."""
    value = float(value)
    return float(f"{value:.4g}") if np.isfinite(value) else value


#: Samples of one test drawn in the predictive check: more are invisible at print size and
#: only slow the vector figure (CMU's 18 tests of ~5000 samples: 2 s of savefig).
MAX_DRAWN_SAMPLES = 400


def _thinned(index: np.ndarray) -> np.ndarray:
    """At most ``MAX_DRAWN_SAMPLES`` of ``index``, evenly spread, first and last kept."""
    if index.size <= MAX_DRAWN_SAMPLES:
        return index
    return index[np.unique(np.linspace(0, index.size - 1, MAX_DRAWN_SAMPLES).round().astype(int))]


def _nan_quantiles(curves: np.ndarray, q: list[float]) -> np.ndarray:
    """``np.nanquantile(curves, q, axis=0)`` (linear interpolation) in one sort: numpy falls
    back to a Python loop over the columns as soon as one NaN is present (3 s for soil01's
    44,640 samples)."""
    ordered = np.sort(curves.T, axis=1)  # NaN sorts last; rows contiguous for the sort
    valid = (~np.isnan(ordered)).sum(axis=1)
    rows = np.arange(ordered.shape[0])
    out = np.full((len(q), ordered.shape[0]), np.nan)
    has = valid > 0
    for k, p in enumerate(q):
        position = (valid - 1).clip(0) * p
        below = np.floor(position).astype(int)
        above = np.minimum(below + 1, (valid - 1).clip(0))
        t = position - below
        a, b = ordered[rows, below], ordered[rows, above]
        out[k, has] = (a + (b - a) * t)[has]
    return out


def _samples_by_test(tests: np.ndarray) -> dict[str, np.ndarray]:
    """Sample indices of each test (ascending), tests in the order they first appear: one
    sort, not a comparison of every sample with every test (soil01: 372 × 44,640)."""
    codes, names = pd.factorize(tests)
    return dict(zip(names.astype(str), grouped_by_code(codes, len(names)), strict=True))


def _spread_out(bounds: np.ndarray, keep: np.ndarray, measured: Any) -> np.ndarray:
    """(2, kept) band bounds as (2, all samples), NaN where a sample is not drawn."""
    out = np.full((2, measured["y"].size), np.nan)
    out[:, keep] = bounds
    return out


def _same(a: float, b: float) -> bool:
    return (np.isnan(a) and np.isnan(b)) or a == b


def _measured(post: FigurePosterior) -> Any:
    """The measured curves the predictive check draws: ``constant_data`` of a population
    posterior, ``observed_data`` of a pooled one."""
    idata = post.idata
    if post.kind == "population":
        if "constant_data" not in idata.groups() or "y" not in idata.constant_data:
            raise InputError(
                "this population posterior carries no measured curves (constant_data); "
                "re-run it with this soilstats version"
            )
        return idata.constant_data
    if "posterior_predictive" not in idata.groups() or "y" not in idata.posterior_predictive:
        raise InputError(
            "this posterior carries no posterior-predictive data 'y'; re-run it with this "
            "soilstats version"
        )
    return idata.observed_data


def _band(
    post: FigurePosterior, measured: Any, prob: float, draws: int, keep: np.ndarray
) -> tuple[np.ndarray, np.ndarray, str]:
    """Lower and upper band at the samples ``keep`` (NaN elsewhere), and how the band was
    made."""
    q = [(1 - prob) / 2, (1 + prob) / 2]
    idata = post.idata
    if post.kind == "population":
        names = post.model.param_names
        theta = np.column_stack([idata.posterior[n].to_numpy().ravel() for n in names])
        step = max(1, math.ceil(len(theta) / max(draws, 1)))
        theta = theta[::step]
        inputs = [input_name(label) for label in post.model.inputs]
        columns = [measured[name].to_numpy()[keep] for name in inputs]
        x = columns[0] if len(columns) == 1 else np.vstack(columns)
        cols = [theta[:, i : i + 1] for i in range(theta.shape[1])]
        with np.errstate(all="ignore"):
            curves = np.asarray(post.model.func(x, *cols), float)
        lo, hi = _spread_out(_nan_quantiles(curves, q), keep, measured)
        where = "normal pressure" if post.shear else "plate size"
        words = (
            f"the curve a new preparation of the soil gives at that test's {where} "
            f"({len(theta)} posterior draws; the band contains no measurement noise)"
        )
        return lo, hi, words
    rep = idata.posterior_predictive["y"]
    flat = rep.to_numpy().reshape(-1, rep.sizes["obs"])
    lo, hi = _spread_out(np.quantile(flat[:, keep], q, axis=0), keep, measured)
    words = (
        f"the replicated data ({flat.shape[0]} data sets drawn from the weighted Gaussian "
        f"likelihood at joint posterior draws of the parameters and the noise scale σ_w, "
        f"so measurement noise is included)"
    )
    return lo, hi, words


def _predictive_caption(
    post: FigurePosterior,
    prob: float,
    band_words: str,
    counts: tuple[int, int, int, int],
    n_levels: int,
    n_panels: int,
    gwords: str,
) -> str:
    n_tests, drawn, skipped, max_tests = counts
    if post.shear:
        what = "Measured shear stress τ (kPa) against shear displacement j (mm)"
        if post.model.steady_state:
            what += " over each test's steady-state part (the samples Mohr–Coulomb uses)"
    else:
        what = "Measured pressure p (kPa) against sinkage z (mm)"
    text = (
        f"{what} of the {post.title}: each test is one line in its own colour, with the "
        f"{prob:.0%} equal-tailed posterior-predictive band of {band_words} shaded in the "
        f"same colour. One panel per {gwords}."
    )
    if n_panels < n_levels:
        text += f" {n_panels} of the {n_levels} levels of {gwords} are shown, evenly spread."
    if skipped:
        text += (
            f" At most the first {max_tests} tests of a panel are drawn: {drawn} of the "
            f"{n_tests} tests are shown."
        )
    elif drawn < n_tests:
        text += f" {drawn} of {n_tests} tests are shown."
    return text
