"""HTML for notebooks (``_repr_html_``): a result's summary as tables, escaped.

Jupyter shows a result by its ``_repr_html_`` when it has one; these helpers give every result
type the same look: a title, key facts, the main table and the numbered notes.
"""

from __future__ import annotations

import html
from collections.abc import Iterable, Mapping

import pandas as pd

__all__ = ["facts_html", "notes_html", "result_html", "table_html"]


def table_html(frame: pd.DataFrame, *, index: bool = False, caption: str | None = None) -> str:
    """``frame`` as an HTML table (cells escaped); ``caption`` above it."""
    body = frame.to_html(index=index, escape=True, border=0, na_rep="–")
    head = f"<p><b>{html.escape(caption)}</b></p>" if caption else ""
    return head + body


def facts_html(facts: Mapping[str, object]) -> str:
    """Label: value pairs on one line each."""
    items = "".join(
        f"<li><b>{html.escape(str(k))}</b>: {html.escape(str(v))}</li>" for k, v in facts.items()
    )
    return f"<ul style='list-style:none;padding-left:0'>{items}</ul>" if items else ""


def notes_html(notes: Iterable[object], title: str = "Notes") -> str:
    """Numbered notes, as the text summaries number them (each as its ``str``: a sentence,
    or a flag)."""
    texts = [str(n) for n in notes if str(n).strip()]
    if not texts:
        return ""
    items = "".join(f"<li>{html.escape(n)}</li>" for n in texts)
    return f"<p><b>{html.escape(title)}</b></p><ol>{items}</ol>"


def result_html(title: str, *parts: str) -> str:
    """A result: its title, then the parts in order."""
    return f"<div><h4>{html.escape(title)}</h4>{''.join(p for p in parts if p)}</div>"
