"""The PDF text check itself (tests/pdf_text.py), on synthetic PDFs with known text: a check
that reads nothing passes every report, so each defect it exists for is planted and found,
and the same page without the defect passes (issue #47 item 5)."""

from __future__ import annotations

import math

import matplotlib
import pdfplumber
import pytest
from matplotlib.figure import Figure
from pdf_text import glyph, small_and_overlapping

from soilstats.report.document import Document

ANGLES = [0, 30, 45, 90, 135, 270]


def _matplotlib_pdf(path, texts: list[tuple[float, float, str, float]], size: float = 10.0):
    """A PDF written by matplotlib alone (TrueType text): each (x, y, text, angle) in figure
    fractions of a 4 × 4 in figure, anchored at its baseline's start, at ``size`` pt."""
    fig = Figure(figsize=(4, 4))
    for x, y, text, angle in texts:
        fig.text(x, y, text, rotation=angle, fontsize=size, rotation_mode="anchor")
    with matplotlib.rc_context({"pdf.fonttype": 42}):
        fig.savefig(path, format="pdf")
    return path


def test_a_turned_glyph_is_measured_at_its_set_size(tmp_path):
    """The truth is matplotlib's font size and the upright glyph's advance: pdfminer's box
    height is neither once a glyph is turned (its upright hull), the glyph's frame is both."""
    texts = [(0.1 + 0.13 * k, 0.5, "Sizes", angle) for k, angle in enumerate(ANGLES)]
    path = _matplotlib_pdf(tmp_path / "angles.pdf", texts)
    with pdfplumber.open(path) as doc:
        chars = doc.pages[0].chars
    glyphs = [glyph(c) for c in chars]
    assert sorted({g.angle for g in glyphs}) == sorted(ANGLES)
    upright = {g.text: g.along[1] - g.along[0] for g in glyphs if g.angle == 0}
    for char, g in zip(chars, glyphs, strict=True):
        assert g.size == pytest.approx(10.0, abs=0.01), (g.text, g.angle)
        assert g.along[1] - g.along[0] == pytest.approx(upright[g.text], abs=0.01)
        # the box's corners lie inside pdfminer's hull and touch each of its edges
        corners = g.corners()
        assert corners[:, 0].min() == pytest.approx(char["x0"], abs=0.01)
        assert corners[:, 0].max() == pytest.approx(char["x1"], abs=0.01)
        assert corners[:, 1].min() == pytest.approx(char["y0"], abs=0.01)
        assert corners[:, 1].max() == pytest.approx(char["y1"], abs=0.01)
    assert any(abs(c["size"] - 10.0) > 1.0 for c in chars)  # the hull's size is not it
    assert small_and_overlapping(path) == []


def _report(tmp_path, name: str, planted: list[tuple[float, float, str, float]]):
    """A one-figure report through the reports' own pipeline (figure text as real text):
    a plot with a turned axis label, plus the ``planted`` texts (x, y, text, angle) in
    axes fractions at 9 pt."""
    fig = Figure(figsize=(5, 3), layout="constrained")
    ax = fig.subplots()
    ax.plot([1, 2, 3], [3, 1, 2])
    ax.set_xlabel("slip s")
    ax.set_ylabel("drawbar pull (N)")
    for x, y, text, angle in planted:
        ax.text(x, y, text, rotation=angle, fontsize=9, transform=ax.transAxes)
    doc = Document("Planted text")
    doc.figure(fig, "A figure with planted labels.")
    path = tmp_path / name
    doc.render(path)
    return path


def _overlaps(path) -> list[tuple[str, str]]:
    return [(p[2], p[3]) for p in small_and_overlapping(path) if p[1] == "overlap"]


def test_a_planted_turned_overlap_is_found(tmp_path):
    """Two labels turned 90° set over each other, and a label turned 45° across upright text:
    both found (the old check left turned text out and passed them); the same figure with the
    labels apart passes."""
    turned = _report(
        tmp_path, "turned.pdf", [(0.3, 0.2, "VERTICALONE", 90), (0.31, 0.25, "VERTICALTWO", 90)]
    )
    found = _overlaps(turned)
    assert ("VERTICALONE", "VERTICALTWO") in found or ("VERTICALTWO", "VERTICALONE") in found
    crossed = _report(
        tmp_path, "crossed.pdf", [(0.5, 0.5, "UPRIGHTTEXT", 0), (0.55, 0.3, "DIAGONALTEXT", 45)]
    )
    assert {frozenset(pair) for pair in _overlaps(crossed)} == {
        frozenset({"UPRIGHTTEXT", "DIAGONALTEXT"})
    }
    apart = _report(
        tmp_path, "apart.pdf", [(0.2, 0.2, "VERTICALONE", 90), (0.6, 0.2, "DIAGONALTEXT", 45)]
    )
    assert small_and_overlapping(apart) == []


def test_turned_boxes_are_not_their_upright_hulls(tmp_path):
    """Two parallel lines turned 45°, 14 pt apart across the line at 10 pt: their upright
    hulls overlap by far, their boxes do not — nothing found; 6 pt apart, they do."""

    def parallel(gap_pt: float, name: str):
        dx = gap_pt / 288 * math.cos(math.radians(135))  # across a 45° line, 288 pt a side
        dy = gap_pt / 288 * math.sin(math.radians(135))
        texts = [(0.3, 0.3, "PARALLELONE", 45), (0.3 + dx, 0.3 + dy, "PARALLELTWO", 45)]
        return _matplotlib_pdf(tmp_path / name, texts)

    far = parallel(14.0, "far.pdf")
    with pdfplumber.open(far) as doc:
        chars = doc.pages[0].chars
    one = chars[:11]
    two = chars[11:]
    hull_overlap = min(max(c["x1"] for c in one), max(c["x1"] for c in two)) - max(
        min(c["x0"] for c in one), min(c["x0"] for c in two)
    )
    assert hull_overlap > 30  # what an upright-hull check would call an overlap
    assert small_and_overlapping(far) == []
    assert small_and_overlapping(parallel(6.0, "near.pdf")) != []


def test_python_text_is_found_and_prose_is_not(tmp_path):
    """A printed dict, list, numpy scalar, nan, None as a value and an API pointer are found;
    the same words as prose ("None of the tests", "[1, 2]" note numbers) are not."""
    from pdf_text import python_text

    from soilstats.report.document import Document

    planted = [
        "Physical support: {'b_m': 0.05}",
        "levels ['1', '10', '2']",
        "k = np.float64(3.2)",
        "mean nan kPa",
        "Best method: None.",
        "rows in to_dict()['excluded']",
        "per test in result.tests",
    ]
    doc = Document("Planted reprs")
    for text in planted:
        doc.paragraph(text)
    path = tmp_path / "reprs.pdf"
    doc.render(path)
    found = " | ".join(context for _, context in python_text(path))
    for needle in ("{'b_m'", "['1'", "np.float64", "nan kPa", "None.", "to_dict()", "result.tests"):
        assert needle in found, needle
    prose = Document("Prose")
    prose.paragraph("None of the 962 tests carries a screening code; notes [1, 2]; k_[0, inf).")
    prose.render(tmp_path / "prose.pdf")
    assert python_text(tmp_path / "prose.pdf") == []
