"""The careful reader's check of a report's PDF, read from its text boxes (issue #47 item 5):
no text below 8 pt, no text box overlapping another. Shared by tests/test_reports.py (every
report type) and tests/test_report_length.py (identify and discover on all four bundled
campaigns).

Equation glyphs (Typst's math font) are left out: their sub- and superscripts are set at
70 % and 50 % of the body and stacked, which is typesetting, not small print. So are the
scripts of a figure's mathtext (``m$^{n+2}$``): a smaller run set right after a glyph of full
size, raised or lowered from its baseline.

Figure text is real text (soilstats.report.document.figure_svg), read at its printed size: a
figure drawn wider than the page is scaled down, and its text with it. A rotated glyph (an axis
label set along the axis, a tick label turned 45°) is measured across its baseline — pdfminer
gives the height of its turned box as its size — and is left out of the box test, whose words
read along a horizontal line (turned labels are laid out by matplotlib, not checked here).
"""

from __future__ import annotations

import pdfplumber

MIN_PT = 8.0


def _is_math(fontname: str) -> bool:
    return "Math" in fontname


def _rotated(char: dict) -> bool:
    a, b = char["matrix"][:2]
    return abs(b) > 1e-3 * abs(complex(a, b))


def _size(char: dict) -> float:
    """The printed size. pdfminer gives a glyph's box height, which for a glyph turned by θ is
    adv·|sin θ| + size·|cos θ| (and its width adv·|cos θ| + size·|sin θ|): solved for size."""
    a, b = char["matrix"][:2]
    scale = abs(complex(a, b)) or 1.0
    cos, sin = abs(a) / scale, abs(b) / scale
    if cos >= sin:
        return float((char["height"] - char["adv"] * sin) / cos)
    return float((char["width"] - char["adv"] * cos) / sin)


def _along(c: dict) -> tuple[float, float, float, float]:
    """(start, end) along the line and the two edges across it."""
    return (
        (c["y0"], c["y1"], c["x0"], c["x1"])
        if _rotated(c)
        else (c["x0"], c["x1"], c["top"], c["bottom"])
    )


def _beside(c: dict, b: dict) -> bool:
    """Whether the boxes of ``c`` and ``b`` share some height across the line."""
    if _rotated(c):
        return c["x0"] < b["x1"] and b["x0"] < c["x1"]
    return c["top"] < b["bottom"] and b["top"] < c["bottom"]


def _scripts(chars: list[dict]) -> set[int]:
    """Indices of the sub- and superscripts among ``chars``: glyphs below :data:`MIN_PT` (at
    least half of it) and under 80 % of a full-size glyph they touch along the line (within
    1.5 pt), set off its edges by more than 1 pt across the line; and the glyphs of the same
    size running on from them (mathtext places its glyphs in any order, so this is a closure
    over positions, not over the stream)."""
    ink = [i for i, c in enumerate(chars) if c["text"].strip()]
    big = [i for i in ink if _size(chars[i]) >= MIN_PT - 0.05]
    small = [i for i in ink if MIN_PT / 2 <= _size(chars[i]) < MIN_PT - 0.05]
    out: set[int] = set()
    frontier = list(big)
    while frontier:
        grown = []
        for i in small:
            if i in out:
                continue
            c0, c1, ca, cb = _along(chars[i])
            for k in frontier:
                if _rotated(chars[k]) != _rotated(chars[i]):
                    continue
                b0, b1, ba, bb = _along(chars[k])
                lo = min(abs(c0 - b1), abs(b0 - c1))
                if not _beside(chars[i], chars[k]):  # on the same line, not a line away
                    continue
                shifted = max(abs(ca - ba), abs(cb - bb)) > 1.0
                ratio = _size(chars[i]) / _size(chars[k])
                # a script is set at ~70 % of its base and runs on at its own size
                script = abs(ratio - 1) < 0.02 if k in out else ratio < 0.8 and shifted
                if lo < 1.5 and script:
                    out.add(i)
                    grown.append(i)
                    break
        frontier = grown
    return out


def small_and_overlapping(path) -> list[tuple]:
    """[(page, "small", text) | (page, "overlap", a, b)] of the PDF at ``path``."""
    problems: list[tuple] = []
    with pdfplumber.open(path) as doc:
        for page in doc.pages:
            chars = page.chars
            scripts = _scripts(chars)
            small = [
                c["text"]
                for i, c in enumerate(chars)
                if _size(c) < MIN_PT - 0.05
                and c["text"].strip()
                and not _is_math(c["fontname"])
                and i not in scripts
            ]
            if small:
                problems.append((page.page_number, "small", "".join(small)[:80]))
            level = page.filter(lambda o: o.get("object_type") != "char" or not _rotated(o))
            boxes = [
                w
                for w in level.extract_words(extra_attrs=["fontname", "size"])
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
