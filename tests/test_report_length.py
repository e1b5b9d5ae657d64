"""Reports of publishable length on the bundled campaigns (issue #36): identify at most 8
pages with a figure per soil, discover at most 12 with its findings as a grid of figures,
check with no fixed glossary. The figures count soils and the
pages count what a reader must turn; the completeness of each report (every flag and note of
its JSON in the PDF) is tests/test_reports.py's."""

from __future__ import annotations

import json
import re

import pytest
from pdf_text import python_text, small_and_overlapping
from pypdf import PdfReader

from soilstats.cli.main import main

IDENTIFY_MAX_PAGES = 8

CAMPAIGNS = [
    pytest.param("simulated-paper", marks=pytest.mark.slow),  # 38 fits and their bootstraps
    "cmu-3d-terramechanics",
    pytest.param("cullinan-sand", marks=pytest.mark.slow),
    pytest.param("grc1-oravec2009", marks=pytest.mark.slow),
]


def _run(argv: list[str], out) -> None:
    assert main([*argv, "--out", str(out), "--progress", "off"]) == 0, argv


@pytest.mark.parametrize("campaign", CAMPAIGNS)
def test_identify_report_fits_in_eight_pages_with_a_figure_per_soil(campaign, tmp_path):
    _run(["identify", "--data", campaign], tmp_path)
    reader = PdfReader(tmp_path / "identify.pdf")
    assert len(reader.pages) <= IDENTIFY_MAX_PAGES, len(reader.pages)
    assert small_and_overlapping(tmp_path / "identify.pdf") == []  # issue #47
    assert python_text(tmp_path / "identify.pdf") == []
    soils = {fit["soil"] for fit in json.loads((tmp_path / "identify.json").read_text())["fits"]}
    text = re.sub(r"\s+", "", "".join(page.extract_text() for page in reader.pages))
    captions = [f"Figure{k}:" for k in range(1, len(soils) + 1)]
    assert all(c in text for c in captions), (soils, [c for c in captions if c not in text])
    assert f"Figure{len(soils) + 1}:" not in text  # one per soil, not one per condition
    assert "{'column'" not in text  # conditions in words, never Python dict text


def test_check_report_links_the_documentation_instead_of_a_glossary(tmp_path):
    _run(["check", "--data", "cmu-3d-terramechanics"], tmp_path)
    reader = PdfReader(tmp_path / "check.pdf")
    text = "".join(page.extract_text() for page in reader.pages)
    assert "docs/quality.md" in text
    assert "Glossary" not in text and "glossary" not in text
    assert len(reader.pages) <= 6, len(reader.pages)


DISCOVER_MAX_PAGES = 13  # 8 pt figures (issue #47 item 5): simulated-paper takes 13

DISCOVER_CAMPAIGNS = [
    pytest.param("simulated-paper", marks=pytest.mark.slow),  # 12 findings, 104 not found
    "cmu-3d-terramechanics",  # the most findings of the real ones; the others with CI's
    pytest.param("cullinan-sand", marks=pytest.mark.slow),
    pytest.param("grc1-oravec2009", marks=pytest.mark.slow),
]


@pytest.mark.parametrize("campaign", DISCOVER_CAMPAIGNS)
def test_discover_report_fits_in_thirteen_pages_with_its_findings_drawn(campaign, tmp_path):
    """The findings as a grid of figures (at most four findings a figure), every exhaustive
    list in one appendix table; the completeness is tests/test_reports.py's."""
    _run(["discover", "--data", campaign], tmp_path)
    reader = PdfReader(tmp_path / "discover.pdf")
    assert len(reader.pages) <= DISCOVER_MAX_PAGES, len(reader.pages)
    assert small_and_overlapping(tmp_path / "discover.pdf") == []  # issue #47
    assert python_text(tmp_path / "discover.pdf") == []
    findings = json.loads((tmp_path / "discover.json").read_text())["findings"]
    text = re.sub(r"\s+", "", "".join(page.extract_text() for page in reader.pages))
    figures = -(-len(findings) // 4)  # four findings a figure: 8 pt text, one to a row
    assert all(f"Figure{k}:" in text for k in range(1, figures + 1))
    assert f"Figure{figures + 1}:" not in text  # a grid, not a figure per finding
    assert "Appendix" in text
