"""The careful reader's check of a report's PDF, read from its text boxes (issue #47 item 5):
no text below 8 pt, no text box overlapping another. Shared by tests/test_reports.py (every
report type) and tests/test_report_length.py (identify and discover on all four bundled
campaigns).

Equation glyphs (Typst's math font) are left out: their sub- and superscripts are set at
70 % and 50 % of the body and stacked, which is typesetting, not small print.
"""

from __future__ import annotations

import pdfplumber

MIN_PT = 8.0


def _is_math(fontname: str) -> bool:
    return "Math" in fontname


def small_and_overlapping(path) -> list[tuple]:
    """[(page, "small", text) | (page, "overlap", a, b)] of the PDF at ``path``."""
    problems: list[tuple] = []
    with pdfplumber.open(path) as doc:
        for page in doc.pages:
            small = [
                c["text"]
                for c in page.chars
                if c["size"] < MIN_PT - 0.05 and c["text"].strip() and not _is_math(c["fontname"])
            ]
            if small:
                problems.append((page.page_number, "small", "".join(small)[:80]))
            boxes = [
                w
                for w in page.extract_words(extra_attrs=["fontname", "size"])
                if not _is_math(w["fontname"])
            ]
            for i, a in enumerate(boxes):
                for b in boxes[i + 1 :]:
                    # shared area of more than 1 pt each way: a title into a label, a cell
                    # into the next
                    if (
                        min(a["x1"], b["x1"]) - max(a["x0"], b["x0"]) > 1.0
                        and min(a["bottom"], b["bottom"]) - max(a["top"], b["top"]) > 1.0
                    ):
                        problems.append((page.page_number, "overlap", a["text"], b["text"]))
    return problems
