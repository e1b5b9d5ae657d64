"""Publication figures of a posterior: trace, pair and posterior-predictive.

Each function takes a :class:`~soilstats.bayes.PosteriorResult` — or its ``idata``, or a
``posterior.nc`` read back with ``az.from_netcdf`` — and returns ``(Figure, caption)``: a
:class:`matplotlib.figure.Figure` built with the object API (no pyplot state, no backend
change), 6.3 × 4 in by default (an A4 page with 2.5 cm margins), constrained layout, fonts of
8 pt and more, and a caption of full sentences naming what is shown and its units.

Parameters are shown as physical quantities with human labels and display units —
k_c [kN/m^(n+1)], k_φ [kN/m^(n+2)], n [–], c [kPa], φ [°], K [mm] — never as the sampler's
variable names.  For a population posterior the parameters are those of a *new
preparation* (what :meth:`~soilstats.bayes.PosteriorResult.draws` returns).

==========================  ===============================================================
:func:`trace_figure`        chains over kept iterations and the marginal density, per
                            parameter
:func:`pair_figure`         pairwise joint draws with the correlation coefficient, marginals
                            on the diagonal
:func:`predictive_figure`   measured curves against the posterior-predictive band, pressure
                            against sinkage or shear stress against shear displacement, one
                            line per test, one panel per plate size or normal pressure
==========================  ===============================================================
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, cast

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
from ..models import MODELS, Model, get_model
from .document import FIGURE_STYLE, math_text

if TYPE_CHECKING:
    from ..bayes.result import PosteriorResult

__all__ = [
    "FIGSIZE",
    "PARAMETERS",
    "pair_figure",
    "parameter_label",
    "predictive_figure",
    "trace_figure",
]

#: Default figure size [in]: the text width of an A4 page with 2.5 cm margins, by 4 in.
FIGSIZE = (6.3, 4.0)


class _Parameters(Mapping):
    """Display of each parameter: axis label (mathtext), caption name, display unit, unit in
    words, and the factor from the SI value stored in the posterior to the display unit —
    from the model records (``Model.labels``), the first registered model to label a
    parameter for figures saying how."""

    def _table(self) -> dict[str, tuple]:
        out: dict[str, tuple] = {}
        for model in MODELS.values():
            for name, label in cast(tuple, model.labels):  # pairs once built
                if label.axis is not None and name not in out:
                    shown = (label.axis, label.caption, label.unit, label.unit_words)
                    out[name] = (*shown, label.scale)
        return out

    def __getitem__(self, name: str) -> tuple:
        return self._table()[name]

    def __iter__(self):
        return iter(self._table())

    def __len__(self) -> int:
        return len(self._table())


#: Display of each parameter (see :class:`_Parameters`), read from the model records.
PARAMETERS: Mapping[str, tuple] = _Parameters()


def parameter_label(name: str, unit: str | None = None) -> str:
    """Axis label of a parameter with its display unit, e.g. ``$k_c$ (kN/m$^{n+1}$)``.

    A parameter without a display entry keeps its name and ``unit`` (SI) as given.
    """
    if name in PARAMETERS:
        symbol, _, shown, _, _ = PARAMETERS[name]
        return f"{symbol} ({shown})"
    return f"{name} ({unit})" if unit else name


def _caption_name(name: str) -> str:
    return PARAMETERS[name][1] if name in PARAMETERS else name


def _units_sentence(names, units: dict) -> str:
    parts = []
    for n in names:
        unit = PARAMETERS[n][3] if n in PARAMETERS else units.get(n, "")
        if unit in ("", "-", "dimensionless"):
            parts.append(f"{_caption_name(n)} dimensionless")
        else:
            parts.append(f"{_caption_name(n)} in {unit}")
    return "Units: " + ", ".join(parts) + "."


def _scale(name: str) -> float:
    return PARAMETERS[name][4] if name in PARAMETERS else 1.0


@dataclass(frozen=True)
class _Posterior:
    """What the figures need from a result or an InferenceData."""

    # arviz.InferenceData: Any, as its groups (posterior, observed_data, …) are attributes
    # made at run time, which its type does not name.
    idata: Any
    model: Model
    kind: str
    names: tuple[str, ...]
    units: dict

    @property
    def title(self) -> str:
        return f"{self.model.name} {self.kind} posterior"

    @property
    def shear(self) -> bool:
        return self.model.output.startswith("tau")


def _posterior(obj) -> _Posterior:
    idata = getattr(obj, "idata", obj)
    attrs = idata.posterior.attrs
    model = get_model(getattr(obj, "model_name", None) or attrs["model"])
    kind = getattr(obj, "kind", None) or attrs.get("kind", "pooled")
    names = tuple(getattr(obj, "param_names", None) or model.param_names)
    units = dict(getattr(obj, "units", None) or model.unit_of)
    return _Posterior(idata, model, kind, names, units)


def _shown(posterior, most: int) -> tuple[_Posterior, tuple[str, ...], str]:
    """(the posterior, the parameters a figure shows, the caption's note when some are left
    out): the first ``most`` of the model's parameters (:func:`_capped`)."""
    post = _posterior(posterior)
    return post, *_capped(post.names, most)


