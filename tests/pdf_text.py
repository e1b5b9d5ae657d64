"""The careful reader's check of a report's PDF, read from its text boxes (issue #47 item 5):
no text below 8 pt, no text box overlapping another. Shared by tests/test_reports.py (every
report type) and tests/test_report_length.py (identify and discover on all four bundled
campaigns); tested itself on synthetic PDFs with planted defects (tests/test_pdf_text.py).

Equation glyphs (Typst's math font) are left out: their sub- and superscripts are set at
70 % and 50 % of the body and stacked, which is typesetting, not small print. So are the
scripts of a figure's mathtext (``m$^{n+2}$``): a smaller run set right after a glyph of full
size, raised or lowered from its baseline.

Figure text is real text (soilstats.report.document.figure_svg), read at its printed size: a
figure drawn wider than the page is scaled down, and its text with it.

Every glyph is measured in its own frame, upright or turned (an axis label set along the axis,
a tick label turned 45°): the char's matrix gives the direction of its baseline and its scale,
its advance the extent along the line, and pdfminer's box — the upright hull of the turned
glyph box — the extent across it (font size and descent, solved for). pdfminer's own ``size``
and ``height`` are those of the hull, which for a glyph turned 45° is neither. Two glyphs
overlap when their turned boxes share more than 1 pt along every edge direction of both
(separating axes), so turned text is tested against turned and upright text alike.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np
import pdfplumber

MIN_PT = 8.0
#: Shared depth (pt) along every edge direction beyond which two glyph boxes overlap: kerning
#: pulls neighbours of one word into each other by a fraction of a point.
OVERLAP_PT = 1.0


@dataclass(frozen=True)
class Glyph:
    """One char's box in its own frame: ``u`` the baseline's direction, ``v`` across it
    (page coordinates, y up); ``along`` and ``across`` its extents (pt) on those axes."""

    text: str
    fontname: str
    u: tuple[float, float]
    v: tuple[float, float]
    along: tuple[float, float]
    across: tuple[float, float]

    @property
    def angle(self) -> int:
        """The baseline's direction in whole degrees: glyphs of one line share it."""
        return round(math.degrees(math.atan2(self.u[1], self.u[0]))) % 360

    @property
    def size(self) -> float:
        """The printed size: the font size times the matrix's scale (pt)."""
        return self.across[1] - self.across[0]

    def corners(self) -> np.ndarray:
        u, v = np.array(self.u), np.array(self.v)
        return np.array([a * u + c * v for a in self.along for c in self.across])


def glyph(char: dict) -> Glyph:
    """The turned box of a pdfplumber char. Along the line: origin to origin plus the advance
    (pdfminer's ``adv`` is in text space: times the matrix's scale). Across it: the hull
    pdfminer gives spans the across extent projected on x (or y, whichever is better
    conditioned) plus the advance's projection, solved for the across extent."""
    a, b, c, d, e, f = char["matrix"]
    su, sv = math.hypot(a, b) or 1.0, math.hypot(c, d) or 1.0
    u, v = (a / su, b / su), (c / sv, d / sv)
    length = char["adv"] * su
    if abs(v[0]) >= abs(v[1]):
        lo_edge, hi_edge, origin, run, k = char["x0"], char["x1"], e, u[0] * length, v[0]
    else:
        lo_edge, hi_edge, origin, run, k = char["y0"], char["y1"], f, u[1] * length, v[1]
    p = lo_edge - origin - min(0.0, run)
    q = hi_edge - origin - max(0.0, run)
    lo, hi = (p / k, q / k) if k > 0 else (q / k, p / k)
    start = e * u[0] + f * u[1]
    base = e * v[0] + f * v[1]
    return Glyph(
        text=char["text"],
        fontname=char["fontname"],
        u=u,
        v=v,
        along=(start, start + length),
        across=(base + lo, base + hi),
    )


def _is_math(fontname: str) -> bool:
    return "Math" in fontname


def _size(char: dict) -> float:
    return glyph(char).size


def _scripts(glyphs: list[Glyph]) -> set[int]:
    """Indices of the sub- and superscripts among ``glyphs``: glyphs below :data:`MIN_PT` (at
    least half of it) and under 80 % of a full-size glyph they touch along the line (within
    1.5 pt), set off its edges by more than 1 pt across the line; and the glyphs of the same
    size running on from them (mathtext places its glyphs in any order, so this is a closure
    over positions, not over the stream)."""
    ink = [i for i, g in enumerate(glyphs) if g.text.strip()]
    big = [i for i in ink if glyphs[i].size >= MIN_PT - 0.05]
    small = [i for i in ink if MIN_PT / 2 <= glyphs[i].size < MIN_PT - 0.05]
    out: set[int] = set()
    frontier = list(big)
    while frontier:
        grown = []
        for i in small:
            if i in out:
                continue
            g = glyphs[i]
            for k in frontier:
                h = glyphs[k]
                if g.angle != h.angle:
                    continue
                lo = min(abs(g.along[0] - h.along[1]), abs(h.along[0] - g.along[1]))
                # on the same line, not a line away
                if not (g.across[0] < h.across[1] and h.across[0] < g.across[1]):
                    continue
                shifted = max(abs(g.across[0] - h.across[0]), abs(g.across[1] - h.across[1])) > 1
                ratio = g.size / h.size
                # a script is set at ~70 % of its base and runs on at its own size
                script = abs(ratio - 1) < 0.02 if k in out else ratio < 0.8 and shifted
                if lo < 1.5 and script:
                    out.add(i)
                    grown.append(i)
                    break
        frontier = grown
    return out


