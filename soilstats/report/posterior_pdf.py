"""A short PDF report of a posterior: trace, pair (corner) and posterior-predictive plots."""

from __future__ import annotations

import warnings
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.backends.backend_pdf import PdfPages

from ..bayes.result import PosteriorResult
from .files import output_path
from .pages import provenance_page
from .provenance import Provenance

__all__ = ["write_report"]


def _trace(res: PosteriorResult):
    names = res.param_names
    fig, axes = plt.subplots(len(names), 2, figsize=(8.3, 2.0 * len(names)), squeeze=False)
    post = res.idata.posterior
    for i, n in enumerate(names):
        v = post[n].to_numpy()
        for chain in v:
            axes[i, 0].plot(chain, lw=0.4, alpha=0.5)
        axes[i, 0].set_ylabel(f"{n} [{res.units[n]}]")
        axes[i, 1].hist(v.ravel(), bins=60, color="0.4")
    axes[0, 0].set_title("trace (one line per walker)")
    axes[0, 1].set_title("marginal posterior")
    status = "converged" if res.converged else "NOT CONVERGED: " + "; ".join(res.problems[:3])
    fig.suptitle(f"{res.model_name} ({res.kind}) — {status}", fontsize=9)
    fig.tight_layout()
    return fig


def _pair(res: PosteriorResult):
    d = res.draws(min(2000, len(res.draws())), seed=0)
    names = res.param_names
    k = len(names)
    fig, axes = plt.subplots(k, k, figsize=(8.3, 8.3), squeeze=False)
    for i in range(k):
        for j in range(k):
            ax = axes[i, j]
            if j > i:
                ax.axis("off")
            elif i == j:
                ax.hist(d[names[i]], bins=40, color="0.4")
            else:
                ax.plot(d[names[j]], d[names[i]], ".", ms=1, alpha=0.3, color="C0")
            if i == k - 1:
                ax.set_xlabel(names[j])
            if j == 0 and i > 0:
                ax.set_ylabel(names[i])
    fig.suptitle("pair plot (joint draws)", fontsize=9)
    fig.tight_layout()
    return fig


def _ppc(res: PosteriorResult):
    fig, ax = plt.subplots(figsize=(8.3, 5))
    obs = res.idata.observed_data
    pp = res.idata.posterior_predictive
    if "y" in obs:
        y = obs["y"].to_numpy()
        order = np.arange(y.size)
        rep = pp["y"].to_numpy().reshape(-1, y.size)
        lo, hi = np.quantile(rep, [0.05, 0.95], axis=0)
        ax.fill_between(
            order, lo, hi, color="C1", alpha=0.4, step="mid", label="90 % posterior-predictive band"
        )
        ax.plot(order, y, ".", ms=1.5, color="k", label="measured")
        ax.set_xlabel("sample (tests in campaign order)")
        ax.set_ylabel("measured quantity [Pa]")
    else:
        eta = obs["eta_hat"].to_numpy()
        rep = pp["eta_hat"].to_numpy().reshape(-1, *eta.shape)
        lo, hi = np.quantile(rep[..., 1], [0.05, 0.95], axis=0)
        t = np.arange(eta.shape[0])
        ax.fill_between(
            t,
            lo,
            hi,
            color="C1",
            alpha=0.4,
            step="mid",
            label="90 % band of n for a new preparation",
        )
        ax.plot(t, eta[:, 1], "o", color="k", label="per-test fit of n")
        ax.set_xlabel("test")
        ax.set_ylabel("n [-]")
    ax.legend()
    ax.set_title("posterior predictive (equal-tailed 90 %)")
    fig.tight_layout()
    return fig


def write_report(
    results: list[PosteriorResult],
    path: str | Path,
    *,
    provenance: Provenance | None = None,
    overwrite: bool = True,
) -> Path:
    """Write trace, pair and posterior-predictive pages for each result to one PDF.

    ``provenance`` goes into the PDF metadata and onto a last page.
    """
    path = output_path(Path(path).parent, Path(path).name, overwrite=overwrite)
    title = "soilstats posterior: " + ", ".join(r.model_name for r in results)
    metadata = None if provenance is None else provenance.pdf_metadata(title)
    with PdfPages(path, metadata=metadata) as pdf, warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*tight_layout.*", category=UserWarning)
        for res in results:
            for make in (_trace, _pair, _ppc):
                fig = make(res)
                pdf.savefig(fig)
                plt.close(fig)
        if provenance is not None:
            provenance_page(pdf, provenance)
    return path
