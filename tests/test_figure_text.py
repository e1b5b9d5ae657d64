"""Text stays text in figures (issue #44, item 6): data labels never go through mathtext.

A soil, level or series name is data: ``$x^{$`` once stopped identify and study with
matplotlib's mathtext parser error, and ``$5 and $6`` printed in italics without its dollars.
soilstats' own symbols (``$k_c$``) are marked as mathtext where they are made.
"""

from __future__ import annotations

import matplotlib
import pytest
from matplotlib.figure import Figure
from matplotlib.text import Text

from soilstats.report.document import figure_svg, math_text, tight_layout

HOSTILE = ["$x^{$", "$5 and $6", "a_b $\\alpha$"]


def _figure(labels: list[str], *, layout: object = None) -> Figure:
    fig = Figure(figsize=(3, 2))
    ax = fig.subplots()
    ax.bar(labels, [1, 2, 3], label=labels[0])  # categorical ticks: made while drawing
    ax.set_title(labels[1])
    ax.legend()
    fig.suptitle(labels[2])
    if layout is not None:
        layout(fig)
    return fig


def _matplotlib_svg(fig: Figure) -> bytes:
    """What figure_svg writes, by matplotlib alone (mathtext on, as by default)."""
    import io

    buffer = io.BytesIO()
    style = {"svg.hashsalt": "soilstats", "svg.fonttype": "none", "text.parse_math": True}
    with matplotlib.rc_context(style):
        fig.savefig(buffer, format="svg", metadata={"Date": None})
    return buffer.getvalue()


def test_data_labels_print_as_written():
    """The truth: the same labels with every ``$`` escaped (matplotlib's documented way to
    print a dollar sign) render to the very same SVG."""
    escaped = [t.replace("$", r"\$") for t in HOSTILE]
    assert figure_svg(_figure(HOSTILE)) == _matplotlib_svg(_figure(escaped))
    # Laid out, the labels are measured before any drawing (where the parser error came from).
    expected = _matplotlib_svg(_figure(escaped, layout=Figure.tight_layout))
    assert figure_svg(_figure(HOSTILE, layout=tight_layout)) == expected


def test_our_own_symbols_stay_mathtext():
    def labelled(mark: bool) -> bytes:
        fig = Figure(figsize=(2, 2))
        text = fig.subplots().set_ylabel(r"$k_\varphi$ (kN/m$^{n+2}$)")
        if mark:
            math_text(text)
        return figure_svg(fig)

    assert labelled(True) != labelled(False)  # typeset, not printed with its dollars


@pytest.mark.parametrize("command", ["identify"])
def test_a_soil_named_like_mathtext_gives_a_report(command, tmp_path, capsys):
    from soilstats.campaign import load_campaign
    from soilstats.cli.main import main

    folder = load_campaign("simulated-paper").select(soil="soil01").save(tmp_path / "camp")
    tests = folder / "tests.csv"
    tests.write_text(tests.read_text(encoding="utf-8").replace("soil01", "$x^{$"), "utf-8")
    assert main([command, "--data", str(folder), "--out", str(tmp_path / "o")]) == 0
    assert "ParseSyntaxException" not in capsys.readouterr().err
    assert (tmp_path / "o" / "identify.pdf").stat().st_size > 0


def _report_with(tmp_path, size: float, name: str):
    from soilstats.report.document import Document

    fig = Figure(figsize=(6.4, 2.4), layout="constrained")  # narrower than the text
    ax = fig.subplots()
    ax.plot([1, 2], [3, 4])
    ax.set_xlabel("slip s", fontsize=size)
    ax.tick_params(labelsize=size)
    math_text(ax.set_ylabel(r"$k_\varphi$ (kN/m$^{n+2}$)", fontsize=9))  # rotated, scripts
    doc = Document("Figure text")
    doc.figure(fig, "A figure.")
    path = tmp_path / name
    doc.render(path)
    return path


def test_figure_text_is_real_text_the_pdf_check_reads(tmp_path):
    """Issue #47 item 5: figure text reaches the PDF as text (it was outlines, which no text
    test can see): 6 pt ticks are found, 9 pt ones are not, and neither the rotated axis
    label nor its mathtext scripts are flagged; the same figure gives the same bytes."""
    import sys
    from pathlib import Path

    import pdfplumber

    sys.path.insert(0, str(Path(__file__).parent))
    from pdf_text import small_and_overlapping

    small = _report_with(tmp_path, 6, "small.pdf")
    with pdfplumber.open(small) as doc:
        text = "".join(c["text"] for c in doc.pages[0].chars)
    assert "slip s" in text and "1.0" in text  # the axis label and ticks, as text
    assert any(p[1] == "small" and "slips" in p[2] for p in small_and_overlapping(small))
    fine = _report_with(tmp_path, 9, "fine.pdf")
    assert small_and_overlapping(fine) == []
    assert fine.read_bytes() == _report_with(tmp_path, 9, "again.pdf").read_bytes()


def _clipped_texts(fig) -> list[str]:
    """Texts drawn past the figure's edge (tick labels outside their axis' view are not
    drawn and do not count): the PDF text check cannot see a label cut at the edge."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    width, height = fig.bbox.width, fig.bbox.height
    out = []
    for text in fig.findobj(Text):
        if not (text.get_visible() and text.get_text().strip()):
            continue
        for ax in fig.axes:
            if text in ax.get_xticklabels() or text in ax.get_yticklabels():
                lo, hi = sorted(ax.get_xlim() if text in ax.get_xticklabels() else ax.get_ylim())
                pos = text.get_position()[0 if text in ax.get_xticklabels() else 1]
                if not lo - 1e-9 * (hi - lo) <= pos <= hi + 1e-9 * (hi - lo):
                    break
        else:
            box = text.get_window_extent(renderer)
            if box.x0 < -0.5 or box.y0 < -0.5 or box.x1 > width + 0.5 or box.y1 > height + 0.5:
                out.append(text.get_text())
    return out


def test_no_study_figure_text_runs_past_the_figure_edge():
    """The velocity study repeated "penetration velocity (m/s)" under each of three panels and
    the last ran past the page edge (issue #47, item 5); now one label under all panels."""
    from soilstats.campaign import load_campaign
    from soilstats.data import bundled_path
    from soilstats.report.study_figures import make_figures
    from soilstats.study import run_study

    campaign = load_campaign(bundled_path("simulated-paper"))
    result = run_study("velocity", campaign)
    figures = make_figures(result, campaign)
    assert figures
    for title, fig, _ in figures:
        assert not _clipped_texts(fig), (title, _clipped_texts(fig))


def test_a_system_font_in_the_users_style_is_set_in_a_shipped_font(tmp_path):
    """Typst sees only matplotlib's own fonts: text in a family it cannot find would be drawn
    in a substitute with other metrics than the layout's (review of issue #47, item 5)."""
    fig = Figure(figsize=(4, 2))
    label = fig.subplots().set_xlabel("slip s")
    label.set_fontfamily("a family no machine has")
    svg = figure_svg(fig).decode()
    assert "a family no machine has" not in svg and "DejaVu Sans" in svg
