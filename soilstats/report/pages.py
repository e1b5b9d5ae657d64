"""Text pages of the PDF reports: one layout for every report soilstats writes.

Monospace pages on A4, paginated (nothing is cut off), with the same wrapping rules for
prose, tables and the provenance page.
"""

from __future__ import annotations

import textwrap

from matplotlib.figure import Figure

__all__ = [
    "A4",
    "frame_lines",
    "provenance_page",
    "text_pages",
    "wrap_lines",
    "wrap_paragraphs",
]

A4 = (8.27, 11.69)  # inches
LINES_PER_PAGE = 62
WIDTH = 110  # characters of monospace text at the page font size


def wrap_paragraphs(text: str, width: int = WIDTH) -> list[str]:
    """Prose as lines: paragraphs (blank-line separated) re-flowed, each followed by a blank."""
    out: list[str] = []
    for para in text.split("\n\n"):
        out += [*textwrap.wrap(" ".join(para.split()), width), ""]
    return out


def wrap_lines(lines, width: int = WIDTH, indent: str = "") -> list[str]:
    """Each line wrapped at ``width``, continuation lines indented by ``indent``."""
    return [
        part
        for line in lines
        for part in (textwrap.wrap(line, width, subsequent_indent=indent) or [""])
    ]


def frame_lines(frame) -> list[str]:
    """A DataFrame as text lines (4 significant digits, no index)."""
    import pandas as pd

    with pd.option_context(
        "display.width", 140, "display.max_columns", 30, "display.max_colwidth", 40
    ):
        return frame.to_string(index=False, float_format=lambda v: f"{v:.4g}").split("\n")


def text_pages(pdf, title: str, lines: list[str], *, fontsize: float = 7.2) -> int:
    """Write ``lines`` under ``title`` onto as many A4 pages as they need; return the count."""
    per_page = LINES_PER_PAGE
    chunks = [lines[i : i + per_page] for i in range(0, max(len(lines), 1), per_page)]
    for i, chunk in enumerate(chunks):
        fig = Figure(figsize=A4)
        head = title if i == 0 else f"{title} (continued)"
        fig.text(0.06, 0.965, head, fontsize=13, weight="bold", va="top")
        fig.text(0.06, 0.935, "\n".join(chunk), fontsize=fontsize, family="monospace", va="top")
        pdf.savefig(fig)
    return len(chunks)


def provenance_page(pdf, provenance) -> int:
    """The last page of every report: version, campaign hash, command, seed."""
    return text_pages(pdf, "Provenance", wrap_lines(provenance.lines()))
