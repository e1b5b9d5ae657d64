"""PDF report of a discovery: what the model gets wrong, the cause, the extension, the gain.

One page of summary, then one page per finding: the per-test deviations against the cause
(the structure the base model leaves), measured curves of one test per level with the base
and extended model's predictions (the misfit on the curves), and the extended parameters
± σ (Eq. 3) with the cross-validated gain; then the red flags.  Reads a
:class:`DiscoveryResult` only (plotting never feeds back into the analysis).
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_pdf import PdfPages
from matplotlib.figure import Figure

from ..discovery.candidates import candidate_values
from .files import output_path
from .pages import A4, provenance_page, text_pages, wrap_lines

_INDENT = "      "

__all__ = ["write_report"]


def _finding_page(index: int, f) -> Figure:
    fig = Figure(figsize=A4)
    fig.suptitle(f"[{index}] {f.kind} / {f.soil}: cause {f.cause}", fontsize=12, weight="bold")
    g, rows = f.group, f.scope_rows
    ax1 = fig.add_axes((0.1, 0.68, 0.82, 0.22))
    response = f.responses[0] if f.responses else "level"
    dev = g.tests[f"_dev_{response}"].to_numpy(float)[rows]
    values = candidate_values(g.tests, f.cause).to_numpy()[rows]
    labels = sorted({str(v) for v in values}, key=lambda s: (len(s), s))
    try:
        labels = sorted(labels, key=float)
    except ValueError:
        pass
    pos = {lv: i for i, lv in enumerate(labels)}
    xs = np.array([pos[str(v)] for v in values], float)
    jitter = np.random.default_rng(0).uniform(-0.15, 0.15, xs.size)  # display only
    ax1.scatter(xs + jitter, dev, s=10, alpha=0.7)
    for i in pos.values():
        m = dev[xs == i]
        if m.size:
            ax1.hlines(np.nanmean(m), i - 0.3, i + 0.3, color="k")
    ax1.axhline(0, color="0.6", lw=0.8)
    ax1.set_xticks(range(len(labels)), labels, fontsize=7, rotation=30)
    ax1.set_xlabel(f.cause)
    ax1.set_ylabel(f"deviation ({response})")
    ax1.set_title("what the base model leaves, per test (black: level mean)", fontsize=9)

    ax2 = fig.add_axes((0.1, 0.36, 0.82, 0.25))
    if f.base_fitted is not None and f.fitted is not None:
        colors = iter(["C0", "C1", "C2", "C3", "C4", "C5", "C6", "C7", "C8", "C9"] * 10)
        for lv in labels[:8]:
            pick = rows[[str(v) == lv for v in values]]
            if not pick.size:
                continue
            one = pick[:1]
            mask = g.samples_of(one)
            xk = "z" if g.kind == "sinkage" else "j"
            x, order = g.x[xk][mask], np.argsort(g.x[xk][mask])
            col = next(colors)
            ax2.plot(x[order], g.y[mask][order], ".", ms=2, color=col, label=f"{f.cause}={lv}")
            yb = f.base_fitted.extension.predict(f.base_fitted, g, one)
            ye = f.fitted.extension.predict(f.fitted, g, one)
            ax2.plot(x[order], yb[order], "--", color=col, lw=0.9)
            ax2.plot(x[order], ye[order], "-", color=col, lw=1.2)
        ax2.set_xlabel("z [m]" if g.kind == "sinkage" else "j [m]")
        ax2.set_ylabel("p [Pa]" if g.kind == "sinkage" else "tau [Pa]")
        ax2.legend(fontsize=6, ncol=2)
        ax2.set_title(
            f"one test per level: data (dots), base (dashed), {f.fitted.extension.name} (solid)",
            fontsize=9,
        )
    else:
        ax2.text(0.5, 0.5, "no extended model could be fitted", ha="center")
        ax2.set_axis_off()
    lines = f.summary_lines()[1:]
    wrapped: list[str] = []
    for line in lines:
        wrapped += textwrap.wrap(line, 115, subsequent_indent="      ") or [""]
    fig.text(0.05, 0.3, "\n".join(wrapped[:40]), family="monospace", fontsize=6, va="top")
    return fig


def write_report(
    result,
    folder: Path,
    *,
    name: str = "discover.pdf",
    max_findings: int = 12,
    overwrite: bool = False,
):
    """Write the PDF report into ``folder`` (created if needed); returns its path.

    The last page and the PDF metadata carry the result's provenance; an existing file is
    an error unless ``overwrite``.
    """
    path = output_path(folder, name, overwrite=overwrite)
    provenance = result.provenance
    metadata = None if provenance is None else provenance.pdf_metadata("soilstats discovery")
    with PdfPages(path, metadata=metadata) as pdf:
        text_pages(
            pdf, "soilstats discovery", wrap_lines(result.summary().splitlines(), indent=_INDENT)
        )
        for i, f in enumerate(result.findings[:max_findings], 1):
            if f.group is not None and f.scope_rows is not None:
                pdf.savefig(_finding_page(i, f))
        flags = [
            f"{fl['kind']} / {fl['soil']} [{fl['scope']}] {fl['code']}: {fl['message']}"
            for fl in result.flags
        ] or ["No red flags."]
        text_pages(pdf, "Physical red flags", wrap_lines(flags, indent=_INDENT))
        if provenance is not None:
            provenance_page(pdf, provenance)
    return path