def _words(glyphs: list[Glyph]) -> list[int]:
    """The word of each glyph, for messages: runs of the text stream broken at blanks, at a
    turn and at a jump along the line."""
    word, out = 0, []
    for i, g in enumerate(glyphs):
        if i and not (
            glyphs[i - 1].text.strip()
            and g.text.strip()
            and g.angle == glyphs[i - 1].angle
            and abs(g.along[0] - glyphs[i - 1].along[1]) < 3.0
        ):
            word += 1
        out.append(word)
    return out


def _axes(glyphs: list[Glyph], i: int, j: int) -> list[np.ndarray]:
    return [np.array(ax) for ax in (glyphs[i].u, glyphs[i].v, glyphs[j].u, glyphs[j].v)]


def _shared(p: np.ndarray, q: np.ndarray) -> float:
    """The length two sets of projected corners share on their axis."""
    return float(min(p.max(), q.max()) - max(p.min(), q.min()))


def overlapping_pairs(glyphs: list[Glyph]) -> list[tuple[int, int]]:
    """Pairs (i, j) of glyphs whose turned boxes share more than :data:`OVERLAP_PT` along
    each edge direction of both boxes (the separating-axis test of two rectangles)."""
    if len(glyphs) < 2:
        return []
    corners = np.stack([g.corners() for g in glyphs])  # (n, 4, 2)
    lo, hi = corners.min(axis=1), corners.max(axis=1)  # upright hulls: a quick first cut
    order = np.argsort(lo[:, 0], kind="stable")
    pairs = []
    for rank, i in enumerate(order):
        rest = order[rank + 1 :]
        rest = rest[lo[rest, 0] < hi[i, 0]]
        rest = rest[(lo[rest, 1] < hi[i, 1]) & (lo[i, 1] < hi[rest, 1])]
        for j in rest:
            depth = min(_shared(corners[i] @ ax, corners[j] @ ax) for ax in _axes(glyphs, i, j))
            if depth > OVERLAP_PT:
                pairs.append((min(i, j), max(i, j)))
    return sorted(pairs)


def _kerned(glyphs: list[Glyph], i: int, j: int) -> bool:
    """Whether glyphs ``i`` < ``j`` are a kerned pair: next to each other in the text stream,
    on one baseline at one size, the second pulled into the first's advance by less than a
    quarter of the size ("VA", "Te" in a heading)."""
    g, h = glyphs[i], glyphs[j]
    return (
        j == i + 1
        and g.angle == h.angle
        and abs(g.across[0] - h.across[0]) < 0.1
        and abs(g.size - h.size) < 0.1
        and g.along[0] < h.along[0] < g.along[1] < h.along[1]
        and g.along[1] - h.along[0] < 0.25 * g.size
    )


def small_and_overlapping(path) -> list[tuple]:
    """[(page, "small", text) | (page, "overlap", a, b)] of the PDF at ``path``; ``a`` and
    ``b`` are the words holding two overlapping glyphs, each pair of words named once."""
    problems: list[tuple] = []
    with pdfplumber.open(path) as doc:
        for page in doc.pages:
            glyphs = [glyph(c) for c in page.chars]
            scripts = _scripts(glyphs)
            small = [
                g.text
                for i, g in enumerate(glyphs)
                if g.size < MIN_PT - 0.05
                and g.text.strip()
                and not _is_math(g.fontname)
                and i not in scripts
            ]
            if small:
                problems.append((page.page_number, "small", "".join(small)[:80]))
            ink = [i for i, g in enumerate(glyphs) if g.text.strip() and not _is_math(g.fontname)]
            words = _words(glyphs)
            text: dict[int, str] = {}
            for i, g in enumerate(glyphs):
                text[words[i]] = text.get(words[i], "") + g.text
            seen = set()
            for i, j in overlapping_pairs([glyphs[k] for k in ink]):
                if _kerned(glyphs, ink[i], ink[j]):
                    continue
                a, b = words[ink[i]], words[ink[j]]
                if (a, b) not in seen:
                    seen.add((a, b))
                    problems.append((page.page_number, "overlap", text[a], text[b]))
    return problems


#: What a Python object or API call printed as text looks like (issue #47 item 5: typeset
#: tables only): a dict or list of strings, numpy's scalar repr, a missing value, Python's None
#: as a value, an API attribute or call pointed to from a report.
PYTHON_TEXT = re.compile(
    r"\{'|\['|np\.float|\bnan\b|\bNaN\b|\bNone[.,;:)]|[:=]\s*None\b|to_dict\(\)|\bresult\.\w"
)


def python_text(path) -> list[tuple[int, str]]:
    """[(page, context)] of every :data:`PYTHON_TEXT` match in the PDF at ``path`` (its text
    with line breaks joined; soft hyphens and zero-width breaks removed)."""
    out = []
    with pdfplumber.open(path) as doc:
        for page in doc.pages:
            text = re.sub(r"[\u200b\u00ad]", "", page.extract_text() or "")
            text = re.sub(r"\s+", " ", text)
            for m in PYTHON_TEXT.finditer(text):
                out.append((page.page_number, text[max(0, m.start() - 40) : m.end() + 40]))
    return out