def _capped(names, most: int) -> tuple[tuple[str, ...], str]:
    names = tuple(names)
    if most < 1:
        raise InputError(f"the most parameters to show must be at least 1, got {most}")
    if len(names) <= most:
        return names, ""
    return names[:most], f" Only the first {most} of the {len(names)} parameters are shown."


def _new_preparation_note(post: _Posterior) -> str:
    if post.kind != "population":
        return ""
    return (
        " The values are those of a new preparation of the soil: the soil-level parameters "
        "with the between-preparation scatter applied, one per posterior draw."
    )


def trace_figure(
    posterior: PosteriorResult | az.InferenceData,
    *,
    max_params: int = 4,
    figsize: tuple[float, float] = FIGSIZE,
) -> tuple[Figure, str]:
    """Trace of every chain over the kept iterations, and the marginal density, per parameter.

    Parameters
    ----------
    posterior : PosteriorResult or arviz.InferenceData
        A result of :func:`~soilstats.bayes.sample_posterior` or
        :func:`~soilstats.bayes.sample_population`, or its ``idata``.
    max_params : int
        Most parameters shown (one row each); the caption says when some are left out.
    figsize : (width, height) in inches

    Returns
    -------
    (Figure, str)
        The figure and its caption.
    """
    post, names, capped = _shown(posterior, max_params)
    data = post.idata.posterior
    with rc_context(FIGURE_STYLE):
        fig = Figure(figsize=figsize, layout="constrained")
        grid = fig.add_gridspec(len(names), 2, width_ratios=(3.2, 1.0))
        for row, name in enumerate(names):
            values = data[name].to_numpy() * _scale(name)
            chains, draws = values.shape
            trace = fig.add_subplot(grid[row, 0])
            dens = fig.add_subplot(grid[row, 1], sharey=trace)
            colours = [_chain_colour(i, chains) for i in range(chains)]
            steps = np.arange(draws)
            log = spans_decades(values)
            for i in range(chains):
                trace.plot(steps, values[i], lw=0.4, alpha=0.6, color=colours[i], rasterized=True)
                grid_i, pdf_i = _kde(values[i], log, bw="scott")
                dens.plot(pdf_i, grid_i, lw=0.4, alpha=0.5, color=colours[i])
            grid_all, pdf_all = _kde(values.ravel(), log)
            dens.plot(pdf_all, grid_all, lw=1.2, color="k")
            if log:
                trace.set_yscale("log")
            math_text(trace.set_ylabel(parameter_label(name, post.units.get(name))))
            trace.set_xlim(0, max(draws - 1, 1))
            if not log:
                trace.yaxis.set_major_locator(MaxNLocator(4))
            dens.tick_params(labelleft=False)
            dens.set_xticks([])
            if row == len(names) - 1:
                trace.set_xlabel("kept draw (after burn-in and thinning)")
                dens.set_xlabel("density")
            else:
                trace.tick_params(labelbottom=False)
        diag = _diagnostics(data, names)
    chains, draws = data.sizes["chain"], data.sizes["draw"]
    listed = ", ".join(_caption_name(n) for n in names)
    caption = (
        f"Trace of the {post.title} ({post.model.equation.split(':')[0]}) for {listed}: left, "
        f"the value of each of the {chains} emcee walkers (one line per walker) over its "
        f"{draws} kept draws after burn-in and thinning; right, the marginal posterior "
        f"density of all {chains * draws} draws (black) and of each walker (thin lines). "
        f"{_units_sentence(names, post.units)} {diag}{_log_note(values_of(data, names))}"
        f"{_new_preparation_note(post)}{capped}"
    )
    return fig, caption


#: A parameter whose draws (1st to 99th percentile) span this ratio or more is drawn on a
#: logarithmic axis: on a linear one its lower decade is a line at zero.
DECADES_RATIO = 10.0


