"""Publication figures of a posterior: trace, pair and (in :mod:`.posterior_predictive`, which
builds on this module) posterior-predictive.

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
from matplotlib import colormaps, rc_context
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from ..bayes._arviz import az
from ..errors import InputError
from ..models import MODELS, Model, get_model
from .document import FIGURE_STYLE, math_text

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from ..bayes.result import PosteriorResult

__all__ = [
    "FIGSIZE",
    "PARAMETERS",
    "pair_figure",
    "parameter_label",
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


def _units_sentence(names: Iterable[str], units: dict) -> str:
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
class FigurePosterior:
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


def figure_posterior(obj: Any) -> FigurePosterior:
    """What the figures read of a PosteriorResult (or of its InferenceData)."""
    idata = getattr(obj, "idata", obj)
    attrs = idata.posterior.attrs
    model = get_model(getattr(obj, "model_name", None) or attrs["model"])
    kind = getattr(obj, "kind", None) or attrs.get("kind", "pooled")
    names = tuple(getattr(obj, "param_names", None) or model.param_names)
    units = dict(getattr(obj, "units", None) or model.unit_of)
    return FigurePosterior(idata, model, kind, names, units)


def _shown(posterior: Any, most: int) -> tuple[FigurePosterior, tuple[str, ...], str]:
    """(the posterior, the parameters a figure shows, the caption's note when some are left
    out): the first ``most`` of the model's parameters (:func:`_capped`)."""
    post = figure_posterior(posterior)
    return post, *_capped(post.names, most)


def _capped(names: Iterable[str], most: int) -> tuple[tuple[str, ...], str]:
    names = tuple(names)
    if most < 1:
        raise InputError(f"the most parameters to show must be at least 1, got {most}")
    if len(names) <= most:
        return names, ""
    return names[:most], f" Only the first {most} of the {len(names)} parameters are shown."


def _new_preparation_note(post: FigurePosterior) -> str:
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


def _kde(values: np.ndarray, log: bool, **kwargs: Any) -> tuple[np.ndarray, np.ndarray]:
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


def _chain_colour(i: int, n: int) -> tuple[float, float, float, float]:
    return colormaps["viridis"](0.1 + 0.8 * i / max(n - 1, 1))


def _diagnostics(data: Any, names: Iterable[str]) -> str:  # data: an xarray Dataset
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


def _marginal_panel(ax: Axes, x: np.ndarray, log: bool) -> None:
    """A diagonal panel of :func:`pair_figure`: the marginal density of one parameter's
    draws ``x`` (per decade on a log axis), without a y axis."""
    grid, pdf = _kde(x, log)
    ax.plot(grid, pdf, color="k", lw=1.0)
    ax.fill_between(grid, pdf, color="0.8", lw=0)
    ax.set_yticks([])
    ax.spines["left"].set_visible(False)


def _joint_panel(ax: Axes, x: np.ndarray, y: np.ndarray, r: float, log_y: bool) -> None:
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
    post: FigurePosterior,
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
