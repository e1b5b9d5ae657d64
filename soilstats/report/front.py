"""Page 1 of every report: the question, the data (measured or simulated, said plainly), and
the conclusion in sentences — so a reader who stops after one page has the answer.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

from ..campaign.io import resolve
from .document import Document, Markup, strong

__all__ = ["data_origin", "front_page"]


def data_origin(source: str) -> str:
    """Whether the campaign ``source`` is measured or simulated, in words for page 1.

    A campaign written by ``soilstats simulate`` carries ``truth.json`` next to its tables
    (the planted parameters); every other campaign is treated as measured data.
    """
    if not source or source == "<memory>":
        return "data passed in memory (origin not recorded)"
    try:
        folder, _ = resolve(source.removeprefix("bundled:"))
    except Exception:  # a source that no longer exists: say so rather than guess
        return f"{source} (origin not checked: the folder is no longer there)"
    if (Path(folder) / "truth.json").is_file():
        return f"SIMULATED data with known truth ({source}), not measurements"
    return f"measured data ({source})"


def front_page(
    doc: Document,
    *,
    question: Sequence[Markup | str],
    data: Sequence[Markup | str],
    conclusion: Sequence[Sequence[Markup | str] | Markup | str],
    defaults: Mapping[str, str] | None = None,
    default_warnings: Mapping[str, str] | None = None,
) -> None:
    """Question, data and conclusion sections; each conclusion item is one paragraph.
    ``defaults``: the options the user left at their defaults (``{"--alpha": "0.05"}``),
    said under Data, since the result rests on them; ``default_warnings``: those of them
    that move a verdict (``{"--alpha": "one line naming the verdict"}``), each a warning."""
    doc.heading("Question")
    doc.paragraph(*question)
    doc.heading("Data")
    doc.paragraph(*data)
    if defaults:
        doc.paragraph(
            "Settings left at their defaults (not given on the command line or in an input file): "
            + ", ".join(f"{k} {v}" for k, v in defaults.items())
            + "."
        )
    for text in (default_warnings or {}).values():
        doc.paragraph(strong("Warning: "), text, ".")
    doc.heading("Conclusion")
    for item in conclusion:
        parts = item if isinstance(item, list | tuple) else (item,)
        doc.paragraph(*parts)