def spans_decades(values: np.ndarray) -> bool:
    """Whether positive draws span a decade or more (1st to 99th percentile)."""
    v = np.asarray(values, float).ravel()
    v = v[np.isfinite(v)]
    if v.size < 2 or not (v > 0).all():
        return False
    lo, hi = np.quantile(v, [0.01, 0.99])
    return bool(hi / lo >= DECADES_RATIO)


def _kde(values: np.ndarray, log: bool, **kwargs) -> tuple[np.ndarray, np.ndarray]:
    """Kernel density of ``values`` (for a log axis: of their log10, per decade, returned
    at the values themselves)."""
    if not log:
        return az.kde(values, **kwargs)
    grid, pdf = az.kde(np.log10(values), **kwargs)
    return 10.0**grid, pdf


def values_of(data: Any, names: Iterable[str]) -> dict[str, np.ndarray]:
    """Each parameter's draws (all chains, flattened) in its display unit."""
    return {n: data[n].to_numpy().ravel() * _scale(n) for n in names}


def _log_note(values: dict[str, np.ndarray]) -> str:
    """The caption's sentence naming the parameters drawn on log axes (empty: none)."""
    logs = [n for n, v in values.items() if spans_decades(v)]
    if not logs:
        return ""
    listed = ", ".join(_caption_name(n) for n in logs)
    return (
        f" {listed} {'spans' if len(logs) == 1 else 'span'} a decade or more and "
        f"{'is' if len(logs) == 1 else 'are'} drawn on a logarithmic axis (its density per "
        "decade)."
    )


def _signed(value: float) -> str:
    """``+0.94`` / ``−0.23`` with a typographic minus."""
    return f"{value:+.2f}".replace("-", "\u2212")


def _chain_colour(i: int, n: int):
    from matplotlib import colormaps

    return colormaps["viridis"](0.1 + 0.8 * i / max(n - 1, 1))


def _diagnostics(data, names) -> str:
    ds = data[list(names)]
    rhat = az.rhat(ds)
    ess = az.ess(ds, method="bulk")
    worst = max(float(rhat[n]) for n in names)
    fewest = min(float(ess[n]) for n in names)
    return (
        f"Largest rank-normalised split R-hat {worst:.3f}, smallest bulk effective sample "
        f"size {fewest:.0f}."
    )


#: The box behind a pair panel's correlation coefficient.
_R_BOX = {"boxstyle": "round,pad=0.2", "fc": "white", "ec": "none", "alpha": 0.8}


def pair_figure(
    posterior: PosteriorResult | az.InferenceData,
    *,
    max_params: int = 4,
    max_points: int = 1500,
    figsize: tuple[float, float] = FIGSIZE,
) -> tuple[Figure, str]:
    """Pairwise joint posterior of the physical parameters, with correlation coefficients.

    Lower triangle: joint draws as points (at most ``max_points``, evenly spaced over the
    stored draws — no random subsampling), with Pearson's r of *all* draws printed in the
    panel; diagonal: marginal densities.  Parameters (``max_points`` aside) and the returned
    (figure, caption) as :func:`trace_figure`.
    """
    post, names, capped = _shown(posterior, max_params)
    data = post.idata.posterior
    values = values_of(data, names)
    logs = {n: spans_decades(v) for n, v in values.items()}
    labels = [parameter_label(n, post.units.get(n)) for n in names]
    total = next(iter(values.values())).size
    step = max(1, math.ceil(total / max_points))
    shown = np.arange(0, total, step)
    k = len(names)
    corr = np.corrcoef(np.vstack([values[n] for n in names])) if k > 1 else np.ones((1, 1))
    with rc_context(FIGURE_STYLE):
        fig = Figure(figsize=figsize, layout="constrained")
        axes = fig.subplots(k, k, squeeze=False)
        for i in range(k):
            for j in range(k):
                ax = axes[i, j]
                if j > i:
                    ax.set_axis_off()
                    continue
                x = values[names[j]]
                if i == j:
                    _marginal_panel(ax, x, logs[names[j]])
                else:
                    y = values[names[i]]
                    _joint_panel(ax, x[shown], y[shown], corr[i, j], logs[names[i]])
                    if j == 0:
                        math_text(ax.set_ylabel(labels[i]))
                    else:
                        ax.tick_params(labelleft=False)
                if logs[names[j]]:
                    ax.set_xscale("log")
                else:
                    ax.xaxis.set_major_locator(MaxNLocator(3))
                if i == k - 1:
                    math_text(ax.set_xlabel(labels[j]))
                else:
                    ax.tick_params(labelbottom=False)
                if i != j and j > 0:
                    ax.sharey(axes[i, 0])
                if i != j:
                    ax.sharex(axes[j, j])
    return fig, _pair_caption(post, names, values, corr, shown.size, step, capped)


def _marginal_panel(ax, x: np.ndarray, log: bool) -> None:
    """A diagonal panel of :func:`pair_figure`: the marginal density of one parameter's
    draws ``x`` (per decade on a log axis), without a y axis."""
    grid, pdf = _kde(x, log)
    ax.plot(grid, pdf, color="k", lw=1.0)
    ax.fill_between(grid, pdf, color="0.8", lw=0)
    ax.set_yticks([])
    ax.spines["left"].set_visible(False)


def _joint_panel(ax, x: np.ndarray, y: np.ndarray, r: float, log_y: bool) -> None:
    """A panel below the diagonal of :func:`pair_figure`: the shown joint draws (``x``,
    ``y``) as points, Pearson's ``r`` of all draws printed in its corner, and the y axis
    (logarithmic when ``log_y``)."""
    ax.scatter(x, y, s=1.5, alpha=0.35, color="C0", lw=0, rasterized=True)
    ax.text(
        0.04,
        0.96,
        f"r = {_signed(r)}",
        transform=ax.transAxes,
        va="top",
        ha="left",
        fontsize=8,
        bbox=_R_BOX,
    )
    if log_y:
        ax.set_yscale("log")
    else:
        ax.yaxis.set_major_locator(MaxNLocator(3))


def _pair_caption(
    post: _Posterior,
    names: tuple[str, ...],
    values: dict[str, np.ndarray],
    corr: np.ndarray,
    n_shown: int,
    step: int,
    capped: str,
) -> str:
    """The caption of :func:`pair_figure`: the parameters, how many draws each panel
    shows, every pair's correlation, the units, the log axes and what was left out."""
    k = len(names)
    total = next(iter(values.values())).size
    listed = ", ".join(_caption_name(n) for n in names)
    every = "all of them" if step == 1 else f"one in every {step}, evenly spaced"
    pairs = "; ".join(
        f"{_caption_name(names[i])}–{_caption_name(names[j])} {_signed(corr[i, j])}"
        for i in range(k)
        for j in range(i)
    )
    return (
        f"Joint posterior of {listed} ({post.title}). Below the diagonal each panel shows "
        f"{n_shown} of the {total} posterior draws ({every}) of one pair of "
        f"parameters, with Pearson's correlation coefficient r of all draws printed in the "
        f"panel{f' ({pairs})' if pairs else ''}; the diagonal shows each parameter's marginal "
        f"posterior density. {_units_sentence(names, post.units)}{_log_note(values)}"
        f"{_new_preparation_note(post)}{capped}"
    )


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
    post = _posterior(posterior)
    measured = _measured(post)
    xname, xlabel, ylabel, xs, ys = _CURVES[post.shear]
    gname, gwords, gtitle, gs = _PANELS[post.shear]
    samples_of = _samples_by_test(measured["test"].to_numpy().astype(str))
    order = list(samples_of)  # test order as stored
    if gname in measured.coords:
        values = measured[gname].to_numpy()
        level_of = {t: _round(np.mean(values[where])) for t, where in samples_of.items()}
        levels = sorted(set(level_of.values()))
    else:
        level_of, levels = dict.fromkeys(order, np.nan), [np.nan]
    if len(levels) > max_panels:
        pick = np.unique(np.linspace(0, len(levels) - 1, max_panels).round().astype(int))
        panels = [levels[i] for i in pick]
    else:
        panels = levels
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
                colour = f"C{c % 10}"
                where = thinned[t]
                sort = where[np.argsort(x_all[where], kind="stable")]
                ax.fill_between(
                    x_all[sort] * xs,
                    lo[sort] * ys,
                    hi[sort] * ys,
                    color=colour,
                    alpha=0.25,
                    lw=0,
                )
                ax.plot(x_all[where] * xs, y_all[where] * ys, color=colour, lw=0.9)
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


def _spread_out(bounds: np.ndarray, keep: np.ndarray, measured) -> np.ndarray:
    """(2, kept) band bounds as (2, all samples), NaN where a sample is not drawn."""
    out = np.full((2, measured["y"].size), np.nan)
    out[:, keep] = bounds
    return out


def _same(a: float, b: float) -> bool:
    return (np.isnan(a) and np.isnan(b)) or a == b


def _measured(post: _Posterior):
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


def _band(post: _Posterior, measured, prob: float, draws: int, keep: np.ndarray):
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


def _predictive_caption(post, prob, band_words, counts, n_levels, n_panels, gwords) -> str:
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
